"""Windows where the nominal model's residual exceeds the noise, labelled by operating condition.

The residual used is the equation error (effort units): it is instantaneous, so it sits where
the missing physics acts, unlike a simulation error that carries on after the cause.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from teleop.diagnose.axis_model import Array


@dataclass(frozen=True, slots=True)
class Window:
    """A time span where the residual exceeds the noise, and the condition that marks it."""

    t_start_s: float
    t_end_s: float
    why: str
    excess: float  # peak moving-rms residual over the noise level


def moving_rms(r: Array, width: int) -> Array:
    """Centered moving RMS over ``width`` samples."""
    width = max(1, width)
    k = np.ones(width) / width
    return np.sqrt(np.convolve(r ** 2, k, mode="same"))


def conditions(t: Array, x: Array, v: Array, u: Array | None) -> dict[str, Array]:
    """Per-sample boolean masks of operating conditions."""
    n = len(t)
    dt = float(np.median(np.diff(t))) if n > 1 else 1.0
    vrms = float(np.sqrt(np.mean(v ** 2))) or 1.0
    near = np.abs(v) < 0.1 * vrms
    rev = np.zeros(n, bool)
    idx = np.nonzero(np.diff(np.sign(v)) != 0)[0]
    span = max(1, int(0.05 / dt))
    for i in idx:
        rev[max(0, i - span): i + span] = True
    xc = x - np.median(x)
    out = {"velocity reversal": rev, "near-zero velocity": near,
           "large position": np.abs(xc) > 0.7 * np.max(np.abs(xc)),
           "high velocity": np.abs(v) > 0.7 * np.max(np.abs(v))}
    if u is not None:
        out["high load"] = np.abs(u) > 0.7 * np.max(np.abs(u))
        du = np.abs(np.diff(u, prepend=u[0]))
        step = np.zeros(n, bool)
        steps = np.nonzero(du > 0.2 * (np.max(u) - np.min(u) + 1e-300))[0]
        after = max(1, int(0.3 / dt))
        for i in steps:
            step[i: i + after] = True
        out["after a command step"] = step
    return out


def label(mask_window: Array, conds: dict[str, Array]) -> str:
    """The condition(s) over-represented in the window (enrichment > 1.3, present > 25 %)."""
    scored = []
    for name, m in conds.items():
        overall = float(np.mean(m))
        inside = float(np.mean(m[mask_window]))
        if overall > 0 and inside > 0.25 and inside / overall > 1.3:
            scored.append((inside / overall, name))
    scored.sort(reverse=True)
    if not scored:
        return "no operating condition stands out"
    return " + ".join(name for _, name in scored[:2])


def moving_mean(r: Array, width: int) -> Array:
    """Centered moving average over ``width`` samples."""
    width = max(1, width)
    return np.convolve(r, np.ones(width) / width, mode="same")


def robust_std(r: Array) -> float:
    """1.4826 x median absolute deviation."""
    return 1.4826 * float(np.median(np.abs(r - np.median(r)))) if len(r) else 0.0


def excess(t: Array, r_nominal: Array, r_final: Array, valid: Array,
           fast_s: float = 0.05, slow_s: float = 0.2, bursts: float = 3.0) -> Array:
    """How far the nominal residual stands above the noise, per sample (in noise units).

    Two views: the moving RMS over ``fast_s`` against the final model's robust noise level
    (bursts: reversals, steps, saturation); when no burst exceeds ``bursts``, the moving mean
    over ``slow_s`` against the spread of the final model's moving mean (a small persistent
    bias, such as friction in a free swing).
    """
    dt = float(np.median(np.diff(t)))
    noise = robust_std(r_final[valid])
    fast = moving_rms(r_nominal, int(fast_s / dt)) / noise if noise > 0 else np.zeros(len(t))
    sm_fin = moving_mean(r_final, int(slow_s / dt))
    spread = robust_std(sm_fin[valid])
    slow = (np.abs(moving_mean(r_nominal, int(slow_s / dt))) / spread if spread > 0
            else np.zeros(len(t)))
    fast = np.where(valid, fast, 0.0)
    return fast if np.max(fast) > bursts else np.where(valid, slow, 0.0)


def locate_windows(t: Array, score: Array, conds: dict[str, Array], min_len_s: float = 0.02,
                   merge_s: float = 0.1, factor: float = 3.0,
                   max_windows: int = 50) -> tuple[Window, ...]:
    """Spans where ``score`` (residual over noise, see :func:`excess`) exceeds ``factor``."""
    if len(t) < 3:
        return ()
    dt = float(np.median(np.diff(t)))
    mr = score
    over = mr > factor
    # merge short gaps
    idx = np.flatnonzero(over)
    if len(idx) == 0:
        return ()
    spans: list[list[int]] = [[int(idx[0]), int(idx[0])]]
    gap = int(merge_s / dt)
    for i in idx[1:]:
        if i - spans[-1][1] <= gap:
            spans[-1][1] = int(i)
        else:
            spans.append([int(i), int(i)])
    out = []
    for a, b in spans:
        if (b - a) * dt < min_len_s:
            continue
        m = np.zeros(len(t), bool)
        m[a: b + 1] = True
        out.append(Window(float(t[a]), float(t[b]), label(m, conds),
                          float(np.max(mr[a: b + 1]))))
    out.sort(key=lambda w: -w.excess)
    return tuple(sorted(out[:max_windows], key=lambda w: w.t_start_s))


def where_text(windows: tuple[Window, ...], top: int = 3) -> str:
    """The largest ``top`` windows as report text: "; where (largest first): a-b s (xE, why)"."""
    if not windows:
        return ""
    big = sorted(windows, key=lambda x: -x.excess)[:top]
    return "; where (largest first): " + "; ".join(
        f"{x.t_start_s:.3g}-{x.t_end_s:.3g} s (x{x.excess:.1f}, {x.why})" for x in big) + (
        f"; {len(windows) - top} more" if len(windows) > top else "")


def windows_json(windows: tuple[Window, ...]) -> list[dict[str, object]]:
    """The windows as the diagnose JSON writes them (``windows``, ``unexplained_where``)."""
    return [{"t_start_s": w.t_start_s, "t_end_s": w.t_end_s, "why": w.why, "excess": w.excess}
            for w in windows]
