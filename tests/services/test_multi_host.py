"""A real multi-host run: the secure commands of ``docs/multi-machine.md``, across network
namespaces.

Two network namespaces made by this test stand for the two machines: A (the operator's desk,
10.77.0.1) and B (the NUC, 10.77.0.2), joined by a veth pair; the addresses are a private
range that exists only inside these namespaces.  The commands are read from the page's
"Secure mode across machines" section (``teleop certs``, then ``teleop run controller`` and
``teleop run hand`` in B, ``teleop run master`` in A), the page's ``10.0.0.2`` replaced by
B's address.  Each machine runs in a working directory of its own holding
``config/secure.toml`` and only its own certificate files.  Added to the page's commands:
``links.master_controller.delay_s`` (the injected delay) on both ends of that link, a
duration, a peer timeout and ``--no-realtime`` (this machine is shared).

Then, from the recordings of both machines: a grasp completed (the hand closed on the object,
the master displayed the force), and the achieved delays match the injected ones.  With
``zenoh.shared_clock=false`` a delay counts from a message's arrival, so the recorded delay is
the time the receiving delay line held a message until the receiver's loop took it: the
injected delay plus at most one loop period (1 ms at 1 kHz) and the scheduling lateness of a
loop on a busy two-core machine.  The veth link's own latency (tens of microseconds) is not in
it; the controller's round trip, measured on its own clock from the echoes, includes it and is
checked too.

Root only (``ip netns``); skipped with the reason elsewhere.  Namespaces and processes are
removed whatever happens.
"""

from __future__ import annotations

import os
import re
import shlex
import shutil
import signal
import subprocess
import sys
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest

from teleop.recording import Recording, read_recording

pytestmark = [pytest.mark.network, pytest.mark.slow]

REPO = Path(__file__).resolve().parents[2]
DOC = REPO / "docs" / "multi-machine.md"
SECTION = "### Secure mode across machines"
DOC_HOST = "10.0.0.2"
ADDR_A, ADDR_B, PREFIX = "10.77.0.1", "10.77.0.2", 24
DELAY_S = 0.05  # injected one way on the master <-> controller link
DURATION_S = 16.0
#: recorded delay beyond the injected one: one loop period (1 ms) plus loop lateness on a
#: shared, busy machine without real-time priority (a few ms; 5 ms is generous for a median)
MEDIAN_TOL_S = 0.005


@dataclass(frozen=True)
class DocCommands:
    """The commands of the page's secure section, in the page's order."""

    certs: list[str]
    runs: dict[str, list[str]]  # role -> argv (without the leading ``teleop``)


def doc_commands(text: str) -> DocCommands:
    """The ``teleop`` commands of the secure section's ``sh`` blocks."""
    start = text.index(SECTION)
    end = text.find("\n### ", start + len(SECTION))
    section = text[start:end if end >= 0 else None]
    certs: list[str] = []
    runs: dict[str, list[str]] = {}
    for block in re.findall(r"```sh\n(.*?)```", section, flags=re.S):
        for line in block.replace("\\\n", " ").splitlines():
            argv = shlex.split(line)
            if argv[:2] == ["teleop", "certs"]:
                certs = argv[1:]
            elif argv[:2] == ["teleop", "run"]:
                runs[argv[2]] = argv[1:]
    return DocCommands(certs, runs)


def _teleop() -> list[str]:
    """The ``teleop`` command of this interpreter's environment."""
    script = Path(sys.executable).parent / "teleop"
    return [str(script)] if script.exists() else [sys.executable, "-m", "teleop.cli"]


def _ip(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(["ip", *args], capture_output=True, text=True, timeout=10)


@pytest.fixture
def namespaces() -> Iterator[tuple[str, str]]:
    """Two namespaces joined by a veth pair, A at ADDR_A and B at ADDR_B; removed after."""
    if os.geteuid() != 0:
        pytest.skip("network namespaces need root (ip netns add)")
    if shutil.which("ip") is None:
        pytest.skip("no 'ip' command (iproute2) to make network namespaces")
    tag = f"t17-{os.getpid()}"
    ns_a, ns_b = f"{tag}-a", f"{tag}-b"
    made: list[str] = []
    try:
        for ns in (ns_a, ns_b):
            r = _ip("netns", "add", ns)
            if r.returncode != 0:
                pytest.skip(f"network namespaces not permitted here: {r.stderr.strip()}")
            made.append(ns)
        steps = [("-n", ns_a, "link", "set", "lo", "up"), ("-n", ns_b, "link", "set", "lo", "up"),
                 ("-n", ns_a, "link", "add", "veth-a", "type", "veth", "peer", "name", "veth-b",
                  "netns", ns_b),
                 ("-n", ns_a, "addr", "add", f"{ADDR_A}/{PREFIX}", "dev", "veth-a"),
                 ("-n", ns_b, "addr", "add", f"{ADDR_B}/{PREFIX}", "dev", "veth-b"),
                 ("-n", ns_a, "link", "set", "veth-a", "up"),
                 ("-n", ns_b, "link", "set", "veth-b", "up")]
        for step in steps:
            r = _ip(*step)
            if r.returncode != 0:
                pytest.skip(f"cannot set up the veth link (ip {' '.join(step)}): "
                            f"{r.stderr.strip()}")
        yield ns_a, ns_b
    finally:
        for ns in made:  # deleting a namespace removes its end of the veth pair too
            _ip("netns", "del", ns)


def _machine_dir(root: Path, certs: Path, files: list[str]) -> Path:
    """A machine's working directory: ``config/secure.toml`` and its own ``certs/``."""
    (root / "config").mkdir(parents=True)
    shutil.copy(REPO / "config" / "secure.toml", root / "config" / "secure.toml")
    (root / "certs").mkdir()
    for name in files:
        shutil.copy2(certs / name, root / "certs" / name)
    return root


def _stop(procs: list[subprocess.Popen[str]]) -> None:
    for proc in procs:
        if proc.poll() is None:
            proc.send_signal(signal.SIGINT)
    for proc in procs:
        try:
            proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait(timeout=10)


def _finite(rec: Recording, name: str) -> np.ndarray:
    v = rec.column(name)
    return v[np.isfinite(v)]


def test_the_page_has_the_secure_commands() -> None:
    # read without root too: the page keeps the commands the namespaced run executes
    cmds = doc_commands(DOC.read_text(encoding="utf-8"))
    assert cmds.certs == ["certs", "certs", "--hostname", DOC_HOST]
    assert cmds.runs["controller"][-3:] == ["zenoh.endpoint=tls/0.0.0.0:7447", "--record",
                                            "runs/today"]
    assert f"zenoh.endpoint=tls/{DOC_HOST}:7447" in cmds.runs["master"]
    assert "zenoh.endpoint=tls/127.0.0.1:7447" in cmds.runs["hand"]


def test_secure_multi_host_run_grasps_with_the_injected_delay(
        namespaces: tuple[str, str], tmp_path: Path) -> None:
    ns_a, ns_b = namespaces
    cmds = doc_commands(DOC.read_text(encoding="utf-8"))
    assert cmds.certs and set(cmds.runs) == {"controller", "hand", "master"}, cmds
    for argv in cmds.runs.values():  # what this test is about: secure, separate clocks
        assert "config/secure.toml" in argv and "zenoh.shared_clock=false" in argv, argv
        assert any(a.startswith("zenoh.endpoint=tls/") for a in argv), argv

    def here(argv: list[str]) -> list[str]:
        return [a.replace(DOC_HOST, ADDR_B) for a in argv]

    admin = tmp_path / "admin"
    admin.mkdir()
    made = subprocess.run(_teleop() + here(cmds.certs), cwd=admin, capture_output=True,
                          text=True, timeout=60)
    assert made.returncode == 0, made.stderr
    certs = admin / "certs"
    own = ["pem", "key", "credentials"]
    machine_b = _machine_dir(tmp_path / "B", certs, ["ca.pem", "credentials.txt"]
                             + [f"{r}.{x}" for r in ("controller", "hand") for x in own])
    machine_a = _machine_dir(tmp_path / "A", certs, ["ca.pem"] + [f"master.{x}" for x in own])
    extra = ["--duration", f"{DURATION_S:g}", "--wait-peers", "30", "--no-realtime"]
    delay = ["--set", f"links.master_controller.delay_s={DELAY_S:g}"]
    where = {"controller": (ns_b, machine_b), "hand": (ns_b, machine_b),
             "master": (ns_a, machine_a)}
    procs: list[subprocess.Popen[str]] = []
    outs: dict[str, tuple[str, str]] = {}
    try:
        for role in ("controller", "hand", "master"):  # the listening controller first
            ns, cwd = where[role]
            argv = here(cmds.runs[role]) + extra + (delay if role != "hand" else [])
            procs.append(subprocess.Popen(
                ["ip", "netns", "exec", ns, "nice", "-n", "10", *_teleop(), *argv],
                cwd=cwd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True))
        for role, proc in zip(("controller", "hand", "master"), procs, strict=True):
            try:
                outs[role] = proc.communicate(timeout=DURATION_S + 40)
            except subprocess.TimeoutExpired:
                raise AssertionError(f"{role} did not stop by itself") from None
    finally:
        _stop(procs)
    for role, proc in zip(("controller", "hand", "master"), procs, strict=True):
        assert proc.returncode == 0, f"{role}: {outs[role][1][-2000:]}"

    master = read_recording(machine_a / "runs" / "today" / "master.csv")
    ctrl = read_recording(machine_b / "runs" / "today" / "controller.csv")
    hand = read_recording(machine_b / "runs" / "today" / "hand.csv")
    assert master.t_s[-1] > DURATION_S - 1 and hand.t_s[-1] > DURATION_S - 1

    # a grasp completed: the trigger closed, the fingers closed on the object and pressed
    # it, and the master displayed the force (the whole loop, both machines, ran)
    pressure = np.column_stack([hand.column(f"pressure_f{i // 9 + 1}_{i % 9}")
                                for i in range(27)])
    peak_pressure = float(np.nanmax(pressure))
    closed = float(np.nanmax(hand.column("proximal_angle_rad_f1")))
    peak_row = np.nanmax(pressure, axis=1)
    touched = np.flatnonzero(peak_row > 100)
    released = bool(len(touched)) and bool(np.any(peak_row[touched[0]:] < 20))
    peak_force = float(np.nanmax(master.column("displayed_force_n")))
    trigger = float(np.nanmax(master.column("trigger_position_m")))

    # achieved delays: controller -> master (master's delay_s), master -> controller
    # (the controller's master_delay_s); the hand's link had none injected
    to_master = _finite(master, "delay_s")
    to_ctrl = _finite(ctrl, "master_delay_s")
    to_hand = _finite(hand, "delay_s")
    rtt = _finite(ctrl, "round_trip_s")
    figures = {
        "peak_pressure": peak_pressure, "finger_closed_rad": closed,
        "peak_displayed_force_n": peak_force, "trigger_max_m": trigger, "released": released,
        **{f"{name}_{q}_ms": float(np.percentile(v, p)) * 1e3
           for name, v in (("ctrl_to_master", to_master), ("master_to_ctrl", to_ctrl),
                           ("ctrl_to_hand", to_hand))
           for q, p in (("min", 0), ("median", 50), ("p99", 99), ("max", 100))},
        "round_trip_median_ms": float(np.median(rtt)) * 1e3,
        "round_trip_min_ms": float(np.min(rtt)) * 1e3,
        "samples": {"master": len(master), "controller": len(ctrl), "hand": len(hand)},
    }
    print(figures)

    assert trigger > 0.02  # the operator closed the trigger (travel 25 mm)
    assert peak_pressure > 100  # the fingers pressed the object (noise floor 6)
    assert closed > 0.1  # the finger closed onto the cylinder (it touches at ~0.14 rad)
    assert released  # and let go again: the grasp completed
    assert peak_force > 0.5  # and the master displayed the force [N]

    for name, v in (("controller->master", to_master), ("master->controller", to_ctrl)):
        assert len(v) > 1000, name  # most ticks got a message (1 kHz for 16 s)
        # released no earlier than injected (the delay line counts from arrival) ...
        assert v.min() >= DELAY_S - 1e-6, (name, figures)
        # ... and, typically, within a loop period and scheduling lateness of it
        assert np.median(v) <= DELAY_S + MEDIAN_TOL_S, (name, figures)
    # no delay injected towards the hand: held for at most a few of the hand's loop
    # lateness (the hand's 40 Hz loop takes the latest command at its tick: < 25 ms)
    assert np.median(to_hand) < 0.025, figures
    # the controller's round trip (its own clock, the real links included) holds the master
    # leg's 2 x 50 ms; on top come the hand leg and the holds (the hand's and the
    # controller's hold of hand states, each up to the hand's 25 ms period; measured
    # 35-65 ms) and loop lateness on a loaded machine, the estimate being a 200 ms running max
    assert 2 * DELAY_S <= np.median(rtt) <= 2 * DELAY_S + 0.15, figures
