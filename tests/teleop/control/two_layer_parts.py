"""Mutants of the two-layer suite reach every side: the suite lives in three modules
(:mod:`teleop.control.two_layer_master`, ``_controller``, ``_hand``), each looking names up in
its own globals, so a breakage is patched into every side that uses the name."""

from __future__ import annotations

from typing import Any

import pytest

from teleop.control import two_layer_controller, two_layer_hand, two_layer_master

SIDES = (two_layer_master, two_layer_controller, two_layer_hand)


def patch_sides(mp: pytest.MonkeyPatch, name: str, value: Any) -> None:
    """``mp.setattr`` of ``name`` on every side that has it (at least one must)."""
    hit = [m for m in SIDES if hasattr(m, name)]
    assert hit, f"no two-layer side uses {name}"
    for m in hit:
        mp.setattr(m, name, value)
