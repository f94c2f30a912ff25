"""Validation of a diagnosis on a held-out recording: both models' NRMSE, output-error (only
the initial state fitted) or equation-error (effort)."""

from __future__ import annotations

import numpy as np
from scipy import optimize

from teleop.diagnose.axis_data import decimate, initial_state, recording_signals
from teleop.diagnose.axis_model import Array
from teleop.diagnose.ee_align import shifted
from teleop.diagnose.ee_filter import ee_signals
from teleop.diagnose.equation_error import EEFit, ee_apply
from teleop.diagnose.fit import BEFORE, FitData, ModelFit, simulate
from teleop.diagnose.model import AxisNominal
from teleop.diagnose.results import DiagnoseOptions, Validation, nrmse
from teleop.errors import UserInputError
from teleop.recording import Recording


def validate_oe(rec: Recording, opts: DiagnoseOptions, data: FitData, nom: ModelFit,
              final: ModelFit) -> Validation:
    """NRMSE of both models on a held-out recording (only the initial state is fitted)."""
    t, u, y = recording_signals(rec, opts)
    if (u is None) != (not data.has_input):
        raise UserInputError(f"{rec.source}: validation recording must match the input setup")
    seg = decimate(t, u, y, 1.0 / float(np.median(np.diff(data.segments[0].t))))
    vdata = FitData((seg,), data.max_dt_s, data.scales, data.fixed_inertia,
                    data.stribeck_velocity)
    x0, v0 = initial_state(t, y)
    out = []
    for f in (nom, final):
        start = {**{k: v for k, v in f.as_dict().items()
                    if not k.startswith(("x0_", "v0_", BEFORE))},
                 "x0_0": x0, "v0_0": v0}
        out.append(nrmse(seg.y, _fit_state_only(vdata, start)))
    return Validation(out[0], out[1])


def validate_ee(rec: Recording, opts: DiagnoseOptions, nominal: AxisNominal, nom: EEFit,
                 final: EEFit, fixed_inertia: float, shift_s: float) -> Validation:
    """Equation-error NRMSE (effort) of both fitted models on a held-out recording (its input
    aligned as the fitted recordings' was)."""
    ((t, u, y),) = shifted([recording_signals(rec, opts)], shift_s)
    sig = ee_signals(t, y, u)
    m = int(3 * sig.fs_hz / sig.cutoff_hz)
    keep = slice(m, len(t) - m)
    tgt = (fixed_inertia * sig.a if sig.u is None else sig.u)[keep]
    scale = float(np.linalg.norm(tgt - np.mean(tgt))) or 1.0
    return Validation(*(float(np.linalg.norm(ee_apply(sig, nominal, f, fixed_inertia)[keep]))
                        / scale for f in (nom, final)))


def _fit_state_only(data: FitData, start: dict[str, float]) -> Array:
    """Simulation with every parameter fixed but the initial state (fitted)."""
    names = tuple(start)
    base = [start[k] for k in names]
    i0, i1 = names.index("x0_0"), names.index("v0_0")

    def theta(s: Array) -> tuple[float, ...]:
        th = list(base)
        th[i0], th[i1] = float(s[0]), float(s[1])
        return tuple(th)

    def resid(s: Array) -> Array:
        r = simulate(names, theta(s), data) - data.y
        return np.where(np.isfinite(r), r, 10 * data.scales.position)

    x0 = np.array([start["x0_0"], start["v0_0"]])
    res = optimize.least_squares(resid, x0, x_scale=np.array([data.scales.position,
                                                              data.scales.velocity]),
                                 max_nfev=40)
    return simulate(names, theta(res.x), data)
