"""The figures of a soak (``teleop faults --soak``), from what the services and the parent
logged: pure functions over arrays and lists, no I/O.

* :func:`latency_windows`: loop lateness per service per window (p50, p99 re-based after
  stalls, the max with the stalls' true lateness, the stall count);
* :func:`growth`: RSS and thread counts of each process over time, growth after warm-up;
* :func:`energy_audit`: the physical energy balance (virtual operator and simulated object,
  ``sim.operator``/``sim.audit``) against the tanks' initial energy, every controller
  incarnation's included;
* :func:`recovery_s`: how long after a fault every service's watchdog is clear again, and
  :func:`watchdog_share`: how much of a window each watchdog was tripped;
* :func:`grasps`: closures of the trigger and the hand's contact episodes.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np

from teleop.analysis.port_audit import audit_margin_j

GROWTH_GOAL_PCT = 10.0
ROBUST_SAMPLES = 5  # growth compares medians of this many samples (a 10 MB spike that comes
#                     and goes within seconds is not growth)


def latency_windows(timing: dict[str, list[np.ndarray]], window_s: float, start_s: float,
                    end_s: float) -> list[dict[str, Any]]:
    """Per window ``[start + k w, start + (k+1) w)`` and role: ticks, p50/p99 (us), max (us),
    stalls (what ran before ``start_s``, the start-up, is left out).

    ``timing[role]`` holds one :data:`services.soak_log.TIMING_DTYPE` array per process of
    that role (a restarted controller has several)."""
    out: list[dict[str, Any]] = []
    n = max(1, math.ceil((end_s - start_s) / window_s - 1e-9))
    if n > 1 and end_s - (start_s + (n - 1) * window_s) < 0.5 * window_s:
        n -= 1  # a short tail (the stop) joins the last full window
    joined = {r: np.concatenate(a) if a else np.empty(0) for r, a in timing.items()}
    for k in range(n):
        t0 = start_s + k * window_s
        t1 = end_s if k == n - 1 else t0 + window_s
        row: dict[str, Any] = {"start_s": t0, "end_s": t1}
        for role, rec in joined.items():
            sel = rec[(rec["t_s"] >= t0) & (rec["t_s"] < t1)] if rec.size else rec
            if not sel.size:
                row[role] = {"ticks": 0}
                continue
            late = sel["late_s"].astype(float)
            stall = sel["stall_s"].astype(float)
            row[role] = {
                "ticks": int(sel.size),
                "p50_us": float(np.percentile(late, 50)) * 1e6,
                "p99_us": float(np.percentile(late, 99)) * 1e6,
                "max_us": float(max(np.max(late), np.max(stall))) * 1e6,
                "stalls": int(np.count_nonzero(stall > 0)),
            }
        out.append(row)
    return out


def growth(samples: Sequence[tuple[float, str, int, float, int]], warmup_s: float,
           exclude: Sequence[tuple[float, float]] = ()) -> list[dict[str, Any]]:
    """Per process (role, pid) from ``(t_s, role, pid, rss_mb, threads)`` samples: the RSS
    after warm-up (the median of the :data:`ROBUST_SAMPLES` samples from ``warmup_s`` after
    its first) and at the end (the median of the last ones), the thread count the same way
    but the fewest in each window (the threads that stay), the range, the
    growth in % between the two (None when the process did not outlive its warm-up by that
    many samples) and the whole series ``[t_s, rss_mb, threads]``.

    ``rss_growth_outside_pct``: the same growth counting only the sampling intervals that
    overlap none of the ``exclude`` windows (the malformed floods: a zenoh receiver keeps
    about 19 MB per new connection that delivers a message over ~4 kB, see docs/faults.md),
    so what the services themselves accumulate shows apart from it."""
    by: dict[tuple[str, int], list[tuple[float, float, int]]] = {}
    for t, role, pid, rss, thr in samples:
        by.setdefault((role, pid), []).append((t, rss, thr))
    out: list[dict[str, Any]] = []
    for (role, pid), rows in by.items():
        t = np.array([r[0] for r in rows])
        rss = np.array([r[1] for r in rows])
        thr = np.array([r[2] for r in rows])
        after = np.nonzero(t >= t[0] + warmup_s)[0]
        d: dict[str, Any] = {"role": role, "pid": pid, "start_s": float(t[0]),
                             "end_s": float(t[-1]), "samples": len(rows),
                             "rss_first_mb": float(rss[0]), "rss_last_mb": float(rss[-1]),
                             "rss_max_mb": float(np.max(rss)),
                             "threads_min": int(np.min(thr)), "threads_max": int(np.max(thr)),
                             "threads_last": int(thr[-1]),
                             "series": [[round(a, 1), round(b, 2), int(c)]
                                        for a, b, c in zip(t, rss, thr, strict=True)]}
        k = ROBUST_SAMPLES
        if after.size >= 2 * k:
            b = after[0]
            warm, end = float(np.median(rss[b:b + k])), float(np.median(rss[-k:]))
            # threads: the fewest alive in each window - a leaked thread stays and raises
            # it, a transient one (zenoh spawns workers while it reconnects) does not; with
            # ~10 threads a median would count one transient thread at the end as 10 %
            thr_warm, thr_end = float(np.min(thr[b:b + k])), float(np.min(thr[-k:]))
            steps = np.diff(rss[b:])
            inside = [any(lo <= t1 and t0 <= hi for lo, hi in exclude)
                      for t0, t1 in zip(t[b:-1], t[b + 1:], strict=True)]
            in_floods = float(np.sum(steps[np.asarray(inside, dtype=bool)])) if steps.size \
                else 0.0
            d |= {"rss_warm_mb": warm, "rss_end_mb": end,
                  "rss_growth_pct": 100.0 * (end - warm) / warm,
                  "rss_in_floods_mb": in_floods,
                  "rss_growth_outside_pct": 100.0 * (end - warm - in_floods) / warm,
                  "threads_warm": thr_warm,
                  "threads_growth_pct": 100.0 * (thr_end - thr_warm) / thr_warm}
        else:
            d |= {"rss_growth_pct": None, "rss_growth_outside_pct": None,
                  "threads_growth_pct": None}
        out.append(d)
    return out


def _held(t: np.ndarray, v: np.ndarray, at: np.ndarray) -> np.ndarray:
    """``v`` held from each sample time to the next, read at ``at`` (nan before the first)."""
    i = np.searchsorted(t, at, side="right") - 1
    return np.where(i >= 0, v[np.clip(i, 0, None)], np.nan)


def energy_audit(master: Sequence[dict[str, float]], hand: Sequence[dict[str, float]],
                 controllers: Sequence[Sequence[dict[str, float]]], energy_scale: float
                 ) -> dict[str, Any]:
    """The physical energy balance on the master's status times::

        rho (master initial + taken - delivered at the operator)
          + hand initial + every controller's initial + taken - delivered at the object >= 0

    (``rho`` = ``energy_scale``; a controller's initial energy counts from its start; the
    formula is :func:`teleop.analysis.port_audit.audit_margin_j`)."""
    m = [d for d in master if "audit_delivered_j" in d]
    h = [d for d in hand if "audit_delivered_j" in d]
    if not m or not h:
        return {"audited": False, "why": "no simulated operator and object to audit"}
    tm = np.array([d["t_s"] for d in m])
    th = np.array([d["t_s"] for d in h])
    rho = energy_scale
    initial = np.full_like(tm, rho * m[0]["initial_j"] + h[0]["initial_j"])
    for c in controllers:
        if c:
            initial += np.where(tm >= c[0]["t_s"], c[0]["initial_j"], 0.0)
    margin = audit_margin_j(
        initial, rho, np.array([d["audit_taken_j"] for d in m]),
        np.array([d["audit_delivered_j"] for d in m]),
        _held(th, np.array([d["audit_taken_j"] for d in h]), tm),
        _held(th, np.array([d["audit_delivered_j"] for d in h]), tm))
    ok = np.isfinite(margin)
    margin = margin[ok]
    return {
        "audited": True, "samples": int(margin.size), "rate_hz": 10.0,
        "violations": int(np.count_nonzero(margin < -1e-9)),
        "min_margin_j": float(np.min(margin)) if margin.size else math.nan,
        "final_margin_j": float(margin[-1]) if margin.size else math.nan,
        "operator_delivered_j": m[-1]["audit_delivered_j"],
        "operator_taken_j": m[-1]["audit_taken_j"],
        "environment_delivered_j": h[-1]["audit_delivered_j"],
        "environment_taken_j": h[-1]["audit_taken_j"],
        "initial_j": float(rho * m[0]["initial_j"] + h[0]["initial_j"]
                           + sum(c[0]["initial_j"] for c in controllers if c)),
    }


def recovery_s(statuses: Sequence[Sequence[dict[str, float]]], fault_end_s: float,
               limit_s: float) -> float | None:
    """Seconds from ``fault_end_s`` until every role has written a status line with its
    watchdog clear (its inputs flow again; None: not within ``limit_s``).  ``statuses``: one
    list per role (a restarted role's lines merged, in time order).

    The first clear line counts, not a clear spell: on a loaded machine the 20 ms watchdogs
    flicker without any fault (see :func:`watchdog_share`)."""
    worst = 0.0
    for s in statuses:
        t = np.array([d["t_s"] for d in s])
        wd = np.array([float(d["wd"]) for d in s])
        ok = np.nonzero((t >= fault_end_s) & (t <= fault_end_s + limit_s) & (wd == 0.0))[0]
        if not ok.size:
            return None
        worst = max(worst, float(t[ok[0]] - fault_end_s))
    return worst


def watchdog_share(statuses: dict[str, Sequence[dict[str, float]]], start_s: float,
                   end_s: float) -> dict[str, float]:
    """Per role, the share (%) of its status lines in ``[start_s, end_s)`` with the watchdog
    tripped (nan without lines)."""
    out: dict[str, float] = {}
    for role, s in statuses.items():
        wd = [d["wd"] for d in s if start_s <= d["t_s"] < end_s]
        out[role] = 100.0 * float(np.mean(wd)) if wd else math.nan
    return out


def grasps(master: Sequence[dict[str, float]], hand: Sequence[dict[str, float]],
           travel_m: float) -> dict[str, int]:
    """Trigger closures past a fifth of its travel (the object stops the trigger at about a
    third) and contact episodes of the hand."""
    trig = np.array([d.get("trigger_m", 0.0) for d in master]) > 0.2 * travel_m
    touch = np.array([d.get("contacts", 0.0) for d in hand]) > 0
    return {"closures": int(np.count_nonzero(np.diff(trig.astype(int)) > 0)),
            "contact_episodes": int(np.count_nonzero(np.diff(touch.astype(int)) > 0))}
