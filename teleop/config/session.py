"""Config section naming the session (the zenoh key prefix)."""

from __future__ import annotations

from dataclasses import dataclass

from teleop.config.loader import param


@dataclass(frozen=True, slots=True)
class SessionConfig:
    """Identity of one teleoperation session."""

    name: str = param("default", "session name: zenoh keys are teleop/<name>/<role>/<signal>")
    seed: int = param(0, "master seed for everything random in a run", lo=0)
    heap_trim_s: float = param(
        5.0, "each service returns its freed heap to the operating system this often (glibc "
        "malloc_trim on a background thread; after a stall the backlog's high-water mark is "
        "otherwise kept for the process's life); 0 = never", unit="s", lo=0.0, hi=3600.0)
