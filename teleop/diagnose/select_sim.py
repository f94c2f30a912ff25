"""Effect selection for a simulated model against a dynamic recording: the finger against a
``teleop sim`` or ``teleop up --record`` recording (the model object, :class:`SimulatedModel`,
comes from ``sim/finger_dynamic.py``; the CLI wires it in, this module never imports ``sim/``).

Greedy forward selection: the model's candidates (``model.candidates()``) are screened on a
value grid with the current model held, the best ``refine_top`` are fitted jointly with the
refined nominal parameters, and the first one that passes the shared selection rule
(:mod:`teleop.diagnose.criterion`: penalised likelihood with an effective sample size, plus
held-out gain on interleaved blocks the fit did not see) is kept.  A model that can carry a
position-periodic sin/cos pair (``ripple_waves()``: the finger's shaft ripple) has it as one
more candidate, ``term:periodic`` (:mod:`teleop.diagnose.select_sim_terms`), reported apart
from the catalog effects.  Selection stops when the training residual is at the floor (noise
and the coarse physics step's own error).
"""

from __future__ import annotations

import math
import sys
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, Protocol

import numpy as np

from teleop.diagnose import engine
from teleop.diagnose.criterion import DEFAULT, Criterion, Verdict, unexplained
from teleop.diagnose.ee_noise import excess_windows
from teleop.diagnose.library import PERIODIC
from teleop.diagnose.select_sim_terms import each, fit_pair, has_pair, runs, without_pair
from teleop.diagnose.windows import Window, conditions, where_text
from teleop.effects import EffectSet

Array = np.ndarray


class SimulatedModel(Protocol):
    """What the selection needs of a model simulated against a recording.  A model may also
    have ``map(fn, items)``: the selection then hands it every batch of independent
    simulations and fits (``select_sim_terms.each``; the finger runs them on every core);
    and ``lead_fits(fit)`` with ``alignment()``: its input's timing between rows, which the
    rule decides (:func:`aligned`)."""

    dt_s: float      # physics step (a dead time is polished in whole steps)

    @property
    def data(self) -> Any:
        """The recording as the fit sees it: ``y``, ``keep`` and ``split()``; if it has them,
        ``t_s`` (the report then says where a residual is unexplained) and ``force_mode``."""

    def candidates(self) -> dict[str, tuple[tuple[float, ...], tuple[float, float]]]:
        """Effect name -> (screening grid, bounds)."""

    def nominal_start(self) -> tuple[float, ...]:
        """The calibrated values of the refined parameters."""

    def floor(self) -> tuple[float, float]:
        """(floor, physics-step error), rms: what no effect can explain."""

    def run(self, theta: Any, effects: tuple[tuple[str, float], ...]) -> Array:
        """Simulated output on the compared samples."""

    def rss(self, y: Array) -> float:
        """Training residual sum of squares of a simulated output."""

    def residual(self, f: Any) -> Array:
        """Training residual of a fit."""

    def fit(self, theta0: Any, effects: tuple[tuple[str, float], ...]) -> Any:
        """Least-squares fit (``theta``, ``effects``, ``rss``, ``rss_test``, ``y``)."""

    def finish(self, theta: Any, effects: tuple[tuple[str, float], ...]) -> Any:
        """A fit object for given values (no fitting)."""


@dataclass(frozen=True, slots=True)
class DynamicDiagnosis:
    """What the dynamic finger diagnosis found."""

    nominal: Any                                   # the model's fit objects
    final: Any
    chosen: tuple[tuple[str, float, float], ...]   # (effect, final value, step rss reduction)
    ranking: tuple[tuple[str, float], ...]         # (effect, relative rss reduction), best first
    floor_rad: float                               # noise + physics-step error (rms)
    y_meas: Array
    verdicts: tuple[Verdict, ...] = ()             # of the chosen effects
    rejected: tuple[tuple[str, str], ...] = ()     # (effect, why) of the best refused ones
    warning: str | None = None                     # unexplained residual
    scores: tuple[tuple[str, float], ...] = ()     # (effect, the rule's score), fitted ones
    ambiguous: tuple[str, ...] = ()                # pairs the data cannot separate
    unexplained_where: tuple[Window, ...] = ()     # where the final residual stays over it
    terms: tuple[tuple[str, float], ...] = ()      # a position-periodic pair found (final)
    term_verdict: Verdict | None = None            # the rule's verdict on it
    model: Any = None                              # the model selected on (aligned)
    alignment: str | None = None                   # its input alignment, in words


def _say(progress: Callable[[str], None] | None, msg: str) -> None:
    if progress is not None:
        progress(msg)


def _polish_delay(model: SimulatedModel, f: Any, steps: int = 6) -> Any:
    """A delay acts in whole physics steps, where least squares sees no gradient: scan whole
    steps around the fitted value (the other values held)."""
    eff = dict(f.effects)
    tried = [tuple((n, z if n == "dead_time" else v) for n, v in f.effects)
             for k in range(-steps, steps + 1)
             if k != 0 and (z := eff["dead_time"] + k * model.dt_s) >= 0]
    best, best_rss = None, f.rss
    for e, y in zip(tried, runs(model, [(f.theta, e) for e in tried]), strict=True):
        r = model.rss(y)
        if r < best_rss:
            best, best_rss = e, r
    return f if best is None else model.finish(f.theta, best)


#: a delay is fitted from this many of its best screening points
DELAY_STARTS = 2
#: no position-periodic term is scanned when a catalog candidate of the step already leaves
#: the training residual within this factor of the floor: with two parameters more (and its
#: scanned wavenumber) the term would outscore it only by fitting the noise.  The scan is the
#: costly part (two simulations per wavenumber: on a 60 s, 1 kHz recording 568 simulations,
#: about 24 s of CPU)
SCAN_FLOOR = 1.1


def _fit_delay(model: SimulatedModel, effects: tuple[tuple[str, float], ...],
               pts: list[tuple[float, float, Any]]) -> Any:
    """A delay's residual is rugged (it acts in whole physics steps, and the refined
    parameters bend with it), so a fit from one screening point stops in the nearest dip:
    on an independent force recording with a 98 ms delay, the grid's 60 ms point screened a
    hair better than its 100 ms point and the fit from it stopped at 75 ms (RSS 2.7x that of
    the fit from 100 ms, which found 98 ms), and the lag beat it.  So the delay is fitted
    from its ``DELAY_STARTS`` best screening points of different values, each polished, and
    the best kept."""
    starts: dict[float, Any] = {}
    for _, z, theta in pts:
        if len(starts) == DELAY_STARTS:
            break
        starts.setdefault(z, theta)
    best = None
    for f in each(model, lambda s: _polish_delay(model, model.fit(s[1], effects
                                                                  + (("dead_time", s[0]),))),
                  list(starts.items())):
        if best is None or f.rss < best.rss:
            best = f
    return best


def _where(t: Array, y: Array, r: Array, floor: float, extra: dict[str, Array] | None
           ) -> tuple[Window, ...]:
    """Where the final residual ``r`` of the measured output ``y`` stays over 3x the floor
    (0.2 s moving rms), labelled by the operating condition (and the ``extra`` masks, e.g. the
    servo mode), each with the output's range in it: the axis path's windows
    (:func:`teleop.diagnose.ee_noise.excess_windows`) with a constant floor."""
    ok = np.isfinite(r) & np.isfinite(y)
    if floor <= 0 or ok.sum() < 3:
        return ()
    with np.errstate(divide="ignore", invalid="ignore"):
        v = np.gradient(y, t)  # a repeated time stamp: velocity 0 there, not a warning
    conds = conditions(t, y, np.where(np.isfinite(v), v, 0.0), None)
    conds.update(extra or {})
    return excess_windows(t, y, np.where(ok, r, 0.0), np.full(len(t), floor), ok, conds)


def screen_starts(theta: Any, nom0: tuple[float, ...]) -> tuple[Any, ...]:
    """The parameter sets a candidate is screened from: the current ones and the calibrated.

    The refined nominal parameters may have bent to mimic the missing physics (on a 60 s
    recording concealing 1 N of Coulomb friction the motor gain went to its +20 % bound); with
    them held, the missing effect itself screens worse than nothing (RSS x52) and is never
    fitted.  So each candidate is screened on its grid from both, and fitted from whichever
    did better."""
    return (theta,) if tuple(theta) == tuple(nom0) else (theta, nom0)


def _rms(rss: float, n: int) -> float:
    return math.sqrt(rss / max(n, 1))


@dataclass
class SimPath:
    """A simulated model's path for the engine (:mod:`teleop.diagnose.engine`): candidates
    screened on a value grid with the current model held, the best ``refine_top`` fitted
    jointly with the refined nominal parameters; held-out gain on the interleaved blocks the
    fit never sees.  ``screened`` logs the first step's screening (effect, relative RSS
    reduction) for the report."""

    model: SimulatedModel
    refine_top: int
    floor_factor: float
    progress: Callable[[str], None] | None
    nom0: tuple[float, ...]
    floor: float
    n_train: int
    n_test: int
    screened: list[tuple[str, float]] = field(default_factory=list)

    def rss(self, f: Any) -> float:
        return float(f.rss)

    def residual(self, f: Any) -> Array:
        return self.model.residual(f)

    def k_added(self, base: Any, f: Any) -> int:
        # a sin/cos pair's scanned wavenumber counts as one more parameter
        return len(f.effects) - len(base.effects) + int(has_pair(f.effects)
                                                         and not has_pair(base.effects))

    def at_floor(self, current: Any, n_chosen: int) -> bool:
        return _rms(current.rss, self.n_train) < self.floor_factor * self.floor

    def without(self, current: Any, name: str, f: Any) -> Any:
        """``f`` with ``name`` removed, its refined parameters and other effects held
        (:func:`teleop.diagnose.engine.own_share`)."""
        if name == PERIODIC:
            return self.model.finish(f.theta, without_pair(f.effects))
        return self.model.finish(f.theta, tuple((n, v) for n, v in f.effects if n != name))

    def holdout(self, current: Any, name: str, f: Any) -> tuple[float, bool]:
        hg = (1.0 - f.rss_test / current.rss_test
              if self.n_test and current.rss_test > 0 else math.nan)
        return hg, _rms(current.rss_test, self.n_test) > self.floor_factor * self.floor

    def fit_candidates(self, current: Any, names: tuple[str, ...]) -> list[tuple[str, Any]]:
        model = self.model
        cands = model.candidates()
        starts = screen_starts(current.theta, self.nom0)
        screened = []
        for name in names:
            if name == PERIODIC:
                continue
            grid = cands[name][0]
            zs = [(z, th) for z in grid for th in starts]
            ys = runs(model, [(th, current.effects + ((name, z),)) for z, th in zs])
            pts = sorted(((model.rss(y), z, th) for (z, th), y in zip(zs, ys, strict=True)),
                         key=lambda x: x[0])
            screened.append((pts[0][0], name, pts))   # (best RSS, name, points best first)
        screened.sort(key=lambda x: x[0])
        _say(self.progress, "screened: " + ", ".join(f"{nm} {1 - r / current.rss:+.0%}"
                                                       for r, nm, _ in screened[:4]))
        top = screened[:self.refine_top]
        _say(self.progress, "fitting " + ", ".join(name for _, name, _ in top))

        def fit_one(item: tuple[float, str, list[tuple[float, float, Any]]]) -> Any:
            _, name, pts = item
            if name == "dead_time":
                return _fit_delay(model, current.effects, pts)
            _, z, theta = pts[0]
            return model.fit(theta, current.effects + ((name, z),))

        out = [(name, f) for (_, name, _), f in zip(top, each(model, fit_one, top),
                                                     strict=True)]
        best = min((g.rss for _, g in out), default=math.inf)
        if PERIODIC in names and _rms(best, self.n_train) > SCAN_FLOOR * self.floor:
            f = fit_pair(model, current, self.progress)
            if f is not None:
                out.append((PERIODIC, f))
        if not current.effects:
            gains = sorted(((nm, 1.0 - f.rss / current.rss) for nm, f in out),
                           key=lambda x: -x[1])
            self.screened = gains + [(nm, 1.0 - r / current.rss)
                                     for r, nm, _ in screened[self.refine_top:]]
        return out


@dataclass(frozen=True, slots=True)
class _LeadPath:
    """The engine's view of an input lead (:func:`aligned`): one more fitted parameter on
    top of the same fit, judged as a path's effects are."""

    sim: SimPath

    def rss(self, f: Any) -> float:
        return self.sim.rss(f)

    def residual(self, f: Any) -> Array:
        return self.sim.residual(f)

    def k_added(self, base: Any, f: Any) -> int:
        return 1

    def holdout(self, current: Any, name: str, f: Any) -> tuple[float, bool]:
        return self.sim.holdout(current, name, f)


def aligned(path: SimPath, fit: Any) -> tuple[SimulatedModel, Any]:
    """The model at the input lead the rule keeps for ``fit``'s effects, and its fit.

    A model that can say (``lead_fits(fit)``: the model at no lead and at each lead, each
    fitted; the finger's ``sim.finger_dynamic``) has every lead judged against no lead by the
    engine's rule (:func:`teleop.diagnose.engine.accept_first`: the penalised likelihood
    with the effective sample size, then the held-out gain), best score first; none kept:
    the model at no lead.  Any other model: ``path.model`` and ``fit``."""
    lead_fits = getattr(path.model, "lead_fits", None)
    cands = [] if lead_fits is None else lead_fits(fit)
    if not cands:
        return path.model, fit
    rule = _LeadPath(path)
    none = cands[0][1]
    ranked = sorted(((engine.score(rule, none, f), str(i), f)
                     for i, (_, f) in enumerate(cands[1:], 1)), key=lambda c: -c[0])
    step, _ = engine.accept_first(rule, none, ranked)
    return cands[0] if step is None else cands[int(step.name)]


def diagnose_dynamic(model: SimulatedModel, refine_top: int = 3, max_effects: int = 2,
                     floor_factor: float = 2.0, criterion: Criterion = DEFAULT,
                     progress: Callable[[str], None] | None = None) -> DynamicDiagnosis:
    """Nominal fit, then forward selection of catalog effects by the engine."""
    data = model.data
    ym = data.y[data.keep]
    tr, te = data.split()
    nom0 = model.nominal_start()
    floor, step_err = model.floor()
    step_s = getattr(model, "physics_step_s", lambda: model.dt_s)()
    _say(progress, f"physics step {step_s * 1e3:.1f} ms: error {step_err:.2g} rad; floor "
                   f"{floor:.2g} rad; fitting the nominal finger ({len(ym)} samples, "
                   f"{len(te)} held out)")
    nominal = model.fit(nom0, ())

    def path_of(m: SimulatedModel) -> SimPath:
        return SimPath(m, refine_top, floor_factor, progress, nom0, floor, len(tr), len(te))

    model, nominal = aligned(path_of(model), nominal)
    alignment = getattr(model, "alignment", lambda: None)()
    if alignment is not None:
        _say(progress, f"input alignment: {alignment}")
    path = path_of(model)
    cands = model.candidates()
    names = (*cands, *((PERIODIC,) if hasattr(model, "ripple_waves") else ()))
    sel = engine.forward(path, nominal, names, max_effects, engine.Rule(criterion=criterion))
    chosen = []
    verdicts = []
    prev = nominal
    final_fit = sel.final
    # the effects found may move the input's timing back
    model, final_fit = aligned(path_of(model), final_fit)
    alignment = getattr(model, "alignment", lambda: None)()
    final = dict(final_fit.effects)  # every value as it stands in the final (joint) model
    gone = {n for n, v in final.items() if n in cands and at_absent_value(n, v, cands[n][1])}
    terms: tuple[tuple[str, float], ...] = ()
    term_verdict = None
    for st in sel.steps:
        if st.name == PERIODIC:  # outside the catalog: reported as a term, not an effect
            terms = tuple((n, v) for n, v in final_fit.effects if n not in cands)
            term_verdict = st.verdict
        elif st.name not in gone:  # an effect the joint model fitted away is not named
            chosen.append((st.name, final.get(st.name, st.fit.effects[-1][1]),
                           1.0 - st.fit.rss / prev.rss))
            verdicts.append(st.verdict)
        prev = st.fit
    if gone:
        final_fit = model.finish(final_fit.theta, tuple((n, v) for n, v in final_fit.effects
                                                        if n not in gone))
    warn = unexplained(_rms(final_fit.rss, len(tr)), floor)
    where: tuple[Window, ...] = ()
    if warn is not None and getattr(data, "t_s", None) is not None:
        modes = getattr(data, "force_mode", None)  # per row, if the model's data says
        extra = (None if modes is None or modes.all() or not modes.any()
                 else {"force mode": modes[data.keep], "position mode": ~modes[data.keep]})
        where = _where(np.asarray(data.t_s, float)[data.keep], ym, final_fit.y - ym, floor,
                       extra)
        warn += where_text(where)
    return DynamicDiagnosis(nominal, final_fit, tuple(chosen), tuple(path.screened), floor, ym,
                            tuple(verdicts), sel.rejected[:3], warn, sel.ranking, sel.ambiguous,
                            where, terms, term_verdict, model, alignment)


#: an effect within this share of its fit range of the value meaning "absent" is absent
ABSENT_SHARE = 1e-4


def at_absent_value(name: str, value: float, bounds: tuple[float, float]) -> bool:
    """Whether ``value`` is the catalog effect's absent value (``EffectSet``'s neutral one: 0
    for a friction, 1 for a gain, inf for a saturation), to ``ABSENT_SHARE`` of its range
    (a bounded fit stops a hair inside its bound)."""
    absent = getattr(EffectSet(), name)
    if math.isinf(absent) or math.isinf(value):
        return value == absent
    return abs(value - absent) <= ABSENT_SHARE * (bounds[1] - bounds[0])


def print_progress(msg: str) -> None:
    """Progress line on stderr."""
    print(f"diagnose: {msg}", file=sys.stderr, flush=True)
