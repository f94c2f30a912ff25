"""The JSON document and one-line verdict of a soak: reads the services' soak logs and
puts :mod:`services.soak_report`'s figures together."""

from __future__ import annotations

import math
import os
import signal
from pathlib import Path
from typing import Any

from services.soak_log import read_status, read_timing
from services.soak_report import (
    GROWTH_GOAL_PCT,
    energy_audit,
    grasps,
    growth,
    latency_windows,
    recovery_s,
    watchdog_share,
)
from teleop.config import TeleopConfig

WINDOW_S = 300.0
GROWTH_JUDGED_MIN = 10.0  # shorter soaks report growth but do not judge it
ROLES = ("master", "controller", "hand")


def _logs(work: Path, suffix: str) -> dict[str, list[Path]]:
    """Per role, its processes' files in start order (pid order is not start order)."""
    out: dict[str, list[Path]] = {r: [] for r in ROLES}
    for p in work.glob(f"*{suffix}"):
        role = p.stem.split("-")[0]
        if role in out:
            out[role].append(p)
    for r in out:  # by the first status line's time
        out[r].sort(key=_first_t)
    return out


def _trims(work: Path, role: str, pid: int) -> dict[str, float]:
    """A process's heap trims and its slowest trim in ms, from its last status line."""
    path = work / f"{role}-{pid}.jsonl"
    last = read_status(path)[-1:] if path.exists() else []
    return {"heap_trims": last[0].get("heap_trims", 0.0) if last else 0.0,
            "heap_trim_max_ms": last[0].get("heap_trim_max_ms", 0.0) if last else 0.0}


def _first_t(p: Path) -> float:
    status = p.with_suffix(".jsonl")
    if status.exists():
        with open(status) as f:
            line = f.readline()
        if '"t_s": ' in line:
            return float(line.split('"t_s": ')[1].split(",")[0])
    return math.inf


def summarise(run: Any, cfg: TeleopConfig, codes: dict[str, int], tracebacks: list[str], *,
              minutes: float, fault_every_s: float, interrupted: bool) -> dict[str, Any]:
    """The soak's JSON document (``verdict`` is its one-line summary)."""
    status_files = _logs(run.work, ".jsonl")
    status = {r: [read_status(p) for p in ps] for r, ps in status_files.items()}
    timing = {r: [read_timing(p.with_suffix(".timing")) for p in ps
                  if p.with_suffix(".timing").exists()] for r, ps in status_files.items()}
    end_s = max((float(a["t_s"][-1]) for arrs in timing.values() for a in arrs if a.size),
                default=0.0)
    t0 = run.start_s
    window = min(WINDOW_S, max(end_s - t0, 1.0))
    merged = {r: sorted((d for s in lists for d in s), key=lambda d: d["t_s"])
              for r, lists in status.items()}
    faults = []
    for f in run.faults:
        rec = recovery_s([merged[r] for r in ROLES], f.end_s, 20.0)
        d = {"kind": f.kind, "target": f.target, "start_s": round(f.start_s, 3),
             "end_s": round(f.end_s, 3), "recovery_s": rec, "note": f.note}
        if f.kind == "malformed_flood":
            d["injected"] = f.injected
            d["rejected"] = _rejected(status, f.start_s, f.end_s + 2.0)
        faults.append(d)
    unrecovered = [f for f in faults if f["recovery_s"] is None]
    flood_short = [f for f in faults if f["kind"] == "malformed_flood"
                   and (f["injected"] == 0 or f["rejected"] < 0.9 * f["injected"])]
    bad_exit = {r: c for r, c in codes.items() if c not in (0, -signal.SIGINT)}
    crashes = list(run.crashes) + [f"{r} exit status {c} at the end" for r, c in
                                   bad_exit.items()] + [f"traceback in {t}" for t in tracebacks]
    warmup = min(120.0, 0.25 * run.duration_s)
    floods = [(f.start_s - 1.0, f.end_s + 10.0) for f in run.faults
              if f.kind == "malformed_flood"]
    procs = [p | _trims(run.work, p["role"], p["pid"])
             for p in growth(run.samples, warmup, floods)]
    judged = [p for p in procs if p["rss_growth_pct"] is not None]
    worst = max((p["rss_growth_pct"] for p in judged), default=None)
    worst_thr = max((p["threads_growth_pct"] for p in judged), default=None)
    worst_out = max((p["rss_growth_outside_pct"] for p in judged), default=None)
    audit = energy_audit(status["master"][0] if status["master"] else [],
                         status["hand"][0] if status["hand"] else [], status["controller"],
                         cfg.controller.tank.energy_scale)
    g = grasps(merged["master"], merged["hand"], cfg.master.travel_m)
    growth_judged = minutes >= GROWTH_JUDGED_MIN
    growth_ok = (worst is not None and worst < GROWTH_GOAL_PCT
                 and (worst_thr or 0.0) < GROWTH_GOAL_PCT) if growth_judged else None
    ok = (not crashes and not unrecovered and not flood_short and not interrupted
          and (not audit["audited"] or audit["violations"] == 0) and growth_ok is not False)
    doc: dict[str, Any] = {
        "minutes": minutes, "fault_every_s": fault_every_s, "ran_s": round(run.duration_s, 1),
        "interrupted": interrupted, "ok": ok, "crashes": crashes, "faults": faults,
        "faults_unrecovered": len(unrecovered), "flood_short": len(flood_short),
        "grasps": g, "processes": procs, "warmup_s": warmup,
        "rss_growth_max_pct": worst, "rss_growth_outside_floods_max_pct": worst_out,
        "threads_growth_max_pct": worst_thr,
        "growth_goal_pct": GROWTH_GOAL_PCT, "growth_judged": growth_judged,
        "latency_window_s": window, "latency": _windows(timing, merged, window, t0, end_s),
        "energy_audit": audit, "load_avg": _load(),
        "cpus": os.cpu_count(),
    }
    doc["verdict"] = verdict(doc)
    return doc


def _windows(timing: dict[str, list[Any]], merged: dict[str, list[dict[str, float]]],
             window: float, t0: float, end_s: float) -> list[dict[str, Any]]:
    rows = latency_windows(timing, window, t0, end_s)
    for w in rows:
        w["watchdog_tripped_pct"] = watchdog_share(merged, w["start_s"], w["end_s"])
    return rows


def _rejected(status: dict[str, list[list[dict[str, float]]]], t0: float, t1: float) -> int:
    """Rejections the services counted between ``t0`` and ``t1`` (all processes)."""
    total = 0
    for lists in status.values():
        for s in lists:
            inside = [d["rejects"] for d in s if t0 - 0.5 <= d["t_s"] <= t1]
            before = [d["rejects"] for d in s if d["t_s"] < t0 - 0.5]
            if inside:
                total += int(max(inside) - (before[-1] if before else 0))
    return total


def _load() -> list[float]:
    try:
        return [round(x, 2) for x in os.getloadavg()]
    except OSError:
        return []


def _fmt(x: float | None, unit: str = "") -> str:
    return "-" if x is None or not math.isfinite(x) else f"{x:.1f}{unit}"


def verdict(doc: dict[str, Any]) -> str:
    """One line: what ran, what broke, growth, worst p99/max/stalls, the audit."""
    kinds: dict[str, int] = {}
    for f in doc["faults"]:
        kinds[f["kind"]] = kinds.get(f["kind"], 0) + 1
    rec = [f["recovery_s"] for f in doc["faults"] if f["recovery_s"] is not None]
    lat = doc["latency"]
    p99 = max((w[r]["p99_us"] for w in lat for r in ROLES if w.get(r, {}).get("ticks")),
              default=math.nan)
    mx = max((w[r]["max_us"] for w in lat for r in ROLES if w.get(r, {}).get("ticks")),
             default=math.nan)
    stalls = sum(w[r]["stalls"] for w in lat for r in ROLES if w.get(r, {}).get("ticks"))
    a = doc["energy_audit"]
    audit = (f"audit {a['violations']} violations, min margin {a['min_margin_j']:.2f} J"
             if a["audited"] else "no audit")
    growth = (f"RSS growth max {_fmt(doc['rss_growth_max_pct'], ' %')} "
              f"({_fmt(doc['rss_growth_outside_floods_max_pct'], ' %')} outside the floods), "
              f"threads "
              f"{_fmt(doc['threads_growth_max_pct'], ' %')}"
              + ("" if doc["growth_judged"] else " (not judged under 10 min)"))
    return (f"soak {'PASS' if doc['ok'] else 'FAIL'}: {doc['ran_s'] / 60:.1f} min, "
            f"{len(doc['faults'])} faults ("
            + ", ".join(f"{k} {n}" for k, n in kinds.items()) + f"), "
            f"{len(doc['crashes'])} crashes, {doc['faults_unrecovered']} unrecovered "
            f"(recovery max {_fmt(max(rec, default=None), ' s')}), "
            f"{doc['grasps']['closures']} grasps; {growth}; worst window p99 {p99:.0f} us, "
            f"max {mx / 1000:.0f} ms, {stalls} stalls; {audit}")


def soak_table(doc: dict[str, Any]) -> str:
    """Human-readable: latency per window, processes, faults."""
    lines = [f"latency per {doc['latency_window_s']:g} s window (loop lateness, us; max "
             "includes stalls):"]
    base = doc["latency"][0]["start_s"] if doc["latency"] else 0.0
    for w in doc["latency"]:
        cells = []
        for r in ROLES:
            x = w.get(r, {})
            if x.get("ticks"):
                cells.append(f"{r} p50 {x['p50_us']:.0f} p99 {x['p99_us']:.0f} max "
                             f"{x['max_us']:.0f} stalls {x['stalls']}")
        lines.append(f"  {(w['start_s'] - base) / 60:5.1f}-{(w['end_s'] - base) / 60:5.1f} min: "
                     + "; ".join(cells))
        lines.append("    watchdog tripped " + ", ".join(
            f"{r} {v:.1f} %" for r, v in w["watchdog_tripped_pct"].items()))
    lines.append(f"processes (growth from {doc['warmup_s']:.0f} s after each start):")
    for p in doc["processes"]:
        lines.append(f"  {p['role']:10s} pid {p['pid']:7d} {p['start_s']:7.0f}-"
                     f"{p['end_s']:5.0f} s  RSS {p['rss_first_mb']:.0f} -> "
                     f"{p['rss_last_mb']:.0f} MB ({_fmt(p['rss_growth_pct'], ' %')}; "
                     f"{_fmt(p['rss_growth_outside_pct'], ' %')} outside floods)  threads "
                     f"{p['threads_min']}-{p['threads_max']} "
                     f"({_fmt(p['threads_growth_pct'], ' %')})  heap trims "
                     f"{p.get('heap_trims', 0.0):.0f}")
    lines.append("faults:")
    for f in doc["faults"]:
        extra = (f", {f['rejected']}/{f['injected']} rejected"
                 if f["kind"] == "malformed_flood" else "")
        lines.append(f"  {f['start_s']:7.1f} s {f['kind']:18s} {f['target']:16s} recovery "
                     f"{_fmt(f['recovery_s'], ' s')}{extra}{', ' + f['note'] if f['note'] else ''}")
    for c in doc["crashes"]:
        lines.append(f"CRASH {c}")
    lines.append(f"load average {doc['load_avg']} on {doc['cpus']} CPUs")
    return "\n".join(lines)
