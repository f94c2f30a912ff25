"""The finger model as a ``teleop diagnose`` nominal model (static weight test, Table 4.2).

A recording holds one static equilibrium per row: ``tendon_force_n`` (a weight hung on the
detached tendon) and the measured ``proximal_angle_rad``; ``t_s`` is just a sample index.  The
nominal model is :func:`sim.finger.weight_equilibrium` with the base spring and its preload
refined within +-tolerance; candidate effects are those that act on a detached finger: a cubic
base spring (``nonlinear_stiffness``), a gravity moment (``gravity``) and an angle offset
(``sensor_offset``, e.g. the plastic set of the flexure the seed report blames).
"""

from __future__ import annotations

import argparse
from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import NDArray

from sim.finger import weight_equilibrium
from sim.finger_dynamic import (
    DYNAMIC_EXPERIMENTS,
    FingerDynamicModel,
    Fit,
    diagnose_dynamic,
    dynamic_data,
    print_progress,
)
from sim.finger_dynamic import PARAMS as PARAMS_DYN
from sim.params import FingerParams, default_finger_params
from teleop.analysis.candidates import explanation
from teleop.effects import EffectSet
from teleop.errors import RecordingError
from teleop.recording import Recording

Array = NDArray[np.float64]

PARAMS = ("k_base_nm_per_rad", "base_preload_rad")


@dataclass(frozen=True)
class FingerStaticModel:
    """NominalModel adapter: proximal angle at static equilibrium under each tendon force."""

    base: FingerParams
    tolerance: float = 0.2
    name: str = "finger"

    def param_names(self) -> tuple[str, ...]:
        """Refined parameters."""
        return PARAMS

    def initial(self) -> Array:
        """The calibrated values."""
        return np.array([getattr(self.base, n) for n in PARAMS])

    def bounds(self) -> tuple[Array, Array]:
        """+-tolerance around the calibrated values."""
        x = self.initial()
        return x * (1 - self.tolerance), x * (1 + self.tolerance)

    def candidates(self) -> tuple[str, ...]:
        """Effects that act on the detached finger."""
        return ("sensor_offset", "nonlinear_stiffness", "gravity")

    def simulate(self, theta: Array, effects: EffectSet, t_s: Array,
                 u: Array | None) -> Array:
        """Proximal angle (plus sensor offset) at each force in ``u``."""
        p = replace(self.base, **{n: float(v) for n, v in zip(PARAMS, theta, strict=True)})
        forces = np.zeros(len(t_s)) if u is None else u
        neutral = replace(effects, sensor_offset=0.0)
        out = [weight_equilibrium(p, float(f), effects=neutral)[0] for f in forces]
        return np.asarray(out) + effects.sensor_offset


DYNAMIC_COLUMNS = ("motor_cmd_units", "setpoint_rad", "motor_angle_rad")
"""Columns only a dynamic finger recording (``teleop sim force-step|force-blocks|position``) has."""


def _require_static(path: object, rec: Recording) -> None:
    """Refuse, at once and in one line, a recording neither static nor a supported dynamic one."""
    exp = rec.meta_value("experiment")
    if exp is not None or any(c in rec.columns for c in DYNAMIC_COLUMNS):
        what = f"a '{exp}' recording" if exp else "a dynamic recording without '# experiment:'"
        raise RecordingError(
            f"{path}: --model finger supports static weight tables (one equilibrium per row: "
            f"tendon_force_n -> proximal_angle_rad) and one 'teleop sim "
            f"{'|'.join(DYNAMIC_EXPERIMENTS)}' recording, not {what}; use --model axis "
            "--input motor_cmd_units --output motor_angle_rad")


def diagnose_finger_dynamic(args: argparse.Namespace, rec: Recording) -> int:
    """``teleop diagnose REC --model finger`` on a dynamic finger recording."""
    from teleop.commands.common import info, write_json

    out = args.output_col or "motor_angle_rad"
    if out not in ("motor_angle_rad", "proximal_angle_rad"):
        raise RecordingError(f"{rec.source}: --model finger --output must be motor_angle_rad "
                             f"or proximal_angle_rad (got {out!r})")
    data = dynamic_data(rec, out)
    model = FingerDynamicModel(default_finger_params(), data, args.tolerance)
    quiet = getattr(args, "json_path", None) is not None and str(args.json_path) == "-"
    d = diagnose_dynamic(model, progress=None if quiet else print_progress)
    ym = d.y_meas

    def nr(f: Fit) -> float:
        return float(np.linalg.norm(f.y - ym) / np.linalg.norm(ym - np.mean(ym)))

    lines = [f"teleop diagnose {rec.source} --model finger (dynamic "
             f"'{rec.meta_value('experiment')}' recording, output-error on {out}, physics step "
             f"{model.dt_s * 1e3:.1f} ms, {len(ym)} samples)",
             "nominal fit (refined within +-tolerance): "
             + ", ".join(f"{k}={v:.4g}" for k, v in zip(PARAMS_DYN, d.nominal.theta,
                                                        strict=True))]
    if d.chosen:
        for i, (name, val, gain) in enumerate(d.chosen, 1):
            lines.append(f"  {i}. {name}={val:.4g} (residual sum of squares -{gain:.0%}): "
                         f"{explanation(name, val)}")
    else:
        lines.append("missing physics: none the data support above the floor "
                     f"({d.floor_rad:.2g} rad: noise and the physics step)")
    lines.append("candidates (relative RSS reduction, first step): "
                 + ", ".join(f"{n} {g:+.3f}" for n, g in d.ranking))
    lines.append(f"fit NRMSE: before {nr(d.nominal):.4g}, after {nr(d.final):.4g}")
    info(args, "\n".join(lines))
    write_json(args.json_path, {
        "model": "finger", "analysis": "output-error",
        "effects": [{"name": n, "params": {n: v}, "rss_reduction": g,
                     "explanation": explanation(n, v)} for n, v, g in d.chosen],
        "windows": [],
        "fit": {"before": {"nrmse": nr(d.nominal),
                           "params": dict(zip(PARAMS_DYN, d.nominal.theta, strict=True))},
                "after": {"nrmse": nr(d.final),
                          "params": {**dict(zip(PARAMS_DYN, d.final.theta, strict=True)),
                                     **dict(d.final.effects)}}},
        "ranking": [{"name": n, "rss_reduction": g} for n, g in d.ranking]})
    return 0


def diagnose_finger(args: argparse.Namespace) -> int:
    """``teleop diagnose REC --model finger``: static weight recordings against the finger."""
    from teleop.analysis.generic import diagnose_model
    from teleop.commands.common import info, write_json
    from teleop.recording import read_recording

    recs = [read_recording(p, allow_nan=False) for p in args.recordings]
    if len(recs) == 1 and recs[0].meta_value("experiment") in DYNAMIC_EXPERIMENTS:
        return diagnose_finger_dynamic(args, recs[0])
    for p, r in zip(args.recordings, recs, strict=True):
        _require_static(p, r)
    u_col = args.input_col or "tendon_force_n"
    y_col = args.output_col or "proximal_angle_rad"
    u = np.concatenate([r.column(u_col) for r in recs])
    y = np.concatenate([r.column(y_col) for r in recs])
    if len(y) < 3:
        raise RecordingError(f"{args.recordings[0]}: {len(y)} rows is too short (need >= 3)")
    t = np.arange(len(y), dtype=float)
    model = FingerStaticModel(default_finger_params(), args.tolerance)
    noise = float(getattr(args, "noise_rad", None) or 0.1 / np.sqrt(12))  # 0.1 rad protractor
    d = diagnose_model(model, t, u, y, noise,
                       starts={"sensor_offset": (-0.1, 0.1), "nonlinear_stiffness": (-1.0, 1.0),
                               "gravity": (-1.0, 1.0)},
                       effect_bounds={"sensor_offset": (-0.5, 0.5),
                                      "nonlinear_stiffness": (-50.0, 50.0),
                                      "gravity": (-50.0, 50.0)})
    y_cal = model.simulate(model.initial(), EffectSet(), t, u)
    cal = float(np.linalg.norm(y_cal - y) / np.linalg.norm(y - np.mean(y)))
    lines = [f"teleop diagnose {' '.join(map(str, args.recordings))} --model finger "
             "(static weight test, output-error)",
             f"calibrated finger (sim.params defaults): NRMSE {cal:.4g}",
             "nominal fit (refined within +-tolerance): "
             + ", ".join(f"{k}={v:.4g}" for k, v in d.nominal_params)]
    for f, m, a, b in zip(u, y, d.y_nominal, d.y_final, strict=True):
        lines.append(f"  {f:6.2f} N: measured {m:.3f} rad, nominal {a:.3f}, augmented {b:.3f}")
    if d.effects:
        for e in d.effects:
            lines.append(f"effect: {e.name}={e.params[0][1]:.4g} (+-{e.std[0][1]:.2g}), "
                         f"delta BIC {e.delta_bic:.1f}: {e.explanation}")
    else:
        lines.append("missing physics: none the data support at the stated resolution "
                     f"({noise:.3f} rad)")
    lines.append("candidates (delta BIC): " + ", ".join(f"{n} {b:.1f}" for n, b in d.ranking))
    lines.append(f"fit NRMSE: before {d.nrmse_before:.4g}, after {d.nrmse_after:.4g}")
    if getattr(args, "plot", None) is not None:
        lines.append("plot: not produced for --model finger (static points; see the table)")
    info(args, "\n".join(lines))
    write_json(args.json_path, {
        "model": "finger", "analysis": "output-error",
        "effects": [{"name": e.name, "params": dict(e.params), "delta_bic": e.delta_bic,
                     "uncertainty": dict(e.std), "explanation": e.explanation}
                    for e in d.effects],
        "windows": [],
        "fit": {"calibrated": {"nrmse": cal},
                "before": {"nrmse": d.nrmse_before, "params": dict(d.nominal_params)},
                "after": {"nrmse": d.nrmse_after, "params": dict(d.final_params)}},
        "ranking": [{"name": n, "delta_bic": b} for n, b in d.ranking]})
    return 0
