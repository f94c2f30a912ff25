"""``teleop bench loop``: achieved loop rates and period lateness with all three services up.

Runs ``teleop up`` machinery (three spawned processes over zenoh on loopback, a free port,
dashboard off) for a few seconds; each service writes its loop timing when it stops.
Figures: ``<role>_rate_hz`` (ticks per second), ``<role>_lateness_p50_us`` /
``_p99_us`` (tick start minus deadline, re-based after a stall) beside ``_lateness_max_us``
(stalls included, measured from the first deadline a stall missed) and ``_stalls`` (ticks
after which deadlines were skipped), ``<role>_skipped``; the same over the roles as
``lateness_p99_us`` (the worst of master and controller), ``lateness_max_us`` and ``stalls``.
Floors for the master and controller: mean rate >= 990 Hz, p99 lateness <= 1000 us and no
tick later than the services' 20 ms watchdog timeout (``floor_ok``: all three; a stall longer
than that trips the peers' watchdogs, so a run with one misses the floor whatever its p99);
``floor_p99_ok`` is the rate and p99 part alone.
"""

from __future__ import annotations

import json
import math
import socket
import tempfile
from collections.abc import Sequence
from pathlib import Path

from teleop.config import load_config

#: a master/controller tick later than this misses the floor: the services' command and
#: state watchdogs (``safety.timeout_s``, default 20 ms) trip on a gap this long
MAX_LATENESS_FLOOR_US = 20_000.0


def free_port() -> int:
    """A free TCP port on 127.0.0.1."""
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def bench_loop(duration_s: float = 5.0, sets: Sequence[str] = ()) -> dict[str, float]:
    """Run the three services for ``duration_s`` (config ``sets``, ``KEY=VALUE``, on top of
    the defaults) and return their loop figures."""
    import contextlib
    import io

    from services.launcher import Launcher

    overrides = [*sets, f"zenoh.endpoint=tcp/127.0.0.1:{free_port()}",
                 f"session.name=bench{free_port()}"]
    cfg = load_config(None, overrides)
    with tempfile.TemporaryDirectory(prefix="teleop-bench-") as tmp:
        passthrough = [a for o in overrides for a in ("--set", o)]
        launcher = Launcher(cfg, passthrough, dashboard_mode="off", dashboard_path=None,
                            record_dir=None, stats_dir=tmp)
        with contextlib.redirect_stdout(io.StringIO()):
            status = launcher.run(duration_s)
        figures: dict[str, float] = {"duration_s": duration_s, "exit_status": float(status)}
        for role in ("master", "controller", "hand"):
            path = Path(tmp) / f"{role}.json"
            if path.exists():
                figures.update(json.loads(path.read_text()))
    return figures | loop_summary(figures)


def loop_summary(figures: dict[str, float]) -> dict[str, float]:
    """Figures over the roles: worst p99 (master, controller) beside the worst max lateness
    and the total stall count (every role), and the floor checks (see the module doc)."""
    m, c = figures.get("master_rate_hz", 0.0), figures.get("controller_rate_hz", 0.0)
    p99 = max(figures.get("master_lateness_p99_us", float("inf")),
              figures.get("controller_lateness_p99_us", float("inf")))
    roles = ("master", "controller", "hand")
    worst = [v for r in roles
             if (v := figures.get(f"{r}_lateness_max_us")) is not None and not math.isnan(v)]
    loops_max = max(figures.get("master_lateness_max_us", float("inf")),
                    figures.get("controller_lateness_max_us", float("inf")))
    p99_ok = min(m, c) >= 990.0 and p99 <= 1000.0
    return {
        "lateness_p99_us": p99,
        "lateness_max_us": max(worst, default=float("nan")),
        "stalls": float(sum(figures.get(f"{r}_stalls", 0.0) for r in roles)),
        "floor_p99_ok": float(p99_ok),
        "floor_ok": float(p99_ok and loops_max <= MAX_LATENESS_FLOOR_US),
    }
