"""Terminal report and JSON document of a :class:`~teleop.diagnose.diagnose.Diagnosis`."""

from __future__ import annotations

import math
from typing import Any

from teleop.diagnose.criterion import unexplained
from teleop.diagnose.diagnose import Diagnosis
from teleop.diagnose.library import equation
from teleop.diagnose.residual import ResidualStats
from teleop.diagnose.results import ProposedTerm
from teleop.diagnose.windows import where_text, windows_json


def _fmt(v: float) -> str:
    return f"{v:.4g}" if math.isfinite(v) else str(v)


def _stats(s: ResidualStats) -> dict[str, Any]:
    return {"rms": s.rms, "noise_std": s.noise_std, "rms_over_noise": s.rms_over_noise,
            "lag1_autocorr": s.lag1_autocorr, "whiteness": s.whiteness,
            "corr": dict(s.corr)}


def to_json(d: Diagnosis, model: str = "axis") -> dict[str, Any]:
    """The JSON document of DESIGN.md (effects, windows, fit, validation) plus extra keys."""
    out: dict[str, Any] = {
        "model": model,
        "analysis": d.analysis,
        "analysis_reason": d.analysis_reason,
        "effects": [{"name": e.name, "params": dict(e.params), "delta_bic": e.delta_bic,
                     "score": e.delta_bic,
                     "uncertainty": dict(e.std), "holdout_gain": e.holdout_gain,
                     "explanation": e.explanation} for e in d.effects],
        "windows": windows_json(d.windows),
        "fit": {"before": {"nrmse": d.nrmse_before, "params": dict(d.nominal_params)},
                "after": {"nrmse": d.nrmse_after, "params": dict(d.final_params)}},
        "ranking": [{"name": n, "delta_bic": b} for n, b in d.ranking],
        "residual": {"before": _stats(d.residual_before), "after": _stats(d.residual_after)},
        "selection": "penalised likelihood (effective sample size) + held-out gain",
        "unexplained": _warning(d),
        "ambiguous": list(d.ambiguous),
        "unexplained_where": windows_json(d.unexplained_where),
    }
    out["proposed"] = [p.to_json(_equation(p, d.units)) for p in d.proposed]
    if d.validation is not None:
        out["validation"] = {"before": {"nrmse": d.validation.nrmse_before},
                             "after": {"nrmse": d.validation.nrmse_after}}
    return out


def _equation(p: ProposedTerm, units: tuple[str, str]) -> str:
    return equation(dict(zip(p.keys, p.coefs, strict=True)), *units)


def _warning(d: Diagnosis) -> str | None:
    """The unexplained-residual warning (only when effects were named: otherwise the report
    already says that no catalog effect explains the residual)."""
    if not d.effects:
        return None
    w = unexplained(d.residual_after.rms, d.residual_after.noise_std)
    if w is None or not d.unexplained_where:
        return w
    return w + where_text(d.unexplained_where)


def to_text(d: Diagnosis, source: str = "") -> str:
    """A human-readable report."""
    lines = [f"teleop diagnose {source}".rstrip(),
             f"analysis: {d.analysis} ({d.analysis_reason})",
             "nominal fit: " + ", ".join(f"{k}={_fmt(v)}" for k, v in d.nominal_params),
             f"residual of the nominal model: rms {_fmt(d.residual_before.rms)}, noise "
             f"{_fmt(d.residual_before.noise_std)}, lag-1 autocorrelation "
             f"{d.residual_before.lag1_autocorr:.2f}, whiteness {d.residual_before.whiteness:.2f}"]
    if d.residual_before.corr:
        lines.append("  correlation with " + ", ".join(f"{k} {v:+.2f}"
                                                       for k, v in d.residual_before.corr))
    if d.effects:
        lines.append("missing physics (best first):")
        for i, e in enumerate(d.effects, 1):
            ps = ", ".join(f"{k}={_fmt(v)}" for k, v in e.params)
            unc = dict(e.std).get(e.name, math.nan)
            lines.append(f"  {i}. {e.name}: {ps} (+-{_fmt(unc)}), score {e.delta_bic:.1f}, "
                         f"held-out gain {e.holdout_gain:.1%}")
            lines.append(f"     {e.explanation}")
        if _warning(d):
            lines.append(f"WARNING: {_warning(d)}")
        lines += [f"note: {a}" for a in d.ambiguous]
    elif d.proposed:
        lines.append("missing physics: no catalog effect (the terms below explain it)")
    elif d.residual_after.rms_over_noise < 3.0:
        lines.append("missing physics: none the data support (the nominal model explains the "
                     "recording to the noise)")
    else:
        lines.append(f"missing physics: no catalog effect improves the fit enough, yet the "
                     f"residual is {d.residual_after.rms_over_noise:.0f}x the noise (physics "
                     f"outside the catalog, or a start-up transient)")
    if d.proposed:
        held = "simulation" if d.analysis == "output-error" else "inverse dynamics"
        lines.append("physics outside the catalog, proposed by sparse regression on the "
                     f"force-domain residual and kept by held-out {held}:")
        for p in d.proposed:
            lines.append(f"  {_equation(p, d.units)}")
            lines.append(f"     score {p.score:.1f}, held-out gain {p.holdout_gain:.1%}")
    if d.ranking:
        lines.append("candidates (score vs nominal): " + ", ".join(
            f"{n} {b:.0f}" for n, b in d.ranking))
    if d.windows:
        lines.append(f"windows where the nominal residual exceeds the noise ({len(d.windows)}):")
        for w in d.windows[:12]:
            lines.append(f"  {w.t_start_s:8.3f} - {w.t_end_s:8.3f} s  x{w.excess:.1f}  {w.why}")
        if len(d.windows) > 12:
            lines.append(f"  ... {len(d.windows) - 12} more")
    else:
        lines.append("windows: none (the nominal residual stays at the noise level)")
    lines.append(f"fit NRMSE: before {_fmt(d.nrmse_before)}, after {_fmt(d.nrmse_after)}")
    if d.validation is not None:
        lines.append(f"validation NRMSE: before {_fmt(d.validation.nrmse_before)}, after "
                     f"{_fmt(d.validation.nrmse_after)}")
    return "\n".join(lines)
