"""One live service process: zenoh bus, backend, real-time loop, recording, dashboard.

``teleop run ROLE`` calls :func:`run_service`.  Order: start the backend -> open the bus ->
build the service shell -> print ``ready <role>`` -> real-time priority when allowed ->
declare the liveliness token -> wait for the peers' liveliness (the master and the hand also
for the controller's first command, so the operator's grasp script starts only when the whole
chain runs) ->
garbage collector frozen -> tick at the role's rate until SIGINT/SIGTERM, end of stdin (when
launched by ``teleop up``) or ``duration_s`` -> close everything (backend safe/off, zenoh
session, files).
"""

from __future__ import annotations

import gc
import importlib
import json
import math
import signal
import sys
import threading
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from services.heap import HeapTrimmer, limit_arenas
from services.runtime import LoopStats, RateLoop, try_realtime_priority
from services.samples import status_line
from services.telemetry import Telemetry, is_alarm
from teleop.config import TeleopConfig

#: spin before each deadline under SCHED_FIFO (3e-4 otherwise): a real-time thread's sleep
#: overshoots by 10-43 us here, so the spin is rarely reached; at 1e-4 it cost each 1 kHz loop
#: ~10 % of a core, which a 2-core machine's 40 Hz hand (lower priority) went without (with
#: the dashboard saved, the hard operator on the block: its reads p99 0.34 s late at 1e-4,
#: 8-18 ms at 3e-5).  The price: the 1 kHz loops' p99 lateness 0.1 -> 0.25-0.65 ms (a loop
#: that is not spinning when its deadline comes may wait for the other's tick)
REALTIME_SPIN_S = 3e-5
REALTIME_FAST_HZ = 100.0  # loops this fast get the higher SCHED_FIFO priority (20, else 10)

PEERS: dict[str, tuple[str, ...]] = {
    "master": ("controller",),
    "controller": ("master", "hand"),
    "hand": ("controller",),
}


@dataclass(frozen=True, slots=True)
class ServiceOptions:
    """How ``teleop run`` was asked to run one service."""

    role: str
    duration_s: float | None = None
    dashboard: str = "off"  # off | save:PATH | connect:URL | spawn | web
    record_dir: str | None = None
    recording_id: str | None = None
    epoch_s: float | None = None
    watch_stdin: bool = False  # stop at end of stdin (the parent `teleop up` went away)
    stats_path: str | None = None  # write the loop's timing figures as JSON here
    peer_timeout_s: float | None = 30.0  # None: wait for peers forever
    realtime: bool = True  # try SCHED_FIFO (the 1 kHz loops above the hand's)
    soak_dir: str | None = None  # write tick timing and status lines here (services.soak_log)


def build_backend(role: str, cfg: TeleopConfig) -> Any:
    """The configured device backend of ``role`` (None for the controller)."""
    from services.factory import build_hand, build_master

    if role == "master":
        return build_master(cfg)
    if role == "hand":
        return build_hand(cfg)
    return None


def build_service(role: str, cfg: TeleopConfig, bus: Any, backend: Any,
                  clock: Any = None) -> Any:
    """The service shell for ``role`` on ``bus`` around ``backend`` (the hand records when
    it read and wrote the hand on ``clock``'s ``now_s``)."""
    if role == "master":
        from services.master_service import MasterService

        return MasterService(cfg, bus, backend)
    if role == "controller":
        from services.controller_service import ControllerService

        return ControllerService(cfg, bus)
    from services.hand_service import HandService

    return HandService(cfg, bus, backend, clock=None if clock is None else clock.now_s)


def _role_meta(role: str, cfg: TeleopConfig) -> tuple[tuple[str, str], ...]:
    """What a recording must say for the tools that read it: the master's grasp threshold and
    power scale (``teleop grasps DIR``); the hand's driver, for ``teleop diagnose --model
    finger`` to rebuild the motor commands: the backend and, for the dynamixel driver, its
    moving speed and overload back-off (the targets it writes differ from the set-points
    while overloaded)."""
    if role == "master":  # where a grasp starts, for ``teleop grasps DIR``
        from teleop.analysis.grasps import grasp_threshold_m

        return (("grasp_threshold_m", f"{grasp_threshold_m(cfg):.6g}"),
                # master-side joules to hand-side ones, for the physical audit of the run
                ("energy_scale", f"{cfg.controller.tank.energy_scale:.17g}"))
    if role != "hand":
        return ()
    out: tuple[tuple[str, str], ...] = (("hand_backend", cfg.hand.backend),)
    if cfg.hand.backend == "dynamixel":
        d = cfg.hand.dynamixel
        out += (("speed_rad_s", f"{d.speed_rad_s:g}"),
                ("overload_finger_units", f"{d.overload_finger_units:g}"),
                ("load_filter", f"{d.load_filter:g}"))
    return out


def _dashboard_stream(opts: ServiceOptions) -> Any:
    if opts.dashboard == "off":
        return None
    import uuid

    from teleop.viz.dashboard import open_stream

    rid = opts.recording_id or str(uuid.uuid4())
    mode, _, arg = opts.dashboard.partition(":")
    if mode == "save":
        return open_stream(rid, "save", path=arg, send_blueprint=False)
    if mode == "connect":
        return open_stream(rid, "connect", url=arg or None, send_blueprint=False)
    return open_stream(rid, mode)


#: what the master and the hand wait for before ticking: the controller's loop is running
#: (it starts only once master and hand are alive), so the whole chain is up
FIRST_SIGNAL: dict[str, str] = {"master": "force_command", "hand": "hand_command"}


def _wait_for_peers(bus: Any, role: str, loop: RateLoop, timeout_s: float | None) -> bool:
    deadline = None if timeout_s is None else time.monotonic() + timeout_s
    told = False
    first = FIRST_SIGNAL.get(role)
    while not loop.stop_event.is_set():
        missing = [p for p in PEERS[role] if not bus.alive(p)]
        if not missing and first is not None and bus.receive(first):
            first = None  # the controller is ticking
        if not missing and first is None:
            return True
        if not missing:
            missing = ["controller's first command"]
        if deadline is not None and time.monotonic() > deadline:
            print(f"{role}: peers not alive after {timeout_s:g} s: {', '.join(missing)}",
                  file=sys.stderr, flush=True)
            return False
        if not told and deadline is None:
            print(f"{role}: waiting for {', '.join(missing)}", flush=True)
            told = True
        time.sleep(0.01)
    return False


def _discard(_deadline_s: float, _late_s: float, _stall_s: float) -> None:
    """Tick timing nobody reads."""


def _timing_sink(soak: Any, opts: ServiceOptions) -> Any:
    """Where the loop's per-tick timing goes: the soak log; the returned stats (kept in
    memory, 64 kB/s at 1 kHz) only when ``--stats-json`` reads them; otherwise nowhere, so
    a service runs for hours at flat memory (it grew 6 MB a minute before)."""
    if soak is not None:
        return soak.timing
    return None if opts.stats_path else _discard


def _soak_log(opts: ServiceOptions, role: str, rate_hz: float, now_s: float) -> Any:
    if opts.soak_dir is None:
        return None
    import os

    from services.soak_log import SoakLog

    epoch = opts.epoch_s if opts.epoch_s is not None else now_s
    return SoakLog(Path(opts.soak_dir), role, os.getpid(), epoch, rate_hz)


def run_service(cfg: TeleopConfig, opts: ServiceOptions) -> int:
    """Run one service until stopped; exit status."""
    from teleop.transport.clock import MonotonicClock
    from teleop.transport.roster import checking_role_free
    from teleop.transport.zenoh_bus import ZenohBus

    role = opts.role
    limit_arenas(cfg.session.malloc_arenas)  # before the bus's threads exist
    clock = MonotonicClock()
    rate = {"master": cfg.master.rate_hz, "controller": cfg.controller.rate_hz,
            "hand": cfg.hand.state_rate_hz}[role]
    loop = RateLoop(rate, clock=clock)
    previous = {s: signal.signal(s, lambda *_: loop.stop())
                for s in (signal.SIGINT, signal.SIGTERM)}
    if opts.watch_stdin:
        def watch() -> None:
            sys.stdin.read()
            loop.stop()

        threading.Thread(target=watch, daemon=True).start()
    telemetry: Telemetry | None = None
    trimmer = HeapTrimmer(cfg.session.heap_trim_mb)
    bus: Any = None
    backend: Any = None
    svc: Any = None
    stats: LoopStats | None = None
    try:
        # a second service of a role already running in the session is refused before its
        # device starts (a stray would starve the running services; docs/faults.md): asked
        # while the backend is built (in teleop up the controller is not listening yet)
        role_free = checking_role_free(cfg, role)
        # everything slow first (device start, imports, dashboard), the bus last, and its
        # liveliness token (peers take it as "ready to tick") only just before the wait
        try:
            made = build_backend(role, cfg)
        finally:
            role_free()
        if made is not None:
            made.start()
        backend = made  # released at the end only once started
        importlib.import_module(f"services.{role}_service")  # the shell's imports, now
        record = Path(opts.record_dir) / f"{role}.csv" if opts.record_dir else None
        meta = (("role", role), ("controller", cfg.controller.kind),
                ("session", cfg.session.name), ("rate_hz", f"{rate:g}"), *_role_meta(role, cfg))
        audit_source = getattr(backend, "port_audit_j", None)
        telemetry = Telemetry(role, _dashboard_stream(opts), record, opts.epoch_s,
                              cfg.dashboard.rate_hz, meta, audit_source,
                              cfg.dashboard.picture_rate_hz)
        bus = ZenohBus.from_config(role, cfg, clock=clock, announce=False)
        telemetry.rejects_source = lambda: bus.stats().rejects
        svc = build_service(role, cfg, bus, backend, clock)
        print(f"ready {role}", flush=True)
        # real-time priority already for the wait: on a busy machine a normal-priority
        # process can take half a second to notice its peers
        rt_wanted = opts.realtime
        if rt_wanted and try_realtime_priority(20 if rate >= REALTIME_FAST_HZ else 10):
            # real-time threads wake within tens of microseconds (no timer slack): spin less,
            # which also keeps the RT tasks well under the kernel's RT throttling budget
            loop.spin_s = REALTIME_SPIN_S
        elif rt_wanted:
            print(f"{role}: no real-time priority (needs CAP_SYS_NICE); loop timing may "
                  "suffer on a busy machine", file=sys.stderr, flush=True)
        # only now the token: the controller starts ticking as soon as master and hand show
        # theirs, so a hand still building its service (or not yet real-time while two 1 kHz
        # loops take both cores) would start a second late (measured 1.2-1.4 s here)
        bus.announce()
        if not _wait_for_peers(bus, role, loop, opts.peer_timeout_s):
            return 0 if loop.stop_event.is_set() else 1
        tel = telemetry
        is_hand = role == "hand"
        soak = _soak_log(opts, role, rate, clock.now_s())

        last: list[Any] = [None]  # the latest sample, for the status line

        delays = [math.nan, math.nan]  # latest achieved master / hand delay (controller)

        def tick(t_s: float) -> None:
            last[0] = svc.tick(t_s)
            tel.emit(last[0], svc.events, svc.last_reading if is_hand else None)
            for ev in svc.events:  # alarms reach the terminal too, not only the dashboard
                if is_alarm(ev):
                    print(ev, flush=True)
            if soak is not None and soak.due():
                led = getattr(svc, "ledger", None)
                smp = last[0]
                extra = ({"trigger_m": smp.trigger_position_m} if role == "master" else
                         {"contacts": float(sum(smp.contacts))} if is_hand else {})
                extra["heap_trims"] = float(trimmer.trims)
                extra["heap_trim_max_ms"] = trimmer.longest_s * 1e3
                soak.status(t_s, smp.watchdog, bus.stats().rejects.rejected,
                            led.initial_j if led is not None else 0.0,
                            audit_source() if audit_source is not None else None, **extra)
            if role == "controller":
                for k, d in enumerate((last[0].master_delay_s, last[0].hand_delay_s)):
                    if math.isfinite(d):
                        delays[k] = d

        # garbage collection: start-up objects frozen out of the collector's way, automatic
        # collection off, a young-generation collection once a second inside the loop
        # instead (a full collection can pause a process for tens of milliseconds)
        gc.collect()
        gc.freeze()
        gc.disable()
        every = max(1, int(rate))
        count = [0]

        t_start: list[float | None] = [None]

        def tick_gc(t_s: float) -> None:
            tick(t_s)
            count[0] += 1
            if count[0] % every == 0:
                gc.collect(1)
                trimmer.poll()  # in this thread: a background trim would block it (heap.py)
                if role == "controller":  # once a second: what the loop is doing
                    if t_start[0] is None:
                        t_start[0] = t_s - 1.0
                    print(status_line(last[0], t_s - t_start[0], delays[0], delays[1]), flush=True)

        try:
            stats = loop.run(tick_gc, duration_s=opts.duration_s,
                             timing=_timing_sink(soak, opts))
        finally:
            gc.enable()
            if soak is not None:
                soak.close()
        return 0
    finally:
        try:
            if svc is not None:
                svc.close()  # safe state / force off, then the backend is released
            elif backend is not None:
                backend.close()
        finally:
            rejects: dict[str, float] = {}
            if bus is not None:  # messages the bus rejected, per reason (teleop faults)
                rejects = {f"rejects_{k}": float(n) for k, n in bus.stats().rejects.by_reason}
                bus.close()
            if telemetry is not None:
                telemetry.close()
            if stats is not None and opts.stats_path:
                heap = {f"{role}_heap_trims": float(trimmer.trims),
                        f"{role}_heap_trim_max_us": trimmer.longest_s * 1e6}
                Path(opts.stats_path).write_text(
                    json.dumps(stats.figures(role) | rejects | heap) + "\n")
            for s, h in previous.items():
                signal.signal(s, h)
