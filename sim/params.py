"""Physical constants of one ReFlex TakkTile finger and its MX-28 tendon motor.

Every number is SI (m, rad, N, N m, kg, s) unless the name says otherwise (``*_units`` are
Dynamixel servo units).  Sources: the seed report (chapter 4, Tables 4.1/4.2), the ReFlex robot
description and the MX-28 datasheet (``shared/reference/reflex-hardware.md``).

Recalibrated constants (the report's own numbers conflict with its measurements; we match the
measurements, as the issue asks):

* **Base spring** ``k_base_nm_per_rad``: the report's 5.47 N m/rad would need ~315 N of tendon
  force to lift the finger by 1 rad (with the ~17 mm base moment arm), yet its own Table 4.2
  shows 0.767 rad at 9.8 N.  Table 4.2's model column is linear above a threshold: 2.407 rad at
  15.7 N and 0.767 rad at 9.8 N give d(angle)/dF = 0.27797 rad/N, i.e.
  ``k_base = r_base / 0.27797`` = 0.0624 N m/rad, and the threshold (the finger stays on its stop
  at 6.9 N and 4.9 N) is a spring **preload** of ``15.7 r_base / k_base - 2.407`` = 1.957 rad
  against the open stop.  That preload is why the finger rests at 0.
* **Flexure**: the report measured 5.928 N m/rad for the whole urethane joint and then *divided*
  by 4 for 4 series segments; springs in series need each segment 4x stiffer than the whole
  (k_seg = n k_total).  Its 5.928 N m/rad also cannot be read off a 20 g weight with a protractor
  (1.3 mrad).  We calibrate the whole-joint stiffness to the report's position-mode offset
  (~0.25 rad between set-point and proximal angle, section 3.1.1): 0.30 N m/rad total, 1.2 N m/rad
  per segment (offset 0.21-0.27 rad at set-points 0.6-1.2 rad).
* **Motor viscous friction**: Table 4.1's "damping" falls with the input.  We model Coulomb
  friction ``motor_coulomb_units`` plus a viscous coefficient interpolated log-log through
  ``(u - u_c) / slope`` at the table's inputs, so the unloaded-string terminal speed reproduces
  Table 4.1.  The table's slope is read as motor-shaft rad/s.
* **Speed-dependent friction law** (``speed_law_fraction``, default 0): a geared servo's
  friction is better described as a function of its SPEED than of its effort.  At fraction
  ``f`` the viscous friction (units) is ``(1 - f) d(u) w + f G(w)``: ``d(u)`` the effort law
  above, ``G`` a friction force that depends on the shaft speed ``w`` only.  ``G`` goes
  log-log (piecewise power law) through the four steady-state points the seed report and the
  datasheet give, with the Coulomb part ``u_c = 5`` units taken off: Table 4.1's (0.06733 rad/s,
  45 units), (0.1781, 95), (0.4240, 195) and the MX-28's no-load speed 55 rpm at 12 V = 5.76
  rad/s at the stall input 1023 units (1018); exponents 0.768, 0.829 and 0.634 between them
  (the last piece extended above 5.76 rad/s).  Below the first point it is linear through the
  origin (668 units per rad/s), so its slope ``dG/dw`` stays finite at rest and the linearly
  implicit step takes it like any damper.  Both laws give the table's terminal speeds at steady
  state (the unloaded string: ``u - u_c = d(u) w = G(w)``), so every blend does too; they differ
  in transients (a step of effort meets the effort law's coefficient at once, the speed law's
  only as the shaft speeds up) and in position mode (the servo's effort swings while the shaft
  is slow).  The effort law alone does not reach the no-load speed (3.1 rad/s at 1023 units).
* **Spool radius** ``r_motor_m``: the report's "~5 units per N" and the MX-28's 2.5 N m stall at
  1023 load units give r = 2.5 / (1023 / 5) = 12.2 mm.
* **Base moment arm** ``r_base_m`` = 1.42 r_motor: the driver's joint angle is shaft / 1.42 and
  equals the proximal angle when the distal is straight.
* Masses/inertias are not published; the values below are estimates from the link sizes
  (light links: the dynamics are dominated by the motor's friction and the springs).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

# Table 4.2, model column (force N -> proximal rad) and Table 4.1 (input units -> shaft rad/s).
TABLE_4_2_MODEL: tuple[tuple[float, float], ...] = ((15.7, 2.407), (9.8, 0.767), (6.9, 0.0),
                                                     (4.9, 0.0))
#: Table 4.2, measured column (a protractor on the physical finger; 0.087 rad is "~5 degrees")
TABLE_4_2_MEASURED: tuple[tuple[float, float], ...] = ((15.7, 2.35), (9.8, 0.785), (6.9, 0.087),
                                                       (4.9, 0.0))
TABLE_4_1_SLOPES: tuple[tuple[float, float], ...] = ((50.0, 0.06733), (100.0, 0.1781),
                                                     (200.0, 0.4240))
JOINT_RATIO = 1.42  # motor shaft angle / driver joint angle (fingers)
SPEED_LAW_POINTS = 4  # Table 4.1's three terminal speeds and the no-load speed


@dataclass(frozen=True, slots=True)
class FingerParams:
    """Physical constants of one finger + tendon + MX-28 (see module docstring for sources)."""

    # geometry (finger plane; x along the finger at rest, +y towards the palm/flexion side)
    proximal_rigid_m: float = 0.060   # proximal axle -> start of the flexure
    n_flex: int = 4                   # flexure segments in series
    flex_segment_m: float = 0.004     # 4 x 4 mm = the ~16 mm urethane flexure
    distal_length_m: float = 0.045
    pad_offset_m: float = 0.007       # sensor pad surface above the link centre line (+y)
    pin1_xy_m: tuple[float, float] = (0.052, 0.008)   # X1 on the proximal link (proximal frame)
    pin2_xy_m: tuple[float, float] = (0.006, 0.008)   # X2 on the distal link (distal frame)
    tip_xy_m: tuple[float, float] = (0.040, 0.006)    # Xc, tendon anchor (distal frame)
    proximal_sensor_x_m: tuple[float, ...] = (0.0189, 0.0268, 0.0347, 0.0426, 0.0506)
    distal_sensor_x_m: tuple[float, ...] = (0.0114, 0.0193, 0.0272, 0.0375)
    # joints
    k_base_nm_per_rad: float = 0.0         # filled in by default_finger_params (Table 4.2)
    base_preload_rad: float = 0.0          # ditto
    c_base_nm_s_per_rad: float = 1.0e-3
    proximal_limits_rad: tuple[float, float] = (0.0, 2.8)
    k_flex_total_nm_per_rad: float = 0.30  # whole flexure; each segment n times stiffer
    c_flex_segment_nm_s_per_rad: float = 3.0e-3
    flex_segment_limits_rad: tuple[float, float] = (-0.05, 0.45)
    inertia_proximal_kg_m2: float = 1.9e-4  # proximal + distal about the base axle
    inertia_flex_kg_m2: float = 2.0e-5      # distal link about a flexure segment
    # tendon
    r_base_m: float = JOINT_RATIO * 0.01222
    k_tendon_n_per_m: float = 2.0e4
    c_tendon_n_s_per_m: float = 20.0
    tendon_slack_m: float = 0.0005          # slack at rest after the driver's calibration
    # motor (MX-28 + spool), shaft coordinates
    r_motor_m: float = 0.01222
    units_per_n: float = 5.0
    max_effort_units: float = 1023.0
    inertia_motor_kg_m2: float = 3.0e-3     # reflected rotor inertia (estimate, 193:1 gearing)
    motor_coulomb_units: float = 5.0
    coulomb_velocity_rad_s: float = 0.005   # regularisation width of the friction sign
    damping_table: tuple[tuple[float, float], ...] = ()  # (input units, units per rad/s)
    #: (shaft rad/s, friction units) points of the speed law (4 of them, by speed)
    speed_friction_table: tuple[tuple[float, float], ...] = ()
    speed_law_fraction: float = 0.0         # 0: effort-dependent law, 1: speed-dependent law
    kp_units_per_rad: float = 1000.0        # servo P gain on shaft angle error
    max_speed_rad_s: float = 5.76           # no-load shaft speed (55 rpm)
    command_delay_s: float = 0.0            # the stock driver's 0.09 s when enabled
    # position-periodic shaft force (cogging, a detent; outside the effect catalog, found by
    # ``teleop diagnose --model finger``): a sin(w th) + b cos(w th) N of tendon force against
    # the motor at shaft angle th; w = shaft_ripple_per_rad (0: none)
    shaft_ripple_sin_n: float = 0.0
    shaft_ripple_cos_n: float = 0.0
    shaft_ripple_per_rad: float = 0.0
    # gravity on the links (off: the hand's orientation is not modelled; see effects)
    # contact sensing
    pressure_per_n: float = 100.0           # raw TakkTile units per N at the kernel peak
    pressure_sigma_m: float = 0.004
    pressure_tail: float = 0.08             # weak spread through the rubber to neighbours
    pressure_tail_m: float = 0.010
    contact_threshold: float = 20.0         # raw units (driver's contact flag)

    @property
    def k_flex_segment_nm_per_rad(self) -> float:
        """Stiffness of one of the ``n_flex`` series segments (n times the whole joint's)."""
        return self.k_flex_total_nm_per_rad * self.n_flex


def _speed_friction_table(coulomb_units: float, no_load_rad_s: float, stall_units: float
                          ) -> tuple[tuple[float, float], ...]:
    """(shaft rad/s, friction units) at Table 4.1's terminal speeds and the no-load speed."""
    pts = [(slope, u - coulomb_units) for u, slope in TABLE_4_1_SLOPES]
    return (*pts, (no_load_rad_s, stall_units - coulomb_units))


def _damping_table(coulomb_units: float) -> tuple[tuple[float, float], ...]:
    """Viscous coefficient (units per shaft rad/s) reproducing Table 4.1 with Coulomb friction."""
    return tuple((u, (u - coulomb_units) / slope) for u, slope in TABLE_4_1_SLOPES)


@dataclass(frozen=True, slots=True)
class BaseSpringFit:
    """A preloaded base spring fitted to a weight table: angle = max(0, F rad_per_n - preload).

    ``threshold_n`` is the tendon force at which the finger leaves its open stop;
    ``predicted_rad`` / ``residual_rad`` are per table row (predicted - table).
    """

    rad_per_n: float
    preload_rad: float
    threshold_n: float
    predicted_rad: tuple[float, ...]
    residual_rad: tuple[float, ...]
    rms_rad: float


def fit_base_spring(table: tuple[tuple[float, float], ...]) -> BaseSpringFit:
    """Least squares of ``angle = F s - p`` over the rows where the finger moved (angle > 0);
    a row at 0 that the line would lift is added as a point at 0 and the fit repeated."""
    use = [(f, a) for f, a in table if a > 0.0]
    while True:
        n = len(use)
        if n < 2:
            raise ValueError("need at least two rows with the finger lifted")
        if n == 2:  # the line through both (bit-identical to the original calibration)
            (f_hi, a_hi), (f_lo, a_lo) = use
            s = (a_hi - a_lo) / (f_hi - f_lo)
            pre = f_hi * s - a_hi
        else:
            fm = sum(f for f, _ in use) / n
            am = sum(a for _, a in use) / n
            s = sum((f - fm) * (a - am) for f, a in use) / sum((f - fm) ** 2 for f, _ in use)
            pre = s * fm - am
        lifted = [(f, 0.0) for f, a in table if a <= 0.0 and s * f - pre > 0.0
                  and (f, 0.0) not in use]
        if not lifted:
            break
        use += lifted
    pred = tuple(max(0.0, s * f - pre) for f, _ in table)
    res = tuple(p - a for p, (_, a) in zip(pred, table, strict=True))
    rms = math.sqrt(sum(r * r for r in res) / len(res))
    return BaseSpringFit(s, pre, pre / s, pred, res, rms)


#: which Table 4.2 column the base spring is calibrated on
CALIBRATIONS: dict[str, tuple[tuple[float, float], ...]] = {
    "model": TABLE_4_2_MODEL, "measured": TABLE_4_2_MEASURED}


def default_finger_params(calibration: str = "model") -> FingerParams:
    """The calibrated finger: base spring from Table 4.2 (its ``calibration`` column: the
    report's model, as before, or the physical finger's measurements), motor friction from
    Table 4.1."""
    r_base = JOINT_RATIO * 0.01222
    fit = fit_base_spring(CALIBRATIONS[calibration])
    k_base = r_base / fit.rad_per_n
    coulomb = 5.0
    plain = FingerParams()
    no_load, stall = plain.max_speed_rad_s, plain.max_effort_units
    return FingerParams(k_base_nm_per_rad=k_base, base_preload_rad=fit.preload_rad,
                        r_base_m=r_base, motor_coulomb_units=coulomb,
                        damping_table=_damping_table(coulomb),
                        speed_friction_table=_speed_friction_table(coulomb, no_load, stall))


def with_tactile_gain(params: FingerParams, gain: float) -> FingerParams:
    """``params`` with tactile cells ``gain`` times as sensitive as their nominal calibration
    (``hand.sim.tactile_gain``: a mis-calibrated sensor; only the pressure readings change,
    never the physics); the same object at gain 1."""
    if gain == 1.0:
        return params
    return replace(params, pressure_per_n=params.pressure_per_n * gain)


def motor_damping_units(params: FingerParams, effort_units: float) -> float:
    """Viscous coefficient (units per shaft rad/s) at this effort: log-log through Table 4.1.

    Outside the table the end slopes are extended; the effort is clamped to [20, 1023] units.
    """
    table = params.damping_table
    u = min(max(abs(effort_units), 20.0), params.max_effort_units)
    if u <= table[0][0]:
        (u0, d0), (u1, d1) = table[0], table[1]
    elif u >= table[-1][0]:
        (u0, d0), (u1, d1) = table[-2], table[-1]
    else:
        i = 1
        while table[i][0] < u:
            i += 1
        (u0, d0), (u1, d1) = table[i - 1], table[i]
    p = math.log(d1 / d0) / math.log(u1 / u0)
    return d0 * (u / u0) ** p


def speed_law_pieces(params: FingerParams) -> tuple[tuple[float, float, float], ...]:
    """(lower speed w0 rad/s, friction G0 units, exponent) of the speed law's power pieces
    (the first starts at the table's first point; the last is extended upwards)."""
    tab = params.speed_friction_table
    if len(tab) != SPEED_LAW_POINTS:
        raise ValueError(f"speed_friction_table needs {SPEED_LAW_POINTS} points, has {len(tab)}")
    return tuple((w0, g0, math.log(g1 / g0) / math.log(w1 / w0))
                 for (w0, g0), (w1, g1) in zip(tab[:-1], tab[1:], strict=True))


def speed_friction_units(params: FingerParams, speed_rad_s: float) -> tuple[float, float]:
    """The speed law: (friction units opposing shaft speed ``speed_rad_s``, its slope dG/dw in
    units per rad/s, never negative).  Linear through the origin below the first point."""
    return speed_friction_at(speed_rad_s, speed_law_pieces(params))


def speed_friction_at(v: float, pieces: tuple[tuple[float, float, float], ...]
                      ) -> tuple[float, float]:
    """:func:`speed_friction_units` over the law's pieces (:func:`speed_law_pieces`)."""
    w = -v if v < 0.0 else v
    w0, g0, expo = pieces[0]
    if w <= w0:
        slope = g0 / w0
        return slope * v, slope
    for cand in pieces[1:]:
        if w < cand[0]:
            break
        w0, g0, expo = cand
    g = g0 * (w / w0) ** expo
    return (g if v > 0.0 else -g), expo * g / w
