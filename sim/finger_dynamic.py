"""The finger model against a dynamic recording (``teleop sim force-step|force-blocks|position``).

The finger (:func:`sim.finger.finger_step`) is simulated from rest, driven by the recording's own
command: ``motor_cmd_units`` while the experiment's protocol is in force mode, ``setpoint_rad``
(joint angle; the motor goal is ``JOINT_RATIO`` times it) while it is in position mode.  The
simulated ``motor_angle_rad`` (or ``proximal_angle_rad``) is compared with the measured one.

A recording that logs a sampled set-point (its changes fall between rows) gets the next row's
command over the last part of each row (``DynamicData.input_lead``, fitted under the selection's
rule: :meth:`FingerDynamicModel.lead_fits`).

Speed: the physics runs at ``dt_s`` (default 2 ms), at least one step per recorded row (so
rows finer than that, as ``teleop sim --rate 1000`` writes, are stepped one per row:
:meth:`FingerDynamicModel.physics_step_s`); the difference from the recording's own physics step
is measured once and counted as a model-error floor.  The fit compares every ``every``-th
sample.  Refined nominal parameters (within +-tolerance): the motor gain
(``units_per_n``), the motor's Coulomb friction (``motor_coulomb_units``), the base spring
(``k_base_nm_per_rad``) and, within [0, 1] whatever the tolerance, the share of the motor's
viscous friction that follows the speed law rather than the effort law
(``speed_law_fraction``, ``sim/params.py``).  Candidates are screened on a grid of values with
the nominal parameters held, and only the best ``refine_top`` are fitted jointly with them.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy import optimize

from sim.engine import DEFAULT_ENGINE, engine
from sim.finger import (
    ContactObject,
    FingerState,
    MotorCommand,
    finger_outputs,
    finger_step,
    initial_finger_state,
)
from sim.finger_ripple import AMPLITUDE_BOUNDS_N, split, wave_grid
from sim.parallel_runs import pmap
from sim.params import JOINT_RATIO, FingerParams
from teleop.diagnose.library import Term
from teleop.diagnose.residual import noise_std
from teleop.effects import EffectSet
from teleop.errors import RecordingError
from teleop.recording import Recording
from teleop.recording_checks import enough_compared, finite_column, gap_rows

Array = NDArray[np.float64]

PARAMS = ("units_per_n", "motor_coulomb_units", "k_base_nm_per_rad", "speed_law_fraction")
#: refined within these bounds whatever the tolerance (the others: nominal +-tolerance)
ABSOLUTE_BOUNDS: dict[str, tuple[float, float]] = {"speed_law_fraction": (0.0, 1.0)}
DYNAMIC_EXPERIMENTS = ("force-step", "force-blocks", "position")
CANDIDATES: dict[str, tuple[tuple[float, ...], tuple[float, float]]] = {
    # name: (screening grid, bounds); forces in N of tendon force, angles in rad of motor shaft
    "coulomb_friction": ((0.3, 1.0, 2.0, 4.0), (0.0, 20.0)),
    "asymmetric_friction": ((0.3, 1.0, 2.0, 4.0), (0.0, 20.0)),
    "stiction": ((0.5, 2.0, 5.0), (0.0, 20.0)),
    "dead_time": ((0.01, 0.03, 0.06, 0.1, 0.2), (0.0, 0.5)),
    "actuator_lag": ((0.01, 0.03, 0.06, 0.1, 0.2), (0.0, 0.5)),
    "actuator_gain": ((0.6, 0.8, 1.2, 1.5), (0.2, 3.0)),
    "actuator_saturation": ((2.0, 4.0, 8.0, 11.0, 16.0), (0.2, 30.0)),
    "sensor_offset": ((-0.1, -0.03, 0.03, 0.1), (-0.5, 0.5)),
    "backlash": ((0.01, 0.03, 0.1), (0.0, 0.5)),
}


@dataclass(frozen=True, slots=True)
class DynamicData:
    """A dynamic recording as the fit sees it: one command per recorded row."""

    t_s: Array
    commands: tuple[MotorCommand, ...]
    y: Array
    output: str
    keep: Array            # indices of the samples the fit compares
    physics_dt_s: float    # the step the recording was made with (or a fine one)
    out_scale: float = 1.0  # simulated shaft angle -> recorded angle (joint side: 1 / 1.42)
    active: Array | None = None  # rows simulated (False: contact, excluded); None: all
    restart_goal_rad: Array | None = None  # shaft angle to settle at when a segment restarts
    note: str = ""          # what was excluded, for the report
    restart_effort_units: Array | None = None  # servo effort measured there (NaN: holding)
    #: share of each row's span, at its end, over which the next row's command already acts
    #: (a logged, sampled signal: a change between two rows shows only at the later one;
    #: 0: each command holds until the next row, as ``teleop sim`` at 1 kHz logs them);
    #: chosen among :meth:`FingerDynamicModel.lead_fits`; a segment restarting after excluded
    #: rows primes its delay line at the rows' own times
    input_lead: float = 0.0

    @property
    def force_mode(self) -> Array:
        """Per recorded row: whether the servo was in force mode (else position)."""
        return np.array([c.mode == "force" for c in self.commands], bool)

    def split(self, block: int = 10, every: int = 4) -> tuple[Array, Array]:
        """Training and held-out positions in ``keep``: every ``every``-th block of ``block``
        compared samples is held out (interleaved, so both cover every regime)."""
        i = np.arange(len(self.keep))
        test = (i // block) % every == every - 1
        if test.sum() < 3 or (~test).sum() < 3:
            return i, i[:0]
        return i[~test], i[test]


def dynamic_data(rec: Recording, output: str, fit_rate_hz: float = 50.0) -> DynamicData:
    """Commands and measurement of a ``teleop sim`` dynamic recording (protocol from its
    ``# experiment:`` line)."""
    from sim.experiments import ExperimentSpec, _schedule

    exp = rec.meta_value("experiment")
    if exp not in DYNAMIC_EXPERIMENTS:
        raise RecordingError(f"{rec.source}: --model finger needs a static weight table or a "
                             f"'# experiment:' of {', '.join(DYNAMIC_EXPERIMENTS)} (got {exp!r})")
    schedule = _schedule(ExperimentSpec(exp))
    gap_rows(rec, split=False, can_split=False)
    t = rec.t_s
    force = np.array([schedule(ti)[0].mode == "force" for ti in t.tolist()], bool)
    units = finite_column(rec, "motor_cmd_units", force)
    sp = finite_column(rec, "setpoint_rad", ~force)
    y = finite_column(rec, output)
    cmds = [MotorCommand("force", force_units=ui) if fi
            else MotorCommand("position", goal_rad=JOINT_RATIO * si)
            for fi, ui, si in zip(force.tolist(), units.tolist(), sp.tolist(), strict=True)]
    dt_rec = float(np.median(np.diff(t)))
    every = max(1, int(round(1.0 / (fit_rate_hz * dt_rec))))
    keep = np.arange(0, len(t), every)
    enough_compared(rec, len(keep), f"samples compared (at the fit's {fit_rate_hz:g} Hz)")
    try:
        phys = float(rec.meta_value("physics_dt_s") or 0.1 * dt_rec)
    except ValueError:
        phys = 0.1 * dt_rec
    return DynamicData(t, tuple(cmds), y, output, keep, min(max(phys, 1e-4), dt_rec))


def row_steps(t_s: Array, dt_s: float) -> Array:
    """Physics steps over each row's span to the next (at least one), as both engines take
    them."""
    return np.maximum(1, np.round(np.diff(t_s) / dt_s)).astype(np.int64)


def lead_steps(lead: float, n: int) -> int:
    """How many of a row's ``n`` physics steps run under the next row's command at the input
    lead ``lead`` (``DynamicData.input_lead``; the compiled engine rounds the same way)."""
    return min(n, max(0, int(math.floor(lead * n + 0.5))))


#: :meth:`FingerDynamicModel.lead_fits` fits leads of ``j / LEADS`` of a row at most (finer
#: when a row holds fewer physics steps)
LEADS = 4

SETTLE_S = 1.0  # the held finger comes to rest well within this (and any dead time)


def settle_s(eff: EffectSet) -> float:
    """How long a restarting segment settles: :data:`SETTLE_S` plus any dead time."""
    return SETTLE_S + eff.dead_time


def goal_per_unit(p: FingerParams, eff: EffectSet) -> float:
    """Servo set-point above the angle it reads (shaft rad) per unit of effort: the P
    controller's effort is ``kp (set-point - reading)`` times any ``actuator_gain``."""
    return 1.0 / (p.kp_units_per_rad * eff.actuator_gain)


def _settled(p: FingerParams, eff: EffectSet, goal_rad: float, obj: ContactObject,
             dt_s: float, effort_units: float = math.nan) -> FingerState:
    """The free finger at a measured motor angle (a segment restarting after contact or a
    gap).  The shaft is held at the angle the servo reads as ``goal_rad`` (``goal_rad -
    sensor_offset``) while the finger and tendon come to rest on it, the servo's set-point
    kept where its effort holds the shaft against the tension.  Released, the servo's
    set-point is where its effort is the one measured at the restart (``effort_units``;
    NaN: the holding one), so a finger the servo was driving on keeps being driven.
    (Settling from rest under the measured angle as the goal stopped short of it: a loaded
    P servo's standing error and slow approach, 0.07-0.48 rad at the recorded angles, which
    a sensor offset then absorbed.)"""
    state = initial_finger_state(p)
    shaft = goal_rad - eff.sensor_offset
    per_unit = goal_per_unit(p, eff)
    cmd = MotorCommand("position", goal_rad=goal_rad)
    for _ in range(int(settle_s(eff) / dt_s)):
        cmd = MotorCommand("position",
                           goal_rad=goal_rad + per_unit * p.units_per_n * state.tendon_force_n)
        state = replace(state, motor_rad=shaft, motor_vel_rad_s=0.0, command=(cmd, cmd, ()))
        state = finger_step(state, cmd, p, obj, eff, dt_s)
    if math.isfinite(effort_units):
        cmd = MotorCommand("position", goal_rad=goal_rad + per_unit * effort_units)
    gap, _, u, u_cmd = state.drive
    return replace(state, motor_rad=shaft, motor_vel_rad_s=0.0, command=(cmd, cmd, ()),
                   drive=(gap, cmd.goal_rad, u, u_cmd))


def _primed(state: FingerState, data: DynamicData, i: int, delay_s: float) -> FingerState:
    """``state`` restarting at row ``i`` with the delay line's worth of recorded commands:
    the ones written less than ``delay_s`` before row ``i`` are pending, due ``delay_s``
    after they were written (the delayed servo still has them to execute, also when they
    were written during an excluded stretch); until the first is due the settling command
    holds the finger where it was measured (what held it there, e.g. an object, is not in
    the recording)."""
    t = data.t_s
    j0 = i - 1
    while j0 > 0 and t[j0] > t[i] - delay_s:
        j0 -= 1
    active = state.command[0]
    if t[j0] <= t[i] - delay_s:
        j0 += 1
    pending = tuple((state.t_s + float(t[j] + delay_s - t[i]), data.commands[j])
                    for j in range(j0, i))
    return replace(state, command=(active, data.commands[i - 1], pending))


def simulate_dynamic(p: FingerParams, eff: EffectSet, data: DynamicData, dt_s: float,
                     engine_name: str = DEFAULT_ENGINE) -> Array:
    """Simulated output at every recorded sample, from rest at the first one (NaN on rows
    that are not simulated; a segment after them restarts at the measured angle and load,
    with the commands recorded over the last delay still to come: :func:`_primed`).
    ``engine_name`` "compiled" runs it in one compiled call (``sim.compiled_dynamic``)."""
    if engine(engine_name).name == "compiled":
        from sim.compiled_dynamic import simulate_compiled

        return simulate_compiled(p, eff, data, dt_s, settle_s(eff))
    obj = ContactObject(kind="none")
    state = initial_finger_state(p)
    t = data.t_s
    out = np.full(len(t), math.nan)
    steps = row_steps(t, dt_s)
    motor = data.output == "motor_angle_rad"
    active = data.active
    was_active = True
    for i, cmd in enumerate(data.commands):
        if active is not None and not active[i]:
            was_active = False
            continue
        if not was_active and data.restart_goal_rad is not None:
            effort = (math.nan if data.restart_effort_units is None
                      else float(data.restart_effort_units[i]))
            state = _settled(p, eff, float(data.restart_goal_rad[i]), obj, dt_s, effort)
            delay = p.command_delay_s + eff.dead_time
            if delay > 0.0 and i > 0:
                state = _primed(state, data, i, delay)
            was_active = True
        o = finger_outputs(state, p, obj, eff)
        out[i] = (o.motor_angle_rad if motor else o.proximal_rad) * (
            data.out_scale if motor else 1.0)
        if i + 1 < len(t):
            span = t[i + 1] - t[i]
            n = int(steps[i])
            early = n - lead_steps(data.input_lead, n)
            for j in range(n):
                state = finger_step(state, cmd if j < early else data.commands[i + 1], p, obj,
                                    eff, span / n)
    return out


def effect_bounds(name: str) -> tuple[float, float]:
    """Fit bounds of a catalog effect or of a shaft ripple's amplitude."""
    return AMPLITUDE_BOUNDS_N if Term.is_key(name) else CANDIDATES[name][1]


def param_bounds(nom: Array, tolerance: float) -> tuple[Array, Array]:
    """Bounds of the refined parameters: nominal +-``tolerance`` (a hair around the nominal
    at tolerance 0), the :data:`ABSOLUTE_BOUNDS` ones inside their own range."""
    if tolerance <= 0:
        lo, hi = nom - 1e-9 * np.abs(nom), nom + 1e-9 * np.abs(nom)
    else:
        lo, hi = nom * (1 - tolerance), nom * (1 + tolerance)
    for i, n in enumerate(PARAMS):
        if n in ABSOLUTE_BOUNDS:
            a, b = ABSOLUTE_BOUNDS[n]
            if tolerance > 0:
                lo[i], hi[i] = a, b
            else:  # held: a hair inside its range
                lo[i], hi[i] = max(a, nom[i] - 1e-9), min(b, nom[i] + 1e-9)
    return lo, hi


@dataclass(frozen=True, slots=True)
class Fit:
    """One fitted model: nominal parameters, effects, residual sum of squares on the fit grid."""

    theta: tuple[float, ...]
    effects: tuple[tuple[str, float], ...]
    rss: float          # on the training samples (the fit saw these)
    y: Array            # on every compared sample
    rss_test: float = math.nan  # on the held-out samples (same simulation, not fitted)


@dataclass(frozen=True, slots=True)
class FingerDynamicModel:
    """The finger refined against a dynamic recording."""

    base: FingerParams
    data: DynamicData
    tolerance: float = 0.2
    dt_s: float = 2e-3
    engine_name: str = DEFAULT_ENGINE
    #: amplitude the shaft ripple scan probes with, N of tendon force (the motor's own
    #: Coulomb friction is about 1 N; the independent batch's cogging 0.5-1.5 N)
    ripple_probe: float = 1.0

    def candidates(self) -> dict[str, tuple[tuple[float, ...], tuple[float, float]]]:
        """Effects the selection tries: (screening grid, bounds)."""
        return CANDIDATES

    def nominal_start(self) -> tuple[float, ...]:
        """The calibrated values of the refined parameters."""
        return tuple(float(getattr(self.base, n)) for n in PARAMS)

    def floor(self) -> tuple[float, float]:
        """(floor, physics-step error), rms: the noise and the coarse step's own error on the
        calibrated finger."""
        nom0 = self.nominal_start()
        d = replace(self, dt_s=self.data.physics_dt_s).run(nom0, ()) - self.run(nom0, ())
        d = d[np.isfinite(d)]
        step_err = float(np.sqrt(np.mean(d ** 2))) if len(d) else 0.0
        return math.hypot(noise_std(self.data.y[self.data.keep]), step_err), step_err

    def physics_step_s(self) -> float:
        """The step the physics takes on this recording's rows (the median): ``dt_s``, or a
        row's span where rows are finer than ``dt_s`` (one step per row: :func:`row_steps`)."""
        t = np.asarray(self.data.t_s, float)
        if len(t) < 2:
            return self.dt_s
        return float(np.median(np.diff(t) / row_steps(t, self.dt_s)))

    def params(self, theta: Array | tuple[float, ...]) -> FingerParams:
        """Finger parameters with the refined ones set (each inside its absolute bounds)."""
        vals = {n: float(v) for n, v in zip(PARAMS, theta, strict=True)}
        for n, (a, b) in ABSOLUTE_BOUNDS.items():
            vals[n] = min(max(vals[n], a), b)
        return replace(self.base, **vals)

    def _shaft_per_output(self) -> float:
        """Shaft rad per unit of the compared output (a proximal-angle output: the joint
        ratio)."""
        return (1.0 / self.data.out_scale if self.data.output == "motor_angle_rad"
                else JOINT_RATIO)

    def shaft_span_rad(self) -> float:
        """The shaft angle range the compared samples cover (NaN with fewer than two finite
        samples)."""
        y = self.data.y[self.data.keep]
        y = y[np.isfinite(y)]
        if len(y) < 2:
            return math.nan
        return float(np.ptp(y)) * self._shaft_per_output()

    def ripple_position(self) -> Array:
        """The measured shaft angle (rad) at the compared samples, where the ripple acts."""
        return self.data.y[self.data.keep] * self._shaft_per_output()

    def ripple_waves(self) -> Array:
        """Wavenumbers (1/rad of shaft angle) the selection scans for a position-periodic
        shaft force (``sim.finger_ripple``), from the shaft angle range covered."""
        return wave_grid(self.shaft_span_rad())

    def run(self, theta: Array | tuple[float, ...], effects: tuple[tuple[str, float], ...]
            ) -> Array:
        """Simulated output on the fit grid (NaN if the simulation fails); ``effects`` may
        hold a shaft ripple's library pair (``sim.finger_ripple``)."""
        try:
            eff, ripple = split(effects)
            p = self.params(theta)
            if ripple:
                p = replace(p, **ripple)
            y = simulate_dynamic(p, eff, self.data, self.dt_s, self.engine_name)[self.data.keep]
        except (OverflowError, ZeroDivisionError, ValueError, FloatingPointError):
            return np.full(len(self.data.keep), math.nan)
        return y

    def lead_fits(self, fit: Fit) -> list[tuple[FingerDynamicModel, Fit]]:
        """The model at no input lead and at each lead ``j / m`` of a row, each fitted from
        ``fit``'s values (``fit`` itself at this model's own lead); empty for rows no coarser
        than the physics step (at 1 kHz a change's misplacement is under the step).

        A recording that logs a sampled set-point shows a step that came between two rows
        only at the later one, so held row by row the simulated servo starts up to a row
        late: at a 100 Hz recording's 10 ms and a saturated servo's 3-4 rad/s, 30 mrad
        (independent finger batch, truth parameters: 7.7 mrad rms against 2.4 with the best
        lead).  ``m`` is the physics steps per row, at most :data:`LEADS`; ``j < m``: a whole
        row early is a recording one row late, not a sampled one.  A lead only moves a
        command earlier, within its row; a later one is a ``dead_time``, which the catalog
        tests on its own.  Which lead, if any, is the selection's rule's to say
        (``teleop.diagnose.select_sim.aligned``): a lead is a fitted parameter like any
        effect."""
        t = np.asarray(self.data.t_s, float)
        if len(t) < 2 or not math.isfinite(fit.rss):
            return []
        m = min(int(np.max(row_steps(t, self.dt_s))), LEADS)
        if m < 2:
            return []
        models = [self if j / m == self.data.input_lead
                  else replace(self, data=replace(self.data, input_lead=j / m))
                  for j in range(m)]
        fits = self.map(lambda mo: fit if mo is self else mo.fit(fit.theta, fit.effects),
                        models)
        return list(zip(models, fits, strict=True))

    def alignment(self) -> str | None:
        """The input alignment in words (None: each command holds until the next row)."""
        lead = self.data.input_lead
        if lead <= 0.0:
            return None
        span = float(np.median(np.diff(self.data.t_s)))
        return (f"each recorded command acts from {lead:.2g} of a row ({lead * span * 1e3:.3g} "
                "ms) before its row (a logged, sampled signal: a change between two rows shows "
                "at the later one)")

    def _parallel(self) -> bool:
        """Whether independent runs go on every core: the compiled engine releases the GIL,
        the Python reference does not."""
        return engine(self.engine_name).name == "compiled"

    def map(self, fn: Callable[[Any], Any], items: list[Any]) -> list[Any]:
        """``[fn(x) for x in items]`` for independent simulations (or fits): the compiled
        engine's on every core (``sim.parallel_runs``: the same results as one by one)."""
        return pmap(fn, items) if self._parallel() else [fn(x) for x in items]

    def rss(self, y: Array) -> float:
        """Residual sum of squares on the training samples (a failed simulation: infinite)."""
        return self.rss_parts(y)[0]

    def rss_parts(self, y: Array) -> tuple[float, float]:
        """Residual sums of squares on the training and held-out samples."""
        r = y - self.data.y[self.data.keep]
        tr, te = self.data.split()
        out = []
        for idx in (tr, te):
            ri = r[idx]
            out.append(float(ri @ ri) if np.all(np.isfinite(ri)) else math.inf)
        return out[0], out[1]

    def residual(self, f: Fit) -> Array:
        """Training residual of a fit."""
        return (f.y - self.data.y[self.data.keep])[self.data.split()[0]]

    def finish(self, theta: tuple[float, ...], effects: tuple[tuple[str, float], ...],
               y: Array | None = None) -> Fit:
        """A Fit of given values (simulated unless ``y`` is given)."""
        y = self.run(theta, effects) if y is None else y
        tr, te = self.rss_parts(y)
        return Fit(theta, effects, tr, y, te)

    def fit(self, theta0: tuple[float, ...], effects: tuple[tuple[str, float], ...],
            max_nfev: int = 12) -> Fit:
        """Joint least-squares fit of the refined parameters and the effects' values."""
        x0 = np.array(list(theta0) + [v for _, v in effects], float)
        nom = np.array([getattr(self.base, n) for n in PARAMS])
        p_lo, p_hi = param_bounds(nom, self.tolerance)
        lo = np.concatenate([p_lo, [effect_bounds(n)[0] for n, _ in effects]])
        hi = np.concatenate([p_hi, [effect_bounds(n)[1] for n, _ in effects]])
        x0 = np.clip(x0, lo + 1e-6 * (hi - lo), hi - 1e-6 * (hi - lo))
        k = len(PARAMS)
        names = [n for n, _ in effects]
        tr = self.data.split()[0]
        ym = self.data.y[self.data.keep][tr]
        big = 10.0 * float(np.ptp(ym) or 1.0)

        def resid(x: Array) -> Array:
            r = self.run(x[:k], tuple(zip(names, x[k:].tolist(), strict=True)))[tr] - ym
            return np.where(np.isfinite(r), r, big)

        scale = np.concatenate([[0.1 * (ABSOLUTE_BOUNDS[n][1] - ABSOLUTE_BOUNDS[n][0])
                                 if n in ABSOLUTE_BOUNDS else abs(v) * 0.1 + 1e-9
                                 for n, v in zip(PARAMS, nom, strict=True)],
                                [0.1 * (effect_bounds(n)[1] - effect_bounds(n)[0])
                                 for n in names]])
        # a delay acts in whole physics steps: difference it over two of them
        steps = np.array([1e-3] * k + [2.0 * self.dt_s if n == "dead_time" else 1e-3
                                       for n in names])
        res = optimize.least_squares(resid, x0, bounds=(lo, hi), x_scale=scale,
                                     max_nfev=max_nfev, diff_step=steps,
                                     workers=pmap if self._parallel() else None)
        eff = tuple(zip(names, res.x[k:].tolist(), strict=True))
        return self.finish(tuple(res.x[:k].tolist()), eff)


