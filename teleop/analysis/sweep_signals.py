"""Turn the services' run results into :class:`~teleop.analysis.stability.RunSignals`.

The library does not import ``services``; :func:`signals_from_lockstep` reads the attributes of
a ``services.lockstep.LockstepResult`` (duck typing), and :func:`signals_from_columns` the same
quantities from named columns (live recordings).

Which signal is which (finger 1, the first enabled finger, stands for the hand):

* set-point: the joint set-point the *controller* commands (a delayed image of the trigger);
* finger angle: the finger's joint-side motor angle at the hand (what the set-point commands);
  tracking is measured against the set-point delayed by the controller->hand delay;
* measured force: what the displayed force should be, computed at the hand from its pressures
  (per-finger maximum, combined as the transparency layer does, times
  ``force_per_pressure_n``), unfiltered and undelayed; the force error is taken against it
  delayed by the backward path (hand->controller->master);
* oscillation signals: the joint-side motor angle of all three fingers, the displayed force and
  the trigger position, examined in :func:`hold_segments_s` (the holds of the operator's
  script, a round trip after each ramp);
* energies: port energies of master and hand, initial tank energy, from the services' ledgers;
  and the physical audit (``LockstepResult.audit_margin_j``: simulated operator and object)
  when the run has one, which decides ``passive``.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np
from numpy.typing import NDArray

from teleop.analysis.stability import RunSignals
from teleop.config import TeleopConfig

Array = NDArray[np.float64]

__all__ = ["signals_from_lockstep", "signals_from_columns", "fill_nan", "measured_force_n",
           "path_delays_s", "round_trip_s", "settle_time_s", "hold_segments_s"]


def fill_nan(x: Array, before: float | None = None) -> Array:
    """Forward-fill NaNs; leading NaNs take ``before`` (or the first finite value; 0 if none)."""
    x = np.asarray(x, dtype=float).copy()
    ok = np.isfinite(x)
    if not ok.any():
        return np.full_like(x, 0.0 if before is None else before)
    idx = np.where(ok, np.arange(len(x)), 0)
    np.maximum.accumulate(idx, out=idx)
    first = int(np.argmax(ok))
    out = x[idx]
    out[:first] = x[first] if before is None else before
    return out


def measured_force_n(pressure: Array, cfg: TeleopConfig) -> Array:
    """The force the transparency layer would display for these hand pressures (n, 27): its
    own per-finger maximum and combine rule, clipped to the trigger's limit (no filter)."""
    from teleop.control.interface import control_params
    from teleop.control.transparency_layer import combined_force_n

    params = control_params(cfg.controller)
    p = np.asarray(pressure, float).reshape(len(pressure), 3, -1)
    per_finger = np.nanmax(np.nan_to_num(p, nan=0.0), axis=2)
    out = np.array([combined_force_n((float(a), float(b), float(c)), params)
                    for a, b, c in per_finger])
    return np.minimum(out, cfg.master.force_max_n)


def path_delays_s(cfg: TeleopConfig) -> tuple[float, float]:
    """(controller->hand delay, hand->controller->master delay) configured (no jitter)."""
    mc, ch = cfg.links.master_controller, cfg.links.controller_hand
    ch_back = ch.delay_s if ch.backward_delay_s is None else ch.backward_delay_s
    mc_back = mc.delay_s if mc.backward_delay_s is None else mc.backward_delay_s
    return ch.delay_s, ch_back + mc_back


def round_trip_s(cfg: TeleopConfig) -> float:
    """Configured round trip master->hand->master plus the hand's sample-and-hold period."""
    mc = cfg.links.master_controller
    fwd, back = path_delays_s(cfg)
    return mc.delay_s + fwd + back + 1.0 / cfg.hand.state_rate_hz


def settle_time_s(cfg: TeleopConfig) -> float:
    """When the virtual operator holds still and the loop has closed around the grasp.

    The end of the operator's closing ramp plus one round trip; 0 (unknown) when the
    operator repeats its script or is not the virtual one.
    """
    v = cfg.master.virtual
    if cfg.master.backend != "virtual" or v.repeat:
        return 0.0
    return v.close_s + v.ramp_s + round_trip_s(cfg)


def hold_segments_s(cfg: TeleopConfig, t_end_s: float) -> tuple[tuple[float, float], ...]:
    """Where the virtual operator holds still and the loop has closed, up to ``t_end_s``.

    One segment from :func:`settle_time_s` to the end for a single grasp; for a repeating
    script every hold from one round trip after the end of the ramp to the start of the
    release; empty for a non-virtual master.
    """
    v = cfg.master.virtual
    if cfg.master.backend != "virtual":
        return ()
    if not v.repeat:
        settle = settle_time_s(cfg)
        return ((settle, t_end_s + 1e-9),) if t_end_s > settle else ()
    period = v.cycle_s
    rt = round_trip_s(cfg)
    out = []
    k = 0
    while period > 0 and k * period < t_end_s:
        a = k * period + v.close_s + v.ramp_s + rt
        b = min(k * period + v.close_s + v.ramp_s + v.hold_s, t_end_s + 1e-9)
        if b > a:
            out.append((a, b))
        k += 1
    return tuple(out)


def _repeats(cfg: TeleopConfig) -> bool:
    return cfg.master.backend == "virtual" and bool(cfg.master.virtual.repeat)


def _finger(cfg: TeleopConfig) -> int:
    en = tuple(cfg.controller.transparency.finger_enable)
    return next((i for i, e in enumerate(en[:3]) if e), 0)


def _last(x: Any) -> float:
    a = np.asarray(x, float)
    a = a[np.isfinite(a)]
    return float(a[-1]) if a.size else 0.0


def signals_from_columns(cols: Mapping[str, Array], cfg: TeleopConfig,
                         initial_j: float) -> RunSignals:
    """RunSignals from named columns (the LockstepResult attribute names, 2-D where (n, k)).

    Optional: ``trigger_position_m``; ``audit_margin_j`` (with ``audit_throughput_j`` and
    ``ledger_audit_gap_j`` as 1-element/2-element arrays) for the physical audit.
    """
    f = _finger(cfg)
    motors = np.column_stack([fill_nan(np.asarray(cols["motor_angle_rad"], float)[:, i])
                              for i in range(np.asarray(cols["motor_angle_rad"]).shape[1])])
    trigger = (fill_nan(np.asarray(cols["trigger_position_m"], float), 0.0)
               if "trigger_position_m" in cols else None)
    margin = np.asarray(cols["audit_margin_j"], float) if "audit_margin_j" in cols else None
    gap = tuple(np.asarray(cols.get("ledger_audit_gap_j", [np.nan, np.nan]), float))
    t = np.asarray(cols["t_s"], float)
    segs = hold_segments_s(cfg, float(t[-1]) if t.size else 0.0)
    tr = cfg.controller.transparency
    fwd, back = path_delays_s(cfg)
    tanks = [fill_nan(np.asarray(cols[k], float)) for k in
             ("master_tank_j", "hand_tank_j") if k in cols]
    tank = np.column_stack(tanks) if tanks and initial_j > 0 else np.zeros((len(t), 0))
    limited = _last(cols.get("master_limited_count", [0.0])) + _last(
        cols.get("hand_limited_count", [0.0]))
    dropped = sum(_last(cols[k]) for k in ("dropped_master_state", "dropped_force_command",
                                           "dropped_hand_command", "dropped_hand_state")
                  if k in cols)
    return RunSignals(
        t_s=t,
        setpoint_rad=fill_nan(np.asarray(cols["setpoint_rad"], float)[:, f], tr.open_angle_rad),
        finger_rad=motors[:, f],
        force_displayed_n=fill_nan(np.asarray(cols["displayed_force_n"], float), 0.0),
        force_measured_n=measured_force_n(np.asarray(cols["pressure"], float), cfg),
        energy_out_j=fill_nan(np.asarray(cols["master_port_out_j"], float)
                              + np.asarray(cols["hand_port_out_j"], float), 0.0),
        energy_in_j=fill_nan(np.asarray(cols["master_port_in_j"], float)
                             + np.asarray(cols["hand_port_in_j"], float), 0.0),
        tank_j=tank,
        initial_energy_j=float(initial_j),
        forward_delay_s=fwd,
        backward_delay_s=back,
        setpoint_scale_rad=abs(tr.closed_angle_rad - tr.open_angle_rad) or 1.0,
        force_scale_n=cfg.master.force_max_n or 1.0,
        limited_count=int(limited),
        steps=len(t),
        dropped_messages=int(dropped),
        settle_s=settle_time_s(cfg),
        fingers_rad=motors,
        trigger_m=trigger,
        segments_s=segs,
        growth_only=_repeats(cfg) and not segs,
        audit_margin_j=margin,
        audit_throughput_j=float(np.asarray(cols.get("audit_throughput_j", [0.0]))[0]),
        ledger_audit_gap_j=(float(gap[0]), float(gap[1])),
    )


def signals_from_lockstep(result: Any, cfg: TeleopConfig) -> RunSignals:
    """RunSignals from a ``services.lockstep.LockstepResult``."""
    names = ("t_s", "trigger_position_m", "setpoint_rad", "motor_angle_rad",
             "displayed_force_n", "pressure",
             "master_port_out_j", "hand_port_out_j", "master_port_in_j", "hand_port_in_j",
             "master_tank_j", "hand_tank_j", "master_limited_count", "hand_limited_count",
             "dropped_master_state", "dropped_force_command", "dropped_hand_command",
             "dropped_hand_state")
    cols = {n: getattr(result, n) for n in names}
    if getattr(result, "has_audit", False):
        rho = float(result.energy_scale)
        cols["audit_margin_j"] = np.asarray(result.audit_margin_j, float)
        cols["audit_throughput_j"] = np.array([
            rho * (result.audit_operator_delivered_j[-1] + result.audit_operator_taken_j[-1])
            + result.audit_environment_delivered_j[-1] + result.audit_environment_taken_j[-1]])
        gap = result.ledger_audit_gap_j
        cols["ledger_audit_gap_j"] = np.array([gap["operator"], gap["environment"]])
    return signals_from_columns(cols, cfg, float(result.initial_j))
