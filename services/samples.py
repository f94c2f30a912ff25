"""What each service tick produces: one frozen sample of its signals (SI units in the names).

Live services write samples to recordings (:func:`sample_columns`, :func:`sample_row`) and log
them to the dashboard; the lockstep runner stacks them into numpy time series.  Tuple fields
of three values are per finger (columns ``<name>_f1`` .. ``_f3``); ``pressure`` holds the 27
tactile readings (``pressure_f<finger>_<sensor>``, sensors 0-4 proximal, 5-8 distal).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields

from teleop.frozen import fast_init

NAN = math.nan


@fast_init
@dataclass(frozen=True, slots=True)
class MasterSample:
    """One master tick."""

    t_s: float
    trigger_position_m: float
    trigger_velocity_m_s: float
    displayed_force_n: float  # what the trigger displays (after the passivity layer)
    force_desired_n: float  # what the transparency layer asked for
    force_command_n: float  # latest force command received (nan before the first)
    operator_force_n: float  # the virtual operator's push (nan for a real device)
    tank_j: float
    port_in_j: float  # cumulative energy the operator put in
    port_out_j: float  # cumulative energy delivered to the operator
    sent_j: float
    received_j: float
    dissipated_j: float
    tlc_damping_n_s_per_m: float
    limited: float  # 1 when the passivity layer reduced the force this tick
    limit_count: float  # ticks limited so far
    delay_s: float  # achieved controller->master delay of the latest message (nan: none)
    dropped: float  # force commands missing so far (sequence gaps)
    watchdog: float  # 1 while the force-command watchdog is tripped
    model_force_n: float = 0.0  # the contact model rendered locally (model-mediated two-layer)
    model_phase: float = 0.0  # share of the received contact model rendered (0: none)


@fast_init
@dataclass(frozen=True, slots=True)
class ControllerSample:
    """One controller tick."""

    t_s: float
    setpoint_rad: tuple[float, float, float]
    preshape_rad: float
    commanded_force_n: float  # force sent to the master
    force_desired_n: float
    max_pressure: tuple[float, float, float]
    store_j: float
    sent_j: float
    received_j: float
    dissipated_j: float
    master_delay_s: float  # achieved master->controller delay (nan: none this tick)
    hand_delay_s: float  # achieved hand->controller delay (nan: none this tick)
    master_dropped: float
    hand_dropped: float
    watchdog: float  # 1 while the hand-state watchdog is tripped
    force_gain: float = 1.0  # delay-aware force-feedback gain in use
    round_trip_s: float = float("nan")  # measured round trip the gain is scheduled on
    measured_force_n: float = float("nan")  # the hand's pressures through the force map, gain 1
    hand_servo_fault_trips: float = 0.0  # the hand's servo-error safe-state episodes (HandState)


@fast_init
@dataclass(frozen=True, slots=True)
class HandSample:
    """One hand tick."""

    t_s: float
    proximal_angle_rad: tuple[float, float, float]
    distal_angle_rad: tuple[float, float, float]
    motor_angle_rad: tuple[float, float, float]
    motor_load_units: tuple[float, float, float]
    pressure: tuple[float, ...]  # 27
    contacts: tuple[float, float, float]  # sensors in contact per finger
    preshape_rad: float
    setpoint_rad: tuple[float, float, float]  # applied (after the passivity layer)
    setpoint_desired_rad: tuple[float, float, float]
    tank_j: float
    port_in_j: float
    port_out_j: float
    sent_j: float
    received_j: float
    dissipated_j: float
    spring_energy_j: float
    limited: float
    limit_count: float
    delay_s: float  # achieved controller->hand delay of the latest command (nan: none)
    dropped: float
    watchdog: float  # 1 while the command watchdog is tripped
    model_fallbacks: float = 0.0  # contact estimates dropped as diverged so far
    servo_fault_trips: float = 0.0  # servo error bits sent the hand safe this often so far
    servo_safe: float = 0.0  # 1 while held safe because of servo error bits
    yielding: float = 0.0  # fingers whose contact yields (tactile force not trusted there)
    unseen_contact: float = 0.0  # fingers stalled on a contact their cells do not see
    cells_low: float = 0.0  # fingers whose cells read less than the servo's load implies
    # when the hand was really read and the set-points really written (midpoint of the
    # backend's read / apply call, on the loop's clock): ``t_s`` is the tick's deadline.
    # ``t_s`` itself without a clock (lockstep, virtual time); NaN: nothing written this tick
    read_t_s: float = NAN
    write_t_s: float = NAN


Sample = MasterSample | ControllerSample | HandSample


def _names(name: str, n: int) -> list[str]:
    if name == "pressure":
        return [f"pressure_f{i // 9 + 1}_{i % 9}" for i in range(n)]
    if n == 3:
        return [f"{name}_f{i + 1}" for i in range(3)]
    return [f"{name}_{i}" for i in range(n)]


def sample_columns(sample: Sample) -> list[str]:
    """Recording column names of ``sample``'s type (``t_s`` first)."""
    cols: list[str] = []
    for f in fields(sample):
        v = getattr(sample, f.name)
        cols += _names(f.name, len(v)) if isinstance(v, tuple) else [f.name]
    return cols


def sample_row(sample: Sample) -> list[float]:
    """The values of ``sample`` in :func:`sample_columns` order."""
    row: list[float] = []
    for f in fields(sample):
        v = getattr(sample, f.name)
        if isinstance(v, tuple):
            row += [float(x) for x in v]
        else:
            row.append(float(v))
    return row


def status_line(sample: ControllerSample, elapsed_s: float, master_delay_s: float,
                hand_delay_s: float) -> str:
    """One human-readable line of what the loop is doing (printed once a second), with the
    latest achieved delays of the master and hand links."""
    sp = "/".join(f"{v:.2f}" for v in sample.setpoint_rad)
    pr = max(sample.max_pressure)

    def ms(d: float) -> str:
        return f"{d * 1e3:.0f} ms" if math.isfinite(d) else "-"

    wd = "  WATCHDOG" if sample.watchdog else ""
    return (f"status {elapsed_s:5.1f} s  set-points {sp} rad  force {sample.commanded_force_n:+.2f}"
            f" N  max pressure {pr:.0f}  store {sample.store_j:.2f} J  delay master "
            f"{ms(master_delay_s)} hand {ms(hand_delay_s)}{wd}")
