"""A pad pushed past a cylinder's centre keeps being pushed back (no normal flip), in both
engines alike."""

from __future__ import annotations

import math

import numpy as np
import pytest

from sim.contact import ContactObject, pad_contact

CYL = ContactObject(kind="cylinder", x_m=0.045, y_m=0.03, radius_m=0.02,
                    stiffness_n_per_m=300.0)
#: the proximal pad in its own frame: along +x at the pad offset, facing +y
PAD = (0.01, 0.004, 0.06, 0.004)


def _compiled(obj: ContactObject, cphi: float, sphi: float, pad: tuple[float, ...]):
    from sim.compiled import pack_object
    from sim.compiled_kernel import pad_contact as kernel

    return kernel(pack_object(obj), cphi, sphi, *pad)


def _sweep(shift_m: np.ndarray):
    """The cylinder moved towards and through the pad (object frame: its y lowered)."""
    out = []
    for dy in shift_m:
        obj = ContactObject(kind="cylinder", x_m=CYL.x_m, y_m=CYL.y_m - dy,
                            radius_m=CYL.radius_m)
        out.append(pad_contact(obj, 1.0, 0.0, *PAD))
    return out


def test_depth_grows_through_the_centre_and_the_normal_never_flips() -> None:
    shifts = np.linspace(0.0, 0.06, 601)
    res = _sweep(shifts)
    depths = np.array([r[1] for r in res])
    normals = np.array([r[4] for r in res])
    touching = depths > 0
    # touching from when the circle reaches the pad (centre 0.004 + 0.02 above it) ...
    first = shifts[np.argmax(touching)]
    assert first == pytest.approx(CYL.y_m - 0.004 - CYL.radius_m, abs=2e-4)
    # ... depth rising monotonically until the pad is a radius behind the centre
    d = depths[touching]
    assert np.all(np.diff(d) > 0)
    assert d.max() == pytest.approx(2 * CYL.radius_m, abs=2e-4)
    # the force always pushes the pad back towards -y (the open side), never through
    assert np.all(normals[touching] == pytest.approx(-1.0))


@pytest.mark.parametrize("dy", [0.0, 0.006, 0.02, 0.026, 0.03, 0.04, 0.05])
@pytest.mark.parametrize("phi", [0.0, 0.3, -0.2])
def test_compiled_kernel_agrees_to_the_bit(dy: float, phi: float) -> None:
    obj = ContactObject(kind="cylinder", x_m=CYL.x_m, y_m=CYL.y_m - dy, radius_m=CYL.radius_m)
    c, s = math.cos(phi), math.sin(phi)
    for pad in (PAD, (0.0, 0.004, 0.045, 0.004), (0.07, 0.01, 0.1, 0.03)):
        assert tuple(_compiled(obj, c, s, pad)) == pad_contact(obj, c, s, *pad)
