"""Several starts for the output-error fits: keep the lowest residual (the likelihood).

The input's sample alignment (``input_shift``, within one raw sample period) is a nuisance
whose error surface has local minima: a sharp friction law makes the simulated output jump
where the shifted input crosses a reversal.  A fit started with the alignment at a bound (where
the nominal fit put it to make up for a missing effect) stayed there: the Coulomb drive of
independent seed 178 then stopped at 3x the residual of the fit started at the centre, and a
gravity term made up the difference (a false discovery).  So every fit that decides what is
named is also started with the alignment at the centre of its range, and with the stated
nominal values, and the best fit is kept.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

from teleop.diagnose.axis_model import Array
from teleop.diagnose.fit import NUMERIC_FAILURES, SHIFT, FitData, ModelFit, fit_model
from teleop.diagnose.model import AxisNominal


def restarts(start: dict[str, float], nominal: AxisNominal | None = None
             ) -> list[dict[str, float]]:
    """``start``; the same with the alignment at the centre of its range (when it is not);
    with ``nominal``, the same again with every stated nominal value."""
    out = [start]
    if SHIFT in start and start[SHIFT] != 0.0:
        out.append({**start, SHIFT: 0.0})
    if nominal is not None:
        stated = {t: float(v) for t, v in zip(nominal.terms, nominal.values, strict=True)
                  if v is not None and t in start}
        if stated and any(start[t] != v for t, v in stated.items()):
            out.append({**start, **stated, **({SHIFT: 0.0} if SHIFT in start else {})})
    return out


def fit_best(data: FitData, nominal: AxisNominal, starts: Sequence[dict[str, float]],
             effects: tuple[str, ...], max_nfev: int, mask: Array | None = None) -> ModelFit:
    """The fit of lowest residual from ``starts`` (:func:`lowest`; a start whose fit fails
    numerically is skipped; if all fail, the first's failure is raised)."""
    fits: list[ModelFit] = []
    first: Exception | None = None
    for st in starts:
        try:
            fits.append(fit_model(data, nominal, st, effects, max_nfev, mask=mask))
        except NUMERIC_FAILURES as e:
            first = first or e
    if not fits:
        assert first is not None
        raise first
    return lowest(fits)


def lowest(fits: Sequence[ModelFit]) -> ModelFit:
    """The fit of lowest finite residual; the first if none is finite (a non-finite residual,
    NaN included, never beats a finite one: NaN compares false both ways)."""
    best = fits[0]
    for f in fits[1:]:
        if math.isfinite(f.rss) and not (math.isfinite(best.rss) and best.rss <= f.rss):
            best = f
    return best
