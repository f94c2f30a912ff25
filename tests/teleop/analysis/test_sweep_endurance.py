"""The endurance runs' grasp analysis: a finger's closure is its curl, held."""

from __future__ import annotations

import numpy as np
import pytest

from teleop.analysis.sweep_endurance import grasp_threshold_m, grasps_from_columns
from teleop.config import load_config


def test_closure_is_the_curl_not_how_the_links_share_it() -> None:
    """Grasps of equal force whose proximal link takes 0.078-0.091 rad of a 1.21 rad curl (the
    hard operator on the block): equal closures.  By the proximal angle alone (the measure
    before) the weakest would be 0.86 of the first."""
    cfg = load_config(None, [])
    thr = grasp_threshold_m(cfg)
    t = np.arange(0.0, 27.0, 1e-3)
    phase = np.fmod(t, 4.5)
    x = np.where((phase > 0.5) & (phase < 3.5), 4.0 * thr, 0.0)
    k = np.floor(t / 4.5).astype(int)
    share = np.array([0.091, 0.078, 0.085, 0.080, 0.088, 0.082])[k]
    prox = np.where(x > 0, share, 0.0)[:, None] * np.ones(3)
    dist = np.where(x > 0, 1.21 - share, 0.0)[:, None] * np.ones(3)
    p = np.zeros((len(t), 27))
    p[:, 3] = np.where(x > 0, 4993.0, 0.0)
    g = grasps_from_columns(t, x, p, prox, dist, np.where(x > 0, 8.0, 0.0), cfg)
    assert len(g.grasps) == 6
    assert g.min_closure_ratio == pytest.approx(1.0)
    assert [s.closure_rad for s in g.grasps] == pytest.approx([1.21] * 6)
    by_proximal = grasps_from_columns(t, x, p, prox, np.zeros_like(dist),
                                      np.where(x > 0, 8.0, 0.0), cfg)
    assert by_proximal.min_closure_ratio == pytest.approx(0.078 / 0.091)
