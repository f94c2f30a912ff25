"""Options and output helpers shared by the subcommands."""

from __future__ import annotations

import argparse
import json
import math
import os
import signal
import sys
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from teleop.config import TeleopConfig, load_config
from teleop.errors import UserInputError


def add_config_options(p: argparse.ArgumentParser) -> None:
    """``--config FILE`` and repeatable ``--set key=value``."""
    p.add_argument("--config", type=Path, default=None, metavar="FILE",
                   help="TOML config file (default: built-in defaults, as config/default.toml)")
    p.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                   help="override one config key, e.g. --set links.master_controller.delay_s=0.1"
                   " (repeatable)")


def add_json_option(p: argparse.ArgumentParser) -> None:
    """``--json PATH`` ('-' for stdout)."""
    add_output_option(p, "--json", what="JSON", dest="json_path", default=None,
                      metavar="PATH", help="write results as JSON to PATH ('-' for stdout)")


def add_output_option(p: argparse.ArgumentParser, *flags: str, what: str,
                      **kwargs: Any) -> None:
    """An option naming a file the command writes (``what`` in its error): registered so
    that :func:`check_outputs` tries it before the command runs, whatever the command."""
    action = p.add_argument(*flags, **kwargs)
    known = p.get_default("output_paths") or ()
    p.set_defaults(output_paths=(*known, (action.dest, what)))


def check_outputs(args: argparse.Namespace) -> None:
    """Every output file the parsed command was given (:func:`add_output_option`) checked
    with :func:`check_output_path`: a long run fails in one line before it starts, not after
    its results are computed (``teleop budget --seconds 600 --json X`` once ran its ten
    minutes and then found X unwritable)."""
    for dest, what in getattr(args, "output_paths", ()):
        check_output_path(getattr(args, dest, None), what)


def config_from_args(args: argparse.Namespace) -> TeleopConfig:
    """Load the config named by ``--config``/``--set``."""
    return load_config(args.config, args.overrides)


def _clean(obj: Any) -> Any:
    if isinstance(obj, float):
        return obj if math.isfinite(obj) else None
    if isinstance(obj, dict):
        return {str(k): _clean(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_clean(v) for v in obj]
    if hasattr(obj, "item") and callable(obj.item):  # numpy scalar
        return _clean(obj.item())
    return obj


def write_json(path: str | None, obj: Any) -> None:
    """Write ``obj`` as JSON to ``path`` ('-' for stdout); nothing when ``path`` is None."""
    if path is None:
        return
    text = json.dumps(_clean(obj), indent=2, allow_nan=False)
    if path == "-":
        sys.stdout.write(text + "\n")
        sys.stdout.flush()
        return
    try:
        Path(path).parent.mkdir(parents=True, exist_ok=True)
        Path(path).write_text(text + "\n", encoding="utf-8")
    except OSError as exc:
        raise UserInputError(f"{path}: cannot write JSON ({exc.strerror})") from None


def check_output_path(path: str | Path | None, what: str) -> None:
    """Fail early (one line) if ``path`` cannot be written, before a long run's results are
    computed and then lost; creates missing parent directories as the writers do.  ``None``
    and '-' (stdout) always pass."""
    if path is None or str(path) == "-":
        return
    p = Path(path)
    if p.is_dir():
        raise UserInputError(f"{path}: is a directory, cannot write {what}")
    try:
        p.parent.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise UserInputError(f"{path}: cannot write {what} ({exc.strerror})") from None
    if not os.access(p.parent, os.W_OK | os.X_OK) or (p.exists() and not os.access(p, os.W_OK)):
        raise UserInputError(f"{path}: cannot write {what} (permission denied)")


def info(args: argparse.Namespace, text: str) -> None:
    """Human-readable progress; goes to stderr when JSON is on stdout."""
    stream = sys.stderr if getattr(args, "json_path", None) == "-" else sys.stdout
    print(text, file=stream, flush=True)


def positive_float(text: str) -> float:
    """argparse type: a finite number > 0."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
    if not math.isfinite(value) or value <= 0:
        raise argparse.ArgumentTypeError(f"{text!r} must be a finite number > 0")
    return value


def nonneg_float(text: str) -> float:
    """argparse type: a finite number >= 0."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
    if not math.isfinite(value) or value < 0:
        raise argparse.ArgumentTypeError(f"{text!r} must be a finite number >= 0")
    return value


class FractionProgress:
    """A one-line progress bar on stderr for a run that reports the fraction done:
    ``label``, percent, elapsed and estimated remaining wall time (nothing when disabled).
    :meth:`draw` is the bar itself, for callers that say how much in their own words."""

    def __init__(self, label: str, enabled: bool = True) -> None:
        self.label, self.enabled = label, enabled and sys.stderr is not None
        self.t0 = time.perf_counter()
        self.shown = False

    def __call__(self, fraction: float) -> None:
        self.draw(fraction, f"{fraction:4.0%}", f"{self.label}  ")

    def draw(self, fraction: float, amount: str, label: str) -> None:
        """``[####....] AMOUNT ELAPSEDs eta ETAs  LABEL``, over the line drawn before."""
        if not self.enabled:
            return
        elapsed = time.perf_counter() - self.t0
        eta = elapsed * (1.0 - fraction) / fraction if fraction > 0 else 0.0
        fill = int(30 * min(max(fraction, 0.0), 1.0))
        sys.stderr.write(f"\r[{'#' * fill}{'.' * (30 - fill)}] {amount} {elapsed:5.0f}s "
                         f"eta {eta:4.0f}s  {label}")
        sys.stderr.flush()
        self.shown = True

    def finish(self) -> None:
        if self.shown:
            sys.stderr.write("\n")
            sys.stderr.flush()
            self.shown = False


class FirstInterrupt:
    """Within ``with``: the first Ctrl-C (SIGINT) only sets :attr:`asked`, so a long run
    can end at a whole step and report what it has; a second one raises KeyboardInterrupt
    as usual.  Outside the main thread (no signal handlers there) it does nothing."""

    def __init__(self) -> None:
        self.asked = False
        self._old: Any = None

    def __call__(self) -> bool:
        return self.asked

    def _handle(self, signum: int, frame: object) -> None:
        if self.asked:
            raise KeyboardInterrupt
        self.asked = True

    def __enter__(self) -> FirstInterrupt:
        if threading.current_thread() is threading.main_thread():
            self._old = signal.signal(signal.SIGINT, self._handle)
        return self

    def __exit__(self, *exc: object) -> None:
        if self._old is not None:
            signal.signal(signal.SIGINT, self._old)
            self._old = None


def serve_until_stopped(serve: Callable[[], None]) -> None:
    """Run ``serve`` until it returns or SIGINT/SIGTERM arrives (a clean return, also when
    started with SIGINT ignored); the previous handlers are restored after."""
    def stop(signum: int, frame: object) -> None:
        raise KeyboardInterrupt

    old = signal.signal(signal.SIGTERM, stop)
    old_int = signal.signal(signal.SIGINT, stop)
    try:
        serve()
    except KeyboardInterrupt:
        pass
    finally:
        signal.signal(signal.SIGTERM, old)
        signal.signal(signal.SIGINT, old_int)
