"""Live fault scenarios: the three services as spawned processes over real zenoh.

* ``malformed_flood``: a separate flooder process (``python -m services.faults_live flood``)
  opens its own zenoh session and puts malformed payloads at 1 kHz on the real keys of the
  hand's input (``hand_command``) and the controller's (``master_state``, ``hand_state``),
  while the operator keeps the trigger open: the hand's set-point must stay exactly open,
  and every payload that arrives must be rejected (counted per reason by the services'
  buses, written to their ``--stats-json`` at exit).
* ``controller_restart``: mid-grasp the controller process is SIGKILLed and a new one is
  spawned at once: the hand holds still while it is gone and resumes once the new one runs.

Figures come from the services' recordings (``--record``): joint limits (hand set-points),
the energy balance of the controllers' ledgers (master and hand ports against the tanks'
initial energy; live mode has no physical audit - the services run as real processes - so
its results say so, ``audit``, and carry no ``passive_audit`` verdict), recovery
(live: from the end of the fault until the hand's command watchdog is clear again for
0.25 s, so a restart includes the new process's start-up), and exit statuses (nothing
crashes).  Processes are spawned (``sys.executable``), never forked.
"""

from __future__ import annotations

import argparse
import contextlib
import math
import signal
import socket
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import numpy as np

from services.faults import ScenarioResult, SuiteResult
from teleop.analysis.faults import energy_violations, malformed_payload
from teleop.config import TeleopConfig, load_config

LIVE_SCENARIOS: tuple[str, ...] = ("malformed_flood", "controller_restart")
BASE_OVERRIDES: tuple[str, ...] = ("master.virtual.repeat=false",)
READY_TIMEOUT_S = 60.0
_FLOOD_SIGNALS = ("hand_command", "master_state", "hand_state")


def _free_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


class _Service:
    """One spawned ``teleop run ROLE`` process."""

    def __init__(self, role: str, args: list[str], work: Path, epoch: float, tag: str) -> None:
        self.role = role
        self.stats = work / f"{role}{tag}.json"
        cmd = [sys.executable, "-m", "teleop.cli", "run", role, *args, "--dashboard", "off",
               "--record", str(work / f"rec{tag}"), "--epoch", repr(epoch), "--watch-stdin",
               "--wait-peers", repr(READY_TIMEOUT_S), "--stats-json", str(self.stats),
               "--no-realtime"]
        self.proc = subprocess.Popen(cmd, stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                                     stderr=subprocess.DEVNULL, text=True,
                                     start_new_session=True)
        self.ready = threading.Event()
        threading.Thread(target=self._pump, daemon=True).start()

    def _pump(self) -> None:
        assert self.proc.stdout is not None
        for line in self.proc.stdout:
            if line.strip() == f"ready {self.role}":
                self.ready.set()

    def stop(self, timeout_s: float = 5.0) -> int:
        """SIGINT, wait, SIGKILL if needed; the exit status."""
        if self.proc.poll() is None:
            with contextlib.suppress(ProcessLookupError):
                self.proc.send_signal(signal.SIGINT)
        try:
            code = self.proc.wait(timeout_s)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            code = self.proc.wait()
        if self.proc.stdin is not None:
            with contextlib.suppress(OSError):
                self.proc.stdin.close()
        return code

    def kill(self) -> int:
        """SIGKILL (a crash of this service)."""
        self.proc.kill()
        code = self.proc.wait()
        if self.proc.stdin is not None:
            with contextlib.suppress(OSError):
                self.proc.stdin.close()
        return code

    def rejects(self) -> dict[str, int]:
        """Per-reason rejections from the stats file written at exit."""
        import json

        if not self.stats.exists():
            return {}
        d = json.loads(self.stats.read_text())
        return {k[len("rejects_"):]: int(v) for k, v in d.items() if k.startswith("rejects_")}


def _read(path: Path) -> dict[str, np.ndarray]:
    from teleop.recording import read_recording

    rec = read_recording(path)
    return {c: rec.column(c) for c in rec.columns}


def _cols(d: dict[str, np.ndarray], prefix: str) -> np.ndarray:
    keys = sorted(k for k in d if k.startswith(prefix))
    return np.column_stack([d[k] for k in keys]) if keys else np.empty((0, 0))


def _flood_main(argv: list[str]) -> int:
    """``python -m services.faults_live flood``: put malformed payloads on the real keys."""
    import zenoh

    from teleop.transport.keys import data_key
    from teleop.transport.zenoh_bus import zenoh_config

    p = argparse.ArgumentParser(prog="python -m services.faults_live flood")
    p.add_argument("--session", required=True)
    p.add_argument("--connect", required=True)
    p.add_argument("--n", type=int, default=10_000)
    p.add_argument("--rate-hz", type=float, default=1000.0)
    a = p.parse_args(argv)
    session = zenoh.open(zenoh_config("client", [], [a.connect]))
    pubs = {s: session.declare_publisher(data_key(a.session, s)) for s in _FLOOD_SIGNALS}
    print("READY", flush=True)
    time.sleep(0.5)  # let the routes establish
    t0 = time.monotonic()
    sent = {s: 0 for s in _FLOOD_SIGNALS}
    for i in range(a.n):
        target = t0 + i / a.rate_hz
        while (now := time.monotonic()) < target:
            time.sleep(min(target - now, 5e-4))
        pubs["hand_command"].put(malformed_payload(i, "hand_command")[1])
        sig = "master_state" if i % 2 == 0 else "hand_state"
        pubs[sig].put(malformed_payload(i, sig)[1])
        sent["hand_command"] += 1
        sent[sig] += 1
    for pub in pubs.values():
        pub.undeclare()
    session.close()
    print(f"SENT {sum(sent.values())} {time.monotonic() - t0:.3f}", flush=True)
    return 0


def _energy_margin(cfg: TeleopConfig, m: dict[str, np.ndarray], h: dict[str, np.ndarray]
                   ) -> np.ndarray:
    """Bound minus delivered on the master's time base (hand accounts held between rows)."""
    from teleop.control.interface import control_params

    initial = 2.0 * control_params(cfg.controller).initial_j  # master and hand tanks
    idx = np.clip(np.searchsorted(h["t_s"], m["t_s"], side="right") - 1, 0, None)
    h_in = np.where(m["t_s"] >= h["t_s"][0], h["port_in_j"][idx], 0.0)
    h_out = np.where(m["t_s"] >= h["t_s"][0], h["port_out_j"][idx], 0.0)
    return initial + m["port_in_j"] + h_in - m["port_out_j"] - h_out


def _run_one(name: str, config: Path | None, overrides: list[str], short: bool,
             seed: int) -> ScenarioResult:
    t_wall = time.perf_counter()
    port = _free_port()
    session = f"faults{port}"
    n_flood = 1000 if short else 10_000
    flood_s = n_flood / 1000.0
    if name == "malformed_flood":
        scene = ["master.virtual.close_s=1000"]  # the trigger stays open all along
        duration = flood_s + 4.0
        what = f"{n_flood} malformed payloads at 1 kHz from a zenoh peer on the real keys"
    else:
        scene = []
        duration = 5.0
        what = "SIGKILL the controller process mid-grasp, spawn a new one at once"
    sets = [*BASE_OVERRIDES, *overrides, *scene, f"zenoh.endpoint=tcp/127.0.0.1:{port}",
            f"session.name={session}", f"session.seed={seed}"]
    args = ([f"--config={config}"] if config else []) + [x for s in sets for x in ("--set", s)]
    cfg = load_config(config, sets)
    failures: list[str] = []
    crashed = ""
    injected = 0
    codes: dict[str, int] = {}
    fault_start = fault_end = math.nan
    rejects: dict[str, int] = {}
    with tempfile.TemporaryDirectory(prefix="teleop-faults-") as tmp:
        work = Path(tmp)
        epoch = time.monotonic()
        svcs = {r: _Service(r, args, work, epoch, "") for r in ("controller", "hand", "master")}
        flooder: subprocess.Popen[str] | None = None
        try:
            deadline = time.monotonic() + READY_TIMEOUT_S
            for s in svcs.values():
                if not s.ready.wait(max(0.0, deadline - time.monotonic())):
                    raise RuntimeError(f"{s.role} did not start")
            t_run = time.monotonic()
            if name == "malformed_flood":
                time.sleep(1.0)
                flooder = subprocess.Popen(
                    [sys.executable, "-m", "services.faults_live", "flood", "--session",
                     session, "--connect", f"tcp/127.0.0.1:{port}", "--n", str(n_flood)],
                    stdin=subprocess.DEVNULL, stdout=subprocess.PIPE, text=True)
                out, _ = flooder.communicate(timeout=READY_TIMEOUT_S + flood_s * 3)
                fault_end = time.monotonic() - epoch
                fault_start = fault_end - flood_s
                for line in out.splitlines():
                    if line.startswith("SENT "):
                        injected = int(line.split()[1])
                if flooder.returncode != 0:
                    failures.append(f"the flooder exited with {flooder.returncode}")
            else:
                time.sleep(2.5)  # closing over 0.5-1.5 s from the master's start, then hold
                fault_start = time.monotonic() - epoch
                codes["controller(killed)"] = svcs["controller"].kill()
                svcs["controller"] = _Service("controller", args, work, epoch, "2")
                fault_end = time.monotonic() - epoch
                if not svcs["controller"].ready.wait(READY_TIMEOUT_S):
                    failures.append("the restarted controller did not start")
            time.sleep(max(0.0, duration - (time.monotonic() - t_run)))
        except Exception as exc:
            crashed = f"{type(exc).__name__}: {exc}"
            failures.append(f"crashed: {crashed}")
        finally:
            if flooder is not None and flooder.poll() is None:
                flooder.kill()
                flooder.wait()
            for role in ("master", "hand", "controller"):
                codes[role] = svcs[role].stop()
        for role in ("hand", "controller"):
            for k, v in svcs[role].rejects().items():
                rejects[k] = rejects.get(k, 0) + v
        bad = {r: c for r, c in codes.items()
               if c not in (0, -signal.SIGINT) and r != "controller(killed)"}
        if bad:
            failures.append("exit status " + ", ".join(f"{r}={c}" for r, c in bad.items()))
        rec_dir = work / "rec"
        h = _read(rec_dir / "hand.csv") if (rec_dir / "hand.csv").exists() else {}
        m = _read(rec_dir / "master.csv") if (rec_dir / "master.csv").exists() else {}
    return _judge(name, what, cfg, h, m, fault_start, fault_end, injected, rejects, failures,
                  crashed, time.perf_counter() - t_wall)


#: why a live scenario has no physical energy audit (reported instead of a verdict)
LIVE_NO_AUDIT = ("none: live mode runs real processes, no simulated physics to audit; "
                 "the energy check is the ledgers' only")


def _judge(name: str, what: str, cfg: TeleopConfig, h: dict[str, np.ndarray],
           m: dict[str, np.ndarray], fault_start: float, fault_end: float, injected: int,
           rejects: dict[str, int], failures: list[str], crashed: str,
           wall_s: float) -> ScenarioResult:
    viol = e_viol = trips = 0
    margin = rec = math.nan
    moved = False
    n_applied = 0
    if not h or not m:
        failures.append("no recording")
    else:
        sp = _cols(h, "setpoint_rad")
        n_applied = int(sp.shape[0])
        travel = cfg.hand.dynamixel.finger_travel_rad
        viol = int(np.count_nonzero(~np.isfinite(sp) | (sp < -1e-9) | (sp > travel + 1e-9)))
        mg = _energy_margin(cfg, m, h)
        e_viol = energy_violations(mg)
        margin = float(np.min(mg))
        wd = h.get("watchdog", np.zeros_like(h["t_s"]))
        trips = int(np.count_nonzero(np.diff(wd) > 0.5))
        t = h["t_s"]
        if name == "malformed_flood":
            moved = bool(np.max(np.abs(sp)) > 0.0)
            if moved:
                failures.append("the hand set-point moved during the malformed flood")
            if sum(rejects.values()) < 0.9 * injected:
                failures.append(f"only {sum(rejects.values())} of {injected} payloads "
                                "rejected")
            rec = 0.0
        else:
            timeout = 1.0  # generous: process kill and liveliness loss, in real time
            w = (t > fault_start + timeout) & (t < fault_end)
            if np.any(w) and np.max(np.ptp(sp[w], axis=0)) > 1e-9:
                moved = True
                failures.append("the hand moved while the controller was gone")
            clear = (t >= fault_end) & (wd < 0.5)
            rec = math.inf
            for i in np.nonzero(clear)[0]:
                j = np.nonzero((t >= t[i]) & (t <= t[i] + 0.25))[0]
                if np.all(wd[j] < 0.5) and t[-1] >= t[i] + 0.25:
                    rec = float(t[i] - fault_end)
                    break
            if not rec <= 10.0:
                failures.append("the hand never got valid commands again")
        if viol:
            failures.append(f"{viol} set-points outside the joint limits")
        if e_viol:
            failures.append(f"energy ledgers: balance violated at {e_viol} samples")
    return ScenarioResult(
        name=name, what=what, mode="live", ok=not failures, failures=tuple(failures),
        crashed=crashed, fault_start_s=fault_start, fault_end_s=fault_end, injected=injected,
        rejected=sum(rejects.values()), rejects_by_reason=tuple(sorted(rejects.items())),
        energy_violations=e_viol, min_energy_margin_j=margin, recovery_s=rec,
        joint_limit_violations=viol, applied_commands=n_applied, moved_on_invalid=moved,
        watchdog_trips=trips, wall_s=wall_s, no_audit=LIVE_NO_AUDIT)


def run_live_suite(config: Path | None, overrides: list[str], *, short: bool = False,
                   seed: int = 1, names: tuple[str, ...] | None = None) -> SuiteResult:
    """Run the live scenarios (all, or ``names``) one after the other."""
    chosen = [n for n in LIVE_SCENARIOS if names is None or n in names]
    results = tuple(_run_one(n, config, list(overrides), short, seed) for n in chosen)
    return SuiteResult("live", short, seed, results)


if __name__ == "__main__":
    if len(sys.argv) > 1 and sys.argv[1] == "flood":
        sys.exit(_flood_main(sys.argv[2:]))
    sys.exit("usage: python -m services.faults_live flood --session S --connect EP")
