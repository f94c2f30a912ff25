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
already chosen; the best fit is the candidate.
"""

from __future__ import annotations

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


def pair(wave: float, a: float, b: float) -> tuple[tuple[str, float], ...]:
    """The (name, value) pairs of a sin/cos pair in a fit."""
    return ((Term("sin", wave).key, a), (Term("cos", wave).key, b))


def has_pair(effects: tuple[tuple[str, float], ...]) -> bool:
    """Whether a fit carries a sin/cos pair."""
    return any(Term.is_key(n) for n, _ in effects)


def without_pair(effects: tuple[tuple[str, float], ...]) -> tuple[tuple[str, float], ...]:
    """The catalog effects of a fit."""
    return tuple((n, v) for n, v in effects if not Term.is_key(n))


def _explained(model: Any, current: Any, wave: float, r: Array, tr: Array
               ) -> tuple[float, float, float]:
    """(RSS left, sin and cos amplitude) of the linearised pair at ``wave`` on residual ``r``."""
    y0 = current.y
    probe = float(getattr(model, "ripple_probe", PROBE))
    cols = []
    for amp in ((probe, 0.0), (0.0, probe)):
        y = model.run(current.theta, current.effects + pair(wave, *amp))
        cols.append((y - y0)[tr] / probe)
    s = np.column_stack(cols)
    if not np.all(np.isfinite(s)):
        return np.inf, 0.0, 0.0
    c, *_ = np.linalg.lstsq(s, r, rcond=None)
    return float(np.sum((r - s @ c) ** 2)), float(c[0]), float(c[1])


def _local_minima(vals: list[float], k: int) -> list[int]:
    """Indices of the ``k`` lowest local minima of ``vals``."""
    n = len(vals)
    idx = [i for i in range(n) if (i == 0 or vals[i] <= vals[i - 1])
           and (i == n - 1 or vals[i] <= vals[i + 1])]
    return sorted(idx, key=lambda i: vals[i])[:k]


def screen(model: Any, current: Any) -> list[tuple[float, float, float, float]]:
    """(wavenumber, sin and cos amplitude, predicted RSS) of the pairs that explain most of
    ``current``'s training residual, best first: the :data:`STARTS` lowest dips of the scan
    (it is rugged: a dip is a few grid steps wide, and the linearised pair ranks the dips
    only roughly), each refined; empty when the model scans none."""
    waves = getattr(model, "ripple_waves", None)
    grid = np.asarray(waves() if waves is not None else (), float)
    if len(grid) == 0:
        return []
    data = model.data
    tr = data.split()[0]
    r = (data.y[data.keep] - current.y)[tr]
    if not np.all(np.isfinite(r)):
        return []
    coarse = [_explained(model, current, float(w), r, tr) for w in grid]
    step = float(grid[1] - grid[0]) if len(grid) > 1 else 0.1 * float(grid[0])
    out = []
    for i in _local_minima([c[0] for c in coarse], STARTS):
        cands = [(coarse[i], float(grid[i]))]
        cands += [(_explained(model, current, float(w), r, tr), float(w))
                  for w in np.linspace(grid[i] - step / 2, grid[i] + step / 2, REFINE)
                  if w > 0 and w != grid[i]]
        (rss, a, b), w = min(cands, key=lambda x: x[0][0])
        out.append((w, a, b, rss))
    return sorted(out, key=lambda x: x[3])


def fit_pair(model: Any, current: Any, progress: Callable[[str], None] | None) -> Any | None:
    """The best of the screened pairs, each fitted jointly on top of ``current`` (None: no
    scan; the fit clips the screened amplitudes into its bounds)."""
    waves = getattr(model, "ripple_waves", None)
    if progress is not None and waves is not None:
        progress(f"scanning {len(waves())} wavenumbers for a position-periodic force (two "
                 "simulations each)")
    best = None
    for w, a, b, rss in screen(model, current):
        if progress is not None:
            progress(f"screened: {PERIODIC} at {w:.4g} rad^-1 {1 - rss / current.rss:+.0%}; "
                     "fitting it")
        f = model.fit(current.theta, current.effects + pair(w, a, b))
        if best is None or f.rss < best.rss:
            best = f
    return best
