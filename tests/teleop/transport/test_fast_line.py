"""The inbox's mutable delay line equals the pure one, to the bit (teleop.transport.fast_line)."""

from __future__ import annotations

from dataclasses import replace

from hypothesis import given, settings
from hypothesis import strategies as st

from teleop.config.transport import LinkConfig, LinksConfig
from teleop.transport.bus import Inbox
from teleop.transport.delay_line import (
    DelayLineState,
    DelayParams,
    delay_line_pop_due,
    delay_line_push,
)
from teleop.transport.fast_line import FastLine, fast_params
from teleop.transport.safe_decoder import SafeDecoder

fast_params_st = st.builds(
    DelayParams, delay_s=st.sampled_from([0.0, 0.001, 0.05, 1.0, 75.0]),
    jitter=st.sampled_from(["none", "uniform"]), jitter_s=st.just(0.0),
    loss=st.sampled_from([0.0, 0.2, 0.7, 1.0]),
    loss_model=st.sampled_from(["bernoulli", "gilbert"]), burst_length=st.floats(1.0, 20.0),
    reorder=st.booleans(), stream=st.integers(0, 2**64 - 1))


@settings(max_examples=80, deadline=None)
@given(p=fast_params_st,
       steps=st.lists(st.tuples(st.floats(-0.01, 0.05), st.booleans(), st.floats(0.0, 2.0)),
                      min_size=1, max_size=80))
def test_fast_line_equals_the_pure_line(p: DelayParams,
                                        steps: list[tuple[float, bool, float]]) -> None:
    """Pushes (send times going back too: out-of-order insertion), losses of both models,
    FIFO and reordering links, pops of none, one and many messages: the same state, the same
    deliveries (payload, times, achieved delay)."""
    assert fast_params(p)
    line, pure = FastLine.of(DelayLineState()), DelayLineState()
    t = 0.0
    for i, (dt, pop, ahead) in enumerate(steps):
        t = max(0.0, t + dt)
        line.push(p, bytes([i % 256]), t)
        pure = delay_line_push(pure, p, bytes([i % 256]), t)
        assert line.state() == pure
        if pop:
            got = line.pop_due(t + ahead)
            pure, want = delay_line_pop_due(pure, t + ahead)
            assert got == want and line.state() == pure
            assert line.next_release_s() == (pure.pending[0].release_t_s if pure.pending
                                             else None)
    assert line.pop_due(t + 1e3) == delay_line_pop_due(pure, t + 1e3)[1]


def test_inbox_moves_between_the_lines_when_the_link_changes() -> None:
    """A fault giving the link jitter puts the inbox on the pure line and back, in flight
    messages and counters kept."""
    links = LinksConfig(master_controller=LinkConfig(delay_s=0.05))
    inbox = Inbox("master_state", links, SafeDecoder("test"))
    assert inbox._line is not None
    inbox.arrive(b"a", 0.0)
    before = inbox.state
    inbox.params = replace(inbox.params, jitter="uniform", jitter_s=0.01)
    assert inbox._line is None and inbox.state == before
    inbox.arrive(b"b", 0.001)
    inbox.params = replace(inbox.params, jitter="none", jitter_s=0.0)
    assert inbox._line is not None and len(inbox.state.pending) == 2
    assert inbox.state.n_pushed == 2 and inbox.next_release_s() == 0.05
