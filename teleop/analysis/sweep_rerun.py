"""Log a delay sweep to a rerun ``.rrd`` file (``teleop sweep --rerun PATH``).

Entities, per run ``<controller>/loss_<pct>/delay_<ms>ms``:
``signals/...`` the run's time series on the ``t`` timeline (when the sweep kept them), and
``metrics/<controller>/loss_<pct>/<metric>`` scalars on the ``delay_ms`` timeline, so the viewer
shows each metric against delay.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from teleop.analysis.sweep import SweepResult
from teleop.errors import UserInputError

__all__ = ["log_sweep"]

_METRICS = ("energy_generated_j", "tracking_rms_rad", "force_rms_n", "tank_min_j",
            "oscillation_index", "limited_fraction")


def log_sweep(result: SweepResult, path: Path | str) -> Path:
    """Write ``result`` (metrics, and signals when kept) to the rerun file ``path``."""
    import rerun as rr

    out = Path(path)
    try:
        out.parent.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise UserInputError(f"{out}: cannot create directory ({exc.strerror})") from None
    rec = rr.RecordingStream("teleop_sweep")
    try:
        rec.save(str(out))
    except (RuntimeError, OSError) as exc:
        raise UserInputError(f"{out}: cannot write the rerun log ({exc})") from None
    for r in result.runs:
        p, m = r.point, r.metrics
        group = f"{p.controller}/loss_{p.loss * 100:.0f}"
        rec.set_time("delay_ms", sequence=int(round(p.delay_s * 1000)))
        for key in _METRICS:
            value = float(getattr(m, key))
            if np.isfinite(value):
                rec.log(f"metrics/{group}/{key}", rr.Scalars(value))
        rec.log(f"metrics/{group}/stable", rr.Scalars(1.0 if m.stable else 0.0))
        rec.log(f"metrics/{group}/passive", rr.Scalars(1.0 if m.passive else 0.0))
        s = r.signals
        if s is None:
            continue
        base = f"signals/{group}/delay_{p.delay_s * 1000:g}ms"
        times = [rr.TimeColumn("t", duration=np.asarray(s.t_s, float))]
        for name, values in (("setpoint_rad", s.setpoint_rad), ("finger_rad", s.finger_rad),
                             ("force_displayed_n", s.force_displayed_n),
                             ("force_measured_n", s.force_measured_n),
                             ("energy_out_j", s.energy_out_j), ("energy_in_j", s.energy_in_j)):
            rr.send_columns(f"{base}/{name}", indexes=times,
                            columns=rr.Scalars.columns(scalars=np.asarray(values, float)),
                            recording=rec)
    rec.flush()
    rec.disconnect()
    return out
