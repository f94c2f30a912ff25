"""Device interfaces the services are written against.

A hand backend (simulated hand, Dynamixel servos) and a master backend (virtual operator,
Omega 7) are chosen by config through a registry in ``services/factory.py``; services only
ever call these methods.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

from teleop.frozen import fast_init
from teleop.messages import FingerState, HandCommand


@fast_init
@dataclass(frozen=True, slots=True)
class HandReading:
    """One read of the hand: every finger and the preshape joint."""

    t_s: float
    fingers: tuple[FingerState, FingerState, FingerState]
    preshape_rad: float
    faults: tuple[str, ...] = ()  # human-readable fault messages since the last read
    #: no fresh measurement behind this reading (a silent brain board): the hand service
    #: trips its watchdog and does not publish it
    stale: bool = False
    servo_fault_trips: int = 0  # times servo error bits sent the hand to its safe state
    servo_safe: bool = False  # held safe now because of servo error bits


class HandBackend(Protocol):
    """A hand: simulated or real."""

    def start(self) -> None:
        """Connect and get ready (calibrated, torque on)."""

    def apply(self, command: HandCommand) -> None:
        """Set new targets; commands reaching here are already validated."""

    def read(self, t_s: float) -> HandReading:
        """Read the state at time ``t_s`` (a simulated hand advances its physics to ``t_s``)."""

    def safe(self, mode: str) -> None:
        """Go to the safe state: ``"hold"`` the present position or ``"open"``."""

    def close(self) -> None:
        """Release the device (torque off for real servos)."""


@fast_init
@dataclass(frozen=True, slots=True)
class MasterReading:
    """One read of the master device."""

    t_s: float
    grip_position_m: float  # 0 = trigger open, travel_m = fully closed
    grip_velocity_m_s: float


class MasterBackend(Protocol):
    """A grasp trigger: the Omega 7's 7th DoF or a virtual operator."""

    def start(self) -> None:
        """Connect and get ready."""

    def read(self, t_s: float) -> MasterReading:
        """Read the trigger at ``t_s`` (a virtual operator advances its model to ``t_s``)."""

    def apply_force(self, force_n: float) -> None:
        """Display ``force_n`` on the trigger (positive resists closing), held until the next."""

    def close(self) -> None:
        """Release the device (force off)."""
