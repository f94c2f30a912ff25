"""Look up a controller suite by its config name (``teleop.control.registry``)."""

from __future__ import annotations

from teleop.control.interface import ControllerSuite
from teleop.errors import ConfigError


def get_suite(kind: str) -> ControllerSuite:
    """The :class:`ControllerSuite` registered as ``kind`` (``controller.kind``)."""
    from teleop.control.registry import CONTROLLERS

    try:
        return CONTROLLERS[kind]
    except KeyError:
        raise ConfigError(f"controller.kind = {kind!r}: unknown (known: "
                          f"{', '.join(CONTROLLERS)})") from None
