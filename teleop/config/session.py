"""Config section naming the session (the zenoh key prefix)."""

from __future__ import annotations

from dataclasses import dataclass

from teleop.config.loader import param


@dataclass(frozen=True, slots=True)
class SessionConfig:
    """Identity of one teleoperation session."""

    name: str = param("default", "session name: zenoh keys are teleop/<name>/<role>/<signal>")
    seed: int = param(0, "master seed for everything random in a run", lo=0)
    malloc_arenas: int = param(
        0, "glibc malloc arenas a service may use (mallopt M_ARENA_MAX, set before its threads "
        "start); 0 = glibc's default (8 per core), where each zenoh receive thread that takes "
        "a stall's backlog keeps its own high-water mark (1 does not give the first backlog "
        "back: heap_trim_mb does)", lo=0, hi=64)
    heap_trim_mb: float = param(
        4.0, "a service whose resident memory grew this much since its last trim returns its "
        "freed heap to the operating system (glibc malloc_trim, in the loop's once-a-second "
        "slot, at most once per 30 s; after a stall the backlog's high-water mark is "
        "otherwise kept for the process's life); 0 = never", unit="MB", lo=0.0, hi=100000.0)
