"""Effect selection for a simulated model against a dynamic recording: the finger against a
``teleop sim`` or ``teleop up --record`` recording (the model object, :class:`SimulatedModel`,
comes from ``sim/finger_dynamic.py``; the CLI wires it in, this module never imports ``sim/``).

Greedy forward selection: the model's candidates (``model.candidates()``) are screened on a
value grid with the current model held, the best ``refine_top`` are fitted jointly with the
refined nominal parameters, and the first one that passes the shared selection rule
(:mod:`teleop.diagnose.criterion`: penalised likelihood with an effective sample size, plus
held-out gain on interleaved blocks the fit did not see) is kept.  Selection stops when the
training residual is at the floor (noise and the coarse physics step's own error).
"""

from __future__ import annotations

import math
import sys
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np

from teleop.diagnose.criterion import DEFAULT, Criterion, Verdict, judge, unexplained

Array = np.ndarray


class SimulatedModel(Protocol):
    """What the selection needs of a model simulated against a recording."""

    dt_s: float      # physics step (a dead time is polished in whole steps)

    @property
    def data(self) -> Any:
        """The recording as the fit sees it: ``y``, ``keep`` and ``split()``."""

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
    chosen: tuple[tuple[str, float, float], ...]   # (effect, value, relative rss reduction)
    ranking: tuple[tuple[str, float], ...]         # (effect, relative rss reduction), best first
    floor_rad: float                               # noise + physics-step error (rms)
    y_meas: Array
    verdicts: tuple[Verdict, ...] = ()             # of the chosen effects
    rejected: tuple[tuple[str, str], ...] = ()     # (effect, why) of the best refused ones
    warning: str | None = None                     # unexplained residual


def _say(progress: Callable[[str], None] | None, msg: str) -> None:
    if progress is not None:
        progress(msg)


def _polish_delay(model: SimulatedModel, f: Any, steps: int = 6) -> Any:
    """A delay acts in whole physics steps, where least squares sees no gradient: scan whole
    steps around the fitted value (the other values held)."""
    eff = dict(f.effects)
    best = f
    for k in range(-steps, steps + 1):
        z = eff["dead_time"] + k * model.dt_s
        if k == 0 or z < 0:
            continue
        g = model.finish(f.theta, tuple((n, z if n == "dead_time" else v)
                                        for n, v in f.effects))
        if g.rss < best.rss:
            best = g
    return best


def _rms(rss: float, n: int) -> float:
    return math.sqrt(rss / max(n, 1))


def diagnose_dynamic(model: SimulatedModel, refine_top: int = 2, max_effects: int = 2,
                     floor_factor: float = 2.0, criterion: Criterion = DEFAULT,
                     progress: Callable[[str], None] | None = None) -> DynamicDiagnosis:
    """Nominal fit, then forward selection of catalog effects under the shared rule."""
    data = model.data
    ym = data.y[data.keep]
    tr, te = data.split()
    nom0 = model.nominal_start()
    floor, step_err = model.floor()
    _say(progress, f"physics step {model.dt_s * 1e3:.1f} ms: error {step_err:.2g} rad; floor "
                   f"{floor:.2g} rad; fitting the nominal finger ({len(ym)} samples, "
                   f"{len(te)} held out)")
    current = model.fit(nom0, ())
    nominal = current
    chosen: list[tuple[str, float, float]] = []
    verdicts: list[Verdict] = []
    rejected: list[tuple[str, str]] = []
    ranking: list[tuple[str, float]] = []
    while len(chosen) < max_effects:
        if _rms(current.rss, len(tr)) < floor_factor * floor:
            break  # what is left is noise and the physics step
        have = tuple(e for e, _ in current.effects)
        screened = []
        for name, (grid, _) in model.candidates().items():
            if name in have:
                continue
            best = min(((model.rss(model.run(current.theta, current.effects + ((name, z),))), z)
                        for z in grid), key=lambda x: x[0])
            screened.append((best[0], name, best[1]))
        screened.sort()
        _say(progress, "screened: " + ", ".join(f"{nm} {1 - r / current.rss:+.0%}"
                                                  for r, nm, _ in screened[:4]))
        fits = []
        for rss_s, name, z in screened[:refine_top]:
            _say(progress, f"fitting {name}")
            eff = current.effects + ((name, z),)
            # the nominal parameters may have bent to mimic the missing physics: start from the
            # calibrated values when they do better with this candidate
            theta = (nom0 if model.rss(model.run(nom0, eff)) < rss_s else current.theta)
            f = model.fit(theta, eff)
            if name == "dead_time":
                f = _polish_delay(model, f)
            fits.append((f.rss, name, f))
        fits.sort(key=lambda x: x[0])
        gains = [(nm, 1.0 - r / current.rss) for r, nm, _ in fits] + [
            (nm, 1.0 - r / current.rss) for r, nm, _ in screened[refine_top:]]
        if not chosen:
            ranking = gains
        informative = _rms(current.rss_test, len(te)) > floor_factor * floor
        accepted = None
        for rss, name, f in fits:
            hg = (1.0 - f.rss_test / current.rss_test
                  if len(te) and current.rss_test > 0 else math.nan)
            v = judge(current.rss, rss, model.residual(f), 1, hg, informative,
                      criterion=criterion)
            if v.accepted:
                accepted = (name, f, v)
                break
            rejected.append((name, v.why))
        if accepted is None:
            break
        name, f, v = accepted
        chosen.append((name, f.effects[-1][1], 1.0 - f.rss / current.rss))
        verdicts.append(v)
        current = f
    warn = unexplained(_rms(current.rss, len(tr)), floor)
    return DynamicDiagnosis(nominal, current, tuple(chosen), tuple(ranking), floor, ym,
                            tuple(verdicts), tuple(rejected[:3]), warn)


def print_progress(msg: str) -> None:
    """Progress line on stderr."""
    print(f"diagnose: {msg}", file=sys.stderr, flush=True)
