"""Service shells one at a time on the in-process bus: watchdogs, safe states, resume."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
from _svc_fakes import FakeHand

from services.hand_service import HandService
from services.master_service import MasterService
from services.samples import sample_columns, sample_row
from services.suites import get_suite
from teleop.config import load_config
from teleop.devices.base import MasterReading
from teleop.messages import ForceCommand, HandCommand, Header
from teleop.transport.clock import VirtualClock
from teleop.transport.inproc_bus import InProcessHub


class StillTrigger:
    """A master device held still at ``x_m``; records the forces displayed."""

    def __init__(self, x_m: float = 0.01) -> None:
        self.x_m = x_m
        self.forces: list[float] = []

    def start(self) -> None: ...

    def read(self, t_s: float) -> MasterReading:
        return MasterReading(t_s=t_s, grip_position_m=self.x_m, grip_velocity_m_s=0.0)

    def apply_force(self, force_n: float) -> None:
        self.forces.append(force_n)

    def close(self) -> None: ...


def hand_command(seq: int, t: float, sp: float, total_j: float) -> HandCommand:
    return HandCommand(header=Header(seq=seq, t_s=t, energy_total_j=total_j),
                       finger_setpoint_rad=(sp, sp, sp), preshape_rad=0.0)


def test_hand_holds_without_commands_then_resumes_without_a_jump() -> None:
    cfg = load_config(None, [])
    clock = VirtualClock()
    hub = InProcessHub.from_config(cfg, clock)
    hand = FakeHand(contact_rad=3.0)
    svc = HandService(cfg, hub.bus("hand"), hand)
    dt = svc.dt_s
    for k in range(10):  # no controller at all: the hand holds where it is
        clock.set(k * dt)
        s = svc.tick(k * dt)
        assert s.watchdog == 1.0
    assert all(c.finger_setpoint_rad == (0.0, 0.0, 0.0) for c in hand.applied)
    ctrl = hub.bus("controller")
    sps, events = [], []
    for k in range(10, 40):  # the controller appears and asks for 1 rad
        for j in range(25):
            ctrl.publish("hand_command", hand_command(k * 25 + j, k * dt, 1.0, 0.05 * k))
        clock.set(k * dt)
        s = svc.tick(k * dt)
        sps.append(s.setpoint_rad[0])
        events += svc.events
    steps = np.diff([0.0, *sps])
    assert sps[-1] > 0.9  # it gets there ...
    assert steps.max() <= 1.0 * dt / cfg.safety.force_ramp_s + 1e-9  # ... along the ramp
    assert any("blending in" in e for e in events)
    held = hand.angle[0]
    ctrl.close()  # the controller's liveliness goes: hold at once
    for k in range(40, 45):
        clock.set(k * dt)
        s = svc.tick(k * dt)
        assert s.watchdog == 1.0
    assert abs(hand.applied[-1].finger_setpoint_rad[0] - held) < 0.1
    svc.close()
    assert hand.safe_calls == ["hold"] and hand.closed


def test_master_force_ramps_in_and_out_with_the_force_commands() -> None:
    cfg = load_config(None, [])
    clock = VirtualClock()
    hub = InProcessHub.from_config(cfg, clock)
    dev = StillTrigger()
    svc = MasterService(cfg, hub.bus("master"), dev)
    ctrl = hub.bus("controller")
    dt = svc.dt_s
    desired = []
    for k in range(700):
        if k < 400:
            ctrl.publish("force_command", ForceCommand(
                header=Header(seq=k + 1, t_s=k * dt, energy_total_j=0.0), force_n=2.0))
        clock.set(k * dt)
        desired.append(svc.tick(k * dt).force_desired_n)
    d = np.array(desired)
    ramp = 2.0 * dt / cfg.safety.force_ramp_s
    assert np.abs(np.diff(d)).max() <= ramp + 1e-9  # never a jump, in or out
    assert d[300] == 2.0  # fully in while commands flow
    assert d[-1] == 0.0  # ramped out after the commands stopped
    assert svc.wd.trips == 1


class MovingTrigger(StillTrigger):
    """A trigger closing at a steady ``speed_m_s``."""

    def __init__(self, speed_m_s: float = 0.05) -> None:
        super().__init__()
        self.speed_m_s = speed_m_s

    def read(self, t_s: float) -> MasterReading:
        return MasterReading(t_s=t_s, grip_position_m=self.speed_m_s * t_s,
                             grip_velocity_m_s=self.speed_m_s)


def test_after_a_stall_the_master_layer_measures_the_true_speed() -> None:
    """When the loop drops deadlines in a stall, the step gets the time that passed: the
    layer's velocity (position step over it) stays the trigger's, not 30x it (a damping jolt
    in the operator's hand; the CI run of 39f0811 saw one on the TakkTile test)."""
    cfg = load_config(None, [])
    hub = InProcessHub.from_config(cfg, VirtualClock())
    dts: list[float] = []
    base = get_suite(cfg.controller.kind)

    def step_master(s, p, q, cmd, dt_s):  # type: ignore[no-untyped-def]
        dts.append(dt_s)
        return base.step_master(s, p, q, cmd, dt_s)

    svc = MasterService(cfg, hub.bus("master"), MovingTrigger(),
                        suite=replace(base, step_master=step_master))
    dt = svc.dt_s
    ticks = [k * dt for k in range(5)] + [(34 + k) * dt for k in range(5)]  # 29 dropped
    v = [svc.tick(t).trigger_velocity_m_s for t in ticks]
    assert dts[:5] == [dt] * 5 and dts[6:] == [dt] * 4  # bit-identical when on time
    assert dts[5] == 30 * dt
    speed = np.diff([0.05 * t for t in ticks]) / np.array(dts[1:])
    assert np.allclose(speed, v[1:], rtol=1e-6)


def test_sample_columns_match_rows() -> None:
    cfg = load_config(None, [])
    hub = InProcessHub.from_config(cfg, VirtualClock())
    svc = HandService(cfg, hub.bus("hand"), FakeHand())
    s = svc.tick(0.0)
    cols = sample_columns(s)
    assert cols[0] == "t_s" and len(cols) == len(sample_row(s))
    assert "pressure_f3_8" in cols and "proximal_angle_rad_f2" in cols


def test_status_line_reports_setpoints_force_and_latest_delays() -> None:
    import math

    from services.samples import ControllerSample, status_line

    vals: dict[str, object] = {n: 0.0 for n in ControllerSample.__dataclass_fields__}
    vals.update(setpoint_rad=(1.0, 0.5, 0.25), preshape_rad=0.0, commanded_force_n=-2.5,
                max_pressure=(10.0, 660.0, 3.0), store_j=0.75, master_delay_s=math.nan,
                hand_delay_s=math.nan, watchdog=1.0)
    line = status_line(ControllerSample(**vals), 3.0, 0.012, math.nan)  # type: ignore[arg-type]
    assert "set-points 1.00/0.50/0.25 rad" in line and "force -2.50 N" in line
    assert "max pressure 660" in line and "store 0.75 J" in line
    assert "delay master 12 ms hand -" in line and line.endswith("WATCHDOG")
    assert "\n" not in line


class FaultedHand(FakeHand):
    """A hand whose servo error bits have sent it safe ``trips`` times (held now: ``safe``)."""

    trips, safe = 0, False

    def read(self, t_s: float):  # noqa: ANN201 - HandReading
        from dataclasses import replace

        return replace(super().read(t_s), servo_fault_trips=self.trips, servo_safe=self.safe)


def test_the_servo_fault_count_reaches_the_controller_in_the_hand_state() -> None:
    from services.controller_service import ControllerService

    cfg = load_config(None, [])
    clock = VirtualClock()
    hub = InProcessHub.from_config(cfg, clock)
    hand = FaultedHand()
    h_svc = HandService(cfg, hub.bus("hand"), hand)
    c_svc = ControllerService(cfg, hub.bus("controller"))
    events: list[str] = []
    seen: list[tuple[float, float]] = []
    for k in range(12):
        if k == 6:
            hand.trips, hand.safe = 2, True
        t = k * h_svc.dt_s
        clock.set(t)
        hs = h_svc.tick(t)
        clock.set(t + 1e-3)
        cs = c_svc.tick(t + 1e-3)
        events += c_svc.events
        seen.append((hs.servo_fault_trips, cs.hand_servo_fault_trips))
    assert seen[0] == (0.0, 0.0) and seen[-1] == (2.0, 2.0)
    assert (h_svc.bus.alive("controller"), hs.servo_safe) == (True, 1.0)
    assert sum("servo error bits" in e and "episode 2" in e for e in events) == 1


def test_the_hand_records_when_it_really_read_and_wrote(tmp_path) -> None:  # noqa: ANN001
    """``t_s`` is the tick's deadline; ``read_t_s`` / ``write_t_s`` are the midpoints of the
    backend's read and apply calls on the loop clock, on the recording's time base.  A backend
    whose read takes 4 ms and apply 2 ms, ticked 30 ms late: read at deadline + 32 ms, write
    after the read.  Mutants watched failing: the midpoints taken from ``t_s``; the recorder
    leaving the two columns on the clock's epoch."""
    from services.telemetry import Telemetry
    from teleop.recording import read_recording

    cfg = load_config(None, [])
    clock = VirtualClock()
    hub = InProcessHub.from_config(cfg, clock)

    class SlowHand(FakeHand):
        def read(self, t_s: float):  # noqa: ANN202
            clock.set(clock.now_s() + 0.004)
            return super().read(t_s)

        def apply(self, command: HandCommand) -> None:
            clock.set(clock.now_s() + 0.002)
            super().apply(command)

    svc = HandService(cfg, hub.bus("hand"), SlowHand(), clock=clock.now_s)
    tel = Telemetry("hand", None, tmp_path / "hand.csv", 100.0, 1.0)
    for k in range(5):
        deadline = 100.0 + k * svc.dt_s
        clock.set(deadline + 0.030)  # the loop runs late
        s = svc.tick(deadline)
        assert abs(s.read_t_s - (deadline + 0.032)) < 1e-9
        assert abs(s.write_t_s - (deadline + 0.035)) < 1e-9
        tel.emit(s, [])
    tel.close()
    rec = read_recording(tmp_path / "hand.csv")
    assert np.allclose(rec.column("read_t_s") - rec.t_s, 0.032, atol=1e-7)
    assert np.allclose(rec.column("write_t_s") - rec.column("read_t_s"), 0.003, atol=1e-7)
    assert abs(rec.t_s[0]) < 1e-12  # on the session epoch
    hub2 = InProcessHub.from_config(cfg, VirtualClock())
    plain = HandService(cfg, hub2.bus("hand"), FakeHand())  # no clock (lockstep): t_s
    s = plain.tick(0.5)
    assert s.read_t_s == s.write_t_s == 0.5


def test_a_simulated_port_records_the_physical_work_beside_every_sample(tmp_path) -> None:  # noqa: ANN001
    """With an audit source (a simulated hand's ``port_audit_j``) the recording carries its
    cumulative ``audit_delivered_j`` / ``audit_taken_j``, read at each sample; without one
    (a real hand) no such columns."""
    from services.telemetry import Telemetry
    from teleop.recording import read_recording

    cfg = load_config(None, [])
    hub = InProcessHub.from_config(cfg, VirtualClock())
    svc = HandService(cfg, hub.bus("hand"), FakeHand())
    work = [0.0]

    def audit() -> tuple[float, float]:
        work[0] += 0.25
        return work[0], work[0] / 5.0

    tel = Telemetry("hand", None, tmp_path / "hand.csv", 0.0, 1.0, audit_source=audit)
    plain = Telemetry("hand", None, tmp_path / "plain.csv", 0.0, 1.0)
    for k in range(4):
        s = svc.tick(k * svc.dt_s)
        tel.emit(s, [])
        plain.emit(s, [])
    tel.close()
    plain.close()
    rec = read_recording(tmp_path / "hand.csv")
    assert rec.column("audit_delivered_j").tolist() == [0.25, 0.5, 0.75, 1.0]
    assert np.allclose(rec.column("audit_taken_j"), [0.05, 0.1, 0.15, 0.2])
    assert not read_recording(tmp_path / "plain.csv").has("audit_delivered_j")
