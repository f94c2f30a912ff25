"""The ReFlex hand on Dynamixel MX-28s: ``DynamixelHand(bus, cfg)`` (a HandBackend).

ReFlex conventions (``hand.dynamixel`` config; reference: reflex-hardware.md):

* joint angle = inversion * (raw * scale / ratio - zero); ratio 1.42 (fingers), 1.5 (preshape);
  inversion per motor [1, -1, 1, -1].  Set-points are clamped to [0, travel] before they are
  turned into counts, so nothing outside the travel limits ever reaches a motor.
* Load (positive = pulling the tendon) = inversion * signed Dynamixel load; filtered
  ``f = 0.25 new + 0.75 f``.  Overload protection: while |f| is above the threshold (350
  fingers, 400 preshape) the target is backed off to the present angle - 0.05 rad.
* Force mode is the stock integral loop on filtered load; velocity mode a position move to the
  travel limit at the commanded speed.  Optional command pacing delays every command by 0.09 s
  (the stock driver's sleeps), without blocking the caller.
* Calibration: the stock routine steps a motor in 6 counts at a time until the proximal encoder
  moves > 0.05 rad, backs off 50 counts and saves the zero.  The direct-USB layout has no
  proximal encoder on the servo bus.  When a ``proximal_source`` (a callable returning the three
  proximal angles, e.g. an encoder board driver, or the emulator's finger model in tests) is
  injected, the stock criterion is used unchanged.  Without one, the trigger is the load: the
  present load rising by ``calibration_load_units`` above its value at the first step, on two
  consecutive steps (the tendon taking up the finger).  That fallback is approximate: a servo
  that lags its stepped goal (friction) shows a load rise before the tendon is taut, so the
  threshold must be set above the free-motion load at the stepping rate.
* No tactile sensors on this bus: pressures are zeros; contact flags and the proximal/distal
  split are estimated from the load (contact = filtered load above ``contact_load_units`` while
  the motor is stalled; the proximal angle is frozen at contact onset and the distal estimate is
  max(0, joint - proximal)).  This is crude: treat it as a placeholder for real sensors.
* Bus faults: each failed transaction is retried (``retries``) and logged by the bus; a
  cycle whose transactions still fail counts as a failure, and after ``max_failures``
  consecutive failures the hand latches its safe state (hold) and says so in every reading's
  ``faults``.  A vanished port raises :class:`~teleop.errors.DeviceNotConnected`.
* Servo error bits: while any servo (fingers or preshape) reports a hardware error (P1.0:
  overload, overheat, input voltage; P2.0: any bit of the hardware error status) the hand
  holds its safe state: set-points are ignored and every goal is the present position, and
  every reading's ``faults`` says which servo and why (``servo_fault_trips`` counts the
  episodes).  When every bit has cleared the hand resumes cleanly: goals at the present
  position first, then torque on again (the servo's alarm shutdown may have switched it off),
  then the next command is followed.  A P2.0 servo latches its hardware error status until
  it is rebooted: after ``reboot_after_s`` in the safe state the backend reboots the faulted
  servos (``servo_reboots`` counts them), again as often while the status comes back; a
  cause that has gone then leaves the status clear and the hand resumes as above.
"""

from __future__ import annotations

import logging
import time
from collections import deque
from collections.abc import Callable, Sequence

from teleop.config.hand import DynamixelConfig, HandConfig
from teleop.devices import dynamixel_tables as T
from teleop.devices.base import HandReading
from teleop.devices.dynamixel_bus import BusTransactionError, DynamixelBus, Goal, ServoStatus
from teleop.errors import ConfigError, DeviceError
from teleop.messages import N_PRESSURE, FingerState, HandCommand, HandMode

log = logging.getLogger("teleop.devices.dynamixel")

BACKOFF_RAD = 0.05
CAL_STEP_COUNTS = 6
CAL_BACKOFF_COUNTS = 50
CAL_PROXIMAL_RAD = 0.05
CONTACT_STALL_RAD_S = 0.1  # joint speed below which a loaded finger counts as stalled


def _check_config(cfg: DynamixelConfig) -> None:
    where = "hand.dynamixel"
    if len(cfg.ids) != 4 or len(set(cfg.ids)) != 4:
        raise ConfigError(f"{where}.ids must be 4 distinct servo IDs (3 fingers + preshape), "
                          f"got {list(cfg.ids)}")
    if len(cfg.inversion) != 4 or any(v not in (1, -1) for v in cfg.inversion):
        raise ConfigError(f"{where}.inversion must be 4 values of 1 or -1, got "
                          f"{list(cfg.inversion)}")
    if len(cfg.zeros_rad) != 4:
        raise ConfigError(f"{where}.zeros_rad must have 4 values, got {len(cfg.zeros_rad)}")
    if cfg.protocol not in (1.0, 2.0):
        raise ConfigError(f"{where}.protocol must be 1.0 or 2.0, got {cfg.protocol}")


class DynamixelHand:
    """Three finger tendons and the preshape on four MX-28s (implements HandBackend)."""

    def __init__(self, bus: DynamixelBus, cfg: DynamixelConfig,
                 clock: Callable[[], float] = time.monotonic,
                 sleep: Callable[[float], None] = time.sleep,
                 proximal_source: Callable[[], Sequence[float]] | None = None) -> None:
        _check_config(cfg)
        self.bus = bus
        self.proximal_source = proximal_source
        self.cfg = cfg
        self.clock = clock
        self.sleep = sleep
        self.ratio = (cfg.finger_ratio,) * 3 + (cfg.preshape_ratio,)
        self.travel = (cfg.finger_travel_rad,) * 3 + (cfg.preshape_travel_rad,)
        self.overload = (cfg.overload_finger_units,) * 3 + (cfg.overload_preshape_units,)
        self.inv = tuple(cfg.inversion)
        self.zeros = list(cfg.zeros_rad)
        self.counts = [0] * 4
        self.joint = [0.0] * 4
        self.load = [0.0] * 4
        self.load_filt = [0.0] * 4
        self.target = [0.0] * 4
        self.speed_rad_s = [cfg.speed_rad_s] * 4
        self.mode = HandMode.POSITION
        self.force_units = (0.0, 0.0, 0.0)
        self.consecutive_failures = 0
        self.safe_reason = ""  # non-empty while latched safe after bus failures
        self.servo_fault_reason = ""  # non-empty while held safe on servo error bits
        self.servo_fault_trips = 0  # times the servo error bits sent the hand safe
        self.servo_reboots = 0  # P2.0 servos rebooted to clear a latched error status
        self._last_reboot_s: float | None = None
        self.servo_fault_since_s: float | None = None  # clock() when the present episode began
        self.requested_safe = False
        self.started = False
        self._proximal = [0.0] * 3
        self._contact = [False] * 3
        self._faults: list[str] = []
        self._pending: deque[tuple[float, HandCommand]] = deque()
        self._status: tuple[ServoStatus, ...] = ()

    # ---- conversions
    def joint_from_counts(self, k: int, counts: int) -> float:
        """Joint angle of motor ``k`` at raw ``counts``."""
        return self.inv[k] * (counts * self.bus.rad_per_count / self.ratio[k] - self.zeros[k])

    def counts_from_joint(self, k: int, joint_rad: float) -> int:
        """Raw counts of motor ``k`` at ``joint_rad`` (clamped to the servo's range)."""
        raw = round((self.inv[k] * joint_rad + self.zeros[k]) * self.ratio[k]
                    / self.bus.rad_per_count)
        lo, hi = ((T.P1_MULTI_TURN_MIN, T.P1_MULTI_TURN_MAX) if self.bus.protocol == 1
                  else (T.P2_POSITION_MIN, T.P2_POSITION_MAX))
        return max(lo, min(hi, raw))

    def clamp(self, k: int, joint_rad: float) -> float:
        """``joint_rad`` inside motor ``k``'s travel [0, travel]."""
        return max(0.0, min(self.travel[k], joint_rad))

    # ---- HandBackend
    def start(self) -> None:
        """Open the bus, check the servos, set the torque limit, torque on, hold in place."""
        self.bus.open()
        want = T.P1_MODEL_NUMBER if self.bus.protocol == 1 else T.P2_MODEL_NUMBER
        for dxl_id in self.cfg.ids:
            model = self.bus.ping(dxl_id)
            if model != want:
                raise DeviceError(f"{self.bus.port_name}: servo {dxl_id} is model {model}, "
                                  f"expected an MX-28 (model {want}) on protocol "
                                  f"{self.bus.protocol}.0")
            self._setup_servo(dxl_id)
        self._read_state()
        self.target = [self.clamp(k, self.joint[k]) for k in range(4)]
        self._write_goals()  # goals first (hold here), then torque on: no jump to an old goal
        for dxl_id in self.cfg.ids:
            self.bus.write(dxl_id, "torque_enable", 1)
        if self.cfg.calibrate:
            self.calibrate()
            self._write_goals()
        self.started = True

    def _setup_servo(self, dxl_id: int) -> None:
        bus = self.bus
        if bus.protocol == 1:
            mode = (bus.read(dxl_id, "cw_angle_limit"), bus.read(dxl_id, "ccw_angle_limit"),
                    bus.read(dxl_id, "resolution_divider"))
            if mode != (4095, 4095, T.P1_RESOLUTION_DIVIDER):
                raise DeviceError(f"{bus.port_name}: servo {dxl_id} is not set up as on the "
                                  "ReFlex (multi-turn: angle limits 4095/4095, resolution "
                                  f"divider 4); it has {mode}")
            bus.write(dxl_id, "torque_limit", round(self.cfg.torque_limit * T.P1_TORQUE_LIMIT_MAX))
        else:
            if bus.read(dxl_id, "operating_mode") != T.P2_OPERATING_MODE_MULTI_TURN:
                bus.write(dxl_id, "torque_enable", 0)
                bus.write(dxl_id, "operating_mode", T.P2_OPERATING_MODE_MULTI_TURN)
            bus.write(dxl_id, "goal_pwm", round(self.cfg.torque_limit * T.P2_PWM_MAX))

    def apply(self, command: HandCommand) -> None:
        """New targets (after the pacing delay when ``command_pacing`` is on)."""
        if self.safe_reason or self.servo_fault_reason:
            return  # latched safe (bus failures) or held safe (servo error bits): ignored
        if self.cfg.command_pacing:
            now = self.clock()
            self._pending.append((now + self.cfg.command_delay_s, command))
            self._release(now)
        else:
            self._execute(command)

    def read(self, t_s: float) -> HandReading:
        """Read every servo, run overload protection and report (faults included)."""
        self._release(self.clock())
        if self._guard("state read", self._read_state):
            self._check_servo_errors()
            self._protect()
        if self.safe_reason:
            self._faults.append(self.safe_reason)
        elif self.servo_fault_reason:
            self._faults.append(self.servo_fault_reason)
        faults, self._faults = tuple(dict.fromkeys(self._faults)), []
        return HandReading(t_s, self._finger_states(), self.joint[3], faults,
                           servo_fault_trips=self.servo_fault_trips,
                           servo_safe=bool(self.servo_fault_reason))

    def safe(self, mode: str) -> None:
        """Hold the present position (``"hold"``) or open the fingers (``"open"``)."""
        self.requested_safe = True
        self.mode = HandMode.SAFE
        self._pending.clear()
        self.target = [self.clamp(k, self.joint[k]) for k in range(4)]
        if mode == "open":
            self.target[:3] = [0.0, 0.0, 0.0]
        try:  # best effort: going safe must not fail on a dead bus
            self._guard("safe-state goal write", self._write_goals)
        except DeviceError as exc:
            self._faults.append(f"safe-state goal write: {exc}")
            log.error("dynamixel: safe-state goal write failed: %s", exc)

    def close(self) -> None:
        """Torque off (best effort) and close the port."""
        if self.bus.is_open:
            for dxl_id in self.cfg.ids:
                try:
                    self.bus.write(dxl_id, "torque_enable", 0)
                except DeviceError:
                    break
        self.bus.close()

    # ---- commands
    def _release(self, now: float) -> None:
        while self._pending and self._pending[0][0] <= now:
            self._execute(self._pending.popleft()[1])

    def _execute(self, cmd: HandCommand) -> None:
        if self.safe_reason or self.servo_fault_reason:
            return
        if cmd.mode == HandMode.SAFE:
            self.safe("hold")
            return
        self.requested_safe = False
        self.mode = cmd.mode
        speed = [self.cfg.speed_rad_s] * 4
        for k in range(3):
            if cmd.mode in (HandMode.POSITION, HandMode.VELOCITY):
                # VELOCITY is the stock driver's "velocity mode": a position move to the set-point
                # at the configured speed (not wheel mode); the same meaning as the sim hand's.
                self.target[k] = self.clamp(k, cmd.finger_setpoint_rad[k])
            else:  # FORCE: integral loop on the filtered load
                err = cmd.finger_force_units[k] - self.load_filt[k]
                self.target[k] = self.clamp(
                    k, self.target[k] + self.cfg.force_gain_rad_per_unit * err)
        self.force_units = cmd.finger_force_units
        self.target[3] = self.clamp(3, cmd.preshape_rad)
        self.speed_rad_s = speed
        self._back_off()
        self._guard("goal write", self._write_goals)

    def _back_off(self) -> bool:
        """Overload protection: limit overloaded targets to the present angle - 0.05 rad."""
        changed = False
        for k in range(4):
            if abs(self.load_filt[k]) > self.overload[k]:
                limit = self.clamp(k, self.joint[k] - BACKOFF_RAD)
                if self.target[k] > limit:
                    self.target[k] = limit
                    changed = True
                    self._faults.append(f"motor {k + 1} (servo {self.cfg.ids[k]}) overloaded "
                                        f"(load {self.load_filt[k]:.0f}): target backed off")
        return changed

    def _protect(self) -> None:
        if self._back_off():
            self._guard("overload back-off goal write", self._write_goals)

    def _write_goals(self) -> None:
        goals = {}
        cap = T.P1_SPEED_MAX_UNITS if self.bus.protocol == 1 else T.P2_VELOCITY_LIMIT
        for k, dxl_id in enumerate(self.cfg.ids):
            units = self.speed_rad_s[k] * self.ratio[k] / self.bus.rad_s_per_speed_unit
            speed = 0 if units <= 0 else max(1, min(cap, round(units)))
            goals[dxl_id] = Goal(self.counts_from_joint(k, self.clamp(k, self.target[k])), speed)
        self.bus.write_goals(goals)

    # ---- state
    def _read_state(self) -> None:
        status = self.bus.read_states()
        self._status = status
        a = self.cfg.load_filter
        for k, s in enumerate(status):
            self.counts[k] = s.position_counts
            self.joint[k] = self.joint_from_counts(k, s.position_counts)
            self.load[k] = float(self.inv[k] * s.load_cw_units)
            self.load_filt[k] = a * self.load[k] + (1.0 - a) * self.load_filt[k]
            for name in s.hardware_faults:
                self._faults.append(f"servo {s.dxl_id}: {name} error")
        for k in range(3):  # contact: loaded and stalled (a moving motor is loaded by friction)
            v_joint = abs(status[k].velocity_rad_s) / self.ratio[k] if status else 0.0
            touching = self.load_filt[k] > self.cfg.contact_load_units and (
                v_joint < CONTACT_STALL_RAD_S or self._contact[k])
            if not (touching and self._contact[k]):  # free, or contact just began: follow
                self._proximal[k] = self.joint[k]
            self._proximal[k] = min(self._proximal[k], self.joint[k])
            self._contact[k] = touching

    def _finger_states(self) -> tuple[FingerState, FingerState, FingerState]:
        out = []
        for k in range(3):
            prox = max(0.0, self._proximal[k])
            out.append(FingerState(prox, max(0.0, self.joint[k] - prox), self.joint[k],
                                   self.load[k], (0.0,) * N_PRESSURE,
                                   (self._contact[k],) * N_PRESSURE))
        return out[0], out[1], out[2]

    def _check_servo_errors(self) -> None:
        """Hold the safe state while any servo reports hardware error bits; resume after."""
        bad = [f"servo {s.dxl_id} {', '.join(s.hardware_faults)}" for s in self._status
               if s.hardware_faults]
        if bad:
            reason = (f"dynamixel: {'; '.join(bad)} error; hand held in its safe state (hold) "
                      "until the servo error bits clear")
            if not self.servo_fault_reason:
                self.servo_fault_trips += 1
                self.servo_fault_since_s = self.clock()
                log.error("%s", reason)
                self._hold_present()
            self.servo_fault_reason = reason
            self._maybe_reboot([s.dxl_id for s in self._status if s.hardware_faults])
        elif self.servo_fault_reason:
            self._resume_after_servo_error()

    def _maybe_reboot(self, ids: list[int]) -> None:
        """P2.0 latches the hardware error status until a reboot: once the hand has held its
        safe state ``reboot_after_s`` (since the episode began or the last reboot), reboot the
        faulted servos.  A cause that is gone leaves the status clear (the next reading
        resumes); one still present sets it again (held safe, rebooted again later)."""
        after = self.cfg.reboot_after_s
        if self.cfg.protocol < 2.0 or after <= 0.0:
            return
        now = self.clock()
        since = self._last_reboot_s if self._last_reboot_s is not None else (
            self.servo_fault_since_s if self.servo_fault_since_s is not None else now)
        if now - since < after:
            return
        self._last_reboot_s = now
        for dxl_id in ids:
            if self._guard(f"reboot of servo {dxl_id}", lambda i=dxl_id: self.bus.reboot(i)):
                self.servo_reboots += 1
                log.warning("dynamixel: servo %d rebooted after %.2f s in the safe state to "
                            "clear its latched hardware error status", dxl_id, now - since)

    def _hold_present(self) -> bool:
        """Safe state (hold): drop pending commands, goals at the present position."""
        self.mode = HandMode.SAFE
        self._pending.clear()
        self.target = [self.clamp(k, self.joint[k]) for k in range(4)]
        return self._guard("safe-state goal write", self._write_goals)

    def _resume_after_servo_error(self) -> None:
        """The error bits cleared: goals at the present position, then torque on again."""
        if not self._hold_present():
            return  # retried on the next read: still held safe
        for dxl_id in self.cfg.ids:
            if not self._guard(f"torque on of servo {dxl_id}",
                               lambda i=dxl_id: self.bus.write(i, "torque_enable", 1)):
                return  # retried on the next read: still held safe
        held = self.clock() - (self.servo_fault_since_s or self.clock())
        log.warning("dynamixel: servo error bits cleared after %.2f s; torque on, resuming "
                    "from the present position", held)
        self.servo_fault_reason = ""
        self.servo_fault_since_s = None
        self._last_reboot_s = None

    def _guard(self, what: str, fn: Callable[[], object]) -> bool:
        """Run a bus cycle step; count consecutive failures and latch safe at the limit."""
        try:
            fn()
        except BusTransactionError as exc:
            self.consecutive_failures += 1
            self._faults.append(f"{what}: {exc}")
            if self.consecutive_failures >= self.cfg.max_failures and not self.safe_reason:
                self._go_safe()
            return False
        self.consecutive_failures = 0
        return True

    def _go_safe(self) -> None:
        self.safe_reason = (f"dynamixel: {self.consecutive_failures} consecutive bus failures; "
                            "hand latched in its safe state (hold); restart to resume")
        log.error("%s", self.safe_reason)
        self.mode = HandMode.SAFE
        self._pending.clear()
        self.target = [self.clamp(k, self.joint[k]) for k in range(4)]
        try:  # best effort: a single attempt, the bus is failing
            saved, self.bus.retries = self.bus.retries, 0
            self._write_goals()
        except BusTransactionError:
            pass
        finally:
            self.bus.retries = saved

    # ---- calibration
    def calibrate(self) -> tuple[float, ...]:
        """Find each finger's zero (see the module docstring); returns the zeros (rad)."""
        src = self.proximal_source
        base = list(src()) if src is not None else None
        raw = list(self.counts[:3])
        done = [False] * 3
        hits = [0] * 3
        first_load: list[float] | None = None
        for _ in range(self.cfg.calibration_max_steps):
            for k in range(3):
                if not done[k]:
                    raw[k] += CAL_STEP_COUNTS * self.inv[k]
            self.bus.write_goals({self.cfg.ids[k]: Goal(raw[k], 0) for k in range(3)})
            self.sleep(self.cfg.calibration_step_s)
            self._read_state()
            if first_load is None:
                first_load = list(self.load[:3])
            prox = list(src()) if src is not None else None
            for k in range(3):
                if done[k]:
                    continue
                if prox is not None and base is not None:
                    moved = prox[k] - base[k] > CAL_PROXIMAL_RAD
                    hits[k] = 2 if moved else 0
                else:
                    rose = self.load[k] - first_load[k] > self.cfg.calibration_load_units
                    hits[k] = hits[k] + 1 if rose else 0
                if hits[k] >= 2:
                    done[k] = True
                    zero_counts = self.counts[k] - CAL_BACKOFF_COUNTS * self.inv[k]
                    self.zeros[k] = zero_counts * self.bus.rad_per_count / self.ratio[k]
            if all(done):
                break
        else:
            missing = [k + 1 for k in range(3) if not done[k]]
            if src is not None:
                what = f"proximal angle of finger(s) {missing} never moved {CAL_PROXIMAL_RAD} rad"
            else:
                what = (f"load of finger(s) {missing} never rose by "
                        f"{self.cfg.calibration_load_units} units")
            raise DeviceError(f"calibration failed: {what} within "
                              f"{self.cfg.calibration_max_steps} steps")
        self.target[:3] = [0.0, 0.0, 0.0]
        self._write_goals()
        self._read_state()
        zeros = tuple(round(z, 5) for z in self.zeros)
        log.info("dynamixel: calibrated; save as hand.dynamixel.zeros_rad = %s", list(zeros))
        return zeros


def build_dynamixel_hand(cfg: HandConfig) -> DynamixelHand:
    """The hand backend for ``hand.backend = "dynamixel"`` (registered in services/factory.py)."""
    d = cfg.dynamixel
    _check_config(d)
    bus = DynamixelBus(d.port, d.baud_rate, d.protocol, d.ids, retries=d.retries,
                       timeout_s=d.timeout_s, bulk_read=d.bulk_read)
    return DynamixelHand(bus, d)
