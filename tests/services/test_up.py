"""`teleop up` end to end over real zenoh on loopback, and the CLI's one-line errors."""

from __future__ import annotations

import socket
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from teleop.commands.up import resolve_dashboard
from teleop.errors import UserInputError
from teleop.recording import Recording, read_recording


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def teleop(*args: str, timeout: float = 120.0) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "teleop.cli", *args], capture_output=True,
                          text=True, timeout=timeout)


def initial_j(rec: Recording, store: str = "tank_j") -> float:
    """From the ledger identity tank = initial + in + received - out - sent - dissipated."""
    c = rec.column
    port_in = c("port_in_j") if rec.has("port_in_j") else 0.0
    port_out = c("port_out_j") if rec.has("port_out_j") else 0.0
    init = (c(store) - port_in - c("received_j") + port_out + c("sent_j") + c("dissipated_j"))
    assert np.ptp(init) < 1e-5  # the accounts balance at every sample (CSV: 9 digits)
    return float(init[0])


@pytest.fixture(scope="module")
def up_run(tmp_path_factory: pytest.TempPathFactory) -> tuple[subprocess.CompletedProcess[str],
                                                            Path, Path, float]:
    tmp = tmp_path_factory.mktemp("up")
    rrd, rec = tmp / "dash.rrd", tmp / "rec"
    port = free_port()
    t0 = time.monotonic()
    proc = teleop("up", "--duration", "5", "--dashboard", f"save:{rrd}", "--record", str(rec),
                  "--set", f"zenoh.endpoint=tcp/127.0.0.1:{port}",
                  "--set", f"session.name=uptest{port}")
    return proc, rrd, rec, time.monotonic() - t0


@pytest.mark.network
@pytest.mark.slow
def test_up_exits_cleanly(up_run: tuple[subprocess.CompletedProcess[str], Path, Path, float]
                          ) -> None:
    proc, _, _, _ = up_run
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert "ready (" in proc.stdout and "[3/3]" in proc.stdout
    assert "did not stop" not in proc.stdout
    assert "Traceback" not in proc.stderr


@pytest.mark.network
@pytest.mark.slow
def test_rrd_holds_one_recording_with_data_at_every_dashboard_path(
        up_run: tuple[subprocess.CompletedProcess[str], Path, Path, float]) -> None:
    from rerun.chunk import RrdReader

    from teleop.viz.dashboard import DASHBOARD_PATHS, PHYSICS_PATHS

    _, rrd, _, _ = up_run
    reader = RrdReader(rrd)
    assert len(reader.recordings()) == 1 and len(reader.blueprints()) == 1
    found = {ch.entity_path.lstrip("/") for ch in reader.stream()
             if not ch.is_static and ch.num_rows > 0}
    missing = [p for p in (*DASHBOARD_PATHS, *PHYSICS_PATHS) if p not in found]
    assert not missing, f"no data at {missing}"
    assert not rrd.with_name(rrd.name + ".parts").exists()  # parts merged and removed


@pytest.mark.network
@pytest.mark.slow
def test_recordings_show_the_grasp_and_the_energy_balance(
        up_run: tuple[subprocess.CompletedProcess[str], Path, Path, float]) -> None:
    """The run's three recordings: the operator closes, the hand grasps on time, the
    operator feels it, the energy balances.  A non-strict xfail from 2026-11-25 to 11-29
    (it failed in about 1 run of 4): the hand read its sensors up to 0.5 s late and dropped
    deadlines while the dashboard (saved to a file here) logged from its loop; since the
    dashboard's signals go as columns, its pictures at 10 Hz and its types set up before the
    loop, the hand reads within ~30 ms (`teleop bench dashboard`)."""
    _, _, rec_dir, _ = up_run
    m = read_recording(rec_dir / "master.csv")
    c = read_recording(rec_dir / "controller.csv")
    h = read_recording(rec_dir / "hand.csv")
    assert len(m) > 4000 and len(c) > 4000 and len(h) > 150  # 1 kHz, 1 kHz, 40 Hz, ~5 s
    # the virtual operator's script, in the master's own time (exact: the master runs it):
    # wait 0.5 s, close over 1 s, hold 2 s, release over 1 s; it closes until the grasp pushes
    # back.  The hand is judged on the settled second half of the hold, so a slow start on a
    # loaded machine (or a transient while the controller's delay estimate settles) does not
    # decide the outcome.
    t0 = m.t_s[0]
    x = m.column("trigger_position_m")
    before_m = m.t_s < t0 + 0.4
    hold_m = (m.t_s > t0 + 1.8) & (m.t_s < t0 + 3.4)
    assert x[before_m].max() == 0.0 and np.median(x[hold_m]) > 0.005
    # ... and the fingers close on the object: they flex and the tactile sensors load up
    # before the operator starts closing (0.5 s into the master's script); the services share
    # no start barrier, so on a loaded machine the hand may start a little later: then its
    # first sample (well before contact, ~0.9 s into the script) stands for "before"
    before_h = h.t_s <= max(t0 + 0.5, h.t_s[0])
    assert h.t_s[0] < t0 + 0.8
    hold_h = (h.t_s > t0 + 2.5) & (h.t_s < t0 + 3.4)
    assert before_h.sum() >= 1 and hold_h.sum() >= 20, (h.t_s[:3], t0)
    flex = h.column("proximal_angle_rad_f1") + h.column("distal_angle_rad_f1")
    assert flex[hold_h].mean() > flex[before_h].mean() + 0.2
    # ... on time: the hand reads its sensors soon after each 25 ms deadline although the
    # dashboard is saved (before 2026-11-29: p99 0.16-0.5 s, deadlines dropped; measured
    # failing against that tree)
    late = h.column("read_t_s") - h.t_s
    assert np.percentile(late, 99) < 0.05 and late.max() < 0.25, np.percentile(late, [50, 99])
    pressure = np.max([h.column(f"pressure_f1_{j}") for j in range(9)], axis=0)
    assert pressure[hold_h].min() > 20.0 and pressure[before_h].max() < 20.0
    # the operator feels it: force displayed while closed on the object, none before
    f = m.column("displayed_force_n")
    assert np.median(f[hold_m]) > 0.5
    assert np.abs(f[before_m]).max() < 0.2
    # energy: no tank negative; delivered at the ports <= initial + taken from the ports
    for r, store in ((m, "tank_j"), (h, "tank_j"), (c, "store_j")):
        assert r.column(store).min() >= -1e-9
    init = initial_j(m) + initial_j(h) + initial_j(c, "store_j")
    delivered = m.column("port_out_j")[-1] + h.column("port_out_j")[-1]
    taken = m.column("port_in_j")[-1] + h.column("port_in_j")[-1]
    assert delivered <= init + taken + 1e-6
    sent = m.column("sent_j")[-1] + c.column("sent_j")[-1] + h.column("sent_j")[-1]
    received = m.column("received_j")[-1] + c.column("received_j")[-1] + \
        h.column("received_j")[-1]
    assert received <= sent + 1e-6  # the links never create energy


def test_dashboard_mode_resolution() -> None:
    assert resolve_dashboard(None, "auto", "t.rrd", {"DISPLAY": ":0"}) == ("spawn", None)
    assert resolve_dashboard(None, "auto", "t.rrd", {"WAYLAND_DISPLAY": "w"}) == ("spawn", None)
    assert resolve_dashboard(None, "auto", "t.rrd", {}) == ("save", "t.rrd")
    assert resolve_dashboard("save:x/y.rrd", "auto", "t.rrd", {}) == ("save", "x/y.rrd")
    assert resolve_dashboard("off", "spawn", "t.rrd", {}) == ("off", None)
    with pytest.raises(UserInputError):
        resolve_dashboard("bogus", "auto", "t.rrd", {})


@pytest.mark.parametrize("args", [
    ("up", "--dashboard", "nonsense", "--duration", "1"),
    ("run", "master", "--set", "master.backend=nope"),
    ("up", "--config", "/nonexistent/x.toml"),
    ("run", "controller", "--dashboard", "nonsense", "--duration", "1"),
    ("run", "controller", "--dashboard", "save:/proc/x.rrd", "--duration", "1"),
    ("up", "--dashboard", "save:/proc/x.rrd", "--duration", "1"),
    ("up", "--dashboard", "off", "--set", "zenoh.endpoint=tcp/192.0.2.1:7447"),  # remote
    ("run", "master", "--set", "zenoh.endpoint=bogus", "--duration", "1"),  # roster probe
])
def test_user_mistakes_are_one_line_and_exit_2(args: tuple[str, ...]) -> None:
    proc = teleop(*args, timeout=60)
    assert proc.returncode == 2
    assert "Traceback" not in proc.stderr
    assert len(proc.stderr.strip().splitlines()) == 1


@pytest.mark.network
@pytest.mark.slow
@pytest.mark.parametrize("inherited_ignore", [False, True],
                         ids=["terminal", "started-in-the-background-by-a-script"])
def test_ctrl_c_stops_everything_within_2_s(tmp_path: Path, inherited_ignore: bool) -> None:
    """Ctrl-C stops the launcher and its services, also when ``teleop up`` was started by a
    script in the background (``teleop up &``: SIGINT arrives ignored, and Python would
    then never raise KeyboardInterrupt)."""
    import signal

    def ignore_sigint() -> None:
        signal.signal(signal.SIGINT, signal.SIG_IGN)

    port = free_port()
    proc = subprocess.Popen(
        [sys.executable, "-m", "teleop.cli", "up", "--dashboard", "off", "--record",
         str(tmp_path), "--set", f"zenoh.endpoint=tcp/127.0.0.1:{port}",
         "--set", f"session.name=ctrlc{port}"],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
        preexec_fn=ignore_sigint if inherited_ignore else None)
    try:
        assert proc.stdout is not None
        lines = []
        for line in proc.stdout:
            lines.append(line)
            if "running" in line:
                break
        time.sleep(1.0)
        t0 = time.monotonic()
        proc.send_signal(signal.SIGINT)
        out, err = proc.communicate(timeout=30)
        elapsed = time.monotonic() - t0
    finally:
        if proc.poll() is None:  # never leave a loop of three services running
            proc.kill()
            proc.wait()
    assert proc.returncode == 0, "".join(lines) + out + err
    assert elapsed < 2.5
    assert "interrupted" in out and "did not stop" not in out
    assert "Traceback" not in err
    for role in ("master", "controller", "hand"):  # each child closed its recording
        assert read_recording(tmp_path / f"{role}.csv").t_s.size > 10


@pytest.mark.network
def test_a_service_failing_at_start_up_fails_the_run_in_one_line() -> None:
    port = free_port()
    proc = teleop("up", "--duration", "2", "--dashboard", "off", "--set",
                  "hand.backend=dynamixel", "--set", "hand.dynamixel.port=/dev/nonexistent",
                  "--set", f"zenoh.endpoint=tcp/127.0.0.1:{port}",
                  "--set", f"session.name=fail{port}", timeout=60)
    assert proc.returncode == 1
    assert "start-up failed: hand exited" in proc.stdout
    assert "Traceback" not in proc.stderr
    assert "/dev/nonexistent" in proc.stderr


def test_an_endpoint_in_use_is_refused_before_anything_starts() -> None:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        s.listen()
        port = s.getsockname()[1]
        proc = teleop("up", "--duration", "1", "--dashboard", "off",
                      "--set", f"zenoh.endpoint=tcp/127.0.0.1:{port}", timeout=60)
    assert proc.returncode == 2, proc.stdout + proc.stderr
    assert len(proc.stderr.strip().splitlines()) == 1
    assert f"zenoh.endpoint = 'tcp/127.0.0.1:{port}': address in use" in proc.stderr
    assert "starting" not in proc.stdout


@pytest.mark.network
def test_up_on_the_endpoint_of_a_running_session_is_refused() -> None:
    """A second ``teleop up`` on a running session's endpoint (a real zenoh controller
    session listening there) starts nothing and says so in one line, exit 2 (without the
    check: exit 1, a zenoh error, and its master and hand connected to the running
    session's controller until they were killed)."""
    from teleop.transport.zenoh_bus import ZenohBus

    port = free_port()
    endpoint = f"tcp/127.0.0.1:{port}"
    bus = ZenohBus("controller", session=f"busy{port}", listen=[endpoint], connect=[])
    try:
        proc = teleop("up", "--duration", "2", "--dashboard", "off",
                      "--set", f"zenoh.endpoint={endpoint}",
                      "--set", f"session.name=busy{port}", timeout=60)
    finally:
        bus.close()
    assert proc.returncode == 2, proc.stdout + proc.stderr
    assert len(proc.stderr.strip().splitlines()) == 1 and "address in use" in proc.stderr
    assert "starting" not in proc.stdout


def test_omega7_without_its_sdk_is_a_one_line_error() -> None:
    import importlib.util

    if importlib.util.find_spec("forcedimension_core") is not None:
        pytest.skip("the Force Dimension SDK is installed here")
    proc = teleop("run", "master", "--set", "master.backend=omega7", "--duration", "1",
                  timeout=60)
    assert proc.returncode == 2
    assert "pip install 'teleop[omega7]'" in proc.stderr
    assert "Traceback" not in proc.stderr


def test_unwritable_record_dir_is_refused_before_anything_starts(tmp_path: Path) -> None:
    blocker = tmp_path / "file"
    blocker.write_text("")
    proc = teleop("up", "--duration", "1", "--dashboard", "off", "--record", str(blocker / "x"),
                  timeout=60)
    assert proc.returncode == 2
    assert proc.stderr.strip().count("\n") == 0 and "cannot write recordings" in proc.stderr
    assert "starting" not in proc.stdout
