"""``two-layer``: Franken et al. (2011) transparency layer + passivity layer with energy tanks.

Master side (owns the operator's port): exact port energy ``w = -F(k-1) (q(k) - q(k-1))``,
tank update ``H <- H - w + received``, upper limit, a quantum ``beta max(H - H_res, 0)`` sent
as a monotone running total, then the desired force is limited (Franken's limiter against
``H - H_min``, hard guard against ``H``), plus the tank level controller's damping.
Controller: credits the increases of both incoming totals to its store, forwards
``gamma * store`` split ``s : 1 - s`` to hand and master as running totals, and runs the
transparency layer with the delay-aware force gain of :mod:`teleop.control.delay_adapt`
(round trip measured from the echoed timestamps; full gain at small delays).  Hand side
(``hand_port = "object"``, the default): its tank pays for the work the pads do on the object
(:mod:`teleop.control.object_port`) and the set-point may only go where what the finger could
still push into the object fits in the tank (:func:`~teleop.control.passivity_layer.
reserve_project`); ``hand_port = "servo"``: passive set-position modulation against the servo
spring's energy (:mod:`teleop.control.passivity_layer`).

The three sides live in :mod:`~teleop.control.two_layer_master`,
:mod:`~teleop.control.two_layer_controller` and :mod:`~teleop.control.two_layer_hand`; this
module is the suite's face (the registry's entry points and the helpers ``direct`` and
``tdpa`` share).  See :mod:`teleop.control.energy_tank` and ``docs/controllers.md`` for the
equations.
"""

from __future__ import annotations

from teleop.control.two_layer_controller import (
    ControllerStoreState,
    forward_model,
    init_controller,
    make_commands,
    step_controller,
    transparency_commands,
)
from teleop.control.two_layer_hand import (
    HandPortState,
    desired_setpoints,
    finger_contacts,
    free_motion_refund_j,
    guard_fingers,
    hand_hold_j,
    init_hand,
    measure_hand,
    sample_hand_port,
    slew,
    stall_fingers,
    step_hand,
    step_hand_object,
    step_hand_servo,
)
from teleop.control.two_layer_master import (
    MasterPortState,
    init_master,
    measure_master,
    render_model,
    step_master,
)

__all__ = [
    "ControllerStoreState",
    "HandPortState",
    "MasterPortState",
    "desired_setpoints",
    "finger_contacts",
    "forward_model",
    "free_motion_refund_j",
    "guard_fingers",
    "hand_hold_j",
    "init_controller",
    "init_hand",
    "init_master",
    "make_commands",
    "measure_hand",
    "measure_master",
    "render_model",
    "sample_hand_port",
    "slew",
    "stall_fingers",
    "step_controller",
    "step_hand",
    "step_hand_object",
    "step_hand_servo",
    "step_master",
    "transparency_commands",
]
