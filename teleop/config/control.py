"""Config section for the controller (transparency + passivity layers)."""

from __future__ import annotations

from dataclasses import dataclass

from teleop.config.loader import param, section


@dataclass(frozen=True, slots=True)
class TankConfig:
    """Energy tank and passivity-layer tuning (Franken et al. 2011)."""

    initial_j: float = param(1.0, "initial energy of each port's tank", unit="J", lo=0.0, hi=100.0)
    desired_j: float = param(1.0, "tank level the master's level controller aims for", unit="J",
                             lo=0.0, hi=100.0)
    max_j: float = param(5.0, "upper tank limit; surplus is dissipated", unit="J", lo=0.0,
                         hi=1000.0)
    min_j: float = param(0.0, "lowest level the passivity layer lets a tank reach", unit="J",
                         lo=0.0, hi=100.0)
    transfer_fraction: float = param(0.1, "fraction of the tank sent as energy quantum per "
                                     "message (beta)", lo=0.0, hi=1.0)
    tlc_gain: float = param(1.0, "tank level controller gain alpha", unit="N s/(m J)", lo=0.0,
                            hi=1e6)
    tlc_damping_max: float = param(5.0, "cap on the level controller's damping", unit="N s/m",
                                   lo=0.0, hi=1e4)
    controller_split: float = param(0.5, "share of energy the controller forwards to the hand "
                                    "(rest to the master)", lo=0.0, hi=1.0)


@dataclass(frozen=True, slots=True)
class TransparencyConfig:
    """What the operator should feel and where the hand should go."""

    finger_enable: tuple[bool, ...] = param((True, True, True), "fingers driven by the trigger")
    open_angle_rad: float = param(0.0, "finger set-point with the trigger open", unit="rad",
                                  lo=-1.0, hi=4.0)
    closed_angle_rad: float = param(3.0, "finger set-point with the trigger closed", unit="rad",
                                    lo=-1.0, hi=4.0)
    preshape_rad: float = param(0.0, "preshape joint set-point", unit="rad", lo=0.0, hi=1.75)
    force_per_pressure_n: float = param(0.02, "trigger force per unit of the combined maximum "
                                        "pressure", unit="N", lo=0.0, hi=10.0)
    force_combine: str = param("max", "how per-finger maximum pressures combine",
                               choices=("max", "mean", "sum"))
    force_filter_hz: float = param(20.0, "low-pass cut-off of the displayed force", unit="Hz",
                                   lo=0.1, hi=1000.0)


@dataclass(frozen=True, slots=True)
class ControllerConfig:
    """Which controller runs and how."""

    kind: str = param("two-layer", "controller (registry key)",
                      choices=("two-layer", "direct", "tdpa", "wave"))
    rate_hz: float = param(1000.0, "controller loop rate", unit="Hz", lo=1.0, hi=10000.0)
    tank: TankConfig = section(TankConfig, "energy tanks of the passivity layer")
    transparency: TransparencyConfig = section(TransparencyConfig, "transparency layer")
