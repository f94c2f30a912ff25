"""Delay line: never early, statistics of loss/duplication/jitter, determinism, FIFO."""

from __future__ import annotations

import math
import statistics

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from teleop.config.transport import LinkConfig
from teleop.transport.delay_line import (
    PARETO_SHAPE,
    TIME_EPS_S,
    DelayLineState,
    DelayParams,
    Delivered,
    delay_line_pop_due,
    delay_line_push,
    delay_params,
    next_release_s,
)

DT_S = 1e-3


def run(params: DelayParams, n: int, pop_every: int = 1,
        drain: bool = True) -> tuple[DelayLineState, list[Delivered]]:
    """Push message i (payload = i) at i*DT_S; pop every ``pop_every`` steps."""
    state, out = DelayLineState(), []
    for i in range(n):
        t = i * DT_S
        state = delay_line_push(state, params, i.to_bytes(4, "big"), t)
        if i % pop_every == 0:
            state, got = delay_line_pop_due(state, t)
            out += got
    if drain:
        state, got = delay_line_pop_due(state, n * DT_S + 100.0)
        out += got
    return state, out


def idx(d: Delivered) -> int:
    return int.from_bytes(d.payload, "big")


def binomial_ok(k: int, n: int, p: float, z: float = 4.5) -> bool:
    return abs(k - n * p) <= z * math.sqrt(n * p * (1 - p))


params_st = st.builds(
    DelayParams,
    delay_s=st.floats(0.0, 0.2), jitter=st.sampled_from(["none", "uniform", "normal", "pareto"]),
    jitter_s=st.floats(0.0, 0.05), loss=st.floats(0.0, 1.0),
    loss_model=st.sampled_from(["bernoulli", "gilbert"]), burst_length=st.floats(1.0, 20.0),
    duplicate=st.floats(0.0, 1.0), reorder=st.booleans(), stream=st.integers(0, 2**64 - 1),
)


@given(params_st, st.lists(st.tuples(st.floats(0.0, 0.05), st.booleans()), max_size=60))
@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
def test_never_early_and_conserved(p: DelayParams, steps: list[tuple[float, bool]]) -> None:
    state, t, out = DelayLineState(), 0.0, []
    for n, (dt, pop) in enumerate(steps):
        t += dt
        state = delay_line_push(state, p, bytes([n % 256]), t)
        if pop:
            state, got = delay_line_pop_due(state, t)
            assert all(d.release_t_s <= t + TIME_EPS_S for d in got)
            out += got
    state, got = delay_line_pop_due(state, t)
    out += got
    assert all(e.release_t_s > t + TIME_EPS_S for e in state.pending)
    for d in out:
        assert d.delivered_t_s >= d.release_t_s - TIME_EPS_S
        assert d.delay_s >= p.delay_s - 1e-9  # jitter only adds
    assert len(out) + len(state.pending) == state.n_pushed - state.n_lost + state.n_duplicated
    assert state.n_delivered == len(out)


def test_constant_delay_is_exact() -> None:
    _, out = run(DelayParams(delay_s=0.05), 1000, drain=False)
    assert len(out) == 950
    for d in out:
        assert d.delay_s == pytest.approx(0.05, abs=1e-9)
        assert idx(d) * DT_S == pytest.approx(d.sent_t_s)


@pytest.mark.parametrize("seed", [0, 1, 2])
@pytest.mark.parametrize("loss", [0.01, 0.1, 0.5])
def test_bernoulli_loss_rate_within_binomial_bounds(seed: int, loss: float) -> None:
    n = 20000
    state, out = run(DelayParams(loss=loss, stream=seed), n, pop_every=50)
    assert binomial_ok(state.n_lost, n, loss)
    assert len(out) == n - state.n_lost


def _loss_runs(out: list[Delivered], n: int) -> list[int]:
    got = {idx(d) for d in out}
    runs, cur = [], 0
    for i in range(n):
        if i in got:
            if cur:
                runs.append(cur)
            cur = 0
        else:
            cur += 1
    return runs


@pytest.mark.parametrize(("loss", "burst"), [(0.1, 5.0), (0.05, 20.0), (0.3, 2.0)])
def test_gilbert_loss_rate_and_burst_length(loss: float, burst: float) -> None:
    n = 60000
    p = DelayParams(loss=loss, loss_model="gilbert", burst_length=burst, stream=7)
    state, out = run(p, n, pop_every=100)
    # bursts inflate the variance of the count by about (2 * burst - 1)
    sd = math.sqrt(n * loss * (1 - loss) * (2 * burst - 1))
    assert abs(state.n_lost - n * loss) <= 4.5 * sd
    runs = _loss_runs(out, n)
    assert statistics.mean(runs) == pytest.approx(burst, rel=0.12)
    # a Bernoulli process of the same rate has mean run 1 / (1 - loss): clearly shorter
    _, bout = run(DelayParams(loss=loss, stream=7), n, pop_every=100)
    assert statistics.mean(_loss_runs(bout, n)) == pytest.approx(1 / (1 - loss), rel=0.1)


def test_duplication_rate_within_binomial_bounds() -> None:
    n = 20000
    state, out = run(DelayParams(delay_s=0.01, duplicate=0.05, stream=3), n, pop_every=10)
    assert binomial_ok(state.n_duplicated, n, 0.05)
    assert len(out) == n + state.n_duplicated
    assert sum(d.duplicate for d in out) == state.n_duplicated


def test_same_seed_same_outcome_and_other_seed_differs() -> None:
    def outcome(stream: int) -> list[tuple[int, float]]:
        p = DelayParams(0.02, "pareto", 0.01, 0.2, "gilbert", 4.0, 0.1, True, stream)
        return [(idx(d), d.release_t_s) for d in run(p, 3000, pop_every=7)[1]]

    assert outcome(11) == outcome(11)
    assert outcome(11) != outcome(12)


@pytest.mark.parametrize("jitter", ["uniform", "normal", "pareto"])
def test_no_reordering_when_disabled(jitter: str) -> None:
    p = DelayParams(0.01, jitter, 0.02, 0.1, "bernoulli", 5.0, 0.1, False, 5)
    _, out = run(p, 5000, pop_every=3)
    order = [idx(d) for d in out]
    assert order == sorted(order)
    releases = [d.release_t_s for d in out]
    assert releases == sorted(releases)
    # with reordering allowed the same jitter does reorder
    _, out2 = run(DelayParams(0.01, jitter, 0.02, 0.1, "bernoulli", 5.0, 0.1, True, 5), 5000)
    order2 = [idx(d) for d in out2]
    assert order2 != sorted(order2)


@pytest.mark.parametrize(("jitter", "mean_extra"), [
    ("uniform", 0.5), ("normal", math.sqrt(2 / math.pi)), ("pareto", 1 / (PARETO_SHAPE - 1)),
])
def test_jitter_distributions(jitter: str, mean_extra: float) -> None:
    j = 0.004
    _, out = run(DelayParams(0.03, jitter, j, stream=9), 20000)
    extra = [d.release_t_s - d.sent_t_s - 0.03 for d in out]
    assert min(extra) >= -1e-9
    if jitter == "uniform":
        assert max(extra) <= j + 1e-9
        assert statistics.mean(extra) == pytest.approx(mean_extra * j, rel=0.03)
    elif jitter == "normal":
        assert statistics.mean(extra) == pytest.approx(mean_extra * j, rel=0.03)
        assert statistics.pstdev(extra) == pytest.approx(j * math.sqrt(1 - 2 / math.pi), rel=0.05)
    else:  # heavy tail: check the median and that the tail is long
        med = j * (2 ** (1 / PARETO_SHAPE) - 1)
        assert statistics.median(extra) == pytest.approx(med, rel=0.05)
        assert max(extra) > 20 * med


def test_backward_delay_and_salt_from_config() -> None:
    link = LinkConfig(delay_s=0.1, backward_delay_s=0.02, seed=4)
    fwd, bwd = delay_params(link, True), delay_params(link, False)
    assert (fwd.delay_s, bwd.delay_s) == (0.1, 0.02)
    assert fwd.stream != bwd.stream
    assert delay_params(link, True, salt=1).stream != fwd.stream
    assert delay_params(LinkConfig(delay_s=0.1), False).delay_s == 0.1


def test_pop_measures_achieved_delay_and_next_release() -> None:
    p = DelayParams(delay_s=0.05)
    s = delay_line_push(DelayLineState(), p, b"a", 1.0)
    assert next_release_s(s) == pytest.approx(1.05)
    s2, none = delay_line_pop_due(s, 1.049)
    assert none == [] and s2 is s
    s3, (d,) = delay_line_pop_due(s, 1.0503)
    assert d.delay_s == pytest.approx(0.0503)
    assert d.delivered_t_s - d.release_t_s == pytest.approx(0.0003)
    assert s3.n_delivered == 1 and s3.delay_max_s == pytest.approx(0.0503)
    assert next_release_s(s3) is None
    assert len(s.pending) == 1  # pure: the input state is untouched


@settings(max_examples=60, deadline=None)
@given(delay_s=st.sampled_from([0.0, 0.001, 0.05, 1.0, 75.0]), reorder=st.booleans(),
       steps=st.lists(st.tuples(st.floats(-0.01, 0.05), st.booleans(), st.floats(0.0, 0.1)),
                      min_size=1, max_size=60))
def test_the_plain_fast_paths_equal_the_general_ones(delay_s: float, reorder: bool,
                                                     steps: list[tuple[float, bool, float]]
                                                     ) -> None:
    """Without loss, duplicates and jitter, push and pop take fast paths: they must give the
    general paths' states and messages to the bit (send times going back, delays over the
    cap, FIFO and reordering links, pops of one and of many messages)."""
    from teleop.transport import delay_line as dl

    p = DelayParams(delay_s=delay_s, reorder=reorder)
    fast = slow = DelayLineState()
    t = 0.0
    for i, (dt, pop, ahead) in enumerate(steps):
        t = max(0.0, t + dt)
        fast = delay_line_push(fast, p, bytes([i]), t)
        slow = dl._push_general(slow, p, bytes([i]), t, slow.n_pushed)
        assert fast == slow
        if pop and slow.pending and slow.pending[0].release_t_s <= t + ahead + TIME_EPS_S:
            fast, got_fast = delay_line_pop_due(fast, t + ahead)
            slow, got_slow = dl._pop_general(slow, t + ahead)
            assert (fast, got_fast) == (slow, got_slow)
