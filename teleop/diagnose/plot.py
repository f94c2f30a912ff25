"""Plot of a diagnosis: measured vs nominal vs augmented, the residual, windows shaded."""

from __future__ import annotations

from pathlib import Path

from teleop.diagnose.diagnose import Diagnosis
from teleop.errors import UserInputError


def plot_diagnosis(d: Diagnosis, path: str | Path, title: str = "") -> None:
    """Write a two-panel PNG (matplotlib, Agg backend)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    tr = d.traces
    fig, (ax1, ax2) = plt.subplots(2, 1, sharex=True, figsize=(10, 6))
    ax1.plot(tr.t, tr.measured, "k.", ms=1.5, label="measured")
    ax1.plot(tr.t, tr.nominal, "C0-", lw=1, label=f"nominal (NRMSE {d.nrmse_before:.3g})")
    names = "+".join(e.name for e in d.effects) or "no effect"
    ax1.plot(tr.t, tr.augmented, "C3-", lw=1,
             label=f"augmented: {names} (NRMSE {d.nrmse_after:.3g})")
    unit = "position" if d.analysis == "output-error" else "effort"
    ax1.set_ylabel(unit)
    ax1.legend(loc="upper right", fontsize=8)
    ax1.set_title(title or f"teleop diagnose ({d.analysis})")
    ax2.plot(tr.t, tr.measured - tr.nominal, "C0-", lw=0.8, label="nominal residual")
    ax2.plot(tr.t, tr.residual, "C3-", lw=0.8, label="augmented residual")
    ax2.set_ylabel("residual")
    ax2.set_xlabel("t [s] (segments concatenated)")
    ax2.legend(loc="upper right", fontsize=8)
    for w in d.windows:
        for ax in (ax1, ax2):
            ax.axvspan(w.t_start_s, w.t_end_s, color="orange", alpha=0.2, lw=0)
    fig.tight_layout()
    try:
        Path(path).parent.mkdir(parents=True, exist_ok=True)
        fig.savefig(path, dpi=110)
    except OSError as exc:
        raise UserInputError(f"{path}: cannot write plot ({exc.strerror})") from None
    finally:
        plt.close(fig)
