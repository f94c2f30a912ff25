"""Config section for the master service (the Omega 7 grasp trigger or a virtual operator)."""

from __future__ import annotations

from dataclasses import dataclass

from teleop.config.loader import param, section


@dataclass(frozen=True, slots=True)
class VirtualOperatorConfig:
    """An operator model: a finger of given mass, damping and stiffness following a grasp script."""

    style: str = param("relaxed", "grasp style", choices=("hard", "relaxed", "soft"))
    mass_kg: float = param(0.05, "effective mass of the operator's finger and trigger",
                           unit="kg", lo=1e-4, hi=10.0)
    stiffness_n_per_m: float | None = param(
        None, "stiffness of the operator's finger (unset: by style - hard 1500, relaxed 500, "
        "soft 150)", unit="N/m", lo=1.0, hi=1e5)
    damping_n_s_per_m: float | None = param(
        None, "damping of the operator's finger (unset: by style - hard 12, relaxed 6, soft 3)",
        unit="N s/m", lo=0.0, hi=1e4)
    close_s: float = param(0.5, "time before the operator starts closing", unit="s", lo=0.0)
    ramp_s: float = param(1.0, "time taken to close the trigger", unit="s", lo=0.01)
    hold_s: float = param(2.0, "time the grasp is held", unit="s", lo=0.0)
    release_s: float = param(1.0, "time taken to open the trigger again", unit="s", lo=0.01)
    closed_fraction: float = param(1.0, "how far the operator closes the trigger (0-1 of travel)",
                                   lo=0.0, hi=1.0)
    repeat: bool = param(True, "repeat the close/hold/release script")

    @property
    def cycle_s(self) -> float:
        """One grasp of the script: wait, close, hold, release (s)."""
        return self.close_s + self.ramp_s + self.hold_s + self.release_s


@dataclass(frozen=True, slots=True)
class MasterConfig:
    """The master device and its loop."""

    backend: str = param("virtual", "master backend (registry key)",
                         choices=("virtual", "omega7"))
    rate_hz: float = param(1000.0, "master loop rate", unit="Hz", lo=1.0, hi=10000.0)
    travel_m: float = param(0.025, "grasp trigger travel", unit="m", lo=1e-3, hi=0.2)
    force_max_n: float = param(8.0, "largest force the trigger can display", unit="N",
                               lo=0.0, hi=100.0)
    resolution_m: float = param(6e-6, "position resolution of the trigger", unit="m",
                                lo=0.0, hi=1e-3)
    virtual: VirtualOperatorConfig = section(VirtualOperatorConfig, "virtual operator backend")
