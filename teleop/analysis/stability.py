"""Stability, passivity and transparency metrics of one teleoperation run (pure functions).

A run is given as :class:`RunSignals` (numpy arrays on one time base); :func:`classify_run`
turns it into :class:`RunMetrics`.

Definitions
-----------
``stable``
    Every signal stays finite and none of the oscillation signals - the joint angle of every
    finger (all three), the displayed force and the trigger position - shows a sustained or
    growing oscillation whose amplitude exceeds a small multiple of the noise measured in the
    same run (:mod:`teleop.analysis.oscillation`: one engine, noise floor from the run's own
    periodogram, a small absolute floor per signal).  Signals are examined where the operator
    holds still and the loop has closed: :attr:`RunSignals.segments_s`, or from
    :attr:`RunSignals.settle_s` to the end.  Frequency and amplitude are reported per signal.

``passive``
    Judged from the **physical audit** when the run has one (simulated operator and object,
    not controller code): initial tank energy + energy taken at the operator and environment
    ports - energy delivered to them >= 0 at every sample (:attr:`RunSignals.audit_margin_j`),
    within :attr:`StabilityCriteria.energy_tol_j` plus :attr:`StabilityCriteria.energy_rel_tol`
    of the throughput.  ``passive_ledger`` is the same test on the services' ledgers
    (``energy_generated_j``: their largest excess, negative = the margin); without an audit
    (recordings of a real hand or master: no simulated port) ``passive`` falls back to the
    ledgers and ``passive_audit`` is None.  The tolerance is
    :func:`teleop.analysis.port_audit.audit_tolerance_j`.

``tracking_rms_rad`` / ``force_rms_n``
    Finger angle against the set-point delayed by the forward path; displayed force against
    the force the hand's pressures should display, delayed by the backward path.

``tracking_hold_rad``
    The same tracking error, RMS over the late half of every analysis segment (the steady
    part of each hold: a round trip after the ramp the operator is still answering the
    rendered contact, which reaches the hand one forward delay later): how far the hand's
    closure sits from what the operator commands in a steady grasp (nan without segments).

``felt_true_force_ratio``
    In the steady grasp (the analysis segments): mean displayed force over the mean force the
    force-feedback map gives for the pressure the hand really measures (delayed by the
    backward path); nan without contact (measured force below
    :attr:`StabilityCriteria.contact_force_n`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from teleop.analysis.oscillation import (
    OscillationCriteria,
    SignalOscillation,
    analyse_oscillation,
    highpass,
)
from teleop.analysis.port_audit import audit_tolerance_j

Array = NDArray[np.float64]

__all__ = ["RunSignals", "StabilityCriteria", "RunMetrics", "classify_run", "oscillations",
           "analysis_segments", "energy_generated_j", "delayed", "rms_error",
           "felt_true_force_ratio", "tracking_hold_rad", "highpass"]


@dataclass(frozen=True, slots=True)
class RunSignals:
    """The time series of one run that the metrics need (all arrays share ``t_s``).

    ``energy_out_j``/``energy_in_j``: cumulative ledger energies delivered out of / taken in
    at both ports.  ``tank_j``: one column per tank (zero columns without tanks).
    ``fingers_rad``: (n, 3) joint angles of all fingers (``finger_rad`` is the tracked one);
    ``trigger_m``: trigger closing.  ``audit_margin_j``: the physical audit's margin
    (initial + taken - delivered) at every sample, None without an audit.
    """

    t_s: Array
    setpoint_rad: Array
    finger_rad: Array
    force_displayed_n: Array
    force_measured_n: Array
    energy_out_j: Array
    energy_in_j: Array
    tank_j: Array
    initial_energy_j: float = 0.0
    forward_delay_s: float = 0.0
    backward_delay_s: float = 0.0
    setpoint_scale_rad: float = 3.0
    force_scale_n: float = 8.0
    limited_count: int = 0
    steps: int = 0
    dropped_messages: int = 0
    settle_s: float = 0.0  # from here on the operator holds still and the loop has closed
    fingers_rad: Array | None = None
    trigger_m: Array | None = None
    segments_s: tuple[tuple[float, float], ...] = ()  # holds (overrides settle_s)
    audit_margin_j: Array | None = None
    audit_throughput_j: float = 0.0
    ledger_audit_gap_j: tuple[float, float] = (math.nan, math.nan)  # (operator, environment)
    #: the operator repeats a script whose holds are all shorter than the loop's round trip:
    #: no hold can be judged, only a growing oscillation (:func:`analyse_oscillation`)
    growth_only: bool = False


@dataclass(frozen=True, slots=True)
class StabilityCriteria:
    """Thresholds of the classification (see the module doc)."""

    oscillation: OscillationCriteria = field(default_factory=OscillationCriteria)
    angle_floor_rad: float = 0.005  # ~3 encoder counts of the MX-28
    force_floor_n: float = 0.05
    trigger_floor_m: float = 1e-4  # 0.1 mm: 0.4 % of travel, ~0.012 rad of set-point
    energy_tol_j: float = 1e-6
    energy_rel_tol: float = 1e-6
    contact_force_n: float = 0.2


@dataclass(frozen=True, slots=True)
class RunMetrics:
    """What :func:`classify_run` reports for one run."""

    stable: bool
    passive: bool
    energy_generated_j: float
    tracking_rms_rad: float
    force_rms_n: float
    tank_min_j: float
    limited_count: int
    limited_fraction: float
    dropped_messages: int
    oscillation_index: float  # largest late amplitude / threshold over the signals
    growth_ratio: float  # largest late/early amplitude ratio over the signals
    hf_power_fraction: float  # largest share of oscillation power above hf_hz
    reason: str  # why unstable ("" when stable)
    passive_ledger: bool = True
    passive_audit: bool | None = None
    audit_energy_generated_j: float = math.nan  # largest excess (negative: smallest margin)
    ledger_audit_gap_operator_j: float = math.nan
    ledger_audit_gap_environment_j: float = math.nan
    felt_true_force_ratio: float = math.nan
    oscillations: tuple[SignalOscillation, ...] = ()
    tracking_hold_rad: float = math.nan

    @property
    def judged(self) -> str:
        """What the stability verdict examined: "holds", "whole run" or "growth only"."""
        return self.oscillations[0].judged if self.oscillations else "holds"


def delayed(t_s: Array, x: Array, delay_s: float) -> Array:
    """``x(t - delay_s)`` on the grid ``t_s`` (held at its first value before the start)."""
    return np.interp(np.asarray(t_s) - delay_s, t_s, x, left=float(x[0]))


def rms_error(t_s: Array, actual: Array, reference: Array, delay_s: float) -> float:
    """RMS of ``actual(t) - reference(t - delay_s)``."""
    err = np.asarray(actual) - delayed(t_s, np.asarray(reference), delay_s)
    return float(np.sqrt(np.mean(err**2))) if len(err) else 0.0


def energy_generated_j(energy_out_j: Array, energy_in_j: Array, initial_energy_j: float) -> float:
    """Largest excess of energy delivered over energy taken plus initial tank energy."""
    excess = np.asarray(energy_out_j) - np.asarray(energy_in_j) - initial_energy_j
    return float(np.max(excess)) if len(excess) else 0.0


def analysis_segments(s: RunSignals) -> tuple[tuple[float, float], ...]:
    """Where the operator holds still and the loop has closed (empty: unknown)."""
    if s.segments_s:
        return s.segments_s
    t = np.asarray(s.t_s, float)
    if s.settle_s > 0 and t.size and t[-1] > s.settle_s:
        return ((s.settle_s, float(t[-1]) + 1e-9),)
    return ()


def oscillations(s: RunSignals, c: StabilityCriteria = StabilityCriteria()
                 ) -> tuple[SignalOscillation, ...]:
    """The oscillation of every finger, the displayed force and the trigger."""
    segs = analysis_segments(s)
    fingers = (np.asarray(s.fingers_rad, float) if s.fingers_rad is not None
               else np.asarray(s.finger_rad, float)[:, None])
    sigs: list[tuple[str, Array, float]] = [
        (f"finger{i + 1}_rad", fingers[:, i], c.angle_floor_rad) for i in range(fingers.shape[1])]
    sigs.append(("displayed_force_n", np.asarray(s.force_displayed_n, float), c.force_floor_n))
    if s.trigger_m is not None:
        sigs.append(("trigger_m", np.asarray(s.trigger_m, float), c.trigger_floor_m))
    return tuple(analyse_oscillation(n, s.t_s, x, segs, floor, c.oscillation, s.growth_only)
                 for n, x, floor in sigs)


def segment_mask(t: np.ndarray, segments: Sequence[tuple[float, float]],
                 late_half: bool = False) -> np.ndarray:
    """Samples of ``t`` inside any of ``segments`` (``[a, b)``), or only in their late halves
    (a segment open at the end counts up to the last sample)."""
    m = np.zeros(len(t), bool)
    for a, b in segments:
        if late_half:
            b = min(b, float(t[-1]) + 1e-9) if t.size else b
            a = 0.5 * (a + b)
        m |= (t >= a) & (t < b)
    return m


def tracking_hold_rad(s: RunSignals) -> float:
    """RMS of finger minus delayed set-point in the late halves of the analysis segments
    (nan: none)."""
    t = np.asarray(s.t_s, float)
    m = segment_mask(t, analysis_segments(s), late_half=True)
    if not m.any():
        return math.nan
    err = np.asarray(s.finger_rad, float) - delayed(t, np.asarray(s.setpoint_rad, float),
                                                    s.forward_delay_s)
    return float(np.sqrt(np.mean(err[m] ** 2)))


def felt_true_force_ratio(s: RunSignals, c: StabilityCriteria = StabilityCriteria()) -> float:
    """Mean displayed over mean true (pressure-mapped, delayed) force in the steady grasp: the
    late halves of the analysis segments, as :func:`tracking_hold_rad` (a first touch made
    before anything came back squeezes, then relaxes over seconds in the early half); the
    late half of the run when there is no segment."""
    t = np.asarray(s.t_s, float)
    segs = analysis_segments(s)
    m = (segment_mask(t, segs, late_half=True) if segs
         else segment_mask(t, ((float(t[0]) + 0.5 * float(t[-1] - t[0]), math.inf),)))
    if not m.any():
        return math.nan
    true = delayed(t, np.asarray(s.force_measured_n, float), s.backward_delay_s)[m]
    if float(np.mean(true)) < c.contact_force_n:
        return math.nan
    return float(np.mean(np.asarray(s.force_displayed_n, float)[m]) / np.mean(true))


def _audit(s: RunSignals, c: StabilityCriteria) -> tuple[bool | None, float]:
    if s.audit_margin_j is None:
        return None, math.nan
    margin = np.asarray(s.audit_margin_j, float)
    if not margin.size or not np.all(np.isfinite(margin)):
        return None, math.nan
    gen = float(-np.min(margin))
    tol = audit_tolerance_j(s.audit_throughput_j, s.initial_energy_j, c.energy_tol_j,
                            c.energy_rel_tol)
    return gen <= tol, gen


def classify_run(s: RunSignals, c: StabilityCriteria = StabilityCriteria()) -> RunMetrics:
    """Classify one run as stable/passive and compute its error, energy and force metrics."""
    t = np.asarray(s.t_s, float)
    arrays = [t, s.setpoint_rad, s.finger_rad, s.force_displayed_n, s.force_measured_n]
    arrays += [a for a in (s.fingers_rad, s.trigger_m) if a is not None]
    finite = all(np.all(np.isfinite(a)) for a in arrays)
    reasons: list[str] = []
    osc: tuple[SignalOscillation, ...] = ()
    if not finite:
        reasons.append("non-finite signal")
    else:
        osc = oscillations(s, c)
        reasons += [f"{o.state} {o.name} oscillation ({o.amplitude:.3g} at "
                    f"{o.frequency_hz:.2f} Hz, threshold {o.threshold:.3g})"
                    for o in osc if o.unstable]
    gen = energy_generated_j(s.energy_out_j, s.energy_in_j, s.initial_energy_j)
    throughput = float(np.max(s.energy_out_j, initial=0.0) + np.max(s.energy_in_j, initial=0.0))
    tol = c.energy_tol_j + c.energy_rel_tol * (throughput + s.initial_energy_j)
    passive_ledger = bool(np.isfinite(gen) and gen <= tol)
    passive_audit, audit_gen = _audit(s, c)
    tank = np.asarray(s.tank_j, float)

    def growth(o: SignalOscillation) -> float:
        return o.amplitude / o.early_amplitude if o.early_amplitude > 0 else (
            1.0 if o.amplitude == 0 else 1e9)

    return RunMetrics(
        stable=not reasons,
        passive=passive_ledger if passive_audit is None else passive_audit,
        energy_generated_j=gen,
        tracking_rms_rad=rms_error(t, s.finger_rad, s.setpoint_rad, s.forward_delay_s),
        force_rms_n=rms_error(t, s.force_displayed_n, s.force_measured_n, s.backward_delay_s),
        tank_min_j=float(np.min(tank)) if tank.size else math.nan,
        limited_count=int(s.limited_count),
        limited_fraction=(s.limited_count / s.steps) if s.steps else 0.0,
        dropped_messages=int(s.dropped_messages),
        oscillation_index=max((o.index for o in osc), default=0.0),
        growth_ratio=max((growth(o) for o in osc), default=0.0),
        hf_power_fraction=max((o.hf_power_fraction for o in osc), default=0.0),
        reason="; ".join(reasons),
        passive_ledger=passive_ledger,
        passive_audit=passive_audit,
        audit_energy_generated_j=audit_gen,
        ledger_audit_gap_operator_j=float(s.ledger_audit_gap_j[0]),
        ledger_audit_gap_environment_j=float(s.ledger_audit_gap_j[1]),
        felt_true_force_ratio=felt_true_force_ratio(s, c) if finite else math.nan,
        oscillations=osc,
        tracking_hold_rad=tracking_hold_rad(s) if finite else math.nan,
    )
