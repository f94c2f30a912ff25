"""The reflex-takktile backend against the emulated board through an in-memory link.

The link is a test double (no sockets) driving :class:`sim.hand_emulator.BrainBoardModel`
on a virtual clock, so every figure here is deterministic; the real-socket runs are in
test_takktile_up.py.
"""

from __future__ import annotations

import math

import pytest

from services.hand_service import HandService
from sim.hand_emulator import BoardParams, BrainBoardModel
from teleop.config import load_config
from teleop.devices import takktile_units as U
from teleop.devices.base import HandReading
from teleop.devices.brain_board_packets import (
    ModesPacket,
    TargetsPacket,
    decode_command,
    encode_state,
)
from teleop.devices.reflex_takktile import TakkTileHand, build_takktile_hand
from teleop.errors import ConfigError, DeviceNotConnected
from teleop.messages import HandCommand, HandMode, Header
from teleop.transport.clock import VirtualClock
from teleop.transport.inproc_bus import InProcessHub


class Clock:
    def __init__(self) -> None:
        self.t = 0.0
        self.slept: list[float] = []

    def __call__(self) -> float:
        return self.t

    def sleep(self, s: float) -> None:
        self.slept.append(s)
        self.t += s


class ModelLink:
    """A BoardLink stand-in: packets go straight to the board model on the test's clock."""

    def __init__(self, model: BrainBoardModel, clock: Clock) -> None:
        self.model, self.clock = model, clock
        self.dest = ("127.0.0.1", 11333)
        self.next_state_s = 0.0
        self.sent: list[object] = []
        self.silent_after_s = math.inf
        self.extra: list[bytes] = []
        self.last_sent_s = math.nan

    def open(self) -> None: ...

    def close(self) -> None: ...

    def send(self, data: bytes) -> bool:
        pkt = decode_command(data)
        self.sent.append(pkt)
        self.model.handle(pkt, self.clock.t)
        return True

    def receive(self) -> list[bytes]:
        out, self.extra = self.extra, []
        while self.next_state_s <= self.clock.t:
            s = self.model.state_at(self.next_state_s)
            if self.next_state_s < self.silent_after_s:
                out.append(encode_state(s))
                self.last_sent_s = self.next_state_s
            self.next_state_s += self.model.period_s()
        return out


HOMES = (0, 0, 0, 0)


def rig(overrides: list[str] = (), homes: tuple[int, ...] = HOMES,
        **board: float) -> tuple[TakkTileHand, ModelLink, Clock]:
    cfg = load_config(None, ["hand.backend=reflex-takktile", *overrides])
    model = BrainBoardModel(cfg.hand, BoardParams(homes_counts=homes, **board))  # type: ignore[arg-type]
    model.start()
    clock = Clock()
    link = ModelLink(model, clock)
    hand = TakkTileHand(link, cfg.hand, clock=clock, sleep=clock.sleep)  # type: ignore[arg-type]
    return hand, link, clock


def command(sp: float, mode: HandMode = HandMode.POSITION) -> HandCommand:
    return HandCommand(Header(0, 0.0, 0.0), (sp, sp, sp), 0.0, mode)


def run(hand: TakkTileHand, clock: Clock, seconds: float,
        cmd: HandCommand | None = None) -> HandReading:
    """Read every 25 ms for ``seconds``, applying ``cmd`` after each read as the hand
    service does."""
    end = clock.t + seconds
    reading = hand.read(clock.t)
    while clock.t < end - 1e-9:
        clock.t += 0.025
        reading = hand.read(clock.t)
        if cmd is not None:
            hand.apply(cmd)
    return reading


def test_start_takes_the_resting_offsets_and_a_grasp_shows_pressures_and_contact() -> None:
    hand, link, clock = rig()
    hand.start()
    rest = run(hand, clock, 0.2)
    assert max(abs(p) for f in rest.fingers for p in f.pressure) < 10  # offsets ~150-600 gone
    assert all(abs(f.proximal_rad) < 0.01 for f in rest.fingers)  # encoder offsets gone
    assert not any(c for f in rest.fingers for c in f.contact)
    assert isinstance(link.sent[0], ModesPacket) and link.sent[0].modes == (0, 0, 0, 0)
    grasp = run(hand, clock, 2.5, command(1.2))
    for f in grasp.fingers:
        assert 0.3 < f.motor_angle_rad < 1.2  # the cylinder stops it
        assert max(f.pressure) > 50 and any(f.contact)
        assert f.load_units > 100
        assert f.distal_rad == pytest.approx(max(0.0, f.motor_angle_rad - f.proximal_rad))
    assert not grasp.stale and hand.rx.counts().rejected == 0
    assert hand.period_s == pytest.approx(1 / 28, rel=0.03)  # the board's grasping rate


class NoLoosening(TakkTileHand):
    """MUTANT: overload loosening removed."""

    def _loosen(self) -> bool:
        return False


def overload_run(cls: type[TakkTileHand]) -> tuple[int, float]:
    """Grasp hard with a low overload threshold (120); returns (loosenings seen, the largest
    filtered finger load while the target was left beyond the present angle - 0.05)."""
    hand, link, clock = rig(["hand.dynamixel.overload_finger_units=120"], load_noise_units=0.0)
    hand.__class__ = cls
    hand.start()
    loosened, worst = 0, 0.0
    for _ in range(80):
        clock.t += 0.025
        r = hand.read(clock.t)
        loosened += any(f.startswith("motor 1 overloaded") for f in r.faults)
        limit = max(0.0, hand.joint[0] - 0.05)
        if hand.target[0] > limit + 1e-9:  # left beyond the limit: how loaded was it?
            worst = max(worst, hand.load_filt[0])
        sent = [p for p in link.sent if isinstance(p, TargetsPacket)][-1]
        assert U.joint_from_raw(sent.targets[0], 1, 0.0, 1.42) == pytest.approx(
            hand.target[0], abs=U.RAD_PER_COUNT)  # what the board has is the target
        hand.apply(command(1.6))
    return loosened, worst


def test_overload_loosens_the_target_to_the_present_angle_minus_0_05_rad() -> None:
    loosened, worst = overload_run(TakkTileHand)
    assert loosened >= 3
    # after each read, a finger above the threshold never keeps a target beyond the limit
    assert worst <= 120.0


def test_without_loosening_the_overloaded_target_stays_mutant() -> None:
    loosened, worst = overload_run(NoLoosening)
    assert loosened == 0 and worst > 120.0


def test_calibration_finds_the_motor_zeros_against_the_proximal_encoders() -> None:
    homes = (2000, -1500, 1800, 0)
    hand, _, clock = rig(["hand.takktile.calibrate=true"], homes=homes)
    hand.start()
    for k in range(3):  # zero = home - 50 counts back-off + the steps to move 0.05 rad
        found = hand.zeros[k] * 1.42 / U.RAD_PER_COUNT
        assert abs(found - homes[k]) < 60, (k, found)
    rest = run(hand, clock, 0.5)  # commanded open after calibrating
    assert all(abs(f.motor_angle_rad) < 0.1 for f in rest.fingers)


def test_the_speed_change_sequence_is_modes_1_speeds_modes_2_over_0_09_s() -> None:
    hand, link, clock = rig(["hand.takktile.speed_change_sequence=true",
                             "hand.dynamixel.speed_rad_s=1.0"])
    hand.start()
    seq = link.sent[-4:]
    assert seq[0] == ModesPacket((1, 1, 1, 1))
    assert seq[1] == TargetsPacket((U.raw_speed(1.0, 1.42),) * 3 + (U.raw_speed(1.0, 1.5),))
    assert seq[2] == ModesPacket((2, 2, 2, 2)) and isinstance(seq[3], TargetsPacket)
    assert sum(clock.slept[-3:]) == pytest.approx(0.09)


def test_malformed_packets_are_dropped_and_counted_by_reason() -> None:
    hand, link, clock = rig()
    hand.start()
    good = encode_state(link.model.state_at(clock.t + 0.001))  # newer than any sent yet
    link.extra = [good[:100], b"\x07" + good[1:], good, good]  # short, bad magic, 2x same time
    before = hand.rx.accepted
    hand.read(clock.t)
    assert hand.rx.accepted == before + 1
    c = hand.rx.counts()
    assert (c.count("bad_length"), c.count("bad_magic"), c.count("stale_time")) == (1, 1, 1)


def test_no_board_at_start_is_a_one_line_device_error() -> None:
    hand, link, _ = rig(["hand.takktile.start_timeout_s=0.2"])
    link.silent_after_s = 0.0
    with pytest.raises(DeviceNotConnected, match="no valid state packet within 0.2 s"):
        hand.start()


@pytest.mark.parametrize(("overrides", "key"), [
    (["hand.takktile.address=board.local"], "hand.takktile.address"),
    (["hand.takktile.address=127.0.0.1"], "hand.takktile.address"),  # multicast by default
    (["hand.takktile.network=unicast"], "hand.takktile.address"),  # 224.0.0.124 is a group
    (["hand.takktile.interface=eth0"], "hand.takktile.interface"),
    (["hand.takktile.network=broadcast"], "hand.takktile.network"),
    (["hand.takktile.port=0"], "hand.takktile.port"),
    (["hand.takktile.unknown=1"], "hand.takktile.unknown"),
])
def test_bad_board_settings_are_refused_naming_the_key(overrides: list[str], key: str) -> None:
    with pytest.raises(ConfigError, match=key.replace(".", r"\.")):
        build_takktile_hand(load_config(None, overrides).hand)


class MuteBoardIgnored(TakkTileHand):
    """MUTANT: the silence check removed (readings never stale)."""

    def read(self, t_s: float) -> HandReading:
        r = super().read(t_s)
        return HandReading(r.t_s, r.fingers, r.preshape_rad, r.faults)


def silent_board_trip(cls: type[TakkTileHand]) -> tuple[float | None, int, int]:
    """Board silent from 1.0 s; returns (trip time - last packet time, hand states published
    once it has been silent for 4 state periods, stale ticks)."""
    cfg = load_config(None, ["hand.backend=reflex-takktile", "safety.command_timeout_s=60"])
    model = BrainBoardModel(cfg.hand, BoardParams())
    model.start()
    clock = Clock()
    link = ModelLink(model, clock)
    hand = cls(link, cfg.hand, clock=clock, sleep=clock.sleep)  # type: ignore[arg-type]
    vclock = VirtualClock()
    hub = InProcessHub.from_config(cfg, vclock)
    svc = HandService(cfg, hub.bus("hand"), hand)
    ctrl = hub.bus("controller")
    svc.start()
    t0, tripped_at, published = clock.t, None, 0
    link.silent_after_s = t0 + 1.0
    for k in range(80):
        t = t0 + k * svc.dt_s
        clock.t = t
        vclock.set(t)
        ctrl.publish("hand_command", HandCommand(Header(k, t, 0.0), (0.3,) * 3, 0.0))
        svc.tick(t)
        got = ctrl.receive("hand_state")
        if t >= link.last_sent_s + 4 * 0.025 - 1e-9:  # silent for 4 state periods
            published += len(got)
        if tripped_at is None and t - t0 > 1.0 and svc.wd.tripped:
            tripped_at = t
    lag = None if tripped_at is None else tripped_at - link.last_sent_s
    return lag, published, svc.stale_ticks


def test_a_silent_board_trips_the_hand_watchdog_within_4_state_periods() -> None:
    lag, published, stale = silent_board_trip(TakkTileHand)
    assert lag is not None and lag <= 4 * 0.025 + 1e-9
    assert published == 0 and stale > 0  # stale state never reaches the controller


def test_the_silence_check_is_what_trips_it_mutant() -> None:
    lag, published, _ = silent_board_trip(MuteBoardIgnored)
    assert lag is None and published > 0  # without it the hand carries on, blind
