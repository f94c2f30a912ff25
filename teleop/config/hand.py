"""Config section for the hand service and its backends."""

from __future__ import annotations

from dataclasses import dataclass

from teleop.config.loader import param, section


@dataclass(frozen=True, slots=True)
class ObjectConfig:
    """The object the simulated hand grasps."""

    kind: str = param("cylinder", "object shape", choices=("none", "cylinder", "block"))
    x_m: float = param(0.045, "cylinder centre along the palm normal (the open finger's "
                       "line) from the proximal axle, in the finger's plane; not used by a block",
                       unit="m", lo=-1.0, hi=1.0)
    y_m: float = param(0.03, "cylinder centre, or the block's flat face (the block fills "
                       "y >= y_m), offset across the finger's zero line towards the side the "
                       "finger closes to", unit="m", lo=-1.0, hi=1.0)
    radius_m: float = param(0.02, "cylinder radius", unit="m", lo=1e-3, hi=0.5)
    stiffness_n_per_m: float = param(2000.0, "contact stiffness", unit="N/m", lo=1.0, hi=1e7)
    damping_n_s_per_m: float = param(5.0, "contact damping", unit="N s/m", lo=0.0, hi=1e5)
    core_depth_m: float = param(0.012, "depth of the object's compliant skin: pressed deeper, "
                                "a pad meets the rigid core (the servo's full torque must not "
                                "push a finger through the object)", unit="m", lo=1e-4, hi=1.0)
    core_stiffness_n_per_m: float = param(2e5, "stiffness added once the core is reached",
                                          unit="N/m", lo=0.0, hi=1e8)
    yield_force_n: float = param(0.0, "the skin crushes plastically: the skin's spring force "
                                 "on a pad (per engaged fraction) is held at this level by a "
                                 "permanent dent that grows, and the work into the dent is "
                                 "never returned (the core does not yield); 0: an elastic "
                                 "object that never yields", unit="N", lo=0.0, hi=1e4)
    yield_hardening_n_per_m: float = param(0.0, "the yield level's rise per metre of dent "
                                           "(0: perfectly plastic)", unit="N/m", lo=0.0,
                                           hi=1e7)


@dataclass(frozen=True, slots=True)
class SimHandConfig:
    """The simulated hand built from the finger model."""

    physics_rate_hz: float = param(1000.0, "physics integration rate", unit="Hz", lo=100.0,
                                   hi=100000.0)
    command_delay: bool = param(False, "reproduce the stock driver's 0.09 s command delay")
    noise: bool = param(True, "add sensor noise and quantisation")
    engine: str = param("compiled", "physics engine: the numba-compiled step, or the Python "
                        "reference it is held to (within 1e-9 rad)",
                        choices=("compiled", "python"))
    calibration: str = param("model", "which column of the seed's Table 4.2 (weight test) the "
                             "finger's base spring is calibrated on: the report's model "
                             "(2.407/0.767/0/0 rad) or the physical finger's measurements "
                             "(2.35/0.785/0.087/0 rad)", choices=("model", "measured"))
    model: str = param("", "finger model file written by teleop diagnose --write-params "
                       "(TOML: refined finger parameters and effects); empty: the calibrated "
                       "finger")
    tactile_gain: float = param(1.0, "true gain of the simulated tactile cells over their "
                                "nominal calibration (a mis-calibrated sensor: 0.333 reads 3x "
                                "low); multiplies the pressure readings only, not the contact "
                                "physics", lo=0.0, hi=100.0)
    distal_tactile_gain: float = param(1.0, "further gain of the simulated distal pad's 4 "
                                       "cells alone (on top of tactile_gain: 0.333 makes the "
                                       "distal pad read 3x low while the proximal one reads "
                                       "true); readings only", lo=0.0, hi=100.0)
    object: ObjectConfig = section(ObjectConfig, "the grasped object")


@dataclass(frozen=True, slots=True)
class DynamixelConfig:
    """Dynamixel MX-28 servos driven through dynamixel-sdk (the direct-USB ReFlex layout)."""

    port: str = param("/dev/ttyUSB0", "serial port of the servo bus")
    baud_rate: int = param(57142, "serial baud rate", unit="bit/s", lo=1200, hi=4500000)
    protocol: float = param(1.0, "Dynamixel protocol version", lo=1.0, hi=2.0)
    ids: tuple[int, ...] = param((1, 2, 3, 4), "servo IDs: finger 1, 2, 3, preshape",
                                  size=4)
    inversion: tuple[int, ...] = param((1, -1, 1, -1), "direction sign per motor",
                                        size=4)
    finger_ratio: float = param(1.42, "motor-to-joint ratio of the finger motors", lo=0.1, hi=10.0)
    preshape_ratio: float = param(1.5, "motor-to-joint ratio of the preshape motor", lo=0.1,
                                  hi=10.0)
    finger_travel_rad: float = param(3.6, "finger joint travel limit", unit="rad", lo=0.0, hi=10.0)
    preshape_travel_rad: float = param(1.75, "preshape travel limit", unit="rad", lo=0.0, hi=10.0)
    overload_finger_units: float = param(350.0, "finger load above which the target backs off",
                                         unit="load units", lo=0.0, hi=1023.0)
    overload_preshape_units: float = param(400.0, "preshape load threshold", unit="load units",
                                           lo=0.0, hi=1023.0)
    command_pacing: bool = param(False, "pace commands like the stock driver (0.09 s delay)")
    command_delay_s: float = param(0.09, "delay applied to every command when pacing is on",
                                   unit="s", lo=0.0, hi=5.0)
    max_failures: int = param(5, "consecutive bus failures before the hand goes safe", lo=1)
    reboot_after_s: float = param(1.0, "protocol 2.0: time in the servo-error safe state before "
                                  "the faulted servos are rebooted to clear their latched "
                                  "hardware error status (again as often while it comes back; "
                                  "0 = never reboot)", unit="s", lo=0.0, hi=3600.0)
    retries: int = param(2, "retries of one failed bus transaction", lo=0, hi=100)
    timeout_s: float = param(0.02, "serial reply timeout", unit="s", lo=0.001, hi=5.0)
    bulk_read: bool = param(False, "protocol 1.0: read all servos with one BULK_READ per cycle "
                            "instead of one READ per servo")
    zeros_rad: tuple[float, ...] = param((0.0, 0.0, 0.0, 0.0), "calibration zero per motor: "
                                         "raw * scale / ratio at joint angle 0 (what the "
                                         "calibration routine saves)", unit="rad",
                                         lo=-1000.0, hi=1000.0, size=4)
    calibrate: bool = param(False, "run the finger calibration routine at start (step in "
                            "until the load rises, back off, save the zero)")
    calibration_load_units: float = param(40.0, "filtered load rise that marks the tendon "
                                          "taking up the finger (calibration)",
                                          unit="load units", lo=1.0, hi=1023.0)
    calibration_step_s: float = param(0.05, "time between 6-count calibration steps", unit="s",
                                      lo=0.001, hi=1.0)
    calibration_max_steps: int = param(400, "calibration steps before giving up", lo=1,
                                       hi=100000)
    speed_rad_s: float = param(3.5, "joint speed of position moves (0 = servo maximum)",
                               unit="rad/s", lo=0.0, hi=20.0)
    torque_limit: float = param(1.0, "servo torque limit, fraction of maximum", lo=0.0, hi=1.0)
    load_filter: float = param(0.25, "weight of a new load sample in the load filter", lo=0.01,
                               hi=1.0)
    force_gain_rad_per_unit: float = param(4e-5, "force mode: set-point change per load unit "
                                           "of error per control tick", unit="rad/unit",
                                           lo=0.0, hi=0.01)
    contact_load_units: float = param(150.0, "filtered load of a stalled finger taken as "
                                      "contact (this layout has no tactile sensors)",
                                      unit="load units", lo=0.0, hi=1023.0)


@dataclass(frozen=True, slots=True)
class TakkTileConfig:
    """The ReFlex TakkTile's brain board over UDP (the servo mechanics: ratios, inversion,
    travel, overload thresholds, load filter and speed come from hand.dynamixel)."""

    network: str = param("multicast", "how the board is reached: multicast (the real hand) "
                         "or unicast (teleop hand-emulator on loopback)",
                         choices=("multicast", "unicast"))
    address: str = param("224.0.0.124", "the board's multicast group, or its unicast address "
                         "(IPv4)")
    port: int = param(11333, "the board's UDP port (multicast: the PC binds it too)", lo=1,
                      hi=65535)
    interface: str = param("", "multicast: IPv4 address of the local interface facing the "
                           "hand (empty: the system's choice)")
    multicast_loopback: bool = param(False, "multicast: hear our own host's multicast (on "
                                     "when the emulator runs on this host; the stock driver "
                                     "turns it off)")
    zeros_rad: tuple[float, ...] = param((0.0, 0.0, 0.0, 0.0), "motor zero per motor: raw * "
                                         "scale / ratio at joint angle 0 (what calibration "
                                         "saves)", unit="rad", lo=-1000.0, hi=1000.0, size=4)
    calibrate: bool = param(False, "calibrate the finger motor zeros at start against the "
                            "proximal encoders (step 6 counts until the encoder moves 0.05 "
                            "rad, back off 50 counts)")
    calibration_step_s: float = param(0.05, "time between 6-count calibration steps",
                                      unit="s", lo=0.001, hi=1.0)
    calibration_max_steps: int = param(400, "calibration steps before giving up", lo=1,
                                       hi=100000)
    rest_packets: int = param(10, "state packets averaged at start (fingers open, untouched) "
                              "for the tactile offsets and the proximal encoder zeros; 0: no "
                              "offsets, encoder zero at count 0", lo=0, hi=1000)
    contact_threshold: float = param(20.0, "pressure above the resting offset taken as "
                                     "contact", unit="raw", lo=0.0, hi=65535.0)
    speed_change_sequence: bool = param(False, "set the moving speed at start with the stock "
                                        "driver's sequence (velocity mode, speeds, position "
                                        "mode; 0.02 + 0.035 + 0.035 s)")
    start_timeout_s: float = param(2.0, "wait this long for the board's first state packet",
                                   unit="s", lo=0.01, hi=60.0)
    silent_periods: float = param(4.0, "state periods without a valid state packet after "
                                  "which the board is silent and the hand watchdog trips (the "
                                  "board's own period, from its clock: 25 ms free, ~36 ms "
                                  "grasping)", lo=1.0, hi=100.0)

@dataclass(frozen=True, slots=True)
class HandConfig:
    """The hand service."""

    backend: str = param("sim", "hand backend (registry key)",
                         choices=("sim", "dynamixel", "reflex-takktile"))
    state_rate_hz: float = param(40.0, "hand state publication rate", unit="Hz", lo=1.0,
                                 hi=1000.0)
    sim: SimHandConfig = section(SimHandConfig, "simulated hand backend")
    dynamixel: DynamixelConfig = section(DynamixelConfig, "dynamixel backend")
    takktile: TakkTileConfig = section(TakkTileConfig, "reflex-takktile backend (brain board)")
