"""Plot of a delay sweep (matplotlib, Agg backend; no display needed).

Four panels: the stability map over delay and controller/loss (green: stable and passive,
amber: stable but not passive, red: unstable; hatched: not passive), energy generated, tracking
error and force error against delay.  The predicted and measured largest stable delays are
drawn as vertical lines.
"""

from __future__ import annotations

from pathlib import Path

from teleop.analysis.sweep import SweepResult
from teleop.errors import UserInputError

__all__ = ["plot_sweep"]

_COLORS = {"two-layer": "tab:blue", "direct": "tab:red", "tdpa": "tab:green",
           "wave": "tab:purple", "pspm": "tab:orange"}
_LOSS_STYLES = ("-", "--", ":", "-.")


def _xpos(delays: list[float]) -> dict[float, int]:
    return {d: i for i, d in enumerate(delays)}


def plot_sweep(result: SweepResult, path: Path | str) -> Path:
    """Draw ``result`` into a PNG at ``path``; returns the path."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.patches import Patch, Rectangle

    runs = result.grid_runs()
    delays = sorted({r.point.delay_s for r in runs})
    losses = sorted({r.point.loss for r in runs})
    ctrls = list(dict.fromkeys(r.point.controller for r in runs))
    xi = _xpos(delays)
    fig, axes = plt.subplots(2, 2, figsize=(13, 8.5), constrained_layout=True)
    ax = axes[0, 0]
    rows = [(c, p) for c in ctrls for p in losses]
    for yi, (c, p) in enumerate(rows):
        for r in runs:
            if r.point.controller != c or r.point.loss != p:
                continue
            m = r.metrics
            color = ("#2ca02c" if m.passive else "#ffbf00") if m.stable else "#d62728"
            ax.add_patch(Rectangle((xi[r.point.delay_s] - 0.45, yi - 0.45), 0.9, 0.9,
                                   facecolor=color, hatch=None if m.passive else "//",
                                   edgecolor="k", linewidth=0.5))
    ax.set_xlim(-0.6, len(delays) - 0.4)
    ax.set_ylim(-0.6, len(rows) - 0.4)
    ax.set_xticks(range(len(delays)), [f"{d * 1000:g}" for d in delays], rotation=45)
    ax.set_yticks(range(len(rows)), [f"{c}, loss {p:.0%}" for c, p in rows])
    ax.invert_yaxis()
    ax.set_xlabel("one-way delay master<->controller [ms]")
    ax.set_title("stability map")
    ax.legend(handles=[Patch(facecolor="#2ca02c", label="stable, passive"),
                       Patch(facecolor="#ffbf00", hatch="//", label="stable, not passive"),
                       Patch(facecolor="#d62728", label="unstable"),
                       Patch(facecolor="#d62728", hatch="//", label="unstable, not passive")],
              loc="upper left", bbox_to_anchor=(1.0, 1.0), fontsize=8)

    panels = [(axes[0, 1], "audit_energy_generated_j",
               "energy generated, physical audit (max excess) [J]", "symlog"),
              (axes[1, 0], "tracking_rms_rad", "finger tracking RMS vs delayed command [rad]",
               "linear"),
              (axes[1, 1], "force_rms_n", "displayed vs delayed measured force RMS [N]",
               "linear")]
    for axp, key, label, scale in panels:
        for c in ctrls:
            for li, p in enumerate(losses):
                pts = sorted((r.point.delay_s, getattr(r.metrics, key)) for r in runs
                             if r.point.controller == c and r.point.loss == p)
                axp.plot([d for d, _ in pts], [v for _, v in pts],
                         _LOSS_STYLES[li % len(_LOSS_STYLES)], marker="o", ms=3,
                         color=_COLORS.get(c), label=f"{c}, loss {p:.0%}")
        axp.set_yscale(scale, **({"linthresh": 0.1} if scale == "symlog" else {}))
        axp.set_xlabel("one-way delay [s]")
        axp.set_title(label)
        axp.grid(True, alpha=0.3)
        for c, t in result.predicted_max_stable_delay_s:
            axp.axvline(t, color=_COLORS.get(c, "k"), ls="--", lw=0.8)
        for c, lo, hi in result.measured_bracket_s:
            if lo == lo and hi != float("inf"):  # a measured limit inside the grid
                axp.axvline(lo, color=_COLORS.get(c, "k"), ls=":", lw=0.8)
    axes[0, 1].legend(fontsize=7, ncol=2)
    pred = ", ".join(f"{c} {t * 1000:.1f} ms" for c, t in result.predicted_max_stable_delay_s)
    meas = ", ".join(
        f"{c} {'> ' if hi == float('inf') else ''}{lo * 1000:.1f} ms"
        for c, lo, hi in result.measured_bracket_s if lo == lo)
    fig.suptitle(f"delay sweep ({result.mode}, seed {result.seed}, >= {result.duration_s:g} s "
                 f"per run)\nlargest stable one-way delay at loss 0 - predicted (dashed): "
                 f"{pred or 'n/a'}; measured (dotted): {meas or 'n/a'}", fontsize=10)
    out = Path(path)
    try:
        out.parent.mkdir(parents=True, exist_ok=True)
        fig.savefig(out, dpi=110)
    except OSError as exc:
        raise UserInputError(f"{out}: cannot write plot ({exc.strerror})") from None
    finally:
        plt.close(fig)
    return out
