"""Start, supervise and stop the three service processes (the body of ``teleop up``).

Children are spawned with ``sys.executable -m teleop.cli run ROLE`` in their own session (so
the terminal's Ctrl-C reaches only this parent, which forwards it in a known order).  Each
child prints ``ready <role>`` once its bus is up; its stdin is a pipe from this parent, so a
child whose parent dies sees end-of-file and stops.

Dashboards: ``save`` - each child saves ``<PATH>.parts/<role>.rrd`` with the shared recording
id and the parent merges them into ``PATH`` with the blueprint; ``spawn`` - the parent spawns a
viewer and the children stream to it; ``web`` - the parent serves a gRPC proxy and a web viewer
on 127.0.0.1 and the children stream to it.
"""

from __future__ import annotations

import contextlib
import os
import shutil
import signal
import subprocess
import sys
import threading
import time
import uuid
from pathlib import Path

from teleop.config import TeleopConfig
from teleop.errors import UserInputError

START_ORDER = ("controller", "hand", "master")
STOP_ORDER = ("master", "hand", "controller")
READY_TIMEOUT_S = 30.0
STOP_TIMEOUT_S = 2.0
VIEWER_PORT = 9876
WEB_PORT = 9090


def say(text: str) -> None:
    """Progress on stdout."""
    print(f"teleop up: {text}", flush=True)


class Launcher:
    """Runs the three services as child processes."""

    def __init__(self, cfg: TeleopConfig, passthrough: list[str], *, dashboard_mode: str,
                 dashboard_path: str | None, record_dir: str | None,
                 stats_dir: str | None = None) -> None:
        self.cfg = cfg
        self.passthrough = passthrough
        self.mode = dashboard_mode
        self.path = Path(dashboard_path) if dashboard_path else None
        self.record_dir = record_dir
        self.stats_dir = stats_dir
        self.recording_id = str(uuid.uuid4())
        self.procs: dict[str, subprocess.Popen[str]] = {}
        self.ready: dict[str, float] = {}
        self._ready_cv = threading.Condition()
        self._viewer = None  # the parent's rr.RecordingStream in spawn/web mode
        self._web: subprocess.Popen[bytes] | None = None  # the web viewer (web mode)

    # -- dashboard -------------------------------------------------------------------------
    def _parts_dir(self) -> Path:
        assert self.path is not None
        return self.path.with_name(self.path.name + ".parts")

    def _child_dashboard(self, role: str) -> str:
        if self.mode == "save":
            return f"save:{self._parts_dir() / (role + '.rrd')}"
        if self.mode in ("spawn", "web"):
            return f"connect:rerun+http://127.0.0.1:{VIEWER_PORT}/proxy"
        return "off"

    def _start_viewer(self) -> None:
        if self.mode not in ("spawn", "web"):
            return
        from teleop.viz.dashboard import open_stream

        if self.mode == "spawn":
            self._viewer = open_stream(self.recording_id, "spawn")
            return
        # web: the rerun CLI serves the gRPC proxy and the web viewer on 127.0.0.1 only
        exe = Path(sys.executable).with_name("rerun")
        cmd = [str(exe)] if exe.exists() else [sys.executable, "-m", "rerun"]
        self._web = subprocess.Popen(
            [*cmd, "--serve-web", "--bind", "127.0.0.1", "--port", str(VIEWER_PORT),
             "--web-viewer-port", str(WEB_PORT)],
            stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
            start_new_session=True)
        url = f"rerun+http://127.0.0.1:{VIEWER_PORT}/proxy"
        self._viewer = open_stream(self.recording_id, "connect", url=url)
        say(f"web viewer on http://127.0.0.1:{WEB_PORT} (gRPC {url})")

    def _merge_parts(self) -> None:
        if self.mode != "save" or self.path is None:
            return
        import rerun as rr
        from rerun.chunk import RrdReader

        from teleop.viz.dashboard import APPLICATION_ID, blueprint

        parts = sorted(self._parts_dir().glob("*.rrd"))
        rec = rr.RecordingStream(APPLICATION_ID, recording_id=self.recording_id,
                                 send_properties=False)
        rec.save(str(self.path), default_blueprint=blueprint())
        for part in parts:
            try:
                rr.send_chunks(RrdReader(part).stream(), recording=rec)
            except (ValueError, OSError) as exc:
                say(f"could not merge {part}: {exc}")
        rec.flush()
        rec.disconnect()
        shutil.rmtree(self._parts_dir(), ignore_errors=True)
        say(f"dashboard saved to {self.path}; open it with: rerun {self.path}")

    # -- processes ------------------------------------------------------------------------
    def command(self, role: str, epoch: float) -> list[str]:
        """The command line of ``role``'s child process."""
        cmd = [sys.executable, "-m", "teleop.cli", "run", role, *self.passthrough,
               "--dashboard", self._child_dashboard(role), "--recording-id", self.recording_id,
               "--epoch", repr(epoch), "--watch-stdin", "--wait-peers", repr(READY_TIMEOUT_S)]
        if self.stats_dir is not None:
            cmd += ["--stats-json", str(Path(self.stats_dir) / f"{role}.json")]
        if self.record_dir is not None:
            cmd += ["--record", str(self.record_dir)]
        return cmd

    def _pump(self, role: str, proc: subprocess.Popen[str]) -> None:
        assert proc.stdout is not None
        for line in proc.stdout:
            text = line.rstrip("\n")
            if text == f"ready {role}":
                with self._ready_cv:
                    self.ready[role] = time.monotonic()
                    self._ready_cv.notify_all()
            else:
                print(f"[{role}] {text}", flush=True)

    def _spawn(self, role: str, epoch: float) -> None:
        proc = subprocess.Popen(self.command(role, epoch), stdin=subprocess.PIPE,
                                stdout=subprocess.PIPE, text=True, bufsize=1,
                                start_new_session=True)
        self.procs[role] = proc
        threading.Thread(target=self._pump, args=(role, proc), daemon=True).start()

    def _wait_ready(self, t0: float) -> bool:
        deadline = time.monotonic() + READY_TIMEOUT_S
        announced: set[str] = set()
        with self._ready_cv:
            while True:
                for role in START_ORDER:
                    if role in self.ready and role not in announced:
                        announced.add(role)
                        say(f"{role} ready ({self.ready[role] - t0:.1f} s) "
                            f"[{len(announced)}/3]")
                if len(announced) == len(START_ORDER):
                    return True
                dead = [r for r, p in self.procs.items() if p.poll() is not None
                        and r not in self.ready]
                if dead or time.monotonic() > deadline:
                    why = f"{', '.join(dead)} exited" if dead else "timed out"
                    say(f"start-up failed: {why}")
                    return False
                self._ready_cv.wait(0.1)

    def _stop(self) -> dict[str, int]:
        for role in STOP_ORDER:
            proc = self.procs.get(role)
            if proc is not None and proc.poll() is None:
                with contextlib.suppress(ProcessLookupError):
                    proc.send_signal(signal.SIGINT)
        deadline = time.monotonic() + STOP_TIMEOUT_S
        codes: dict[str, int] = {}
        for role, proc in self.procs.items():
            try:
                codes[role] = proc.wait(max(deadline - time.monotonic(), 0.01))
            except subprocess.TimeoutExpired:
                say(f"{role} did not stop within {STOP_TIMEOUT_S} s; killing it")
                proc.kill()
                codes[role] = proc.wait()
            if proc.stdin is not None:
                with contextlib.suppress(OSError):
                    proc.stdin.close()
        return codes

    def run(self, duration_s: float | None) -> int:
        """Start everything, run for ``duration_s`` (or until Ctrl-C), stop; exit status."""
        t0 = time.monotonic()
        self._start_viewer()
        if self.mode == "save":
            try:
                self._parts_dir().mkdir(parents=True, exist_ok=True)
            except OSError as exc:
                raise UserInputError(f"{self.path}: cannot write the dashboard recording "
                                     f"({exc.strerror})") from None
        ok = True
        interrupted = False
        try:
            say(f"starting {', '.join(START_ORDER)} (session {self.cfg.session.name!r}, "
                f"controller {self.cfg.controller.kind!r})")
            for role in START_ORDER:
                self._spawn(role, t0)
            ok = self._wait_ready(t0)
            if ok:
                say("running" + (f" for {duration_s:g} s" if duration_s is not None
                                 else "; Ctrl-C to stop"))
                t_run = time.monotonic()
                end = None if duration_s is None else t_run + duration_s
                tty = sys.stdout.isatty()
                while end is None or time.monotonic() < end:
                    dead = [r for r, p in self.procs.items() if p.poll() is not None]
                    if dead:
                        say(f"{', '.join(dead)} exited early")
                        ok = False
                        break
                    if tty:  # a live elapsed-time line
                        total = f" / {duration_s:g}" if duration_s is not None else ""
                        print(f"\rteleop up: {time.monotonic() - t_run:5.1f}{total} s",
                              end="", flush=True)
                    time.sleep(0.05)
                if tty:
                    print(flush=True)
        except KeyboardInterrupt:
            interrupted = True
            say("interrupted, stopping")
        finally:
            codes = self._stop()
            self._merge_parts()
            if self._viewer is not None:
                self._viewer.flush()
                self._viewer.disconnect()
            if self._web is not None:  # the web viewer (its own process group) goes too
                with contextlib.suppress(ProcessLookupError):
                    os.killpg(self._web.pid, signal.SIGTERM)
                try:
                    self._web.wait(STOP_TIMEOUT_S)
                except subprocess.TimeoutExpired:
                    with contextlib.suppress(ProcessLookupError):
                        os.killpg(self._web.pid, signal.SIGKILL)
        bad = {r: c for r, c in codes.items() if c not in (0, -signal.SIGINT)}
        if bad:
            say("exit status: " + ", ".join(f"{r}={c}" for r, c in bad.items()))
        say(f"stopped ({'interrupted' if interrupted else 'done'})")
        return 0 if ok and not bad else 1
