"""Predicted largest stable round-trip delay of direct position-force control.

Linearised loop with the finger in contact (passivity.md, last sections)::

    Z_m(s) X_m + K_f G P_s(s) F(s) e^{-s T} X_m = 0

* ``Z_m(s) = m s^2 + b s + k_h``: trigger plus operator's finger (mass, damping, stiffness),
  force on the trigger per metre of closing;
* ``G`` (rad/m): the transparency map's slope, finger set-point per metre of trigger closing
  (``(closed - open) / travel``);
* ``P_s(s) = k_e K / (B s + K + k_e)``: contact torque per commanded set-point of a
  first-order position servo (stiffness ``K``, damping ``B``) pressing on a contact of
  stiffness ``k_e`` (all joint-side, N m/rad);
* ``K_f`` (N per N m): displayed trigger force per contact torque (pressure per torque times
  ``force_per_pressure_n``);
* ``F(s) = 1 / (1 + s / (2 pi f_c))``: the displayed-force low-pass (omitted if ``f_c`` is None);
* ``T``: the round-trip delay (master -> controller -> hand -> controller -> master, plus any
  sample-and-hold delays the caller wants to include).

With ``L(jw) = K_f G P_s F / Z_m``: if the zero-delay loop is unstable the limit is 0; if
``|L(jw)| < 1`` at every frequency any delay is stable (``inf``); else
``T_max = min over crossovers w_c (|L(jw_c)| = 1) of ((pi + arg L(jw_c)) mod 2 pi) / w_c``.
"""

from __future__ import annotations

import cmath
import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from teleop.config.control import ControllerConfig


@dataclass(frozen=True, slots=True)
class DirectLoopParams:
    """Parameters of the linearised direct position-force loop (defaults: relaxed operator,
    25 mm trigger mapped onto 3 rad, MX-28 servo at the joint, 2000 N/m object at ~4 cm)."""

    mass_kg: float = 0.05  # trigger + operator finger
    damping_n_s_per_m: float = 6.0  # operator's finger damping
    stiffness_n_per_m: float = 500.0  # operator's finger stiffness
    position_gain_rad_per_m: float = 120.0  # G: 3 rad over 25 mm
    servo_stiffness_nm_per_rad: float = 5.0  # K (MX-28 P gain at the joint)
    servo_damping_nm_s_per_rad: float = 0.87  # B (nominal, not the lower bound)
    contact_stiffness_nm_per_rad: float = 3.2  # k_e
    force_gain_n_per_nm: float = 10.0  # K_f
    filter_hz: float | None = 20.0  # displayed-force low-pass cut-off


def loop_gain(p: DirectLoopParams, w_rad_s: float) -> complex:
    """``L(jw)`` without the delay."""
    return _gain_at(p, 1j * w_rad_s)


def _gain_at(p: DirectLoopParams, s: Any) -> Any:
    """``L(s)`` for a complex ``s`` or an array of them (numpy's arithmetic)."""
    zm = p.mass_kg * s * s + p.damping_n_s_per_m * s + p.stiffness_n_per_m
    ps = (p.contact_stiffness_nm_per_rad * p.servo_stiffness_nm_per_rad
          / (p.servo_damping_nm_s_per_rad * s + p.servo_stiffness_nm_per_rad
             + p.contact_stiffness_nm_per_rad))
    filt = 1.0 if p.filter_hz is None else 1.0 / (1.0 + s / (2.0 * math.pi * p.filter_hz))
    return p.force_gain_n_per_nm * p.position_gain_rad_per_m * ps * filt / zm


def zero_delay_stable(p: DirectLoopParams) -> bool:
    """Whether all closed-loop poles at ``T = 0`` lie in the open left half-plane."""
    zm = np.poly1d([p.mass_kg, p.damping_n_s_per_m, p.stiffness_n_per_m])
    den_s = np.poly1d([p.servo_damping_nm_s_per_rad,
                       p.servo_stiffness_nm_per_rad + p.contact_stiffness_nm_per_rad])
    filt = (np.poly1d([1.0]) if p.filter_hz is None
            else np.poly1d([1.0 / (2.0 * math.pi * p.filter_hz), 1.0]))
    num = (p.force_gain_n_per_nm * p.position_gain_rad_per_m * p.contact_stiffness_nm_per_rad
           * p.servo_stiffness_nm_per_rad)
    char = zm * den_s * filt + np.poly1d([num])
    return bool(np.all(np.real(char.roots) < 0.0))


def _magnitude_minus_one(p: DirectLoopParams, ws: np.ndarray) -> np.ndarray:
    """``|L(jw)| - 1`` on a grid, vectorised (a service's start-up evaluates 480,000 points);
    points within 1e-9 of a crossing are evaluated by :func:`loop_gain` itself, so every sign
    is the scalar one's (numpy's complex division may differ in the last bit)."""
    mags = np.abs(_gain_at(p, 1j * ws)) - 1.0
    for i in np.flatnonzero(np.abs(mags) < 1e-9).tolist():
        mags[i] = abs(loop_gain(p, float(ws[i]))) - 1.0
    return mags


def crossovers_rad_s(p: DirectLoopParams, w_lo: float = 1e-3,
                     w_hi: float = 1e6) -> list[float]:
    """Frequencies where ``|L(jw)| = 1`` (log grid, bisection refinement)."""
    ws = np.logspace(math.log10(w_lo), math.log10(w_hi), 4000)
    mags = _magnitude_minus_one(p, ws)
    out: list[float] = []
    for i in np.nonzero(np.sign(mags[:-1]) != np.sign(mags[1:]))[0]:
        a, b = float(ws[i]), float(ws[i + 1])
        fa = mags[i]
        for _ in range(60):
            mid = math.sqrt(a * b)
            fm = abs(loop_gain(p, mid)) - 1.0
            if (fm > 0) == (fa > 0):
                a, fa = mid, fm
            else:
                b = mid
        out.append(math.sqrt(a * b))
    return out


def predicted_max_stable_delay_s(p: DirectLoopParams | None = None) -> float:
    """Largest round-trip delay (s) at which the linearised direct loop stays stable."""
    p = p or DirectLoopParams()
    if not zero_delay_stable(p):
        return 0.0
    best = math.inf
    for wc in crossovers_rad_s(p):
        phase = (math.pi + cmath.phase(loop_gain(p, wc))) % (2.0 * math.pi)
        best = min(best, phase / wc)
    return best


def loop_params_from_config(cfg: ControllerConfig, *, mass_kg: float,
                            damping_n_s_per_m: float, stiffness_n_per_m: float,
                            contact_stiffness_nm_per_rad: float,
                            pressure_per_nm: float,
                            servo_damping_nm_s_per_rad: float | None = None) -> DirectLoopParams:
    """The loop of a configured direct controller against a given operator and contact.

    ``G``, ``K``, the filter and ``K_f = pressure_per_nm * force_per_pressure_n`` come from the
    controller config; the operator (``mass_kg``, ``damping_n_s_per_m``, ``stiffness_n_per_m``,
    e.g. ``sim.operator.STYLES``), the contact stiffness at the joint and the peak pressure per
    N m of contact torque describe the plant.  ``servo_damping_nm_s_per_rad`` defaults to the
    config's (lower-bound) servo damping.
    """
    tr = cfg.transparency
    return DirectLoopParams(
        mass_kg=mass_kg, damping_n_s_per_m=damping_n_s_per_m,
        stiffness_n_per_m=stiffness_n_per_m,
        position_gain_rad_per_m=abs(tr.closed_angle_rad - tr.open_angle_rad)
        / tr.trigger_travel_m,
        servo_stiffness_nm_per_rad=cfg.ports.servo_stiffness_nm_per_rad,
        servo_damping_nm_s_per_rad=(cfg.ports.servo_damping_nm_s_per_rad
                                    if servo_damping_nm_s_per_rad is None
                                    else servo_damping_nm_s_per_rad),
        contact_stiffness_nm_per_rad=contact_stiffness_nm_per_rad,
        force_gain_n_per_nm=pressure_per_nm * tr.force_per_pressure_n,
        filter_hz=tr.force_filter_hz)
