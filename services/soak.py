"""``teleop faults --soak MINUTES``: the three services as ``teleop up`` starts them, over real
zenoh, for minutes, with the virtual operator grasping again and again and a fault every
``fault_every_s`` (default a minute), cycling through

* ``controller_restart``: the controller process SIGKILLed and a new one spawned at once;
* ``link_cut``: the hand's (then the master's) TCP link to the controller cut for
  :data:`FAULT_S` (a relay, :class:`services.link_proxy.LinkProxy`, closes the connections
  and refuses new ones; zenoh reconnects by itself);
* ``malformed_flood``: a separate zenoh peer puts malformed payloads at 1 kHz on the real
  keys of the hand's and the controller's inputs for :data:`FAULT_S`;
* ``stall``: one service (hand, controller, master in turn) SIGSTOPped for :data:`FAULT_S`,
  then SIGCONT.

Measured: crashes (a service that exits on its own, or a traceback on its stderr; it is
restarted so the soak goes on), RSS and threads of every process every few seconds
(/proc), loop lateness per window, the physical energy audit, every fault's recovery, the
flood's rejections.  Progress on stderr each minute.  Figures: :mod:`services.soak_report`.
"""

from __future__ import annotations

import contextlib
import os
import signal
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from services.launcher import START_ORDER, Launcher
from services.link_proxy import LinkProxy
from teleop.config import load_config

FAULT_S = 3.0
FAULT_KINDS: tuple[str, ...] = ("controller_restart", "link_cut", "malformed_flood", "stall")
CUT_TARGETS = ("hand", "master")
STALL_TARGETS = ("hand", "controller", "master")
SAMPLE_EVERY_S = 5.0
READY_TIMEOUT_S = 60.0
RECOVERY_LIMIT_S = 20.0


@dataclass
class Fault:
    """One injected fault (times in s from the session epoch)."""

    kind: str
    target: str
    start_s: float
    end_s: float = float("nan")
    injected: int = 0
    note: str = ""


@dataclass
class SoakRun:
    """What the parent saw: faults, crashes, process samples (figures come later)."""

    work: Path
    epoch: float
    faults: list[Fault] = field(default_factory=list)
    crashes: list[str] = field(default_factory=list)
    samples: list[tuple[float, str, int, float, int]] = field(default_factory=list)
    start_s: float = 0.0  # when all three were ready (latency windows count from here)
    duration_s: float = 0.0


def proc_figures(pid: int) -> tuple[float, int] | None:
    """(RSS in MB, threads) of a process from /proc (None if it is gone)."""
    try:
        text = Path(f"/proc/{pid}/status").read_text()
    except OSError:
        return None
    vals = dict(line.split(":", 1) for line in text.splitlines() if ":" in line)
    try:
        return int(vals["VmRSS"].split()[0]) / 1024.0, int(vals["Threads"])
    except (KeyError, ValueError, IndexError):
        return None


class Soak:
    """Runs the services, injects the faults, watches the processes."""

    def __init__(self, config: Path | None, overrides: list[str], *, realtime: bool,
                 port: int, work: Path) -> None:
        self.port = port
        self.session = f"soak{port}"
        sets = [*overrides, f"zenoh.endpoint=tcp/127.0.0.1:{port}",
                f"session.name={self.session}"]
        self.cfg = load_config(config, sets)
        passthrough = ([f"--config={config}"] if config else []) + [
            x for s in sets for x in ("--set", s)]
        if not realtime:
            passthrough.append("--no-realtime")
        self.launcher = Launcher(self.cfg, passthrough, dashboard_mode="off",
                                 dashboard_path=None, record_dir=None)
        self.proxies = {r: LinkProxy(port) for r in CUT_TARGETS}
        self.run = SoakRun(work, time.monotonic())
        self.procs: dict[str, subprocess.Popen[str]] = {}
        self.ready: dict[str, threading.Event] = {}
        self._stderr: list[Path] = []

    def now(self) -> float:
        """Seconds since the session epoch."""
        return time.monotonic() - self.run.epoch

    def spawn(self, role: str) -> None:
        """Start ``role`` (its master/hand through its relay)."""
        cmd = [*self.launcher.command(role, self.run.epoch), "--soak-log", str(self.run.work)]
        if role in self.proxies:
            cmd += ["--set", f"zenoh.endpoint=tcp/127.0.0.1:{self.proxies[role].port}"]
        err = self.run.work / f"{role}-{len(self._stderr)}.stderr"
        self._stderr.append(err)
        with open(err, "w") as f:
            proc = subprocess.Popen(cmd, stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                                    stderr=f, text=True, start_new_session=True)
        ev = threading.Event()
        self.procs[role], self.ready[role] = proc, ev

        def pump() -> None:
            assert proc.stdout is not None
            for line in proc.stdout:
                if line.strip() == f"ready {role}":
                    ev.set()

        threading.Thread(target=pump, daemon=True).start()

    def start(self) -> None:
        """Start the three services; raise if one is not ready in time."""
        for role in START_ORDER:
            self.spawn(role)
        deadline = time.monotonic() + READY_TIMEOUT_S
        for role in START_ORDER:
            if not self.ready[role].wait(max(0.0, deadline - time.monotonic())):
                raise RuntimeError(f"{role} did not start within {READY_TIMEOUT_S:g} s")

    def check_crashes(self) -> None:
        """A service that exited on its own is a crash: count it, start it again."""
        for role, proc in list(self.procs.items()):
            code = proc.poll()
            if code is not None:
                self.run.crashes.append(f"{role} exited with {code} at {self.now():.1f} s")
                self.spawn(role)

    def sample(self) -> None:
        """RSS and threads of every running service."""
        t = self.now()
        for role, proc in self.procs.items():
            fig = proc_figures(proc.pid)
            if fig is not None:
                self.run.samples.append((t, role, proc.pid, fig[0], fig[1]))

    def inject(self, k: int, wait: Callable[[float], None]) -> Fault:
        """The ``k``-th fault (kinds and targets in turn); returns when it has ended."""
        kind = FAULT_KINDS[k % len(FAULT_KINDS)]
        n = k // len(FAULT_KINDS)
        f = Fault(kind, "controller", self.now())
        if kind == "controller_restart":
            proc = self.procs["controller"]
            proc.kill()
            proc.wait()
            self.spawn("controller")
            f.end_s = self.now()
            if not self.ready["controller"].wait(READY_TIMEOUT_S):
                f.note = "the new controller did not start"
        elif kind == "link_cut":
            f.target = CUT_TARGETS[n % len(CUT_TARGETS)]
            self.proxies[f.target].cut()
            wait(FAULT_S)
            self.proxies[f.target].restore()
            f.end_s = self.now()
        elif kind == "malformed_flood":
            f.target = "hand+controller"
            f.injected, f.note, f.start_s = self._flood(int(FAULT_S * 1000), f.start_s)
            f.end_s = self.now()
        else:
            f.target = STALL_TARGETS[n % len(STALL_TARGETS)]
            pid = self.procs[f.target].pid
            os.kill(pid, signal.SIGSTOP)
            try:
                wait(FAULT_S)
            finally:
                os.kill(pid, signal.SIGCONT)
            f.end_s = self.now()
        self.run.faults.append(f)
        return f

    def _flood(self, n: int, t_spawn: float) -> tuple[int, str, float]:
        """Run the flooder: (payloads sent, a note, when its session was up)."""
        cmd = [sys.executable, "-m", "services.faults_live", "flood", "--session",
               self.session, "--connect", f"tcp/127.0.0.1:{self.port}", "--n", str(n)]
        p = subprocess.Popen(cmd, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE,
                             stderr=subprocess.DEVNULL, text=True)
        assert p.stdout is not None
        start, sent = t_spawn, 0
        try:
            for line in p.stdout:  # READY once its session is open (start-up not counted)
                if line.startswith("READY"):
                    start = self.now()
                elif line.startswith("SENT "):
                    sent = int(line.split()[1])
            code = p.wait(READY_TIMEOUT_S)
        except subprocess.TimeoutExpired:
            p.kill()
            code = p.wait()
        return sent, "" if sent else f"the flooder exited with {code}", start

    def stop(self) -> dict[str, int]:
        """SIGINT in the order ``teleop up`` uses, wait, kill stragglers; exit statuses."""
        for proc in self.procs.values():
            with contextlib.suppress(ProcessLookupError):
                os.kill(proc.pid, signal.SIGCONT)  # never leave one stopped
        codes: dict[str, int] = {}
        for role in ("master", "hand", "controller"):
            proc = self.procs.get(role)
            if proc is not None and proc.poll() is None:
                proc.send_signal(signal.SIGINT)
        for role, proc in self.procs.items():
            try:
                codes[role] = proc.wait(10.0)
            except subprocess.TimeoutExpired:
                proc.kill()
                codes[role] = proc.wait()
            if proc.stdin is not None:
                with contextlib.suppress(OSError):
                    proc.stdin.close()
        for p in self.proxies.values():
            p.close()
        return codes

    def tracebacks(self) -> list[str]:
        """Stderr files of the services that hold a Python traceback."""
        return [p.name for p in self._stderr
                if p.exists() and "Traceback (most recent call last)" in p.read_text()]


def run_soak(config: Path | None, overrides: list[str], minutes: float, *,
             fault_every_s: float = 60.0, realtime: bool = True,
             progress: Callable[[str], None] | None = None,
             work_dir: Path | None = None) -> dict[str, Any]:
    """Run a soak; the JSON document (see :func:`services.soak_summary.summarise`)."""
    from services.bench import free_port
    from services.soak_summary import summarise

    say = progress or (lambda _text: None)
    with contextlib.ExitStack() as stack:
        work = work_dir or Path(stack.enter_context(
            tempfile.TemporaryDirectory(prefix="teleop-soak-")))
        soak = Soak(config, overrides, realtime=realtime, port=free_port(), work=work)
        duration = minutes * 60.0
        codes: dict[str, int] = {}
        stopped: dict[str, Any] = {"flag": False}

        def wait(s: float) -> None:
            end = time.monotonic() + s
            while (left := end - time.monotonic()) > 0:
                time.sleep(min(left, 0.2))

        try:
            soak.start()
            say(f"started (session {soak.session}); {minutes:g} min, a fault every "
                f"{fault_every_s:g} s")
            t_run = soak.run.start_s = soak.now()
            next_fault = t_run + fault_every_s / 2.0
            next_sample = t_run
            next_report = t_run + 60.0
            k = 0
            while (t := soak.now()) < t_run + duration:
                soak.check_crashes()
                if t >= next_sample:
                    soak.sample()
                    next_sample += SAMPLE_EVERY_S
                if t >= next_fault and t + FAULT_S < t_run + duration:
                    f = soak.inject(k, wait)
                    say(f"fault {k + 1}: {f.kind} ({f.target}) {f.start_s:.1f}-{f.end_s:.1f} s"
                        + (f", {f.note}" if f.note else ""))
                    k += 1  # a fault that overran its slot leaves the services half a slot
                    next_fault = max(next_fault + fault_every_s, soak.now() + fault_every_s / 2)
                if t >= next_report:
                    say(_minute_line(soak, t - t_run, duration))
                    next_report += 60.0
                time.sleep(0.2)
            soak.run.duration_s = soak.now() - t_run
            wait(min(RECOVERY_LIMIT_S, 2.0))
        except KeyboardInterrupt:
            stopped["flag"] = True
            soak.run.duration_s = soak.now()
        finally:
            codes = soak.stop()
        return summarise(soak.run, soak.cfg, codes, soak.tracebacks(), minutes=minutes,
                         fault_every_s=fault_every_s, interrupted=stopped["flag"])


def _minute_line(soak: Soak, elapsed_s: float, duration_s: float) -> str:
    last = {role: (rss, thr) for _, role, _pid, rss, thr in soak.run.samples}
    mem = ", ".join(f"{r} {v[0]:.0f} MB/{v[1]} thr" for r, v in sorted(last.items()))
    return (f"{elapsed_s / 60:.0f}/{duration_s / 60:.0f} min: {len(soak.run.faults)} faults, "
            f"{len(soak.run.crashes)} crashes; {mem}")
