"""A live sweep point: ``teleop up`` over zenoh on loopback, recordings read back."""

from __future__ import annotations

import socket
from dataclasses import replace

import numpy as np
import pytest

from teleop.analysis.stability import classify_run
from teleop.analysis.sweep import SweepPoint, point_config
from teleop.analysis.sweep_live import run_live_point
from teleop.config import apply_overrides, load_config

pytestmark = [pytest.mark.network, pytest.mark.slow]


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


# was a non-strict xfail (issue 13): a small ~1.7 Hz live cycle on the held grasp that lockstep
# did not show; with model-mediated rendering the force loop is local and it passed every run
def test_live_point_is_passive_and_stable_at_zero_delay() -> None:
    cfg = load_config()
    cfg = apply_overrides(cfg, cfg.sweep.scenario)
    cfg = replace(cfg, zenoh=replace(cfg.zenoh, endpoint=f"tcp/127.0.0.1:{free_port()}"))
    pcfg = point_config(cfg, SweepPoint("two-layer", 0.0, 0.0, 0.0, 1))
    s = run_live_point(pcfg, 4.0)
    assert s.t_s[-1] > 3.0 and np.all(np.diff(s.t_s) > 0)
    assert s.initial_energy_j == pytest.approx(2 * cfg.controller.tank.initial_j)
    m = classify_run(s)
    assert m.passive, m.energy_generated_j
    # judged by the physics (the work done at the trigger and on the object), not the books
    assert s.audit_margin_j is not None and m.passive_audit is True, m.audit_energy_generated_j
    assert m.stable, m.reason
    assert s.force_displayed_n.max() > 1.0  # the grasp closed on the object and was felt


def test_a_live_loop_without_its_passivity_layer_is_caught_by_the_physics() -> None:
    """The mutant of the test above: the direct controller (no tanks, no passivity layer) at
    zero delay, 3 s.  Live it delivers more energy than the ports took (0.08 J in 4 s measured
    2026-11-29; lockstep's 1 s run: 0.015 J, tests/services/data/sweep_direct_record.json);
    the ledgers hold no tank to judge, the physical audit reads it."""
    cfg = load_config()
    cfg = apply_overrides(cfg, cfg.sweep.scenario)
    cfg = replace(cfg, zenoh=replace(cfg.zenoh, endpoint=f"tcp/127.0.0.1:{free_port()}"))
    s = run_live_point(point_config(cfg, SweepPoint("direct", 0.0, 0.0, 0.0, 1)), 3.0)
    m = classify_run(s)
    assert m.passive_audit is False and m.audit_energy_generated_j > 0.005, m
    assert not m.passive
