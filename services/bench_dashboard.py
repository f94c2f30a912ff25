"""``teleop bench dashboard``: how late the hand reads its sensors while the dashboard runs.

Runs ``teleop up --duration D --dashboard save:FILE --record DIR`` (three real-time processes
over zenoh on loopback, the dashboard written to a file as on a machine without a display,
the default) and reads the hand's recording back: ``read_t_s - t_s`` per hand tick is how
late the hand really read its sensors after the tick's deadline.  On a two-core machine the
dashboard's logging can starve the 40 Hz hand behind the two 1 kHz loops (2026-11-29: half
the hand's reads more than 50 ms late, up to 0.5 s); with ``--dashboard off`` the same run's
reads are at most ~10 ms late.

With ``reference`` (a source tree of an earlier implementation) the two trees run in turn,
``repeats`` times each, the same command in each (``python -m teleop.cli`` with that tree
first on the path), and every figure is reported for both: ``<tree>_read_late_*_ms`` (median
of the runs' p50, p90, p99, max), ``<tree>_late_over_50ms_pct`` and ``<tree>_rows_pct``
(hand rows written of those due: a stall over 0.5 s drops deadlines).
"""

from __future__ import annotations

import sys
import tempfile
from pathlib import Path

import numpy as np

from services.bench import free_port

#: how long each run lasts (s): several grasps of the virtual operator's script
DURATION_S = 20.0


def _run(tree: Path, duration_s: float) -> dict[str, float]:
    """One ``teleop up`` run of ``tree``; the hand's read lateness figures."""
    from teleop.analysis.up_child import run_up
    from teleop.recording import read_recording

    port = free_port()
    with tempfile.TemporaryDirectory(prefix="teleop-bench-dash-") as tmp:
        run_up(["--duration", f"{duration_s:g}", "--dashboard", f"save:{tmp}/d.rrd",
                "--record", f"{tmp}/rec", "--set", f"zenoh.endpoint=tcp/127.0.0.1:{port}",
                "--set", f"session.name=benchdash{port}"],
               timeout_s=duration_s + 120, what="bench dashboard", tree=tree)
        hand = read_recording(Path(tmp) / "rec" / "hand.csv")
    late = hand.column("read_t_s") - hand.t_s
    late = late[np.isfinite(late)]
    rate_hz = float(hand.meta_value("rate_hz") or 40.0)  # the hand's configured rate
    due = (hand.t_s[-1] - hand.t_s[0]) * rate_hz + 1.0
    return {"p50": float(np.median(late)) * 1e3, "p90": float(np.percentile(late, 90)) * 1e3,
            "p99": float(np.percentile(late, 99)) * 1e3, "max": float(late.max()) * 1e3,
            "over50": 100.0 * float(np.mean(late > 0.05)), "rows": 100.0 * len(hand) / due}


def bench_dashboard(repeats: int = 2, reference: str | None = None,
                    duration_s: float = DURATION_S) -> dict[str, float]:
    """Figures for ``teleop bench dashboard`` (see the module docstring)."""
    from services.bench_lockstep import check_reference

    here = Path(__file__).resolve().parent.parent
    trees = {"this": here}
    if reference is not None:
        trees["reference"] = check_reference(reference)
    runs: dict[str, list[dict[str, float]]] = {k: [] for k in trees}
    for k in range(repeats):
        for name, tree in trees.items():
            print(f"bench dashboard: {name} run {k + 1} of {repeats} ({duration_s:g} s)",
                  file=sys.stderr, flush=True)
            runs[name].append(_run(tree, duration_s))
    out: dict[str, float] = {"duration_s": duration_s, "repeats": float(repeats)}
    for name, rs in runs.items():
        def med(key: str, rs: list[dict[str, float]] = rs) -> float:
            return float(np.median([r[key] for r in rs]))

        out |= {f"{name}_read_late_p50_ms": med("p50"), f"{name}_read_late_p90_ms": med("p90"),
                f"{name}_read_late_p99_ms": med("p99"), f"{name}_read_late_max_ms": med("max"),
                f"{name}_late_over_50ms_pct": med("over50"), f"{name}_rows_pct": med("rows")}
    return out
