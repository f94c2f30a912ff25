"""Physics outside the catalog for a simulated model: a position-periodic force as one more
candidate of the engine (:mod:`teleop.diagnose.select_sim`).

A model that can carry the library's sin/cos pair (:mod:`teleop.diagnose.library`; the finger's
shaft ripple, ``sim/finger_ripple.py``) says which wavenumbers to scan (``ripple_waves()``).
The pair competes with the catalog effects under the same rule, its scanned wavenumber counted
as one more parameter: where a cogging force was read as Coulomb friction or stiction before
(the independent finger batch), the catalog effect now has to beat it.

Scanning a wavenumber by full fits would cost a fit per grid point.  Instead the output's
sensitivity to each of the pair's amplitudes (a secant over the model's ``ripple_probe``, an
amplitude typical of the physics; the other values held) is simulated at every wavenumber and
the residual regressed on the two.  That scan is rugged (a dip is a few grid steps wide, and
the linearised pair ranks the dips only roughly), so its :data:`STARTS` lowest dips are each
refined on a finer grid and fitted jointly with the refined parameters and the effects
already chosen; the best fit is the candidate.  Over many periods (:data:`MANY_PERIODS`) a
periodogram of the residual against the measured position (``ripple_position()``) gives one
more start: its amplitudes sized by simulation along the residual's phase, fitted twice in a
row, its wavenumber then polished by simulation.

Independent simulations and fits go through the model's ``map`` when it has one
(:func:`each`; the finger runs them on every core, with the same results).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np

from teleop.diagnose.library import PERIODIC, Term

Array = np.ndarray

#: amplitude of the probe simulations when the model states none (``ripple_probe``)
PROBE = 1.0
#: points of the refining grid, over half a scan step either side
REFINE = 5
#: dips of the scan fitted in full
STARTS = 3
#: wavenumbers whose probe simulations run at once
CHUNK = 32
#: a recording whose measured position range holds more than this many periods of some
#: scanned wavenumbers gets, besides the probe scan's dips, the lowest dip of a periodogram of
#: the residual against that position over those wavenumbers as one more start: over many
#: periods a pair of the amplitude that matters moves the position by a good part of a
#: period, and the probes' linearisation can rank the dips wrongly (a 1 N shaft ripple at 100
#: rad^-1 over 33 periods: the probes' lowest dips 106.7, 65.7 and 92.5 rad^-1, the
#: periodogram's 99.8), while where the response is a transient rather than a shifted rest
#: the periodogram is the one that misses (a lag model in the tests), so neither replaces the
#: other and the fits decide
MANY_PERIODS = 8.0
#: points of the periodogram's refining grid, over half a scan step either side
FINE = 21
#: sizes (times the probe amplitude) a periodogram start's amplitudes are tried at
SIZES = (0.5, 1.0, 2.0)


def pair(wave: float, a: float, b: float) -> tuple[tuple[str, float], ...]:
    """The (name, value) pairs of a sin/cos pair in a fit."""
    return ((Term("sin", wave).key, a), (Term("cos", wave).key, b))


def has_pair(effects: tuple[tuple[str, float], ...]) -> bool:
    """Whether a fit carries a sin/cos pair."""
    return any(Term.is_key(n) for n, _ in effects)


def without_pair(effects: tuple[tuple[str, float], ...]) -> tuple[tuple[str, float], ...]:
    """The catalog effects of a fit."""
    return tuple((n, v) for n, v in effects if not Term.is_key(n))


def each(model: Any, fn: Callable[[Any], Any], items: list[Any]) -> list[Any]:
    """``[fn(x) for x in items]`` through the model's own ``map`` when it has one (the
    finger's runs independent simulations on every core, with the same results), else here
    one by one."""
    m = getattr(model, "map", None)
    if m is not None:
        return list(m(fn, items))
    return [fn(x) for x in items]


def runs(model: Any, jobs: list[tuple[Any, tuple[tuple[str, float], ...]]]) -> list[Array]:
    """``model.run`` of every ``(theta, effects)`` job, in order (:func:`each`)."""
    return each(model, lambda j: model.run(*j), jobs)


def _explained(model: Any, current: Any, waves: list[float], r: Array, tr: Array
               ) -> list[tuple[float, float, float]]:
    """(RSS left, sin and cos amplitude) of the linearised pair at each of ``waves`` on
    residual ``r`` (the probe simulations of all of them at once: :func:`runs`)."""
    probe = float(getattr(model, "ripple_probe", PROBE))
    out = []
    for k in range(0, len(waves), CHUNK):  # (a chunk's outputs held at once, not the scan's)
        chunk = waves[k:k + CHUNK]
        ys = runs(model, [(current.theta, current.effects + pair(w, *amp))
                          for w in chunk for amp in ((probe, 0.0), (0.0, probe))])
        out += [_regress(current.y, ys[2 * i], ys[2 * i + 1], probe, r, tr)
                for i in range(len(chunk))]
    return out


def _regress(y0: Array, y_sin: Array, y_cos: Array, probe: float, r: Array, tr: Array
             ) -> tuple[float, float, float]:
    """(RSS left, sin and cos amplitude) of ``r`` regressed on the two probes' secants."""
    s = np.column_stack([(y_sin - y0)[tr] / probe, (y_cos - y0)[tr] / probe])
    if not np.all(np.isfinite(s)):
        return np.inf, 0.0, 0.0
    return _least_squares_pair(s, r)


def _least_squares_pair(s: Array, r: Array) -> tuple[float, float, float]:
    """(RSS left, first and second coefficient) of ``r`` regressed on the two columns
    ``s``."""
    c, *_ = np.linalg.lstsq(s, r, rcond=None)
    return float(np.sum((r - s @ c) ** 2)), float(c[0]), float(c[1])


def _local_minima(vals: list[float], k: int) -> list[int]:
    """Indices of the ``k`` lowest local minima of ``vals``."""
    n = len(vals)
    idx = [i for i in range(n) if (i == 0 or vals[i] <= vals[i - 1])
           and (i == n - 1 or vals[i] <= vals[i + 1])]
    return sorted(idx, key=lambda i: vals[i])[:k]


def _periodogram(r: Array, x: Array, waves: list[float]) -> list[tuple[float, float, float]]:
    """(RSS left, sin and cos coefficient) of ``r`` regressed on ``sin(w x)``, ``cos(w x)`` at
    each of ``waves`` (no simulation: the residual read against the measured position)."""
    return [_least_squares_pair(np.column_stack([np.sin(w * x), np.cos(w * x)]), r)
            for w in waves]


def _sized(model: Any, current: Any, wave: float, c_sin: float, c_cos: float
           ) -> tuple[float, float]:
    """Amplitudes for a periodogram start: along the residual's phase (``c_sin``, ``c_cos``,
    in output units), sized by simulation at :data:`SIZES` times the model's probe amplitude,
    either sign (a fit from zero amplitudes stopped short: on an independent 40 s recording
    at 0.16 of the nominal RSS where a start of the right size reached 0.03)."""
    norm = math.hypot(c_sin, c_cos)
    if not norm > 0.0:
        return 0.0, 0.0
    probe = float(getattr(model, "ripple_probe", PROBE))
    cands = [(k * probe * c_sin / norm, k * probe * c_cos / norm)
             for k in SIZES for k in (k, -k)]
    ys = runs(model, [(current.theta, current.effects + pair(wave, a, b)) for a, b in cands])
    return min(zip((model.rss(y) for y in ys), cands, strict=True))[1]


def screen(model: Any, current: Any) -> list[tuple[float, float, float, float, str]]:
    """(wavenumber, sin and cos amplitude, predicted RSS, how screened) of the pairs that
    explain most of ``current``'s training residual, best first; empty when the model scans
    none: the :data:`STARTS` lowest dips of the probe scan (it is rugged: a dip is a few grid
    steps wide, and the linearised pair ranks the dips only roughly), each refined; and, for
    a model with ``ripple_position()`` whose measured position range holds more than
    :data:`MANY_PERIODS` periods of some scanned wavenumbers, the lowest dip of the
    periodogram over those, refined at :data:`FINE` points over half a step either side (its
    amplitudes are left to the fit)."""
    waves = getattr(model, "ripple_waves", None)
    grid = np.asarray(waves() if waves is not None else (), float)
    if len(grid) == 0:
        return []
    data = model.data
    tr = data.split()[0]
    r = (data.y[data.keep] - current.y)[tr]
    if not np.all(np.isfinite(r)):
        return []
    step = _step(grid)
    out = []
    coarse = _explained(model, current, [float(w) for w in grid], r, tr)
    for i in _local_minima([c[0] for c in coarse], STARTS):
        fine = [float(w) for w in np.linspace(grid[i] - step / 2, grid[i] + step / 2, REFINE)
                if w > 0 and w != grid[i]]
        cands = [(coarse[i], float(grid[i]))]
        cands += list(zip(_explained(model, current, fine, r, tr), fine, strict=True))
        (rss, a, b), w = min(cands, key=lambda c: c[0][0])
        out.append((w, a, b, rss, "probes"))
    position = getattr(model, "ripple_position", None)
    x = None if position is None else np.asarray(position(), float)[tr]
    if x is not None and np.all(np.isfinite(x)) and np.ptp(x) > 0:
        high = grid[grid * float(np.ptp(x)) / (2.0 * np.pi) > MANY_PERIODS]
        if len(high):
            pg = _periodogram(r, x, [float(w) for w in high])
            w0 = float(high[_local_minima([c[0] for c in pg], 1)[0]])
            fine = [float(w) for w in np.linspace(w0 - step / 2, w0 + step / 2, FINE)]
            (rss, cs, cc), w = min(zip(_periodogram(r, x, fine), fine, strict=True))
            a, b = _sized(model, current, w, cs, cc)
            out.append((w, a, b, rss, "periodogram"))
    return sorted(out, key=lambda c: c[3])


def fit_pair(model: Any, current: Any, progress: Callable[[str], None] | None) -> Any | None:
    """The best of the screened pairs, each fitted jointly on top of ``current`` (None: no
    scan; the fit clips the screened amplitudes into its bounds)."""
    waves = getattr(model, "ripple_waves", None)
    grid = np.asarray(waves() if waves is not None else (), float)
    if progress is not None and waves is not None:
        progress(f"scanning {len(grid)} wavenumbers for a position-periodic force (two "
                 "simulations each; a periodogram too over those the range holds more than "
                 f"{MANY_PERIODS:g} periods of)")
    starts = screen(model, current)
    if progress is not None:
        for w, _, _, rss, how in starts:
            progress(f"screened: {PERIODIC} at {w:.4g} rad^-1 {1 - rss / current.rss:+.0%} "
                     f"({how}); fitting it")
    step = _step(grid)

    def fit_start(s: tuple[float, float, float, float, str]) -> Any:
        f = model.fit(current.theta, current.effects + pair(*s[:3]))
        if s[4] != "periodogram":
            return f
        f = model.fit(f.theta, f.effects)  # over many periods one fit stops short
        return _polish_wave(model, f, s[0], step)

    best = None
    for f in each(model, fit_start, starts):
        if best is None or f.rss < best.rss:
            best = f
    return best


def _step(grid: Array) -> float:
    """The scan grid's step (0 for an empty grid: nothing is scanned)."""
    if len(grid) == 0:
        return 0.0
    return float(grid[1] - grid[0]) if len(grid) > 1 else 0.1 * float(grid[0])


def _polish_wave(model: Any, f: Any, wave: float, step: float) -> Any:
    """Over many periods the wavenumber matters to a small part of a scan step (30 periods
    and 0.4 % off: a tenth of a period of drift by the range's end), finer than the
    periodogram places it: simulate the fit with its values held at :data:`FINE` wavenumbers
    over a step either side, and refit at the best when it is not ``wave``."""
    amps = [v for n, v in f.effects if Term.is_key(n)]
    rest = without_pair(f.effects)
    tried = [float(w) for w in np.linspace(wave - step, wave + step, FINE) if w > 0]
    ys = runs(model, [(f.theta, rest + pair(w, *amps)) for w in tried])
    rss, w = min(zip((model.rss(y) for y in ys), tried, strict=True))
    if not rss < f.rss:
        return f
    return model.fit(f.theta, rest + pair(w, *amps))
