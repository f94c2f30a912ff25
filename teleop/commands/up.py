"""``teleop up``: start the master, controller and hand services and a live dashboard.

Examples::

    teleop up                                  # until Ctrl-C, viewer if there is a display
    teleop up --duration 10 --dashboard save:run.rrd --record runs/1
    teleop up --set links.master_controller.delay_s=0.1 --dashboard web

Each service is a separate process (``python -m teleop.cli run ROLE``, spawned, never forked)
on one zenoh session space: the controller listens on ``zenoh.endpoint`` and the master and
hand connect to it.  ``up`` waits for every service's ``ready`` line, forwards Ctrl-C, and
stops the services within 2 s.  With ``--dashboard save:PATH`` each service writes its own
part and ``up`` merges the parts into one ``.rrd`` (one recording) at the end.
"""

from __future__ import annotations

import argparse
import os
from pathlib import Path

from teleop.commands.common import (
    add_config_options,
    check_output_path,
    config_from_args,
    nonneg_float,
)
from teleop.commands.run import add_dashboard_option, add_realtime_option
from teleop.config import TeleopConfig
from teleop.errors import UserInputError


def register(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Add the ``up`` subcommand."""
    p = sub.add_parser("up", help="start the three services and a live dashboard",
                       description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    add_config_options(p)
    p.add_argument("--duration", type=nonneg_float, default=None, metavar="S",
                   help="stop after S seconds (default: until Ctrl-C)")
    add_dashboard_option(p, default=None)
    p.add_argument("--record", default=None, metavar="DIR",
                   help="write each service's signals to DIR/<role>.csv")
    add_realtime_option(p)
    p.set_defaults(run=run)


def resolve_dashboard(arg: str | None, cfg_mode: str, cfg_path: str,
                      env: dict[str, str] | None = None) -> tuple[str, str | None]:
    """``(mode, path)`` from ``--dashboard`` (or the config's ``dashboard.mode``).

    ``auto``: ``spawn`` when a display is available (DISPLAY or WAYLAND_DISPLAY), else save.
    """
    env = dict(os.environ) if env is None else env
    text = arg if arg is not None else cfg_mode
    if text.startswith("save:"):
        path = text[len("save:"):]
        if not path:
            raise UserInputError("--dashboard save:PATH: empty PATH")
        return "save", path
    if text == "save":
        return "save", cfg_path
    if text == "auto":
        has_display = bool(env.get("DISPLAY") or env.get("WAYLAND_DISPLAY"))
        return ("spawn", None) if has_display else ("save", cfg_path)
    if text in ("spawn", "web", "off"):
        return text, None
    raise UserInputError(f"--dashboard {text!r}: expected spawn, web, save:PATH or off")


def check_listen_endpoints_free(cfg: TeleopConfig) -> None:
    """UserInputError, before anything starts, if an endpoint a service of this run would
    listen on is taken (another ``teleop up`` of the same endpoint, typically) or is not
    this machine's (see :mod:`teleop.transport.endpoint_check`)."""
    import errno

    from teleop.transport.endpoint_check import endpoint_bind_errno, role_endpoints

    listen, _ = role_endpoints("controller", cfg.zenoh)  # every role listens on zenoh.listen
    for i, endpoint in enumerate(listen):
        key = "zenoh.endpoint" if i == len(cfg.zenoh.listen) else f"zenoh.listen[{i}]"
        why = endpoint_bind_errno(endpoint)
        if why == errno.EADDRINUSE:
            raise UserInputError(
                f"{key} = {endpoint!r}: address in use (another teleop session, or another "
                "program, listens there); stop it, or give this run its own endpoint, e.g. "
                "--set zenoh.endpoint=tcp/127.0.0.1:7448")
        if why == errno.EADDRNOTAVAIL:
            raise UserInputError(
                f"{key} = {endpoint!r}: not an address of this machine, and teleop up "
                "listens there (it starts the controller here); for a controller on another "
                "machine run each service with teleop run (README, 'Running on several "
                "machines')")


def run(args: argparse.Namespace) -> int:
    """Start, supervise and stop the services."""
    from services.launcher import Launcher

    cfg = config_from_args(args)  # fail early, in one line, on a bad config
    mode, path = resolve_dashboard(args.dashboard, cfg.dashboard.mode, cfg.dashboard.path)
    if args.record is not None:  # fail before starting anything, not after the run
        check_output_path(Path(args.record) / "master.csv", "recordings")
    if mode == "save":
        check_output_path(path, "the dashboard recording")
    check_listen_endpoints_free(cfg)
    passthrough: list[str] = []
    if args.config is not None:
        passthrough += ["--config", str(args.config)]
    for item in args.overrides:
        passthrough += ["--set", item]
    if not args.realtime:
        passthrough.append("--no-realtime")
    launcher = Launcher(cfg, passthrough, dashboard_mode=mode, dashboard_path=path,
                        record_dir=args.record)
    return launcher.run(args.duration)
