"""One sweep point on the live services: ``teleop up`` over zenoh, read back its recordings.

The point's configuration is written to a temporary TOML file; ``teleop up --duration D
--record DIR --dashboard off --config FILE`` runs master, controller and hand as three
processes in real time; their ``DIR/<role>.csv`` recordings are merged onto the master's
time base (the others held at their latest sample) and turned into
:class:`~teleop.analysis.stability.RunSignals` like a lockstep run, the physical energy audit
included (:mod:`teleop.analysis.port_audit`: the run is judged passive by the physics).
"""

from __future__ import annotations

import tempfile
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from teleop.analysis.port_audit import ledger_initial_j, recorded_audit
from teleop.analysis.stability import RunSignals
from teleop.analysis.sweep_signals import signals_from_columns
from teleop.analysis.up_child import run_up
from teleop.config import TeleopConfig
from teleop.config.loader import render_toml
from teleop.recording import Recording, read_recording

Array = NDArray[np.float64]

__all__ = ["run_live_point", "signals_from_recordings"]

#: extra wall time allowed for start-up and shutdown of the three processes
STARTUP_ALLOWANCE_S = 60.0


def _triple(src: Recording, t: Array, name: str) -> Array:
    return np.column_stack([src.held(f"{name}_f{i + 1}", t) for i in range(3)])


def signals_from_recordings(master: Recording, controller: Recording, hand: Recording,
                            cfg: TeleopConfig) -> RunSignals:
    """RunSignals from the three live recordings (master time base)."""
    t = master.t_s
    pressure = np.column_stack([hand.held(f"pressure_f{i // 9 + 1}_{i % 9}", t)
                                for i in range(27)])
    m_tank = master.column("tank_j")
    initial = ledger_initial_j(master) + ledger_initial_j(hand) + ledger_initial_j(
        controller, "store_j")
    cols = {
        "t_s": t - t[0],
        "setpoint_rad": _triple(controller, t, "setpoint_rad"),
        "motor_angle_rad": _triple(hand, t, "motor_angle_rad"),
        "displayed_force_n": master.column("displayed_force_n"),
        "pressure": pressure,
        "master_port_out_j": master.column("port_out_j"),
        "master_port_in_j": master.column("port_in_j"),
        "hand_port_out_j": np.nan_to_num(hand.held("port_out_j", t)),
        "hand_port_in_j": np.nan_to_num(hand.held("port_in_j", t)),
        "master_tank_j": m_tank,
        "hand_tank_j": hand.held("tank_j", t),
        "master_limited_count": master.column("limit_count"),
        "hand_limited_count": hand.held("limit_count", t),
        "dropped_force_command": master.column("dropped"),
        "dropped_hand_command": hand.held("dropped", t),
        "dropped_master_state": controller.held("master_dropped", t),
        "dropped_hand_state": controller.held("hand_dropped", t),
    }
    if master.has("trigger_position_m"):
        cols["trigger_position_m"] = master.column("trigger_position_m")
    audit = recorded_audit(master, hand, controller, cfg.controller.tank.energy_scale)
    if audit is not None:  # judged by the physics, like a lockstep run
        cols["audit_margin_j"] = audit.margin_j
        cols["audit_throughput_j"] = np.array([audit.throughput_j])
        cols["ledger_audit_gap_j"] = np.array([audit.ledger_gap_operator_j,
                                               audit.ledger_gap_environment_j])
    return signals_from_columns(cols, cfg, max(initial, 0.0))


def run_live_point(cfg: TeleopConfig, duration_s: float) -> RunSignals:
    """Run ``teleop up`` for ``duration_s`` with ``cfg`` and read its recordings back."""
    with tempfile.TemporaryDirectory(prefix="teleop-sweep-") as tmp:
        conf = Path(tmp) / "point.toml"
        conf.write_text(render_toml(cfg), encoding="utf-8")
        rec_dir = Path(tmp) / "rec"
        run_up(["--config", str(conf), "--duration", f"{duration_s:g}", "--record",
                str(rec_dir), "--dashboard", "off"],
               timeout_s=duration_s + STARTUP_ALLOWANCE_S, what="live sweep point")
        recs = [read_recording(rec_dir / f"{role}.csv") for role in
                ("master", "controller", "hand")]
    return signals_from_recordings(recs[0], recs[1], recs[2], cfg)
