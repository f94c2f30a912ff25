"""Dashboard: every path logged, read back from a saved .rrd; finger drawing geometry."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from teleop.devices.base import HandReading
from teleop.messages import FingerState
from teleop.viz import dashboard as dash


def reading() -> HandReading:
    f = FingerState(proximal_rad=0.5, distal_rad=0.2, motor_angle_rad=0.7, load_units=50.0,
                    pressure=tuple(float(i) for i in range(9)),
                    contact=tuple(i in (2, 3) for i in range(9)))
    return HandReading(t_s=0.0, fingers=(f, f, f), preshape_rad=0.1)


def entity_paths(path: Path) -> set[str]:
    from rerun.chunk import RrdReader

    paths = set()
    for chunk in RrdReader(path).stream():
        if not chunk.is_static and chunk.num_rows > 0:
            paths.add(chunk.entity_path.lstrip("/"))
    return paths


def test_all_dashboard_paths_hold_data(tmp_path: Path) -> None:
    out = tmp_path / "d.rrd"
    rec = dash.open_stream("test-recording", "save", path=out)
    assert rec is not None
    for k in range(3):
        t = 0.02 * k
        dash.log_master(rec, t, trigger_position_m=0.01, displayed_force_n=1.0, tank_j=0.9,
                        port_in_j=0.1, port_out_j=0.05, delay_s=0.01, model_force_n=0.9,
                        physics_j=(0.04, 0.1))
        dash.log_controller(rec, t, setpoints_rad=(1.0, 1.0, 1.0), commanded_force_n=1.0,
                            energy_stored_j=0.01, master_delay_s=0.01, hand_delay_s=0.02,
                            measured_force_n=1.1)
        dash.log_hand(rec, t, reading(), tank_j=1.0, port_in_j=0.2, port_out_j=0.1,
                      delay_s=0.03, physics_j=(0.1, 0.05))
        dash.log_event(rec, t, "master", "passivity layer limiting the force")
    rec.flush()
    rec.disconnect()
    found = entity_paths(out)
    missing = [p for p in (*dash.DASHBOARD_PATHS, *dash.PHYSICS_PATHS) if p not in found]
    assert not missing, f"no data at {missing}"
    assert "links/controller_to_master/delay_s" in found


def test_finger_drawing_keeps_link_lengths_and_curls_towards_the_palm() -> None:
    links, tendon, sensors = dash.finger_drawing(0.0, 0.0, 0)
    assert links[-1] == pytest.approx((0.072 + 0.045, 0.0))
    assert len(sensors) == 9 and len(tendon) == 4
    links, _, _ = dash.finger_drawing(0.8, 0.6, 1)
    (x0, y0), (x1, y1), (x2, y2) = links
    assert math.hypot(x1 - x0, y1 - y0) == pytest.approx(0.072)
    assert math.hypot(x2 - x1, y2 - y1) == pytest.approx(0.045)
    assert y2 < y1 < 0.0  # flexion moves the finger towards -y
    assert x0 == pytest.approx(0.14)


def test_blueprint_views_show_logged_paths() -> None:
    """Every view's origin and every ``+ path`` in its contents reaches a path the dashboard
    logs (a renamed signal would leave a view empty)."""
    logged = [*dash.DASHBOARD_PATHS, *dash.PHYSICS_PATHS, "events", "rejects/hand/malformed"]
    views = dash.blueprint().root_container.contents
    assert len(views) == 8
    for view in views:
        origin = str(view.origin).strip("/")
        assert origin == "" or any(p == origin or p.startswith(origin + "/") for p in logged), \
            f"{view.name}: nothing logged under {origin!r}"
        exprs = [view.contents] if isinstance(view.contents, str) else view.contents or []
        for expr in exprs:
            pat = expr.removeprefix("+ ").replace("$origin", origin).strip("/")
            prefix = pat.removesuffix("/**")
            hits = [p for p in logged if p == prefix or (pat.endswith("/**")
                                                        and p.startswith(prefix + "/"))]
            assert hits, f"{view.name}: {expr!r} matches no logged path"


def scalar_series(path: Path, entity: str) -> list[tuple[float, float]]:
    """(time s, value) of every row at ``entity`` in a saved .rrd, in time order."""
    import pyarrow as pa
    from rerun.chunk import RrdReader

    rows = []
    for chunk in RrdReader(path).stream():
        if chunk.is_static or chunk.entity_path.lstrip("/") != entity:
            continue
        batch = chunk.to_record_batch()
        ns = batch.column("time").cast(pa.int64()).to_pylist()
        values = batch.column("Scalars:scalars").to_pylist()
        rows += [(t * 1e-9, v[0]) for t, v in zip(ns, values, strict=True)]
    return sorted(rows)


def test_signals_sent_as_columns_read_back_as_logged_one_by_one(tmp_path: Path) -> None:
    """The services send their signals as columns every 0.2 s (``ScalarColumns``): the saved
    recording holds every sample at its own time, as logging each at once does, and the last
    ones arrive with the final flush.  Mutant watched failing: the columns sent without their
    time index (every sample at the flush's time)."""
    def run(out: Path, batched: bool) -> list[tuple[float, float]]:
        rec = dash.open_stream("cols", "save", path=out, send_blueprint=False)
        assert rec is not None
        stream: dash.Stream = dash.ScalarColumns(rec, 0.2) if batched else rec
        for k in range(25):
            t = 0.02 * k
            dash.log_master(stream, t, trigger_position_m=0.001 * k, displayed_force_n=1.0,
                            tank_j=10.0 - 0.1 * k, port_in_j=0.1, port_out_j=0.05,
                            delay_s=None)
            if batched:
                stream.flush_due(t)  # type: ignore[union-attr]
        if batched:
            stream.flush()  # type: ignore[union-attr]
        rec.flush()
        rec.disconnect()
        return scalar_series(out, "master/tank_j")

    one_by_one = run(tmp_path / "a.rrd", False)
    columns = run(tmp_path / "b.rrd", True)
    assert len(one_by_one) == 25 and len(columns) == 25
    assert np.allclose(columns, one_by_one, rtol=0.0, atol=1e-9)
    assert columns[-1] == pytest.approx((0.48, 7.6))
