"""The diagnose pipeline for the axis model: nominal fit, residual, windows, effects, ranking.

Pure functions over recordings; the result is a frozen :class:`Diagnosis`
(:mod:`teleop.diagnose.results`) that the terminal report, the JSON writer and the plot consume.
Effect selection lives in :mod:`teleop.diagnose.select`.

Analysis mode: output-error (simulate and compare positions) when the fitted nominal simulation
tracks the measurement (NRMSE below ``OE_DRIFT_NRMSE``); otherwise (a simulation that drifts or
diverges, typical of closed-loop data or an integrating axis) equation-error (inverse dynamics:
the effort residual on the filtered, differentiated position).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from teleop.diagnose import candidates as cand
from teleop.diagnose import library
from teleop.diagnose.axis_data import decimate, initial_state, recording_signals
from teleop.diagnose.axis_model import Array
from teleop.diagnose.ee_align import aligned_selection
from teleop.diagnose.ee_filter import concat_ee, contiguous, ee_signals
from teleop.diagnose.ee_noise import Raw, ee_noise, excess_windows, noise_level
from teleop.diagnose.equation_error import EEFit, ee_fit, model_equation_error
from teleop.diagnose.fit import (
    BEFORE,
    SHIFT,
    FitData,
    ModelFit,
    build,
    fit_model,
)
from teleop.diagnose.model import AxisNominal
from teleop.diagnose.multistart import fit_best, restarts
from teleop.diagnose.propose import select_with_library
from teleop.diagnose.propose_ee import select_ee_with_library
from teleop.diagnose.residual import analyse_residual, noise_std
from teleop.diagnose.results import (
    DiagnoseOptions,
    Diagnosis,
    EffectResult,
    ProposedTerm,
    Traces,
    Validation,
    nrmse,
)
from teleop.diagnose.select import OEPath
from teleop.diagnose.validate import validate_ee, validate_oe
from teleop.diagnose.windows import conditions, excess, locate_windows, moving_rms
from teleop.errors import RecordingError, UserInputError
from teleop.recording import Recording

OE_DRIFT_NRMSE = 0.7


def _fit_nominal(data: FitData, nominal: AxisNominal, start: dict[str, float],
                 opts: DiagnoseOptions) -> ModelFit:
    """Nominal output-error fit; if it tracks poorly from the equation-error start, grow the
    fitted horizon (first 20 %, 50 %, all of every segment) so the fit cannot lock onto a wrong
    oscillation."""
    fit = fit_best(data, nominal, restarts(start, nominal), (), opts.max_nfev * 4)
    if nrmse(data.y, fit.y_fit) < 0.05:
        return fit
    grown = start
    for frac in (0.2, 0.5, 1.0):
        mask = np.concatenate([np.arange(len(s.y)) < frac * len(s.y) for s in data.segments])
        g = fit_model(data, nominal, grown, (), opts.max_nfev * 4, mask=mask if frac < 1 else None)
        grown = g.as_dict()
    return g if g.rss < fit.rss else fit


def diagnose(recordings: Sequence[Recording], opts: DiagnoseOptions,
             validate: Recording | None = None) -> Diagnosis:
    """Diagnose what the nominal axis model misses in ``recordings``."""
    if not recordings:
        raise UserInputError("no recording given")
    raw = [recording_signals(r, opts) for r in recordings]
    has_input = opts.input_col is not None
    if has_input:  # the equation-error fit divides by the input's spread over them all
        u_all = np.concatenate([u for _, u, _ in raw if u is not None])
        if float(np.ptp(u_all)) == 0.0:
            raise RecordingError(f"{recordings[0].source}: column {opts.input_col!r} is "
                                 f"{float(u_all[0]):g} on every row: no input excites the "
                                 "model (for free motion leave --input out)")
    nominal = opts.nominal
    fixed_inertia = nominal.value("inertia") or 1.0
    sigs = [ee_signals(t, y, u) for t, u, y in raw]
    sig = concat_ee(sigs)
    # scales for start values and bounds
    vel = float(np.sqrt(np.mean(sig.v ** 2))) or 1.0
    umax = float(max(np.max(np.abs(u)) for _, u, _ in raw)) if has_input else 0.0  # type: ignore
    effort = (float(np.sqrt(np.mean(sig.u ** 2))) if sig.u is not None
              else fixed_inertia * float(np.sqrt(np.mean(sig.a ** 2))))
    pos = float(max(np.ptp(y) for _, _, y in raw))
    nom_ee = ee_fit(sig, nominal, {}, fixed_inertia)
    inertia = nom_ee.get("inertia", fixed_inertia) if has_input else fixed_inertia
    dur = float(sum(t[-1] - t[0] for t, _, _ in raw))
    dt = float(np.median(np.diff(raw[0][0])))
    scales = cand.Scales(effort or 1.0, pos, vel, umax, max(inertia, 1e-9), dur, dt)
    rate = min(opts.fit_rate_hz, max(100.0, opts.max_fit_samples / dur))
    segs = tuple(decimate(t, u, y, rate) for t, u, y in raw)
    max_dt = min(2e-3, float(np.median(np.diff(segs[0].t))))
    data = FitData(segs, max_dt, scales, fixed_inertia, 0.05 * vel)
    start = {n: c for n, c in zip(nom_ee.names, nom_ee.coef, strict=True)}
    if has_input and "inertia" in nominal.terms:
        start["inertia"] = max(start.get("inertia", inertia), 1e-6)
    for i, (t, _, y) in enumerate(raw):
        start[f"x0_{i}"], start[f"v0_{i}"] = initial_state(t, y)
    names = cand.applicable(nominal, has_input)
    noise = float(np.sqrt(np.mean([noise_std(y) ** 2 for _, _, y in raw])))

    nom_fit = _fit_nominal(data, nominal, start, opts)
    nom_nrmse = nrmse(data.y, nom_fit.y_fit)
    mode = opts.analysis
    if mode == "auto":
        if nom_nrmse < OE_DRIFT_NRMSE:
            mode, reason = "output-error", (f"the nominal simulation tracks the measurement "
                                            f"(NRMSE {nom_nrmse:.3f})")
        else:
            mode, reason = "equation-error", (f"the nominal simulation drifts (NRMSE "
                                              f"{nom_nrmse:.3g}); fitting inverse dynamics")
    else:
        reason = "chosen by --analysis"

    t_all = contiguous([s.t for s in segs])
    edge = np.zeros(len(sig.t), bool)  # filter transients at the ends of every segment
    m = int(3 * sig.fs_hz / sig.cutoff_hz)
    start_i = 0
    for s_ in sigs:
        edge[start_i: start_i + m] = True
        edge[start_i + len(s_.t) - m: start_i + len(s_.t)] = True
        start_i += len(s_.t)
    conds = conditions(sig.t, sig.x, sig.v, sig.u)
    signals = {"position": data.y}
    proposed: tuple[ProposedTerm, ...] = ()   # library terms outside the catalog
    if mode == "output-error":
        final, chosen, ranking, proposed, amb = select_with_library(
            OEPath(data, nominal, opts, names, sig, fixed_inertia, noise), nom_fit)
        r_before, r_after = data.y - nom_fit.y_fit, data.y - final.y_fit
        before, after = nom_nrmse, nrmse(data.y, final.y_fit)
        p_nom, e_nom = build(nom_fit.names, nom_fit.theta, data)
        p_fin, e_fin = build(final.names, final.theta, data)
        ee_nom = model_equation_error(sig, p_nom, e_nom)
        ee_fin = model_equation_error(sig, p_fin, e_fin)
        nominal_params = tuple((k, v) for k, v in nom_fit.as_dict().items()
                               if not k.startswith(("x0_", "v0_", BEFORE)))
        final_params = tuple((k, v) for k, v in final.as_dict().items()
                             if not k.startswith(("x0_", "v0_", BEFORE)))
        traces = Traces(t_all, data.y, nom_fit.y_fit, final.y_fit, r_after)
        if segs[0].u is not None:
            signals["input"] = np.concatenate([s.u for s in segs])  # type: ignore[misc]
    else:
        def select_ee(raw_a: list[Raw]):  # noqa: ANN202 (a local tuple)
            sig_a = concat_ee([ee_signals(t, y, u) for t, u, y in raw_a])
            floors: dict[int, tuple[EEFit, Array]] = {}

            def floor_of(f: EEFit) -> Array:
                """The fit's effort noise floor, worked out once per fit (the selection asks
                for the nominal's and the final's, and the report needs both again)."""
                hit = floors.get(id(f))
                if hit is None or hit[0] is not f:
                    hit = floors[id(f)] = (f, ee_noise(raw_a, sig_a, nominal, f, fixed_inertia,
                                                       ~edge))
                return hit[1]

            def noise_of(f: EEFit) -> float:
                return noise_level(floor_of(f), ~edge)

            return sig_a, floor_of, select_ee_with_library(
                sig_a, nominal, opts, names, fixed_inertia, scales, noise_of)

        shift_s, (sig, floor_of, selected) = aligned_selection(
            raw, nominal, fixed_inertia, select_ee, lambda r: r[2][1])
        nom_e, fin_e, chosen, ranking, proposed, amb = selected
        ee_nom, ee_fin = nom_e.residual, fin_e.residual
        tgt = (fixed_inertia * sig.a if sig.u is None else sig.u)[~edge]
        tgt_scale = float(np.linalg.norm(tgt - np.mean(tgt)))
        before = float(np.linalg.norm(ee_nom[~edge])) / tgt_scale
        after = float(np.linalg.norm(ee_fin[~edge])) / tgt_scale
        r_before, r_after = ee_nom, ee_fin
        aligned = ((SHIFT, shift_s),) if sig.u is not None else ()
        nominal_params = tuple(zip(nom_e.names, nom_e.coef, strict=True)) + aligned
        final_params = tuple(zip(fin_e.names, fin_e.coef, strict=True)) + fin_e.extra + aligned
        traces = Traces(sig.t, sig.u if sig.u is not None else fixed_inertia * sig.a,
                        (sig.u if sig.u is not None else fixed_inertia * sig.a) + ee_nom,
                        (sig.u if sig.u is not None else fixed_inertia * sig.a) + ee_fin, ee_fin)
        signals = {"position": sig.x}
        if sig.u is not None:
            signals["input"] = sig.u
    windows = locate_windows(sig.t, excess(sig.t, ee_nom, ee_fin, ~edge), conds)
    if not windows and mode == "output-error" and noise > 0:
        # no burst and no bias in the effort balance: where does the simulated position
        # depart from the measurement by more than the noise?
        dt_fit = float(np.median(np.diff(t_all)))
        score = moving_rms(r_before, int(0.2 / dt_fit)) / noise
        conds_fit = {k: np.interp(t_all, sig.t, m.astype(float)) > 0.5 for k, m in conds.items()}
        windows = locate_windows(t_all, score, conds_fit)
    if mode == "output-error":
        # a position residual: the measurement noise of the position
        noise_y = noise_std(data.y)
        stats_b = analyse_residual(r_before, noise_y, signals)
        stats_a = analyse_residual(r_after, noise_y, signals)
        conds_t = {k: np.interp(t_all, sig.t, m.astype(float)) > 0.5 for k, m in conds.items()}
        flat = np.full(len(t_all), noise_y)
        where = excess_windows(t_all, data.y, r_after, flat, np.ones(len(t_all), bool), conds_t)
    else:
        # an effort residual: the position noise carried through filter, derivatives and model
        ok = ~edge
        fl_b, fl_a = floor_of(nom_e), floor_of(fin_e)
        sig_ok = {k: v[ok] for k, v in signals.items()}
        stats_b = analyse_residual(r_before[ok], noise_level(fl_b, ok), sig_ok)
        stats_a = analyse_residual(r_after[ok], noise_level(fl_a, ok), sig_ok)
        where = excess_windows(sig.t, sig.x, r_after, fl_a, ok, conds)
    val = None
    if validate is not None:
        val = (validate_oe(validate, opts, data, nom_fit, final) if mode == "output-error"
               else validate_ee(validate, opts, nominal, nom_e, fin_e, fixed_inertia, shift_s))
    units = (library.units(opts.input_col, "effort units"),
             library.units(opts.output_col, "position units"))
    return Diagnosis(mode, reason, nominal_params, final_params, tuple(chosen), tuple(ranking),
                     windows, stats_b, stats_a, before, after, val, traces, proposed, units,
                     tuple(amb), where)


__all__ = ["DiagnoseOptions", "Diagnosis", "EffectResult", "Validation", "Traces", "diagnose",
           "nrmse", "noise_std"]
