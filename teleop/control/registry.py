"""Controllers by config name (``controller.kind``).

Usage (what a service does)::

    suite = CONTROLLERS[cfg.controller.kind]
    params = control_params(cfg.controller)
    st = suite.init_master(params)
    st, out = suite.step_master(st, params, grip_position_m, latest_force_command, dt_s)
"""

from __future__ import annotations

from teleop.config.control import ControllerConfig
from teleop.control import direct, tdpa, two_layer
from teleop.control.interface import ControllerSuite, ControlParams, control_params
from teleop.errors import ConfigError

CONTROLLERS: dict[str, ControllerSuite] = {
    "two-layer": ControllerSuite(
        name="two-layer",
        init_master=two_layer.init_master, step_master=two_layer.step_master,
        init_controller=two_layer.init_controller, step_controller=two_layer.step_controller,
        init_hand=two_layer.init_hand, step_hand=two_layer.step_hand, passive=True),
    "direct": ControllerSuite(
        name="direct",
        init_master=direct.init_master, step_master=direct.step_master,
        init_controller=direct.init_controller, step_controller=direct.step_controller,
        init_hand=direct.init_hand, step_hand=direct.step_hand, passive=False),
    "tdpa": ControllerSuite(
        name="tdpa",
        init_master=tdpa.init_master, step_master=tdpa.step_master,
        init_controller=tdpa.init_controller, step_controller=tdpa.step_controller,
        init_hand=tdpa.init_hand, step_hand=tdpa.step_hand, passive=True),
}


def controller_suite(cfg: ControllerConfig) -> tuple[ControllerSuite, ControlParams]:
    """The suite named by ``cfg.kind`` and its parameters."""
    if cfg.kind not in CONTROLLERS:
        raise ConfigError(f"controller.kind = {cfg.kind!r} is not one of: "
                          + ", ".join(CONTROLLERS))
    return CONTROLLERS[cfg.kind], control_params(cfg)
