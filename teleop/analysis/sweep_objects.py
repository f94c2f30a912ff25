"""The objects and operators of the robustness grid (``teleop sweep --grid full``).

Objects are presets of ``hand.sim.object`` (the compliant body of ``sim.contact``: along each
pad's normal it pushes back with ``k d + c d'``, never pulls, and a rigid core past
``core_depth_m``; a yielding one crushes plastically at ``F_y``, ``sim.crush``).  Positions are
the config's (cylinder centre 45 mm along the palm normal, 30 mm across; block face 30 mm
across):

======================  ========  =======  =========  =======  ===================================
name                    kind      k [N/m]  c [N s/m]  F_y [N]
======================  ========  =======  =========  =======  ===================================
``free-air``            none      -        -          -        (nothing to touch: closes freely)
``soft-cylinder``       cylinder  300      2          -        (foam-like; deep, slow contact)
``stiff-cylinder``      cylinder  2000     5          -        (the config default, the default
                                                               sweep's)
``block``               block     5000     10         -        (a hard flat face)
``crushable-cylinder``  cylinder  2000     5          5        (the stiff cylinder's skin yields:
                                                               the default relaxed operator's
                                                               first grasp dents it 4.1 mm, for
                                                               good: ``teleop budget``)
======================  ========  =======  =========  =======  ===================================
"""

from __future__ import annotations

from dataclasses import replace

from teleop.config import TeleopConfig
from teleop.errors import UserInputError

__all__ = ["OBJECTS", "OPERATORS", "with_object", "object_name"]

#: name -> (kind, stiffness N/m, damping N s/m, yield force N: 0 never yields)
OBJECTS: dict[str, tuple[str, float, float, float]] = {
    "free-air": ("none", 2000.0, 5.0, 0.0),
    "soft-cylinder": ("cylinder", 300.0, 2.0, 0.0),
    "stiff-cylinder": ("cylinder", 2000.0, 5.0, 0.0),
    "block": ("block", 5000.0, 10.0, 0.0),
    "crushable-cylinder": ("cylinder", 2000.0, 5.0, 5.0),
}

#: operator styles of the grid (``master.virtual.style``), hardest last
OPERATORS: tuple[str, ...] = ("soft", "relaxed", "hard")


def with_object(cfg: TeleopConfig, name: str) -> TeleopConfig:
    """``cfg`` with the simulated hand's object set to the preset ``name``."""
    if name not in OBJECTS:
        raise UserInputError(f"sweep object {name!r}: expected one of {', '.join(OBJECTS)}")
    kind, k, c, f_y = OBJECTS[name]
    obj = replace(cfg.hand.sim.object, kind=kind, stiffness_n_per_m=k, damping_n_s_per_m=c,
                  yield_force_n=f_y)
    return replace(cfg, hand=replace(cfg.hand, sim=replace(cfg.hand.sim, object=obj)))


def object_name(cfg: TeleopConfig) -> str:
    """The preset name of ``cfg``'s object, or ``kind k=.. c=..`` (`` yield=..`` when it
    yields) when it is none of them."""
    o = cfg.hand.sim.object
    for name, (kind, k, c, f_y) in OBJECTS.items():
        if o.kind == kind == "none" or (o.kind == kind and o.stiffness_n_per_m == k
                                        and o.damping_n_s_per_m == c
                                        and o.yield_force_n == f_y):
            return name
    label = f"{o.kind} k={o.stiffness_n_per_m:g} c={o.damping_n_s_per_m:g}"
    return label + (f" yield={o.yield_force_n:g}" if o.yield_force_n > 0.0 else "")
