"""``teleop watch``: a read-only dashboard session on a running session (the observer role).

Examples::

    teleop watch                                  # until Ctrl-C, a viewer if there is a display
    teleop watch --dashboard save:obs.rrd --duration 30 --json -
    teleop watch --set zenoh.endpoint=tls/10.0.0.2:7447 --set security.enabled=true \\
        --set security.cert_dir=certs             # from another machine, in secure mode

The session is a zenoh client of ``zenoh.endpoint`` (the controller), opened as the
``observer`` role: in secure mode with the observer's own certificate, key and password, so
the services refuse anything it could publish; it publishes nothing anyway.  It logs master
state, force and hand commands and hand state under ``observer/...`` and counts what arrived
and what its decoder rejected (``--json``).
"""

from __future__ import annotations

import argparse
import sys

from teleop.commands.common import (
    add_config_options,
    add_json_option,
    config_from_args,
    nonneg_float,
    write_json,
)
from teleop.commands.run import add_dashboard_option


def register(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Add the ``watch`` subcommand."""
    p = sub.add_parser("watch", help="read-only dashboard session (observer role)",
                       description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    add_config_options(p)
    add_json_option(p)
    p.add_argument("--duration", type=nonneg_float, default=None, metavar="S",
                   help="stop after S seconds (default: until Ctrl-C)")
    add_dashboard_option(p, default=None)
    p.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    """Observe until stopped; write the counts."""
    import uuid

    from services.observer import watch
    from teleop.commands.run import check_service_dashboard
    from teleop.commands.up import resolve_dashboard
    from teleop.security.zenoh_secure import secure_zenoh_config
    from teleop.viz.dashboard import open_stream

    cfg = config_from_args(args)
    secure_zenoh_config(cfg, "observer")  # missing certificate or password: one line, now
    text = args.dashboard
    if text is not None and text.startswith("connect"):
        check_service_dashboard(text)
        mode, url = "connect", text.partition(":")[2] or None
        path = None
    else:
        mode, path = resolve_dashboard(text, cfg.dashboard.mode, cfg.dashboard.path)
        url = None
    rec = open_stream(str(uuid.uuid4()), mode, path=path, url=url, send_blueprint=False)

    def say(line: str) -> None:
        print(f"teleop watch: {line}", file=sys.stderr, flush=True)

    try:
        doc = watch(cfg, args.duration, rec, say)
    finally:
        if rec is not None:
            rec.flush()
            rec.disconnect()
    doc["dashboard"] = f"{mode}:{path}" if path else mode
    if args.json_path != "-":
        got = ", ".join(f"{k} {v}" for k, v in doc["received"].items())
        print(f"received: {got}; rejected: {doc['rejected']}")
    write_json(args.json_path, doc)
    return 0
