"""Lockstep runs: the three services on one in-process bus and a virtual clock.

The same service shells as the live processes (:mod:`services.master_service` etc.), ticked in
deadline order on a :class:`~teleop.transport.clock.VirtualClock` (master, then controller,
then hand at equal times), with the injected link impairments of ``cfg.links``.  Nothing
depends on wall time, so a run is a pure function of the config and the seed, and it runs
much faster than real time.  ``teleop sweep`` calls :func:`run_lockstep` once per point.

Example::

    from services.lockstep import run_lockstep
    res = run_lockstep(cfg, 6.0, seed=1)
    res.proximal_rad[:, 0]      # finger 1's proximal angle at every master tick
    res.energy_margin_j.min()   # >= 0: the energy balance held at every sample
"""

from __future__ import annotations

from array import array
from collections.abc import Callable
from dataclasses import dataclass, replace
from operator import attrgetter
from typing import Any

import numpy as np

from services.controller_service import ControllerService
from services.factory import build_hand, build_master
from services.hand_service import HandService
from services.master_service import MasterService
from services.samples import ControllerSample, HandSample, MasterSample
from services.telemetry import Telemetry
from teleop.analysis.port_audit import audit_margin_j
from teleop.config import TeleopConfig
from teleop.devices.base import HandBackend, MasterBackend
from teleop.transport.clock import VirtualClock
from teleop.transport.inproc_bus import InProcessHub
from teleop.transport.safe_decoder import RejectCounts

Array = np.ndarray


@dataclass(frozen=True)
class LockstepResult:
    """Time series of one lockstep run, one row per master tick (hand values held between
    hand ticks).  Triples are ``(n, 3)`` arrays (fingers 1-3); energies are cumulative."""

    controller: str
    seed: int
    duration_s: float
    t_s: Array
    # master port
    trigger_position_m: Array
    trigger_velocity_m_s: Array
    operator_force_n: Array  # nan for a non-virtual master
    displayed_force_n: Array  # on the trigger, after the master's passivity layer
    master_force_desired_n: Array
    # controller
    commanded_force_n: Array  # force command the controller sends to the master
    setpoint_rad: Array  # (n, 3) set-points the controller commands
    max_pressure: Array  # (n, 3) per-finger max pressure seen by the controller
    # hand port
    hand_setpoint_rad: Array  # (n, 3) applied at the hand, after its passivity layer
    proximal_rad: Array  # (n, 3)
    distal_rad: Array  # (n, 3)
    motor_angle_rad: Array  # (n, 3)
    pressure: Array  # (n, 27)
    # energy
    master_tank_j: Array
    controller_store_j: Array
    hand_tank_j: Array
    master_port_in_j: Array
    master_port_out_j: Array
    hand_port_in_j: Array
    hand_port_out_j: Array
    sent_j: Array  # total put on the links by all three sides
    received_j: Array  # total credited from the links by all three sides
    dissipated_j: Array  # total thrown away by the tanks' upper limits
    initial_j: float  # total initial tank energy
    # network
    delay_master_to_controller_s: Array  # achieved; nan where no message arrived that tick
    delay_controller_to_master_s: Array
    delay_controller_to_hand_s: Array
    delay_hand_to_controller_s: Array
    dropped_master_state: Array  # cumulative missing messages (sequence gaps)
    dropped_force_command: Array
    dropped_hand_command: Array
    dropped_hand_state: Array
    # passivity layer and watchdogs
    master_limited_count: Array  # cumulative ticks the master's layer limited the force
    hand_limited_count: Array  # cumulative ticks the hand's layer moved the set-point
    watchdog_trips: int  # all three services' watchdogs
    # physical energy audit (sim.operator / sim.audit: from the simulated physics, not from
    # controller code); cumulative; nan when a backend has no audit (real hardware, fakes)
    audit_operator_delivered_j: Array | None = None
    audit_operator_taken_j: Array | None = None
    audit_environment_delivered_j: Array | None = None
    audit_environment_taken_j: Array | None = None
    energy_scale: float = 1.0  # hand-side joules per master-side joule (power scaling)
    initial_master_j: float = 0.0
    initial_hand_j: float = 0.0
    master_watchdog_trips: int = 0  # of which the master's (no force command)

    @property
    def energy_delivered_j(self) -> Array:
        """Energy delivered at both ports so far."""
        return self.master_port_out_j + self.hand_port_out_j

    @property
    def energy_bound_j(self) -> Array:
        """Initial tank energy plus the energy taken from both ports so far."""
        return self.initial_j + self.master_port_in_j + self.hand_port_in_j

    @property
    def energy_margin_j(self) -> Array:
        """Bound minus delivered: >= 0 at every sample when the loop is passive."""
        return self.energy_bound_j - self.energy_delivered_j

    @property
    def energy_generated_j(self) -> float:
        """Largest excess of delivered over bound (0 when passive)."""
        return float(max(0.0, -float(np.min(self.energy_margin_j)))) if self.t_s.size else 0.0

    @property
    def has_audit(self) -> bool:
        """Whether both backends reported the physical audit (simulated master and hand)."""
        return (self.audit_operator_delivered_j is not None
                and self.audit_environment_delivered_j is not None
                and bool(np.all(np.isfinite(self.audit_operator_delivered_j)))
                and bool(np.all(np.isfinite(self.audit_environment_delivered_j))))

    @property
    def audit_initial_j(self) -> float:
        """Initial tank energy in hand-side joules (master tank weighted by the power scale)."""
        return self.energy_scale * self.initial_master_j + self.initial_hand_j

    @property
    def audit_margin_j(self) -> Array:
        """Physical passivity margin at every sample, in hand-side joules::

            initial tanks + taken at both ports - delivered at both ports  (>= 0: passive)

        from the simulated operator and object, weighting the operator port by the power
        scale (1 = plain joules)."""
        if not self.has_audit:
            return np.full_like(self.t_s, np.nan)
        return audit_margin_j(self.audit_initial_j, self.energy_scale,
                              self.audit_operator_taken_j, self.audit_operator_delivered_j,
                              self.audit_environment_taken_j, self.audit_environment_delivered_j)

    @property
    def audit_energy_generated_j(self) -> float:
        """Largest excess of the physical audit's delivered energy over its bound (>= 0)."""
        m = self.audit_margin_j
        if not m.size or not np.all(np.isfinite(m)):
            return float("nan")
        return float(max(0.0, -float(np.min(m))))

    @property
    def ledger_audit_gap_j(self) -> dict[str, float]:
        """Net port energy out by the controllers' ledgers minus by the physical audit, per
        port, at the end of the run (how far the books are from the physics)."""
        if not self.has_audit or not self.t_s.size:
            return {"operator": float("nan"), "environment": float("nan")}
        led_m = self.master_port_out_j[-1] - self.master_port_in_j[-1]
        led_h = self.hand_port_out_j[-1] - self.hand_port_in_j[-1]
        aud_m = self.audit_operator_delivered_j[-1] - self.audit_operator_taken_j[-1]
        aud_h = self.audit_environment_delivered_j[-1] - self.audit_environment_taken_j[-1]
        return {"operator": float(led_m - aud_m), "environment": float(led_h - aud_h)}


@dataclass
class LockstepContext:
    """The running services of a lockstep run, handed to ``hook(t_s, ctx)`` before each
    time step.  A hook may inject faults: close a service's bus view and set it to None (the
    service is dead: not ticked), put a new shell on a fresh view (a restart), or push raw
    bytes with ``hub``'s views.  Mutable on purpose; only hooks touch it."""

    cfg: TeleopConfig
    clock: VirtualClock
    hub: InProcessHub
    master: MasterService | None
    controller: ControllerService | None
    hand: HandService | None
    controller_restarts: int = 0

    def kill_controller(self) -> None:
        """The controller dies: its bus view closes (liveliness lost) and it stops ticking."""
        if self.controller is not None:
            self.controller.bus.close()
            self.controller = None

    def restart_controller(self) -> None:
        """Kill the controller (if running) and start a fresh one on a new bus view.

        The new controller counts its messages (and its energy totals) from the start
        again; the hub starts a new sender epoch when the role rejoins (as the zenoh bus does
        on the liveliness token's return): its peers reset their sequence filters, drop what
        the old controller still had in flight, and continue the energy totals monotone."""
        if self.controller is not None:
            self.controller.bus.close()
        self.controller = ControllerService(self.cfg, self.hub.bus("controller"),
                                            watchdogs=True)
        self.controller_restarts += 1


def _rejects(ctx: LockstepContext, role: str) -> RejectCounts:
    """The rejection counts of ``role``'s current bus view (zeros while it is dead)."""
    svc = getattr(ctx, role)
    return svc.bus.stats().rejects if svc is not None else RejectCounts(0, 0, ())


def _seeded(cfg: TeleopConfig, seed: int | None) -> TeleopConfig:
    if seed is None:
        return cfg
    links = replace(cfg.links,
                    master_controller=replace(cfg.links.master_controller, seed=seed),
                    controller_hand=replace(cfg.links.controller_hand, seed=seed))
    return replace(cfg, session=replace(cfg.session, seed=seed), links=links)


_MASTER_COLS = ("t_s", "trigger_position_m", "trigger_velocity_m_s", "operator_force_n",
                "displayed_force_n", "force_desired_n", "tank_j", "port_in_j", "port_out_j",
                "sent_j", "received_j", "dissipated_j", "delay_s", "dropped", "limit_count")


_master_row = attrgetter(*_MASTER_COLS)


_N_C, _N_H = 16, 3 * 5 + 27 + 10  # controller and hand columns
_NAN_C, _NAN_H = (np.nan,) * _N_C, (np.nan,) * _N_H


class _Recorder:
    """Collects rows (one per master tick) of the latest sample of each service.

    Rows go into growing C arrays of doubles (``array('d')``; ``extend`` converts each value
    as ``float()`` does, the same float64 as writing it into a preallocated numpy array) and
    become float64 arrays once, at the end (:meth:`arrays`, a copy of the buffer).  The
    controller's and hand's rows are built once per (sample, fresh) and kept once: a master
    tick records only their index (the hand ticks at 40 Hz, the master at 1 kHz), and
    :meth:`arrays` repeats the distinct rows by index (the same float64 values as stacking
    every tick's row)."""

    def __init__(self) -> None:
        self.n = 0
        self._m = array("d")
        self._audit = array("d")
        self._c_rows = array("d", _NAN_C)  # distinct rows; 0: no sample yet
        self._h_rows = array("d", _NAN_H)
        self._c = array("q")  # per master tick: index into ``_c_rows``
        self._h = array("q")
        self._c_key: tuple[object, bool] | None = None
        self._h_key: tuple[object, bool] | None = None
        self._c_at = 0
        self._h_at = 0

    def row(self, m: MasterSample, c: ControllerSample | None, h: HandSample | None,
            c_fresh: bool, h_fresh: bool, audit: tuple[float, float, float, float]) -> None:
        self._audit.extend(audit)
        self._m.extend(_master_row(m))
        if c is None:
            self._c.append(0)
        else:
            key = self._c_key
            if key is None or key[0] is not c or key[1] != c_fresh:
                self._c_key = (c, c_fresh)
                self._c_at = len(self._c_rows) // _N_C
                self._c_rows.extend((
                    *c.setpoint_rad, c.commanded_force_n, *c.max_pressure, c.store_j,
                    c.sent_j, c.received_j, c.dissipated_j,
                    c.master_delay_s if c_fresh else np.nan,
                    c.hand_delay_s if c_fresh else np.nan, c.master_dropped,
                    c.hand_dropped, 0.0))
            self._c.append(self._c_at)
        if h is None:
            self._h.append(0)
        else:
            key = self._h_key
            if key is None or key[0] is not h or key[1] != h_fresh:
                self._h_key = (h, h_fresh)
                self._h_at = len(self._h_rows) // _N_H
                self._h_rows.extend((
                    *h.setpoint_rad, *h.proximal_angle_rad, *h.distal_angle_rad,
                    *h.motor_angle_rad, *h.setpoint_desired_rad, *h.pressure, h.tank_j,
                    h.port_in_j, h.port_out_j, h.sent_j, h.received_j, h.dissipated_j,
                    h.delay_s if h_fresh else np.nan, h.dropped, h.limit_count, 0.0))
            self._h.append(self._h_at)
        self.n += 1

    def arrays(self) -> tuple[Array, Array, Array, Array]:
        """(master, controller, hand, audit) rows as float64 arrays, one row per master tick."""
        def stack(rows: array[float], width: int) -> Array:
            return np.frombuffer(rows, dtype=np.float64).reshape(-1, width).copy()

        def repeat(rows: array[float], width: int, index: array[int]) -> Array:
            return stack(rows, width)[np.frombuffer(index, dtype=np.int64)]

        return (stack(self._m, len(_MASTER_COLS)), repeat(self._c_rows, _N_C, self._c),
                repeat(self._h_rows, _N_H, self._h), stack(self._audit, 4))


def run_lockstep(cfg: TeleopConfig, duration_s: float, *, seed: int | None = None,
                 master: MasterBackend | None = None, hand: HandBackend | None = None,
                 watchdogs: bool = True,
                 progress: Callable[[float], None] | None = None,
                 rec: Any | None = None,
                 hook: Callable[[float, LockstepContext], None] | None = None,
                 stop: Callable[[], bool] | None = None
                 ) -> LockstepResult:
    """Run master, controller and hand in lockstep for ``duration_s`` of virtual time.

    ``seed`` (if given) replaces the session and link seeds; ``master``/``hand`` replace the
    backends the config names (fakes in tests); ``watchdogs`` turns the service watchdogs
    off when False; ``progress(fraction)`` is called about 100 times; ``rec`` (a
    ``rerun.RecordingStream``) gets the run logged like the live dashboard, in virtual time;
    ``hook(t_s, ctx)`` is called before each time step with a :class:`LockstepContext`
    (fault injection: kill or restart a service); ``stop()`` (asked after every master row)
    ends the run early when it returns True: the result then covers the time reached
    (``duration_s`` says how much), every row whole (a command's Ctrl-C, say).
    """
    cfg = _seeded(cfg, seed)
    clock = VirtualClock(0.0)
    hub = InProcessHub.from_config(cfg, clock)
    m_dev = master or build_master(cfg)
    h_dev = hand or build_hand(cfg)
    m_audit = getattr(m_dev, "port_audit_j", None)
    h_audit = getattr(h_dev, "port_audit_j", None)

    def audit() -> tuple[float, float, float, float]:
        mo, mi = m_audit() if m_audit is not None else (np.nan, np.nan)
        ho, hi = h_audit() if h_audit is not None else (np.nan, np.nan)
        return (mo, mi, ho, hi)

    m_svc = MasterService(cfg, hub.bus("master"), m_dev, watchdogs=watchdogs)
    c_svc = ControllerService(cfg, hub.bus("controller"), watchdogs=watchdogs)
    h_svc = HandService(cfg, hub.bus("hand"), h_dev, watchdogs=watchdogs)
    ctx = LockstepContext(cfg, clock, hub, m_svc, c_svc, h_svc)
    services: list[Any] = [m_svc, c_svc, h_svc]
    periods = [1.0 / s.rate_hz for s in services]
    ticks = [0, 0, 0]
    due_t = [0.0, 0.0, 0.0]  # each service's next tick time, ``ticks[i] * periods[i]``
    n_master = int(np.floor(duration_s * m_svc.rate_hz + 1e-9)) + 1
    rows = _Recorder()
    last_c: ControllerSample | None = None
    last_h: HandSample | None = None
    for s in services:
        s.start()
    tels = None
    if rec is not None:
        sources = {"master": m_audit, "hand": h_audit}  # the physics beside the books
        tels = [Telemetry(s.role, rec, None, 0.0, cfg.dashboard.rate_hz, (),
                          sources.get(s.role), cfg.dashboard.picture_rate_hz)
                for s in services]
        for tel in tels:  # the live view of the role (a restarted service has a new one)
            tel.rejects_source = lambda r=tel.role: _rejects(ctx, r)
    report_every = max(1, n_master // 100)
    try:
        while True:
            t = min(due_t)
            if t > duration_s + 1e-12 or rows.n >= n_master:
                break
            if t > clock.now_s():
                clock.set(t)
            if hook is not None:
                hook(t, ctx)
                services = [ctx.master, ctx.controller, ctx.hand]
            m_sample: MasterSample | None = None
            c_fresh = h_fresh = False
            for i, s in enumerate(services):
                t_i = due_t[i]
                if t_i < t or abs(t_i - t) < 1e-12:
                    k = ticks[i] = ticks[i] + 1
                    due_t[i] = k * periods[i]
                    if s is None:  # a dead service (fault injection)
                        if i == 0:
                            m_sample = None
                        continue
                    sample = s.tick(t_i)
                    if tels is not None:
                        tels[i].emit(sample, s.events, h_svc.last_reading if i == 2 else None)
                    if i == 0:
                        m_sample = sample  # type: ignore[assignment]
                    elif i == 1:
                        last_c, c_fresh = sample, True  # type: ignore[assignment]
                    else:
                        last_h, h_fresh = sample, True  # type: ignore[assignment]
            if m_sample is not None:
                rows.row(m_sample, last_c, last_h, c_fresh, h_fresh, audit())
                if progress is not None and rows.n % report_every == 0:
                    progress(rows.n / n_master)
                if stop is not None and stop():
                    duration_s = t
                    break
    finally:
        for s in services:
            if s is not None:
                s.close()
    return _result(cfg, duration_s, rows, m_svc, ctx.controller or c_svc, h_svc)


def _result(cfg: TeleopConfig, duration_s: float, rows: _Recorder, m_svc: MasterService,
            c_svc: ControllerService, h_svc: HandService) -> LockstepResult:
    M, C, H, audit = rows.arrays()  # noqa: N806
    mc = {k: M[:, j] for j, k in enumerate(_MASTER_COLS)}
    hp = 15
    initial = sum(s.ledger.initial_j for s in (m_svc, c_svc, h_svc) if s.ledger is not None)

    def fill(a: Array) -> Array:
        """Before the first sample of a service: zeros for cumulative counters."""
        return np.nan_to_num(a, nan=0.0)

    return LockstepResult(
        controller=cfg.controller.kind, seed=cfg.session.seed, duration_s=duration_s,
        t_s=mc["t_s"], trigger_position_m=mc["trigger_position_m"],
        trigger_velocity_m_s=mc["trigger_velocity_m_s"],
        operator_force_n=mc["operator_force_n"], displayed_force_n=mc["displayed_force_n"],
        master_force_desired_n=mc["force_desired_n"],
        commanded_force_n=C[:, 3], setpoint_rad=C[:, 0:3], max_pressure=C[:, 4:7],
        hand_setpoint_rad=H[:, 0:3], proximal_rad=H[:, 3:6], distal_rad=H[:, 6:9],
        motor_angle_rad=H[:, 9:12], pressure=H[:, hp:hp + 27],
        master_tank_j=mc["tank_j"], controller_store_j=fill(C[:, 7]),
        hand_tank_j=H[:, hp + 27],
        master_port_in_j=mc["port_in_j"], master_port_out_j=mc["port_out_j"],
        hand_port_in_j=fill(H[:, hp + 28]), hand_port_out_j=fill(H[:, hp + 29]),
        sent_j=mc["sent_j"] + fill(C[:, 8]) + fill(H[:, hp + 30]),
        received_j=mc["received_j"] + fill(C[:, 9]) + fill(H[:, hp + 31]),
        dissipated_j=mc["dissipated_j"] + fill(C[:, 10]) + fill(H[:, hp + 32]),
        initial_j=initial,
        delay_master_to_controller_s=C[:, 11], delay_controller_to_master_s=mc["delay_s"],
        delay_controller_to_hand_s=H[:, hp + 33], delay_hand_to_controller_s=C[:, 12],
        dropped_master_state=fill(C[:, 13]), dropped_force_command=mc["dropped"],
        dropped_hand_command=fill(H[:, hp + 34]), dropped_hand_state=fill(C[:, 14]),
        master_limited_count=mc["limit_count"], hand_limited_count=fill(H[:, hp + 35]),
        watchdog_trips=m_svc.wd.trips + c_svc.wd.trips + h_svc.wd.trips,
        master_watchdog_trips=m_svc.wd.trips,
        audit_operator_delivered_j=audit[:, 0], audit_operator_taken_j=audit[:, 1],
        audit_environment_delivered_j=audit[:, 2], audit_environment_taken_j=audit[:, 3],
        energy_scale=cfg.controller.tank.energy_scale,
        initial_master_j=m_svc.ledger.initial_j if m_svc.ledger is not None else 0.0,
        initial_hand_j=((h_svc.ledger.initial_j if h_svc.ledger is not None else 0.0)
                        + (c_svc.ledger.initial_j if c_svc.ledger is not None else 0.0)),
    )


__all__ = ["LockstepContext", "LockstepResult", "run_lockstep"]
