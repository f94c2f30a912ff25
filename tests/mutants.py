"""Kept mutants: whether a check (a test function called directly) fails on the code as it
stands, for the tests that patch in a broken implementation and want some check to catch it."""

from __future__ import annotations

from collections.abc import Callable


def fails(check: Callable[[], None]) -> bool:
    """``check()`` raised an assertion error (any other error propagates)."""
    try:
        check()
    except AssertionError:
        return True
    return False
