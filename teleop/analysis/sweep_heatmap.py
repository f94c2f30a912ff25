"""Heat maps of the robustness grid: one PNG per controller, panels stable / passive /
transparency (felt over true force in the steady grasp); rows operator x object, columns
loss x jitter x delay.  matplotlib with the Agg backend (no display)."""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from teleop.analysis.sweep import SweepResult, SweepRun

__all__ = ["grid_matrix", "plot_heatmaps"]


def _key_row(r: SweepRun) -> tuple[str, str]:
    return (r.point.operator, r.point.object)


def _key_col(r: SweepRun) -> tuple[float, str, float]:
    return (r.point.loss, r.point.jitter or "none", r.point.delay_s)


def grid_matrix(runs: Sequence[SweepRun], value: str) -> tuple[np.ndarray, list[str], list[str]]:
    """(matrix, row labels, column labels) of metric ``value`` (nan where no run)."""
    rows = list(dict.fromkeys(_key_row(r) for r in runs))
    cols = sorted(dict.fromkeys(_key_col(r) for r in runs))
    m = np.full((len(rows), len(cols)), np.nan)
    for r in runs:
        v = getattr(r.metrics, value)
        m[rows.index(_key_row(r)), cols.index(_key_col(r))] = (
            math.nan if v is None else float(v))
    row_labels = [f"{op} / {ob}" for op, ob in rows]
    col_labels = [f"{d * 1000:.0f} ms, loss {loss:.0%}, {jit}" for loss, jit, d in cols]
    return m, row_labels, col_labels


def plot_heatmaps(result: SweepResult, path: str | Path) -> list[Path]:
    """Write ``<stem>-<controller>.png`` beside ``path``; return the paths written."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.colors import ListedColormap

    base = Path(path)
    base.parent.mkdir(parents=True, exist_ok=True)
    out = []
    controllers = list(dict.fromkeys(r.point.controller for r in result.runs))
    yesno = ListedColormap(["#d62728", "#2ca02c"])
    for c in controllers:
        runs = [r for r in result.runs if r.point.controller == c]
        panels = [("stable", "stable (green) / unstable (red)", yesno, (0, 1)),
                  ("passive", "passive by the physical audit", yesno, (0, 1)),
                  ("felt_true_force_ratio", "felt / true force, steady grasp", "viridis",
                   (0, 1.2))]
        mats = [grid_matrix(runs, key) for key, *_ in panels]
        n_rows, n_cols = mats[0][0].shape
        fig, axes = plt.subplots(1, 3, figsize=(6 + 1.1 * n_cols, 2 + 0.32 * n_rows),
                                 sharey=True, squeeze=False)
        for ax, (key, title, cmap, (lo, hi)), (m, rl, cl) in zip(axes[0], panels, mats,
                                                                  strict=True):
            im = ax.imshow(np.ma.masked_invalid(m), cmap=cmap, vmin=lo, vmax=hi,
                           aspect="auto", interpolation="nearest")
            ax.set_title(title, fontsize=9)
            ax.set_xticks(range(len(cl)), cl, rotation=90, fontsize=6)
            ax.set_yticks(range(len(rl)), rl, fontsize=7)
            ax.set_facecolor("#bbbbbb")  # no contact (ratio undefined)
            if key == "felt_true_force_ratio":
                fig.colorbar(im, ax=ax, fraction=0.04)
        fig.suptitle(f"{c}: robustness grid ({len(runs)} runs)")
        fig.tight_layout()
        p = base.with_name(f"{base.stem}-{c}{base.suffix or '.png'}")
        fig.savefig(p, dpi=90)
        plt.close(fig)
        out.append(p)
    return out
