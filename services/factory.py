"""Backend registries: the config names a backend, the registry builds it (lazy imports).

``MASTER_BACKENDS`` and ``HAND_BACKENDS`` map a config key to ``"module:function"``; the
function takes the whole :class:`~teleop.config.TeleopConfig` and returns a backend
implementing :class:`teleop.devices.base.MasterBackend` / ``HandBackend``.  Importing a
backend only when it is chosen keeps optional SDKs (forcedimension-core, dynamixel-sdk) out of
runs that do not use them.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable
from typing import Any

from teleop.config import TeleopConfig
from teleop.devices.base import HandBackend, MasterBackend
from teleop.errors import ConfigError

MASTER_BACKENDS: dict[str, str] = {
    "virtual": "services.factory:_virtual_master",
    "omega7": "teleop.devices.omega7:Omega7Master",
}

HAND_BACKENDS: dict[str, str] = {
    "sim": "services.factory:_sim_hand",
    "dynamixel": "services.factory:_dynamixel_hand",
    "reflex-takktile": "teleop.devices.reflex_takktile:build_takktile_hand_from",
}


def _load(spec: str) -> Callable[..., Any]:
    module, _, name = spec.partition(":")
    return getattr(importlib.import_module(module), name)


def _virtual_master(cfg: TeleopConfig) -> MasterBackend:
    from sim.operator import VirtualOperator

    return VirtualOperator(cfg.master, seed=cfg.session.seed)


def _sim_hand(cfg: TeleopConfig) -> HandBackend:
    from sim.sim_hand import SimHand

    return SimHand(cfg.hand, seed=cfg.session.seed)


def _dynamixel_hand(cfg: TeleopConfig) -> HandBackend:
    from teleop.devices.dynamixel_hand import build_dynamixel_hand

    return build_dynamixel_hand(cfg.hand)


def build_master(cfg: TeleopConfig) -> MasterBackend:
    """The master backend named by ``master.backend``."""
    try:
        spec = MASTER_BACKENDS[cfg.master.backend]
    except KeyError:
        raise ConfigError(f"master.backend = {cfg.master.backend!r}: unknown (known: "
                          f"{', '.join(MASTER_BACKENDS)})") from None
    return _load(spec)(cfg)


def build_hand(cfg: TeleopConfig) -> HandBackend:
    """The hand backend named by ``hand.backend``."""
    try:
        spec = HAND_BACKENDS[cfg.hand.backend]
    except KeyError:
        raise ConfigError(f"hand.backend = {cfg.hand.backend!r}: unknown (known: "
                          f"{', '.join(HAND_BACKENDS)})") from None
    return _load(spec)(cfg)
