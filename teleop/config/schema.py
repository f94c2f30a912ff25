"""The root config: every section of ``config/default.toml``."""

from __future__ import annotations

from dataclasses import dataclass

from teleop.config.control import ControllerConfig
from teleop.config.hand import HandConfig
from teleop.config.loader import section
from teleop.config.master import MasterConfig
from teleop.config.runtime import DashboardConfig, SafetyConfig, SweepConfig
from teleop.config.security import SecurityConfig
from teleop.config.session import SessionConfig
from teleop.config.transport import LinksConfig, ZenohConfig


@dataclass(frozen=True, slots=True)
class TeleopConfig:
    """Everything a teleop run is configured with."""

    session: SessionConfig = section(SessionConfig, "the session")
    zenoh: ZenohConfig = section(ZenohConfig, "zenoh network")
    security: SecurityConfig = section(SecurityConfig, "TLS, authentication and access "
                                       "control of the zenoh network")
    links: LinksConfig = section(LinksConfig, "injected delay, jitter and loss per link")
    master: MasterConfig = section(MasterConfig, "master service")
    controller: ControllerConfig = section(ControllerConfig, "controller service")
    hand: HandConfig = section(HandConfig, "hand service")
    safety: SafetyConfig = section(SafetyConfig, "watchdogs and validation")
    dashboard: DashboardConfig = section(DashboardConfig, "live dashboard")
    sweep: SweepConfig = section(SweepConfig, "delay-sweep stability test")
