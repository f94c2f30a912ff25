"""The ReFlex TakkTile through its brain board: ``TakkTileHand(link, cfg)`` (a HandBackend).

The board owns the four MX-28s and the 27 tactile sensors; the PC sends mode and target
packets and receives the state packet about every 25 ms (:mod:`brain_board_packets`,
:mod:`brain_board_link`).  The stock driver's conventions (reference: reflex-hardware.md),
with the servo mechanics of ``hand.dynamixel`` and the board's own settings in
``hand.takktile``:

* joint angle = inversion * (raw * scale / ratio - zero) (:mod:`takktile_units`); set-points
  are clamped to [0, travel] before they become counts.
* Start: an idle modes packet (torque off; on unicast it tells the board where to answer),
  wait for the first valid state (``start_timeout_s``, else DeviceNotConnected), average
  ``rest_packets`` states with the fingers open for the tactile offsets and the proximal
  encoder zeros, position mode holding the present angles, then the optional calibration and
  the optional speed-change sequence (velocity mode, speeds, position mode; 0.02 + 0.035 +
  0.035 s as the stock driver sleeps).
* Calibration of the finger motor zeros against the proximal encoders: step 6 counts at a
  time, ``calibration_step_s`` apart, until the encoder has moved > 0.05 rad; back off 50
  counts; that is the zero.
* Pressures = raw - resting offset; contact = pressure > ``contact_threshold`` (20).
  Load (positive = pulling) filtered ``f = 0.25 new + 0.75 f``; while |f| exceeds the
  overload threshold (350 fingers, 400 preshape) the target is loosened to the present angle
  - 0.05 rad and sent again.
* Malformed packets (length, magic byte, board time not moving forward) are dropped and
  counted by reason (:class:`~brain_board_packets.StateReceiver`).  No valid state for
  ``silent_periods`` (4) state periods and every reading is ``stale`` with a fault: the hand
  service trips its watchdog and stops publishing the stale state.  The period is the
  board's own, from the board clock of consecutive packets (filtered, 20-100 Hz), so the
  28 Hz of a grasp does not read as silence and PC-side scheduling does not bias it.
"""

from __future__ import annotations

import ipaddress
import logging
import time
from collections.abc import Callable

from teleop.config import TeleopConfig
from teleop.config.hand import HandConfig
from teleop.devices import takktile_units as U
from teleop.devices.base import HandReading
from teleop.devices.brain_board_link import BoardLink
from teleop.devices.brain_board_packets import (
    MODE_IDLE,
    MODE_POSITION,
    MODE_VELOCITY,
    BoardState,
    StateReceiver,
    encode_modes,
    encode_targets,
)
from teleop.errors import ConfigError, DeviceError, DeviceNotConnected
from teleop.messages import N_PRESSURE, FingerState, HandCommand, HandMode

log = logging.getLogger("teleop.devices.takktile")

LOOSEN_RAD = 0.05
CAL_STEP_COUNTS = 6
CAL_BACKOFF_COUNTS = 50
CAL_PROXIMAL_RAD = 0.05
SPEED_SEQUENCE_S = (0.02, 0.035, 0.035)
POLL_S = 0.002
PERIOD_FILTER = 0.25  # weight of a new board-clock interval in the period estimate


def check_takktile_config(cfg: HandConfig) -> None:
    """Refuse addresses that cannot work, naming the key."""
    t = cfg.takktile
    try:
        ip = ipaddress.IPv4Address(t.address)
    except ValueError:
        raise ConfigError(f"hand.takktile.address = {t.address!r}: not an IPv4 address") \
            from None
    if (t.network == "multicast") != ip.is_multicast:
        raise ConfigError(f"hand.takktile.address = {t.address!r}: " + (
            "network = multicast needs a multicast group (224.0.0.124 on the hand)"
            if t.network == "multicast" else "a multicast group needs network = multicast"))
    if t.interface:
        try:
            ipaddress.IPv4Address(t.interface)
        except ValueError:
            raise ConfigError(f"hand.takktile.interface = {t.interface!r}: not an IPv4 "
                              "address") from None
    if any(v not in (1, -1) for v in cfg.dynamixel.inversion):
        raise ConfigError("hand.dynamixel.inversion must be 4 values of 1 or -1")


class TakkTileHand:
    """Three fingers, the preshape and 27 tactile sensors behind the brain board."""

    def __init__(self, link: BoardLink, cfg: HandConfig,
                 clock: Callable[[], float] = time.monotonic,
                 sleep: Callable[[float], None] = time.sleep) -> None:
        self.link = link
        self.cfg = cfg.takktile
        d = cfg.dynamixel
        self.clock, self.sleep = clock, sleep
        self.ratio = (d.finger_ratio,) * 3 + (d.preshape_ratio,)
        self.travel = (d.finger_travel_rad,) * 3 + (d.preshape_travel_rad,)
        self.overload = (d.overload_finger_units,) * 3 + (d.overload_preshape_units,)
        self.load_filter = d.load_filter
        self.force_gain = d.force_gain_rad_per_unit
        self.speed_rad_s = d.speed_rad_s
        self.inv = tuple(d.inversion)
        self.zeros = list(self.cfg.zeros_rad)
        self.rx = StateReceiver()
        self.state: BoardState | None = None
        self.last_valid_s: float | None = None
        self.joint = [0.0] * 4
        self.load = [0.0] * 4
        self.load_filt = [0.0] * 4
        self.target = [0.0] * 4
        self.tactile_offset = [0.0] * 27
        self.encoder_zero = [0, 0, 0]
        self._encoder: list[int | None] = [None, None, None]
        self.proximal = [0.0] * 3
        self.silent_trips = 0
        self.period_s = 1.0 / cfg.state_rate_hz  # the board's state period (estimated)
        self._silent = False
        self._faults: list[str] = []

    # ---- packets
    def _send_modes(self, mode: int) -> None:
        self.link.send(encode_modes((mode,) * 4))  # type: ignore[arg-type]

    def _send_targets(self) -> None:
        goals = tuple(U.raw_goal(self._clamp(k, self.target[k]), self.inv[k], self.zeros[k],
                                 self.ratio[k]) for k in range(4))
        self.link.send(encode_targets(goals))  # type: ignore[arg-type]

    def _clamp(self, k: int, joint_rad: float) -> float:
        return max(0.0, min(self.travel[k], joint_rad))

    def _poll(self) -> int:
        """Take in every waiting packet; returns how many valid states arrived."""
        n = 0
        for data in self.link.receive():
            prev_us = self.rx.last_time_us
            s = self.rx.accept(data)
            if s is not None and prev_us is not None:
                dt = ((s.systime_us - prev_us) % (1 << 32)) * 1e-6
                self.period_s += PERIOD_FILTER * (min(max(dt, 0.01), 0.05) - self.period_s)
            if s is not None:
                self._use(s)
                n += 1
        if n:
            self.last_valid_s = self.clock()
        return n

    def _use(self, s: BoardState) -> None:
        self.state = s
        a = self.load_filter
        for k in range(4):
            self.joint[k] = U.joint_from_raw(s.dxl_angle[k], self.inv[k], self.zeros[k],
                                             self.ratio[k])
            self.load[k] = U.load_from_raw(s.dxl_load[k], self.inv[k])
            self.load_filt[k] = a * self.load[k] + (1.0 - a) * self.load_filt[k]
            if s.dxl_error[k]:
                self._faults.append(f"motor {k + 1}: servo error bits {s.dxl_error[k]:#04x}")
        for k in range(3):
            self._encoder[k] = U.unwrap_counts(self._encoder[k], s.encoders[k])
            self.proximal[k] = (self._encoder[k] - self.encoder_zero[k]) \
                * U.ENCODER_RAD_PER_COUNT  # type: ignore[operator]

    def _wait_states(self, n: int, timeout_s: float) -> list[BoardState]:
        """The next ``n`` valid states (DeviceNotConnected when they do not come)."""
        got: list[BoardState] = []
        end = self.clock() + timeout_s
        while len(got) < n:
            before = self.rx.accepted
            self._poll()
            if self.rx.accepted > before and self.state is not None:
                got.append(self.state)
                end = self.clock() + timeout_s
            elif self.clock() > end:
                c = self.rx.counts()
                raise DeviceNotConnected(
                    f"brain board {self.link.dest[0]}:{self.link.dest[1]}: no valid state "
                    f"packet within {timeout_s} s (dropped: {dict(c.by_reason) or 'none'}); "
                    "is the hand on and hand.takktile.network/address/interface right?")
            else:
                self.sleep(POLL_S)
        return got

    # ---- HandBackend
    def start(self) -> None:
        """Open the link, wait for the board, take the resting offsets, hold in place."""
        try:
            self.link.open()
        except OSError as exc:
            raise DeviceNotConnected(f"brain board link ({self.link.dest[0]}:"
                                     f"{self.link.dest[1]}): {exc.strerror or exc}") from None
        self._send_modes(MODE_IDLE)
        self._wait_states(1, self.cfg.start_timeout_s)
        if self.cfg.rest_packets:
            rest = self._wait_states(self.cfg.rest_packets, self.cfg.start_timeout_s)
            n = len(rest)
            self.tactile_offset = [sum(s.pressures[i] for s in rest) / n for i in range(27)]
            self.encoder_zero = [round(sum(self._unwrapped(s, k) for s in rest) / n)
                                 for k in range(3)]
            self._use(rest[-1])
        self.target = [self._clamp(k, self.joint[k]) for k in range(4)]
        self._send_modes(MODE_POSITION)
        self._send_targets()
        if self.cfg.calibrate:
            self.calibrate()
        if self.cfg.speed_change_sequence:
            self.set_speed(self.speed_rad_s)
        self.last_valid_s = self.clock()

    def _unwrapped(self, s: BoardState, k: int) -> int:
        return U.unwrap_counts(self._encoder[k], s.encoders[k])

    def set_speed(self, joint_speed_rad_s: float) -> None:
        """The stock speed-change sequence: velocity mode, speeds, position mode (0.09 s)."""
        pause = SPEED_SEQUENCE_S
        self._send_modes(MODE_VELOCITY)
        self.sleep(pause[0])
        self.link.send(encode_targets(tuple(U.raw_speed(joint_speed_rad_s, r)  # type: ignore[arg-type]
                                            for r in self.ratio)))
        self.sleep(pause[1])
        self._send_modes(MODE_POSITION)
        self._send_targets()
        self.sleep(pause[2])

    def apply(self, command: HandCommand) -> None:
        """New targets (position/velocity: set-points; force: the integral loop on load)."""
        if command.mode == HandMode.SAFE:
            self.safe("hold")
            return
        for k in range(3):
            if command.mode == HandMode.FORCE:
                err = command.finger_force_units[k] - self.load_filt[k]
                self.target[k] = self._clamp(k, self.target[k] + self.force_gain * err)
            else:
                self.target[k] = self._clamp(k, command.finger_setpoint_rad[k])
        self.target[3] = self._clamp(3, command.preshape_rad)
        self._loosen()
        self._send_targets()

    def read(self, t_s: float) -> HandReading:
        """Take in the board's packets; loosen overloaded fingers; report (stale if silent)."""
        if self._poll() and self._loosen():
            self._send_targets()
        now = self.clock()
        quiet = now - self.last_valid_s if self.last_valid_s is not None else float("inf")
        stale = quiet >= self.cfg.silent_periods * self.period_s - 1e-9
        if stale:
            if not self._silent:
                self.silent_trips += 1
                log.error("brain board silent for %.3f s", quiet)
            self._faults.append(f"brain board silent: no valid state packet for {quiet:.3f} s")
        self._silent = stale
        faults, self._faults = tuple(dict.fromkeys(self._faults)), []
        return HandReading(t_s, self._fingers(), self.joint[3], faults, stale=stale)

    def safe(self, mode: str) -> None:
        """Hold the present angles (``"hold"``) or open the fingers (``"open"``)."""
        self.target = [self._clamp(k, self.joint[k]) for k in range(4)]
        if mode == "open":
            self.target[:3] = [0.0, 0.0, 0.0]
        self._send_targets()

    def close(self) -> None:
        """Torque off (idle mode, best effort) and close the socket."""
        self._send_modes(MODE_IDLE)
        self.link.close()

    # ---- state
    def _loosen(self) -> bool:
        changed = False
        for k in range(4):
            if abs(self.load_filt[k]) > self.overload[k]:
                limit = self._clamp(k, self.joint[k] - LOOSEN_RAD)
                if self.target[k] > limit:
                    self.target[k] = limit
                    changed = True
                    self._faults.append(f"motor {k + 1} overloaded (load "
                                        f"{self.load_filt[k]:.0f}): target loosened")
        return changed

    def pressures(self, k: int) -> tuple[float, ...]:
        """Finger ``k``'s 9 pressures above their resting offsets (raw units)."""
        s = self.state
        if s is None:
            return (0.0,) * N_PRESSURE
        return tuple(float(s.pressures[9 * k + j]) - self.tactile_offset[9 * k + j]
                     for j in range(N_PRESSURE))

    def _fingers(self) -> tuple[FingerState, FingerState, FingerState]:
        thr = self.cfg.contact_threshold
        out = []
        for k in range(3):
            p = self.pressures(k)
            prox = self.proximal[k]
            out.append(FingerState(prox, max(0.0, self.joint[k] - prox), self.joint[k],
                                   self.load[k], p, tuple(v > thr for v in p)))
        return out[0], out[1], out[2]

    # ---- calibration
    def calibrate(self) -> tuple[float, ...]:
        """Find each finger's motor zero against its proximal encoder; returns the zeros."""
        self._poll()
        if self.state is None:
            raise DeviceError("calibration: no state from the brain board")
        base = list(self.proximal)
        raw = [U.signed_counts(self.state.dxl_angle[k]) for k in range(3)]
        goal = [U.signed_counts(U.raw_goal(self._clamp(3, self.target[3]), self.inv[3],
                                           self.zeros[3], self.ratio[3]))]
        done = [False] * 3
        for _ in range(self.cfg.calibration_max_steps):
            for k in range(3):
                if not done[k]:
                    raw[k] += CAL_STEP_COUNTS * self.inv[k]
            self.link.send(encode_targets(tuple(U.wire_counts(c) for c in (*raw, *goal))))  # type: ignore[arg-type]
            self.sleep(self.cfg.calibration_step_s)
            self._poll()
            for k in range(3):
                if not done[k] and self.proximal[k] - base[k] > CAL_PROXIMAL_RAD:
                    done[k] = True
                    raw[k] -= CAL_BACKOFF_COUNTS * self.inv[k]
                    self.zeros[k] = raw[k] * U.RAD_PER_COUNT / self.ratio[k]
            if all(done):
                break
        else:
            missing = [k + 1 for k in range(3) if not done[k]]
            raise DeviceError(f"calibration failed: proximal angle of finger(s) {missing} "
                              f"never moved {CAL_PROXIMAL_RAD} rad within "
                              f"{self.cfg.calibration_max_steps} steps")
        self.target[:3] = [0.0, 0.0, 0.0]
        self._send_targets()
        zeros = tuple(round(z, 5) for z in self.zeros)
        log.info("takktile: calibrated; save as hand.takktile.zeros_rad = %s", list(zeros))
        return zeros


def build_takktile_hand(cfg: HandConfig) -> TakkTileHand:
    """The backend for ``hand.backend = "reflex-takktile"`` (registered in services/factory.py)."""
    check_takktile_config(cfg)
    t = cfg.takktile
    return TakkTileHand(BoardLink(t.network, t.address, t.port, t.interface,
                                  t.multicast_loopback), cfg)


def build_takktile_hand_from(cfg: TeleopConfig) -> TakkTileHand:
    """The registry entry (services/factory.py): the whole config in, the backend out."""
    return build_takktile_hand(cfg.hand)
