"""``teleop faults``: the fault suite (controller kill, link cut, burst loss, duplicate and
reorder storms, a malformed-payload flood), checked and measured.

Examples::

    teleop faults                         # full suite in lockstep (deterministic), table
    teleop faults --short --json -        # the CI version, JSON on stdout
    teleop faults --only malformed_flood,controller_restart
    teleop faults --mode live --short     # over real zenoh: spawned service processes
    teleop faults --soak 30 --json soak.json   # 30 min live, a fault every minute

Exit status: 0 when every scenario passed its checks, 1 when one failed, 2 on a user error.
"""

from __future__ import annotations

import argparse
import math
import sys
from typing import Any

from teleop.commands.common import (
    add_config_options,
    add_json_option,
    positive_float,
    write_json,
)
from teleop.commands.run import add_realtime_option
from teleop.errors import UserInputError


def register(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Add the ``faults`` subcommand."""
    p = sub.add_parser("faults", help="fault suite: kill, cut, loss, storms, malformed flood",
                       description="Inject named faults into a grasp and check that the hand "
                       "stays inside its joint limits, never moves on invalid data, the energy "
                       "balance holds and the services recover; prints a table (and JSON) of "
                       "faults run, messages rejected by reason, energy violations and "
                       "recovery times.")
    add_config_options(p)
    add_json_option(p)
    p.add_argument("--mode", choices=("lockstep", "live"), default="lockstep",
                   help="lockstep: in-process bus, virtual clock, deterministic (default); "
                   "live: spawned service processes over zenoh in real time")
    p.add_argument("--short", action="store_true",
                   help="the CI version: a 1,000-payload flood instead of 10,000")
    p.add_argument("--seed", type=int, default=1, help="run seed (default 1)")
    p.add_argument("--only", default=None, metavar="LIST",
                   help="comma list of scenario names to run (default: all)")
    p.add_argument("--soak", type=positive_float, default=None, metavar="MINUTES",
                   help="soak instead of the suite: the three services live over zenoh for "
                   "MINUTES, repeated grasps, a fault every --fault-every seconds (controller "
                   "killed, link cut, malformed flood, a stalled service, in turn)")
    p.add_argument("--fault-every", type=positive_float, default=60.0, metavar="S",
                   help="soak: seconds between faults (default 60)")
    add_realtime_option(p)
    p.set_defaults(run=run)


def _fmt_s(x: float | None) -> str:
    return "never" if x is None or not math.isfinite(x) else f"{x:.3f}"


def _fmt_j(x: float | None) -> str:
    return "-" if x is None or not math.isfinite(x) else f"{x:.3f}"


def table(doc: dict[str, Any]) -> str:
    """The human-readable table of a suite's JSON document."""
    rows = [("scenario", "ok", "injected", "rejected", "audit viol.", "audit min J",
             "ledger viol.", "ledger min J", "gap op/env J", "recovery s", "limit viol.",
             "wd trips")]
    for s in doc["scenarios"]:
        audited = s.get("passive_audit") is not None
        gap = s.get("ledger_audit_gap_j") or {}
        rows.append((s["name"], "yes" if s["ok"] else "NO", str(s["injected"]),
                     str(s["rejected"]),
                     str(s["audit_violations"]) if audited else "no audit",
                     _fmt_j(s.get("min_audit_margin_j")), str(s["energy_violations"]),
                     _fmt_j(s["min_energy_margin_j"]),
                     "/".join(_fmt_j(gap.get(k)) for k in ("operator", "environment"))
                     if audited else "-",
                     _fmt_s(s["recovery_s"]), str(s["joint_limit_violations"]),
                     str(s["watchdog_trips"])))
    widths = [max(len(r[i]) for r in rows) for i in range(len(rows[0]))]
    lines = ["  ".join(c.ljust(w) for c, w in zip(r, widths, strict=True)) for r in rows]
    lines.insert(1, "  ".join("-" * w for w in widths))
    lines.append("")
    lines.append(f"faults run: {doc['faults_run']}, passed: {doc['faults_passed']}, "
                 f"messages rejected: {doc['messages_rejected']} ({doc['mode']})")
    n_aud = doc.get("audited", 0)
    lines.append(f"passivity by the physical audit: {doc.get('audit_violations', 0)} violating "
                 f"samples in {n_aud} audited scenario(s); by the ledgers: "
                 f"{doc['energy_violations']}")
    for s in doc["scenarios"]:
        if s.get("passive_audit") is None:
            lines.append(f"no audit for {s['name']}: {s.get('audit', 'no physical audit')}")
    reasons = ", ".join(f"{k} {v}" for k, v in doc["rejects_by_reason"].items())
    lines.append(f"rejected by reason: {reasons or 'none'}")
    for s in doc["scenarios"]:
        for f in s["failures"]:
            lines.append(f"FAILED {s['name']}: {f}")
    return "\n".join(lines)


def run(args: argparse.Namespace) -> int:
    """Run the suite; print the table (unless JSON goes to stdout); write JSON."""
    import logging

    from teleop.config import load_config

    # every rejection is counted and reported in the table: no per-message warning lines
    logging.getLogger("teleop.transport").setLevel(logging.ERROR)

    if args.soak is not None:
        return _soak(args)
    only = tuple(x.strip() for x in args.only.split(",") if x.strip()) if args.only else None
    if args.mode == "live":
        from services.faults_live import LIVE_SCENARIOS, run_live_suite

        if only is not None and set(only) - set(LIVE_SCENARIOS):
            raise UserInputError(f"--only: live mode runs {', '.join(LIVE_SCENARIOS)}")
        load_config(args.config, args.overrides)  # a bad key fails here, in one line
        suite = run_live_suite(args.config, args.overrides, short=args.short, seed=args.seed,
                               names=only)
    else:
        from services.faults import BASE_OVERRIDES, run_suite, scenario_names

        known = set(scenario_names())
        if only is not None and set(only) - known:
            bad = ", ".join(sorted(set(only) - known))
            raise UserInputError(f"--only: unknown scenario {bad} (known: "
                                 f"{', '.join(sorted(known))})")
        cfg = load_config(args.config, [*BASE_OVERRIDES, *args.overrides])

        def progress(r: Any) -> None:
            print(f"  {r.name}: {'ok' if r.ok else 'FAILED'} ({r.wall_s:.1f} s)",
                  file=sys.stderr, flush=True)

        suite = run_suite(cfg, short=args.short, seed=args.seed, names=only,
                          progress=progress)
    doc = suite.to_json()
    if args.json_path != "-":
        print(table(doc))
    write_json(args.json_path, doc)
    return 0 if suite.ok else 1


def _soak(args: argparse.Namespace) -> int:
    """``--soak MINUTES``: the verdict line on stdout (and the table unless JSON goes there)."""
    from services.soak import FAULT_S, run_soak
    from services.soak_summary import soak_table
    from teleop.config import load_config

    if args.only is not None or args.short or args.mode != "lockstep":
        raise UserInputError("--soak: runs live on its own; --only, --short and --mode do "
                             "not apply")
    if args.fault_every < 2 * FAULT_S + 2.0:
        raise UserInputError(f"--fault-every {args.fault_every:g}: at least "
                             f"{2 * FAULT_S + 2.0:g} s (a fault lasts {FAULT_S:g} s)")
    load_config(args.config, args.overrides)  # a bad key fails here, in one line

    def say(text: str) -> None:
        print(f"soak: {text}", file=sys.stderr, flush=True)

    doc = run_soak(args.config, list(args.overrides), args.soak,
                   fault_every_s=args.fault_every, realtime=args.realtime, progress=say)
    if args.json_path != "-":
        print(soak_table(doc))
        print(doc["verdict"])
    else:
        say(doc["verdict"])
    write_json(args.json_path, doc)
    return 0 if doc["ok"] else 1
