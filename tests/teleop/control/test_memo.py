"""The one-entry identity memo: the same result for the same objects, a fresh call otherwise."""

from __future__ import annotations

from teleop.control.memo import last_result


def test_last_result_recomputes_unless_both_arguments_are_the_last_ones() -> None:
    calls: list[tuple[object, object]] = []

    @last_result
    def f(a: tuple[float, ...], b: str) -> float:
        calls.append((a, b))
        return sum(a)

    x, y = (1.0, 2.0), "p"
    assert f(x, y) == 3.0 and f(x, y) == 3.0 and len(calls) == 1
    assert f(tuple([1.0, 2.0]), y) == 3.0 and len(calls) == 2  # equal, not the same object
    assert f((5.0,), y) == 5.0 and f(x, y) == 3.0 and len(calls) == 4
