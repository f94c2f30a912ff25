"""A finger squeezed into the block lets go (issue 13): the block's core is met element by element.

The grid's block (``teleop.analysis.sweep_objects``: a flat face 30 mm across, 5000 N/m skin,
12 mm deep, then the rigid core) squeezed at the servo's full effort.  With the core met on the
pressed part's *mean* depth, the distal pad dove into the face tip first 2-3 core depths deep,
curled past the perpendicular, and stayed there after the release (the flexure on its 0.45 rad
stops, ~87 N on the tip, the distal cell at 9,023 with the tendon slack).  Met at each element's
own depth, the tip stops within a few mm of the core, and every release frees the finger.
"""

from __future__ import annotations

import math

import pytest

from sim.contact import ContactObject
from sim.engine import ENGINES, engine
from sim.finger import MotorCommand, default_finger_params, initial_finger_state
from sim.params import JOINT_RATIO
from sim.readout import distal_origin, finger_outputs
from teleop.effects import EffectSet

BLOCK = ContactObject(kind="block", y_m=0.03, stiffness_n_per_m=5000.0, damping_n_s_per_m=10.0)
SQUEEZE_RAD = 2.5  # joint set-point far past the face: the servo pulls at its full effort
CYCLE_S = 4.0      # 2.5 s squeeze (ramped at 2 rad/s), 1.5 s released
DT = 1e-3


def _tip_depth_m(state: object, obj: ContactObject) -> float:
    """How far the distal pad's tip is inside the block's face (world y past ``y_m``)."""
    p = default_finger_params()
    x, y, ca, sa = distal_origin(state, p)  # type: ignore[arg-type]
    bx = x - sa * p.pad_offset_m + ca * p.distal_length_m
    by = y + ca * p.pad_offset_m + sa * p.distal_length_m
    phi = state.prox_rad  # type: ignore[attr-defined]
    return math.sin(phi) * bx + math.cos(phi) * by - obj.y_m


def _squeezes(name: str) -> tuple[list[int], list[int], dict[int, object]]:
    """Three squeezes and releases on engine ``name``: (squeezed steps, released steps, the
    state before every 10th step)."""
    p = default_finger_params()
    n = int(CYCLE_S / DT)
    cmds = []
    for _ in range(3):
        for i in range(n):
            t = i * DT
            goal = min(SQUEEZE_RAD, 2.0 * t) if t < 2.5 else 0.0
            cmds.append(MotorCommand("position", JOINT_RATIO * goal))
    squeezed = [c * n + int(2.45 / DT) for c in range(3)]
    released = [(c + 1) * n for c in range(3)]
    record = [s % 10 == 0 for s in range(len(cmds) + 1)]
    _, rows = engine(name).run_finger(initial_finger_state(p), cmds, [DT] * len(cmds), p, BLOCK,
                                      EffectSet(), record)
    steps = [s for s in range(len(cmds) + 1) if record[s]]
    return squeezed, released, dict(zip(steps, rows, strict=True))


@pytest.mark.parametrize("name", ENGINES)
def test_a_hard_squeeze_into_the_block_is_released_every_time(name: str) -> None:
    p = default_finger_params()
    squeezed, released, by_step = _squeezes(name)
    peaks = []
    for s in squeezed:
        st = by_step[s]
        assert st.tendon_force_n > 150.0  # a hard squeeze: the servo near its full effort
        assert st.pads[2] > 50.0          # the distal pad presses the face
        assert _tip_depth_m(st, BLOCK) < 1.5 * BLOCK.core_depth_m  # stopped near the core
        assert max(st.flex_rad) <= 0.45 and sum(st.flex_rad) < 1.2  # short of perpendicular
        peaks.append(max(finger_outputs(st, p, BLOCK, EffectSet()).pressure))
    for s in released:
        st = by_step[s]
        assert st.pads[2] == 0.0 and st.pads[0] == 0.0  # let go: nothing presses the pads
        assert max(finger_outputs(st, p, BLOCK, EffectSet()).pressure) == 0.0
        assert max(abs(a) for a in st.flex_rad) < 0.05  # the flexure opened
    assert max(peaks) - min(peaks) < 0.02 * max(peaks)  # every squeeze reads the same


def test_both_engines_agree_through_the_squeezes() -> None:
    """The compiled engine within 1e-9 rad of the reference over the 12 s, every 10 ms."""
    a, b = (_squeezes(name)[2] for name in ENGINES)
    assert a.keys() == b.keys()
    worst = 0.0
    for s, u in a.items():
        v = b[s]
        for x, y in zip((u.prox_rad, u.motor_rad, *u.flex_rad),
                        (v.prox_rad, v.motor_rad, *v.flex_rad), strict=True):
            worst = max(worst, abs(x - y))
    assert worst <= 1e-9
