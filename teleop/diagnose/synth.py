"""Synthetic axis recordings with concealed catalog effects (for proving ``teleop diagnose``).

A case draws a nominal axis (inertia, natural frequency, damping), an input signal (steps, a
chirp, band-limited random effort, or none for a free response), measurement noise and one or
more concealed effects with randomised magnitudes in ranges where they matter physically.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy import signal as sps

from teleop.diagnose.axis_model import ROTOR_FRACTION, Array, AxisParams, simulate_axis
from teleop.effects import EffectSet
from teleop.recording import Recording

SIGNALS: tuple[str, ...] = ("steps", "chirp", "random")
INPUT_COL = "torque_nm"
OUTPUT_COL = "angle_rad"


@dataclass(frozen=True, slots=True)
class SynthCase:
    """A generated recording and the truth behind it."""

    recording: Recording
    params: AxisParams
    effects: EffectSet
    signal: str
    noise_std: float
    seed: int


def input_signal(kind: str, t: Array, k: float, rng: np.random.Generator) -> Array:
    """An effort signal scaled to move the axis about one position unit."""
    if kind == "steps":
        u = np.zeros_like(t)
        tt = 0.3
        level = 0.0
        while tt < t[-1]:
            dur = rng.uniform(0.4, 1.2)
            level = rng.uniform(0.4, 1.0) * (1 if level <= 0 else -1) * k
            u[t >= tt] = level
            tt += dur
        return u
    if kind == "chirp":
        return 0.3 * k * sps.chirp(t, f0=0.2, t1=t[-1], f1=4.0, method="logarithmic")
    if kind == "random":
        fs = 1.0 / float(np.median(np.diff(t)))
        b, a = sps.butter(2, 3.0 / (fs / 2))
        w = sps.lfilter(b, a, rng.standard_normal(len(t) + 500))[500:]
        return 0.6 * k * w / float(np.std(w))
    raise ValueError(f"unknown signal kind {kind!r}")


def effect_value(name: str, p: AxisParams, u: Array | None, rng: np.random.Generator,
                 scale: float = 1.0) -> float:
    """A random magnitude for ``name`` on axis ``p`` (``scale`` multiplies the strength)."""
    k = p.stiffness
    sgn = 1.0 if rng.random() < 0.5 else -1.0
    if name == "dead_time":
        return scale * rng.uniform(0.03, 0.1)
    if name in ("coulomb_friction", "asymmetric_friction"):
        return scale * rng.uniform(0.06, 0.15) * k
    if name == "stiction":
        return scale * rng.uniform(0.15, 0.3) * k
    if name == "backlash":
        return scale * rng.uniform(0.06, 0.15)
    if name == "actuator_saturation":
        umax = float(np.max(np.abs(u))) if u is not None else 1.0
        return rng.uniform(0.45, 0.7) * umax
    if name == "actuator_gain":
        return rng.uniform(0.5, 0.7) if sgn < 0 else rng.uniform(1.4, 1.8)
    if name == "actuator_lag":
        return scale * rng.uniform(0.03, 0.08)
    if name == "sensor_offset":
        return sgn * scale * rng.uniform(0.05, 0.2)
    if name == "series_compliance":
        fr = rng.uniform(3.0, 6.0) / scale
        jr = ROTOR_FRACTION * p.inertia
        return (2 * math.pi * fr) ** 2 * jr * p.inertia / (jr + p.inertia)
    if name == "nonlinear_stiffness":  # hardening (a softening spring lets a chirp escape)
        return scale * rng.uniform(0.4, 0.8) * k
    if name == "gravity":
        return sgn * scale * rng.uniform(0.3, 0.5) * k
    raise ValueError(f"unknown effect {name!r}")


def make_case(effects: tuple[str, ...], signal: str | None, seed: int, *,
              duration_s: float = 6.0, rate_hz: float = 1000.0,
              noise_std: float | None = None) -> SynthCase:
    """Generate one case; ``signal=None`` is a free response released from about 1 unit."""
    rng = np.random.default_rng(seed)
    inertia = rng.uniform(0.5, 2.0)
    fn = rng.uniform(1.0, 2.0)
    zeta = rng.uniform(0.05, 0.15)
    k = inertia * (2 * math.pi * fn) ** 2
    p = AxisParams(inertia=inertia, viscous=2 * zeta * math.sqrt(k * inertia), stiffness=k,
                   stribeck_velocity=0.2)
    t = np.arange(int(duration_s * rate_hz)) / rate_hz
    u = None if signal is None else input_signal(signal, t, k, rng)
    eff = EffectSet()
    for name in effects:
        eff = eff.with_effect(name, effect_value(name, p, u, rng))
    sigma = rng.uniform(0.0005, 0.003) if noise_std is None else noise_std
    x0 = rng.uniform(0.8, 1.2) * (1 if rng.random() < 0.5 else -1) if u is None else 0.0
    y = simulate_axis(t, u, p, eff, x0=x0)
    y = y + sigma * rng.standard_normal(len(t))
    cols = {"t_s": t}
    if u is not None:
        cols[INPUT_COL] = u
    cols[OUTPUT_COL] = y
    meta = [("generator", "teleop.diagnose.synth"), ("seed", str(seed))]
    return SynthCase(Recording.from_columns(cols, meta), p, eff, signal or "free", sigma, seed)


def make_validation(case: SynthCase, signal: str | None, seed: int, *,
                    duration_s: float = 6.0, rate_hz: float = 1000.0) -> SynthCase:
    """Another recording of the same truth (parameters and effects) with a new input."""
    rng = np.random.default_rng(seed)
    p, eff = case.params, case.effects
    t = np.arange(int(duration_s * rate_hz)) / rate_hz
    u = None if signal is None else input_signal(signal, t, p.stiffness, rng)
    x0 = rng.uniform(0.8, 1.2) * (1 if rng.random() < 0.5 else -1) if u is None else 0.0
    y = simulate_axis(t, u, p, eff, x0=x0) + case.noise_std * rng.standard_normal(len(t))
    cols = {"t_s": t}
    if u is not None:
        cols[INPUT_COL] = u
    cols[OUTPUT_COL] = y
    rec = Recording.from_columns(cols, [("generator", "teleop.diagnose.synth"),
                                        ("seed", str(seed))])
    return SynthCase(rec, p, eff, signal or "free", case.noise_std, seed)
