"""The delay sweep's text table, and its JSON read back into a SweepResult."""

from __future__ import annotations

import math
from typing import Any

from teleop.analysis.stability import RunMetrics
from teleop.analysis.sweep import SweepPoint, SweepResult, SweepRun

__all__ = ["format_table", "result_from_json"]


def result_from_json(doc: dict[str, Any]) -> SweepResult:
    """Rebuild a :class:`SweepResult` from :meth:`SweepResult.to_json` output."""
    runs = []
    for row in doc["runs"]:
        point = SweepPoint(row["controller"], row["delay_s"], row["jitter_s"], row["loss"],
                           int(row.get("seed", 0)), row.get("operator", ""),
                           row.get("object", ""), row.get("jitter", ""))
        vals = {f: row[f] for f in RunMetrics.__dataclass_fields__
                if f in row and f != "oscillations"}
        vals = {k: (math.nan if v is None and k != "passive_audit" else v)
                for k, v in vals.items()}
        runs.append(SweepRun(point, RunMetrics(**vals), float(row.get("wall_s", 0.0)),
                             bool(row.get("refine", False))))

    def num(v: Any) -> float:
        return math.inf if v is None else float(v)

    brackets = tuple((c, num(lo) if lo is not None else math.nan, num(hi))
                     for c, (lo, hi) in doc.get("measured_bracket_s", {}).items())
    return SweepResult(tuple(runs), tuple(doc["predicted_max_stable_delay_s"].items()),
                       tuple(doc.get("measured_max_stable_delay_s", {}).items()), brackets,
                       doc.get("mode", "lockstep"), int(doc.get("seed", 0)),
                       float(doc.get("duration_s", 0.0)), float(doc.get("wall_s", 0.0)),
                       tuple(doc.get("notes", ())), bool(doc.get("interrupted", False)))


def format_table(result: SweepResult) -> str:
    """The results as a fixed-width text table, then the largest stable delays."""
    head = (f"{'controller':<10} {'delay_s':>8} {'loss':>5} {'stable':>6} {'passive':>7} "
            f"{'audit_J':>8} {'ledger':>6} {'E_gen_J':>8} {'track_rad':>9} {'hold_rad':>8} "
            f"{'force_N':>8} "
            f"{'felt/true':>9} {'tank_min_J':>10} {'limited':>8} {'osc':>6}  oscillation")
    lines = [head, "-" * len(head)]
    for r in result.runs:
        m, p = r.metrics, r.point
        tank = f"{m.tank_min_j:10.3f}" if math.isfinite(m.tank_min_j) else f"{'-':>10}"
        worst = [o for o in m.oscillations if o.unstable]
        osc = (f"{worst[0].name} {worst[0].amplitude:.3g} @ {worst[0].frequency_hz:.2f} Hz"
               if worst else "")
        lines.append(
            f"{p.controller:<10} {p.delay_s:8.4f} {p.loss:5.2f} {'yes' if m.stable else 'NO':>6} "
            f"{'yes' if m.passive else 'NO':>7} {m.audit_energy_generated_j:8.3g} "
            f"{'yes' if m.passive_ledger else 'NO':>6} {m.energy_generated_j:8.3g} "
            f"{m.tracking_rms_rad:9.3f} {m.tracking_hold_rad:8.3f} {m.force_rms_n:8.3f} "
            f"{m.felt_true_force_ratio:9.2f} "
            f"{tank} {m.limited_fraction:8.1%} {m.oscillation_index:6.2f}  {osc}"
            + ("  (bisection)" if r.refine else ""))
    pred = dict(result.predicted_max_stable_delay_s)
    brackets = {c: (lo, hi) for c, lo, hi in result.measured_bracket_s}
    lines.append("")
    lines.append("largest stable one-way delay (loss 0):")
    for c in dict.fromkeys(r.point.controller for r in result.runs):
        lo, hi = brackets.get(c, (math.nan, math.inf))  # (nan, inf): no run at loss 0
        meas = ("not measured (no run at loss 0)" if math.isnan(lo) and math.isinf(hi) else
                "measured unstable at every delay" if math.isnan(lo) else
                f"measured > {lo:.4f} s (stable at every delay swept)" if math.isinf(hi) else
                f"measured {lo:.4f} s (unstable at {hi:.4f} s)")
        line = f"  {c:<10} {meas}"
        if c in pred:
            line += f"; predicted (linearised loop) {pred[c]:.4f} s"
            if math.isfinite(hi) and not math.isnan(lo) and pred[c] > 0:
                line += f"; measured/predicted {lo / pred[c]:.2f}"
        lines.append(line)
    lines.extend(f"note: {n}" for n in result.notes)
    return "\n".join(lines)
