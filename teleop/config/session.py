"""Config section naming the session (the zenoh key prefix)."""

from __future__ import annotations

from dataclasses import dataclass

from teleop.config.loader import param


@dataclass(frozen=True, slots=True)
class SessionConfig:
    """Identity of one teleoperation session."""

    name: str = param("default", "session name: zenoh keys are teleop/<name>/<role>/<signal>")
    seed: int = param(0, "master seed for everything random in a run", lo=0)
