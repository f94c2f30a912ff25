"""The grasps of a lockstep run, by ``teleop grasps``' rule: one helper for the lockstep tests
and the scripts beside them that judge a run grasp by grasp."""

from __future__ import annotations

from services.lockstep import LockstepResult, run_lockstep
from teleop.analysis.grasps import GraspSeries
from teleop.analysis.sweep_endurance import grasps_from_columns
from teleop.config import TeleopConfig


def grasps_of(r: LockstepResult, cfg: TeleopConfig) -> GraspSeries:
    """The grasp series of run ``r`` made with ``cfg``
    (:func:`teleop.analysis.sweep_endurance.grasps_from_columns`)."""
    return grasps_from_columns(r.t_s, r.trigger_position_m, r.pressure, r.proximal_rad,
                               r.distal_rad, r.displayed_force_n, cfg)


def run_grasps(cfg: TeleopConfig, seconds: float,
               seed: int = 1) -> tuple[LockstepResult, GraspSeries]:
    """``(result, grasp series)`` of a lockstep run of ``seconds``."""
    r = run_lockstep(cfg, seconds, seed=seed)
    return r, grasps_of(r, cfg)


def peaks_of(cfg: TeleopConfig, seconds: float, seed: int = 1) -> list[float]:
    """Every grasp's peak pressure over a lockstep run of ``seconds``."""
    return [s.peak_pressure for s in run_grasps(cfg, seconds, seed)[1].grasps]
