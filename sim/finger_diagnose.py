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
    DynamicData,
    FingerDynamicModel,
    dynamic_data,
)
from sim.finger_dynamic import PARAMS as PARAMS_DYN
from sim.finger_hand_rec import hand_finger_data, is_hand_recording
from sim.finger_model_file import write_model
from sim.finger_ripple import describe, split
from sim.params import FingerParams, default_finger_params
from teleop.diagnose.candidates import explanation
from teleop.diagnose.results import ProposedTerm
from teleop.diagnose.select_sim import DynamicDiagnosis, diagnose_dynamic, print_progress
from teleop.diagnose.select_sim_terms import without_pair
from teleop.diagnose.windows import windows_json
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


def _nrmse(y: Array, ym: Array) -> float:
    return float(np.linalg.norm(y - ym) / np.linalg.norm(ym - np.mean(ym)))


def _dynamic_report(d: DynamicDiagnosis, what: str, data: DynamicData, dt_s: float,
                    ripple: dict[str, float], span_rad: float = float("nan")
                    ) -> tuple[list[str], dict[str, object]]:
    """Report lines and JSON; ``ripple``: the shaft ripple found (``FingerParams`` fields,
    empty without one)."""
    ym = d.y_meas
    before, after = _nrmse(d.nominal.y, ym), _nrmse(d.final.y, ym)
    lines = [f"{what} (output-error on {data.output}, physics step {dt_s * 1e3:.1f} ms, "
             f"{len(ym)} samples compared)"]
    if data.note:
        lines.append(f"note: {data.note}")
    lines.append("nominal fit (refined within +-tolerance): "
                 + ", ".join(f"{k}={v:.4g}" for k, v in zip(PARAMS_DYN, d.nominal.theta,
                                                            strict=True)))
    if d.alignment:
        lines.append(f"input alignment: {d.alignment}")
    if d.chosen:
        lines.append("missing physics (best first):")
        for i, ((name, val, gain), v) in enumerate(zip(d.chosen, d.verdicts, strict=True), 1):
            lines.append(f"  {i}. {name}={val:.4g} (RSS -{gain:.0%}; {v.why}): "
                         f"{explanation(name, val)}")
    elif d.terms:
        lines.append("missing physics: no catalog effect (the term below explains it)")
    else:
        lines.append("missing physics: none the data support above the floor "
                     f"({d.floor_rad:.2g} rad: noise and the physics step)")
    tv = d.term_verdict
    if ripple and tv is not None:
        lines.append("physics outside the catalog, scanned over its wavenumber and kept by "
                     "held-out simulation:")
        lines.append(f"  {describe(ripple, span_rad)}")
        lines.append(f"     {tv.why}")
    lines += [f"note: {a}" for a in d.ambiguous]
    for name, why in d.rejected:
        lines.append(f"  not kept: {name} ({why})")
    if d.warning:
        lines.append(f"WARNING: {d.warning}")
    lines.append("candidates (relative RSS reduction, first step): "
                 + ", ".join(f"{n} {g:+.3f}" for n, g in d.ranking))
    lines.append(f"fit NRMSE: before {before:.4g}, after {after:.4g}")
    scores = dict(d.scores)
    doc: dict[str, object] = {
        "model": "finger", "analysis": "output-error",
        "selection": "penalised likelihood (effective sample size) + held-out gain",
        # "delta_bic": the shared rule's score, under the key every diagnose JSON uses
        # (DESIGN.md's contract; the axis path writes the same number as "delta_bic")
        "effects": [{"name": n, "params": {n: v}, "delta_bic": vd.score, "score": vd.score,
                     "rss_reduction": g,
                     "holdout_gain": vd.holdout_gain, "explanation": explanation(n, v)}
                    for (n, v, g), vd in zip(d.chosen, d.verdicts, strict=True)],
        "windows": [],
        "fit": {"before": {"nrmse": before,
                           "params": dict(zip(PARAMS_DYN, d.nominal.theta, strict=True))},
                "after": {"nrmse": after,
                          "params": {**dict(zip(PARAMS_DYN, d.final.theta, strict=True)),
                                     **dict(d.final.effects)}}},
        "ranking": [{"name": n, "rss_reduction": g,
                     **({"delta_bic": scores[n], "score": scores[n]} if n in scores else {})}
                    for n, g in d.ranking],
        "unexplained": d.warning,
        "unexplained_where": windows_json(d.unexplained_where),
        "note": data.note or None, "ambiguous": list(d.ambiguous),
        # the share of a row's span before it that each recorded command acts from
        "input_lead_share": getattr(getattr(d.model, "data", None), "input_lead", 0.0),
        # the axis path's key for terms outside the catalog
        "proposed": ([{**ProposedTerm(tuple(n for n, _ in d.terms),
                                      tuple(v for _, v in d.terms), tv.score,
                                      tv.holdout_gain).to_json(describe(ripple, span_rad)),
                       "params": ripple}] if ripple and tv is not None else [])}
    return lines, doc


def diagnose_finger_dynamic(args: argparse.Namespace, rec: Recording) -> int:
    """``teleop diagnose REC --model finger`` on a dynamic ``teleop sim`` recording or a
    ``teleop up --record`` hand recording (``--finger N``)."""
    from teleop.commands.common import info, write_json

    finger = getattr(args, "finger", None)
    if is_hand_recording(rec):
        if finger is None:
            raise RecordingError(f"{rec.source}: a hand recording holds three fingers; name one "
                                 "with --finger 1|2|3")
        data = hand_finger_data(rec, int(finger), args.output_col or "motor_angle_rad",
                                split_gaps=bool(getattr(args, "split_gaps", False)))
        what = (f"teleop diagnose {rec.source} --model finger --finger {finger} (hand "
                f"recording, set-points from 'setpoint_rad_f{finger}')")
    else:
        out = args.output_col or "motor_angle_rad"
        if out not in ("motor_angle_rad", "proximal_angle_rad"):
            raise RecordingError(f"{rec.source}: --model finger --output must be "
                                 f"motor_angle_rad or proximal_angle_rad (got {out!r})")
        data = dynamic_data(rec, out)
        what = (f"teleop diagnose {rec.source} --model finger (dynamic "
                f"'{rec.meta_value('experiment')}' recording)")
    model = FingerDynamicModel(default_finger_params(), data, args.tolerance)
    quiet = getattr(args, "json_path", None) is not None and str(args.json_path) == "-"
    d = diagnose_dynamic(model, progress=None if quiet else print_progress)
    ripple = split(d.terms)[1]
    lines, doc = _dynamic_report(d, what, data, model.physics_step_s(), ripple,
                                 model.shaft_span_rad())
    out = getattr(args, "write_params", None)
    if out is not None:
        write_model(out, {**dict(zip(PARAMS_DYN, d.final.theta, strict=True)), **ripple},
                    dict(without_pair(d.final.effects)), str(rec.source))
        lines.append(f"wrote the refined finger and its effects to {out} (load with --set "
                     f"hand.sim.model={out})")
    info(args, "\n".join(lines))
    write_json(args.json_path, doc)
    return 0


def diagnose_finger(args: argparse.Namespace) -> int:
    """``teleop diagnose REC --model finger``: static weight recordings against the finger."""
    from sim.parallel_runs import thread_count
    from teleop.commands.common import info, write_json
    from teleop.diagnose.generic import diagnose_model
    from teleop.recording import read_recording

    thread_count()  # a bad TELEOP_THREADS stops here, before any work
    recs = [read_recording(p, allow_nan=True).skip(getattr(args, "skip", 0.0))
            for p in args.recordings]
    if len(recs) == 1 and (recs[0].meta_value("experiment") in DYNAMIC_EXPERIMENTS
                           or is_hand_recording(recs[0])):
        return diagnose_finger_dynamic(args, recs[0])
    if any(is_hand_recording(r) for r in recs):
        raise RecordingError(f"{args.recordings[0]}: --model finger takes one hand recording "
                             "at a time")
    for p, r in zip(args.recordings, recs, strict=True):
        _require_static(p, r)
    u_col = args.input_col or "tendon_force_n"
    y_col = args.output_col or "proximal_angle_rad"
    for p, r in zip(args.recordings, recs, strict=True):
        for c in (u_col, y_col):
            bad = ~np.isfinite(r.column(c))
            if bad.any():
                raise RecordingError(f"{p}: column {c!r} is empty or not finite at data row "
                                     f"{int(np.argmax(bad)) + 1}")
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
                         f"score {e.delta_bic:.1f}: {e.explanation}")
    else:
        lines.append("missing physics: none the data support at the stated resolution "
                     f"({noise:.3f} rad)")
    lines.append("candidates (score, the shared rule; no held-out part in a few static "
                 "points): " + ", ".join(f"{n} {b:.1f}" for n, b in d.ranking))
    lines.append(f"fit NRMSE: before {d.nrmse_before:.4g}, after {d.nrmse_after:.4g}")
    if getattr(args, "plot", None) is not None:
        lines.append("plot: not produced for --model finger (static points; see the table)")
    out = getattr(args, "write_params", None)
    if out is not None:
        fin = dict(d.final_params)
        write_model(out, {k: fin[k] for k in PARAMS if k in fin},
                    {e.name: e.params[0][1] for e in d.effects}, str(args.recordings[0]))
        lines.append(f"wrote the refined finger and its effects to {out} (load with --set "
                     f"hand.sim.model={out})")
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
