"""The shared selection rule and the ambiguity / unexplained-residual notes."""

from __future__ import annotations

import math

import numpy as np

from teleop.diagnose.ambiguity import ambiguous_fits
from teleop.diagnose.criterion import effective_n, judge, score, structured_n, unexplained


def test_effective_sample_size_counts_coloured_noise_as_fewer_samples() -> None:
    rng = np.random.default_rng(3)
    white = rng.standard_normal(20000)
    assert abs(effective_n(white) / len(white) - 1.0) < 0.1
    ar = np.zeros(20000)
    for i in range(1, len(ar)):
        ar[i] = 0.8 * ar[i - 1] + white[i]
    # AR(1) with rho 0.8 is worth 0.11 of its samples; only its fast part (less a local cubic
    # over 21 samples) is judged, which keeps about 0.4
    assert 0.1 < effective_n(ar) / len(ar) < 0.6


def test_score_penalises_parameters_and_refuses_failed_models() -> None:
    assert score(1.0, 1.0, 1000, 1, 1000.0) < 0
    assert score(1.0, 0.5, 1000, 1, 1000.0) > score(1.0, 0.5, 1000, 1, 50.0) > 0
    assert score(1.0, math.inf, 1000, 1, 1000.0) == -math.inf
    # known noise: (RSS0 - RSS1) / sigma^2 - k ln n
    assert math.isclose(score(4.0, 2.0, 10, 1, 10.0, noise=0.5), 8.0 - math.log(10))


def test_held_out_gain_must_confirm_unless_the_held_out_part_is_at_the_noise() -> None:
    rng = np.random.default_rng(4)
    r = rng.standard_normal(2000)
    assert judge(10.0, 1.0, r, 1, 0.3).accepted
    assert not judge(10.0, 1.0, r, 1, 0.0).accepted
    assert judge(10.0, 1.0, r, 1, -0.01, holdout_informative=False).accepted
    assert not judge(10.0, 1.0, r, 1, -0.05, holdout_informative=False).accepted
    assert not judge(1.0, 0.999, r, 1, 0.5).accepted  # too small a gain to score


def test_close_candidates_are_named_with_the_experiment_that_separates_them() -> None:
    rng = np.random.default_rng(5)
    white = rng.standard_normal(1000)   # the chosen model leaves only noise
    rss = float(white @ white)
    fits = [("dead_time", rss, 1, 100.0), ("actuator_lag", rss * 1.005, 1, 95.0),
            ("backlash", rss * 1.5, 1, 20.0)]
    notes = ambiguous_fits("dead_time", white, fits)
    assert len(notes) == 1 and "actuator_lag" in notes[0] and "step" in notes[0]
    # 1000 white samples: 3 % more RSS is evidence (1000 ln 1.03 = 30)
    assert ambiguous_fits("dead_time", white, [("dead_time", rss, 1, 100.0),
                                               ("actuator_lag", rss * 1.03, 1, 70.0)]) == []
    # a runner-up that does not pass the score itself is no rival
    assert ambiguous_fits("dead_time", white, [("dead_time", rss, 1, 100.0),
                                               ("actuator_lag", rss * 1.001, 1, 5.0)]) == []


def test_a_residual_with_slow_structure_separates_candidates_by_fewer_samples() -> None:
    """Two effects that both leave the same slow misfit (physics outside the model) differ by a
    few per cent of RSS: that is not evidence for either.  Counting the residual's samples as
    independent (the fast-part n_eff of the acceptance score) would call it decisive."""
    rng = np.random.default_rng(6)
    t = np.linspace(0.0, 10.0, 1000)
    slow = 8.0 * np.sin(2 * np.pi * 0.3 * t) + rng.standard_normal(len(t))
    rss = float(slow @ slow)
    fits = [("dead_time", rss, 1, 100.0), ("actuator_lag", rss * 1.05, 1, 80.0)]
    notes = ambiguous_fits("dead_time", slow, fits)
    assert len(notes) == 1 and "actuator_lag" in notes[0]
    assert structured_n(slow) < 0.05 * len(slow) < effective_n(slow)
    # the same RSS gap on a white residual is decisive
    white = rng.standard_normal(1000) * math.sqrt(rss / 1000)
    assert ambiguous_fits("dead_time", white, fits) == []


def test_unexplained_warning_only_far_above_the_noise() -> None:
    assert unexplained(2.0, 1.0) is None
    w = unexplained(30.0, 1.0)
    assert w is not None and "30x" in w
