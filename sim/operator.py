"""The virtual operator: a human finger on the grasp trigger, following a grasp script.

The finger is a mass ``m`` pulled towards a scripted reference opening by a spring ``k`` and a
damper ``b`` (the operator's arm impedance; ``hard``, ``relaxed`` and ``soft`` grasp styles
differ in ``k`` and ``b``), and pushed back by the force the trigger displays (positive
resists closing).  The trigger has ``travel_m`` of travel between hard stops, displays at most
``force_max_n`` and reads its position with ``resolution_m`` quantisation (Omega 7's 7th DoF:
25 mm, 8 N, 0.006 mm).

Script (seconds from the start of each cycle): wait ``close_s``, close over ``ramp_s``, hold
``hold_s``, open over ``release_s``; repeat when ``repeat`` is set.

``operator_step`` is pure; :class:`VirtualOperator` wraps it as a
:class:`teleop.devices.base.MasterBackend`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from teleop.config.master import MasterConfig
from teleop.devices.base import MasterReading
from teleop.frozen import fast_init

#: style -> (stiffness N/m, damping N s/m) of the operator's finger
STYLES: dict[str, tuple[float, float]] = {
    "hard": (1500.0, 12.0),
    "relaxed": (500.0, 6.0),
    "soft": (150.0, 3.0),
}

_MAX_SUBSTEP_S = 2.5e-4


@dataclass(frozen=True, slots=True)
class OperatorParams:
    """The operator's finger, the trigger and the grasp script."""

    mass_kg: float
    stiffness_n_per_m: float
    damping_n_s_per_m: float
    travel_m: float
    force_max_n: float
    resolution_m: float
    close_s: float
    ramp_s: float
    hold_s: float
    release_s: float
    closed_fraction: float
    repeat: bool


@fast_init
@dataclass(frozen=True, slots=True)
class OperatorState:
    """Trigger closing ``x_m`` (0 = open) and its rate; ``t_s`` the model time.

    ``delivered_j`` / ``taken_j``: the physical energy audit of the operator port, cumulative
    work the displayed force did on the operator's finger (delivered) and the finger did
    against it (taken), integrated at every substep from the force and the finger's motion.
    """

    t_s: float = 0.0
    x_m: float = 0.0
    v_m_s: float = 0.0
    delivered_j: float = 0.0
    taken_j: float = 0.0


def operator_params(cfg: MasterConfig) -> OperatorParams:
    """Operator parameters from the master config section."""
    v = cfg.virtual
    k, b = STYLES[v.style]
    k = k if v.stiffness_n_per_m is None else v.stiffness_n_per_m
    b = b if v.damping_n_s_per_m is None else v.damping_n_s_per_m
    return OperatorParams(
        mass_kg=v.mass_kg, stiffness_n_per_m=k, damping_n_s_per_m=b, travel_m=cfg.travel_m,
        force_max_n=cfg.force_max_n, resolution_m=cfg.resolution_m, close_s=v.close_s,
        ramp_s=v.ramp_s, hold_s=v.hold_s, release_s=v.release_s,
        closed_fraction=v.closed_fraction, repeat=v.repeat)


def script_fraction(p: OperatorParams, t_s: float) -> float:
    """The scripted trigger closing at ``t_s`` as a fraction of full travel (smooth ramps)."""
    cycle = p.close_s + p.ramp_s + p.hold_s + p.release_s
    if p.repeat and cycle > 0:
        t_s = math.fmod(max(t_s, 0.0), cycle)
    t = t_s - p.close_s
    if t <= 0:
        return 0.0
    if t < p.ramp_s:
        s = 0.5 - 0.5 * math.cos(math.pi * t / p.ramp_s)
    elif t < p.ramp_s + p.hold_s:
        s = 1.0
    elif t < p.ramp_s + p.hold_s + p.release_s:
        s = 0.5 + 0.5 * math.cos(math.pi * (t - p.ramp_s - p.hold_s) / p.release_s)
    else:
        s = 0.0
    return s * p.closed_fraction


def operator_step(state: OperatorState, p: OperatorParams, force_n: float,
                  dt_s: float) -> OperatorState:
    """Advance the finger and trigger by ``dt_s`` under the displayed ``force_n`` (pure)."""
    f_disp = min(max(force_n, -p.force_max_n), p.force_max_n)
    n = max(1, math.ceil(dt_s / _MAX_SUBSTEP_S))
    h = dt_s / n
    t, x, v = state.t_s, state.x_m, state.v_m_s
    out_j, in_j = state.delivered_j, state.taken_j
    k, b, mass, travel = p.stiffness_n_per_m, p.damping_n_s_per_m, p.mass_kg, p.travel_m
    # script_fraction(p, t + h) written out with its sums hoisted (the same operations)
    close, ramp, hold, release, closed = p.close_s, p.ramp_s, p.hold_s, p.release_s, \
        p.closed_fraction
    cycle = close + ramp + hold + release
    wrap = p.repeat and cycle > 0
    ramp_hold = ramp + hold
    ramp_hold_release = ramp + hold + release
    for _ in range(n):
        ts = t + h
        if wrap:
            ts = math.fmod(0.0 if ts < 0.0 else ts, cycle)  # max(ts, 0.0)
        ts = ts - close
        if ts <= 0:
            frac = 0.0
        elif ts < ramp:
            frac = (0.5 - 0.5 * math.cos(math.pi * ts / ramp)) * closed
        elif ts < ramp_hold:
            frac = 1.0 * closed
        elif ts < ramp_hold_release:
            frac = (0.5 + 0.5 * math.cos(math.pi * (ts - ramp - hold) / release)) * closed
        else:
            frac = 0.0 * closed
        x_ref = frac * travel
        a = (k * (x_ref - x) - b * v - f_disp) / mass
        v += a * h
        x_old = x
        x += v * h
        t += h
        if x < 0.0:
            x, v = 0.0, max(v, 0.0)
        elif x > travel:
            x, v = travel, min(v, 0.0)
        # the device pushes the trigger with -f_disp along x: work on the finger this substep
        w = -f_disp * (x - x_old)
        if w > 0.0:
            out_j += w
        else:
            in_j -= w
    return OperatorState(t_s=t, x_m=x, v_m_s=v, delivered_j=out_j, taken_j=in_j)


def operator_force_n(state: OperatorState, p: OperatorParams) -> float:
    """The force the operator's finger pushes the trigger closed with (N)."""
    x_ref = script_fraction(p, state.t_s) * p.travel_m
    return p.stiffness_n_per_m * (x_ref - state.x_m) - p.damping_n_s_per_m * state.v_m_s


def quantise(x_m: float, resolution_m: float) -> float:
    """The trigger's encoder reading of ``x_m``."""
    if resolution_m <= 0:
        return x_m
    return round(x_m / resolution_m) * resolution_m


class VirtualOperator:
    """The ``virtual`` master backend (a :class:`teleop.devices.base.MasterBackend`)."""

    def __init__(self, cfg: MasterConfig, seed: int = 0) -> None:
        self.params = operator_params(cfg)
        self.state = OperatorState()
        self.force_n = 0.0
        self._last_x = 0.0
        self._last_t: float | None = None
        self._t0 = 0.0
        self.seed = seed

    def start(self) -> None:
        """Nothing to connect."""

    def read(self, t_s: float) -> MasterReading:
        """Advance the model to ``t_s`` (under the force last applied) and read the trigger."""
        if self._last_t is None:  # the script starts at the first read
            self._t0 = t_s
            self._last_t = t_s
        elif t_s - self._t0 > self.state.t_s:
            self.state = operator_step(self.state, self.params, self.force_n,
                                       t_s - self._t0 - self.state.t_s)
        x = min(max(quantise(self.state.x_m, self.params.resolution_m), 0.0),
                self.params.travel_m)
        dt = t_s - self._last_t
        v = (x - self._last_x) / dt if dt > 0 else 0.0
        self._last_x, self._last_t = x, t_s
        return MasterReading(t_s=t_s, grip_position_m=x, grip_velocity_m_s=v)

    def apply_force(self, force_n: float) -> None:
        """Display ``force_n`` (clamped to the trigger's limit) until the next call."""
        f = force_n if math.isfinite(force_n) else 0.0
        self.force_n = min(max(f, -self.params.force_max_n), self.params.force_max_n)

    def port_audit_j(self) -> tuple[float, float]:
        """(delivered, taken): physical work at the operator port so far (see OperatorState)."""
        return self.state.delivered_j, self.state.taken_j

    def operator_force_n(self) -> float:
        """What the virtual finger pushes with now (for recordings)."""
        return operator_force_n(self.state, self.params)

    def close(self) -> None:
        """Force off."""
        self.force_n = 0.0
