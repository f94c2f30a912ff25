"""``teleop bench transport``: latency, delay accuracy and throughput over zenoh loopback.

Every phase runs a second process (:mod:`teleop.transport.peer`, spawned, not forked) on
``tcp/127.0.0.1`` with a free port; this process listens, the peer connects.

* ``raw_rtt_*``: bare zenoh ping-pong (8+8 byte payload, echoed from the peer's callback),
  1 kHz: the floor without our codec, delay line and receive loop.
* ``p50_us``/``p99_us``: one-way master->controller latency through ZenohBus (encode, put,
  zenoh, arrival, delay line with zero delay, decode), measured as receive time minus send
  time on the shared ``CLOCK_MONOTONIC`` (same machine), at 1 kHz.  ``rtt_*``: the same
  round trip (master_state out, force_command back), for comparison with ``raw_rtt_*``.
* ``delay_error_*``: achieved minus configured one-way delay with ``delay_s = 0.05``.
* Every ``*_p99_us`` has its ``*_max_us`` and ``*_stalls`` beside it: a p99 hides the worst
  1 %; ``*_stalls`` counts the messages later than :data:`STALL_US` (the services' 20 ms
  watchdog timeout: a gap that long trips them).
* ``messages_per_s``: sustained rate of master_state -> force_command echoes with at most
  32 unanswered (each counted once; every one is encoded, delayed, decoded on both sides);
  a window unanswered for 50 ms is written off, never counted (``written_off``).
  Publishing flat out instead only measures zenoh's drops (CongestionControl.DROP) once
  the Python receiver falls behind.
"""

from __future__ import annotations

import struct
import threading
import time

import numpy as np

from teleop.messages import Header, MasterState
from teleop.transport.clock import MonotonicClock
from teleop.transport.peer import PeerProcess, free_tcp_endpoint
from teleop.transport.zenoh_bus import ZenohBus, zenoh_config

RATE_HZ = 1000.0
DELAY_S = 0.05
_PING = struct.Struct("<qd")


def _pct(values: list[float], q: float) -> float:
    return float(np.percentile(np.asarray(values), q)) if values else float("nan")


def _max(values: list[float]) -> float:
    return max(values, default=float("nan"))


STALL_US = 20_000.0


def _stalls(values: list[float]) -> float:
    """How many of ``values`` (us) exceed :data:`STALL_US`."""
    return float(sum(1 for v in values if v > STALL_US))


def _wait(cond: object, timeout_s: float, what: str) -> None:
    t_end = time.monotonic() + timeout_s
    while not cond():  # type: ignore[operator]
        if time.monotonic() > t_end:
            raise RuntimeError(f"bench transport: timed out waiting for {what}")
        time.sleep(0.001)


def raw_rtt_us(n: int) -> list[float]:
    """Round trips [us] of ``n`` bare zenoh pings at 1 kHz."""
    import zenoh

    ep = free_tcp_endpoint()
    session = zenoh.open(zenoh_config("peer", [ep], []))
    rtts: list[float] = []
    seen = threading.Event()

    def on_pong(sample: zenoh.Sample) -> None:
        _, t0 = _PING.unpack(sample.payload.to_bytes())
        rtts.append((time.monotonic() - t0) * 1e6)

    def on_live(sample: zenoh.Sample) -> None:
        if sample.kind == zenoh.SampleKind.PUT:
            seen.set()

    sub = session.declare_subscriber("bench/raw/pong", on_pong)
    live = session.liveliness().declare_subscriber("bench/raw/raw-echo", on_live, history=True)
    ping = session.declare_publisher("bench/raw/ping", express=True,
                                     priority=zenoh.Priority.REAL_TIME)
    peer = PeerProcess("raw-echo", ["--session", "raw", "--connect", ep])
    try:
        if not seen.wait(10.0):
            raise RuntimeError("bench transport: raw peer not seen")
        t_next = time.monotonic()
        for i in range(n):
            t_next += 1.0 / RATE_HZ
            ping.put(_PING.pack(i, time.monotonic()))
            time.sleep(max(0.0, t_next - time.monotonic()))
        time.sleep(0.1)
    finally:
        peer.stop()
        sub.undeclare()
        live.undeclare()
        ping.undeclare()
        session.close()
    return list(rtts)


def bus_phase(n: int, mode: str, overrides: list[str],
              rate_hz: float | None = RATE_HZ) -> dict[str, object]:
    """Send ``n`` master_state messages (``rate_hz`` None: as fast as possible) to a peer.

    Returns the peer's result plus ``rtt_us`` and ``backward_us`` (echo mode) and
    ``publish_s`` (time spent publishing).
    """
    clock = MonotonicClock()
    ep = free_tcp_endpoint()
    bus = ZenohBus("master", session=f"bench-{mode}", listen=[ep], connect=[])
    peer = None
    try:
        peer = PeerProcess(mode, ["--session", f"bench-{mode}", "--connect", ep,
                                  *[a for o in overrides for a in ("--set", o)]])
        _wait(lambda: bus.alive("controller"), 10.0, "the peer's liveliness")
        sent_at: dict[int, float] = {}
        rtt_us: list[float] = []
        back_us: list[float] = []

        def drain() -> None:
            for r in bus.receive("force_command"):
                rtt_us.append((r.received_t_s - sent_at[r.message.header.seq]) * 1e6)
                back_us.append(r.delay_s * 1e6)

        t0 = clock.now_s()
        t_next = t0
        for i in range(n):
            now = clock.now_s()
            sent_at[i] = now
            bus.publish("master_state", MasterState(Header(i, now, 0.0), 0.01, 0.0))
            if rate_hz is None:
                continue
            t_next += 1.0 / rate_hz
            while (left := t_next - clock.now_s()) > 0:
                bus.wait(left)
                drain()
        publish_s = clock.now_s() - t0
        t_end = clock.now_s() + (0.2 if mode == "count" else DELAY_S * 2 + 0.1)
        while clock.now_s() < t_end:
            bus.wait(0.005)
            drain()
        result = peer.stop()
        peer = None
    finally:
        if peer is not None:
            peer.kill()
        bus.close()
    result.update(rtt_us=rtt_us, backward_us=back_us, publish_s=publish_s, t0_s=t0)
    return result


def throughput_phase(n: int, window: int = 32) -> tuple[float, int, int]:
    """Echo ``n`` messages with at most ``window`` unanswered; ``(elapsed s, echoed,
    written off)``."""
    clock = MonotonicClock()
    ep = free_tcp_endpoint()
    bus = ZenohBus("master", session="bench-thr", listen=[ep], connect=[])
    peer = None
    try:
        peer = PeerProcess("echo", ["--session", "bench-thr", "--connect", ep])
        _wait(lambda: bus.alive("controller"), 10.0, "the peer's liveliness")
        # warm-up: one echo must come back before the clock starts (the peer's subscriber
        # can appear a little after its liveliness token; those first messages are lost)
        seq = 0
        t_give_up = clock.now_s() + 10.0
        while not bus.receive("force_command"):
            if clock.now_s() > t_give_up:
                raise RuntimeError("bench transport: the echo peer never answered")
            bus.publish("master_state", MasterState(Header(seq, clock.now_s(), 0.0), 0.01, 0.0))
            seq += 1
            bus.wait(0.01)
        bus.wait(0.05)
        bus.receive("force_command")
        # window on sequence numbers: an echo acknowledges its own seq and every earlier one
        # (latest-wins delivery may fold several echoes into one); a window with no answer for
        # 50 ms counts as lost and is skipped, never as echoed
        first = seq
        acked = seq  # every seq < acked is answered or written off
        echoed = 0
        t0 = clock.now_s()
        t_give_up = t0 + 60.0
        last_progress = t0
        while acked < first + n and clock.now_s() < t_give_up:
            while seq < first + n and seq - acked < window:
                bus.publish("master_state", MasterState(Header(seq, clock.now_s(), 0.0),
                                                        0.01, 0.0))
                seq += 1
            bus.wait(0.001)
            got = [r.message.header.seq for r in bus.receive("force_command")]
            now = clock.now_s()
            top = max(got, default=-1) + 1
            if top > acked:
                echoed += top - acked
                acked = top
                last_progress = now
            elif now - last_progress > 0.05 and seq > acked:
                acked = seq
                last_progress = now
        elapsed = clock.now_s() - t0
        peer.stop()
        peer = None
    finally:
        if peer is not None:
            peer.kill()
        bus.close()
    return elapsed, echoed, acked - first - echoed


def bench_transport(duration_s: float = 5.0) -> dict[str, float | str]:
    """All transport figures (flat dict, units in the keys)."""
    n = max(100, int(duration_s * RATE_HZ))
    raw = raw_rtt_us(n)
    lat = bus_phase(n, "echo", [])
    fwd: list[float] = lat["delays_us"]  # type: ignore[assignment]
    rtt: list[float] = lat["rtt_us"]  # type: ignore[assignment]
    back: list[float] = lat["backward_us"]  # type: ignore[assignment]
    dly = bus_phase(n, "echo", [f"links.master_controller.delay_s={DELAY_S}"])
    err = [d - DELAY_S * 1e6 for d in dly["delays_us"]]  # type: ignore[attr-defined]
    n_thr = min(4 * n, 20000)
    thr_s, echoed, written_off = throughput_phase(n_thr)
    return {
        "messages_sent": float(n),
        "latency_method": "one-way, receive minus send on the shared CLOCK_MONOTONIC",
        "p50_us": _pct(fwd, 50), "p99_us": _pct(fwd, 99), "max_us": _max(fwd),
        "stalls": _stalls(fwd),
        "received_fraction": len(fwd) / n,
        "backward_p50_us": _pct(back, 50), "backward_p99_us": _pct(back, 99),
        "backward_max_us": _max(back), "backward_stalls": _stalls(back),
        "rtt_p50_us": _pct(rtt, 50), "rtt_p99_us": _pct(rtt, 99), "rtt_max_us": _max(rtt),
        "rtt_stalls": _stalls(rtt),
        "raw_rtt_p50_us": _pct(raw, 50), "raw_rtt_p99_us": _pct(raw, 99),
        "raw_rtt_max_us": _max(raw), "raw_rtt_stalls": _stalls(raw),
        "raw_one_way_p50_us": _pct(raw, 50) / 2,
        "delay_configured_ms": DELAY_S * 1e3,
        "delay_error_p50_us": _pct(err, 50),
        "delay_error_p99_us": _pct([abs(e) for e in err], 99),  # of |error|
        "delay_error_max_us": _max([abs(e) for e in err]),  # of |error|
        "delay_error_stalls": _stalls([abs(e) for e in err]),
        "delay_error_min_us": min(err, default=float("nan")),
        "delay_received_fraction": len(err) / n,
        "messages_per_s": echoed / thr_s,
        "written_off": float(written_off),
    }
