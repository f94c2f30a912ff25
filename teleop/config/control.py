"""Config section for the controller (transparency + passivity layers)."""

from __future__ import annotations

from dataclasses import dataclass

from teleop.config.loader import param, section


@dataclass(frozen=True, slots=True)
class TankConfig:
    """Energy tank and passivity-layer tuning (Franken et al. 2011)."""

    initial_j: float = param(10.0, "initial energy of each port's tank (tdpa: each side's initial "
                             "budget)", unit="J", lo=0.0, hi=100.0)
    desired_j: float = param(0.5, "tank level the master's level controller aims for", unit="J",
                             lo=0.0, hi=100.0)
    max_j: float = param(20.0, "upper tank limit; surplus is dissipated", unit="J", lo=0.0,
                         hi=1000.0)
    min_j: float = param(0.01, "level below which the passivity layer stops paying for the "
                         "transparency layer's demands", unit="J", lo=0.0, hi=100.0)
    reserve_j: float = param(0.25, "level each port's tank keeps for itself; only the surplus "
                             "above it is sent on", unit="J", lo=0.0, hi=100.0)
    transfer_fraction: float = param(0.1, "fraction of the tank surplus sent as energy quantum "
                                     "per message (beta)", lo=0.0, hi=1.0)
    controller_fraction: float = param(0.1, "fraction of the controller's store forwarded per "
                                       "cycle", lo=0.0, hi=1.0)
    tlc_gain: float = param(20.0, "tank level controller gain alpha", unit="N s/(m J)", lo=0.0,
                            hi=1e6)
    tlc_damping_max: float = param(10.0, "cap on the level controller's damping (further capped "
                                   "at trigger_mass_kg / (2 dt))", unit="N s/m", lo=0.0, hi=1e4)
    controller_split: float = param(0.5, "share of energy the controller forwards to the hand "
                                    "(rest to the master)", lo=0.0, hi=1.0)
    energy_scale: float = param(1.0, "power scaling: hand-side joules per master-side joule "
                                "(1 = unscaled, energy conserved literally)", lo=1e-3, hi=1e4)


@dataclass(frozen=True, slots=True)
class PortModelConfig:
    """What the passivity layers assume about the two physical ports."""

    trigger_max_speed_m_s: float = param(1.0, "largest trigger speed; bounds the energy one "
                                         "held force can deliver in a sample", unit="m/s",
                                         lo=1e-3, hi=100.0)
    trigger_mass_kg: float = param(0.05, "smallest effective mass of trigger plus finger (caps "
                                   "the level controller's damping)", unit="kg", lo=1e-4,
                                   hi=10.0)
    force_max_n: float = param(8.0, "largest force the trigger displays", unit="N", lo=0.0,
                               hi=100.0)
    servo_stiffness_nm_per_rad: float = param(5.0, "finger position servo stiffness at the "
                                              "joint (upper bound; MX-28 P gain 1000 load units "
                                              "per shaft rad, 5 units/N, 12.2 mm spool, x 1.42^2)",
                                              unit="N m/rad", lo=1e-3, hi=1e4)
    servo_damping_nm_s_per_rad: float = param(0.8, "finger servo damping at the joint (lower "
                                              "bound, half of Table 4.1's smallest viscous "
                                              "friction, 1.6; dissipation of closing motion "
                                              "credited to the hand tank)",
                                              unit="N m s/rad", lo=0.0, hi=1e3)
    servo_torque_max_nm: float = param(3.55, "finger servo torque limit at the joint (upper "
                                       "bound; MX-28 2.5 N m stall x 1.42)", unit="N m",
                                       lo=1e-3, hi=1e3)
    servo_max_speed_rad_s: float = param(4.0, "set-points move at most this fast (the servo's "
                                         "slew rate at the joint: MX-28 55 rpm / 1.42), so the "
                                         "modelled servo spring matches the servo's own ramp",
                                         unit="rad/s", lo=1e-3, hi=1e6)
    hand_port: str = param("object", "two-layer hand: what its tank pays for. 'object': the "
                           "work the finger pads do on the object (tactile force x pad motion, "
                           "on the safe side), the servo's potential and tendon stretch held "
                           "in reserve; 'servo': the servo spring's energy at every set-point "
                           "move (the older, stricter layer)", choices=("object", "servo"))
    tendon_stiffness_nm_per_rad: float = param(5.0, "tendon stiffness seen at the joint-side "
                                               "motor angle (lower bound: 20 kN/m x (1.42 x "
                                               "12.2 mm)^2 = 6.0); bounds the energy a "
                                               "stretched tendon can push into the object",
                                               unit="N m/rad", lo=1e-3, hi=1e4)
    finger_kinetic_j: float = param(0.015, "kinetic energy of one finger with its rotor at the "
                                    "servo's top speed (upper bound); with the energy the "
                                    "fingers hold back it caps what one hand sample can "
                                    "deliver to the object", unit="J", lo=0.0, hi=100.0)
    free_motion_refund: bool = param(True, "two-layer hand: the servo's work on a finger whose "
                                     "tactile cells report no contact (before and after the "
                                     "sample) stays in the hand and goes back to the tank")


@dataclass(frozen=True, slots=True)
class TactileConfig:
    """The hand's tactile cells as the passivity layer reads them (hand_port = 'object'):
    a force F at x along a link reads gain F (exp(-d^2/2 sigma^2) + tail exp(-|d|/tail_m))
    on the cell d away (TakkTile calibration; see teleop/control/object_port.py)."""

    pressure_per_n: float = param(100.0, "cell reading per N of normal force at the cell",
                                  lo=1e-3, hi=1e6)
    proximal_sensor_x_m: tuple[float, ...] = param(
        (0.0189, 0.0268, 0.0347, 0.0426, 0.0506), "proximal cells: distance from the base axle",
        unit="m", size=5)
    distal_sensor_x_m: tuple[float, ...] = param(
        (0.0114, 0.0193, 0.0272, 0.0375), "distal cells: distance from the flexure's end",
        unit="m", size=4)
    kernel_sigma_m: float = param(0.004, "width of a cell's Gaussian response", unit="m",
                                  lo=1e-5, hi=0.1)
    kernel_tail: float = param(0.08, "weight of the response's exponential tail", lo=0.0, hi=1.0)
    kernel_tail_m: float = param(0.010, "length of the response's exponential tail", unit="m",
                                 lo=1e-5, hi=1.0)
    proximal_length_m: float = param(0.076, "base axle to the distal link's origin", unit="m",
                                     lo=1e-3, hi=1.0)
    proximal_pad_m: tuple[float, ...] = param((0.010, 0.060), "where the proximal pad starts "
                                              "and ends (from the base axle)", unit="m", size=2)
    distal_pad_m: tuple[float, ...] = param((0.0, 0.045), "where the distal pad starts and ends "
                                            "(from the flexure's end)", unit="m", size=2)
    noise_floor: float = param(6.0, "readings at or below this on every cell of a link: no "
                               "contact", lo=0.0, hi=1e6)
    force_margin: float = param(1.15, "bound m on the force sensor's gain error: the estimated "
                                "net work on the object is charged x m while the object has "
                                "received more than it gave back, / m otherwise",
                                lo=1.0, hi=100.0)
    yield_window_m: float = param(0.001, "yielding-contact guard: pad advance over which the "
                                  "force's rise is measured (a chord of force against advance)",
                                  unit="m", lo=1e-5, hi=0.05)
    yield_stiffness_ratio: float = param(0.2, "yielding-contact guard: a chord less stiff than "
                                         "this fraction of the contact's stiffest flags the "
                                         "finger as yielding; its further advance is then "
                                         "charged at the servo's torque (0: guard off)",
                                         lo=0.0, hi=1.0)
    yield_set_check: bool = param(True, "yielding-contact guard: also judge each contact "
                                  "when it ends by the set it left (quick grasps too brief "
                                  "for the chords): a set is charged at the cells' gain the "
                                  "gain cross-check measured in the contact, else the "
                                  "finger is flagged (docs/controllers.md)")
    yield_credit: bool = param(True, "yielding-contact guard: once the gain cross-check has "
                               "measured a flagged finger's cells in the contact, credit back "
                               "what its flag charged at the servo's worst case beyond the "
                               "measured ratio times the contact's estimated work (keeps the "
                               "hard operator's crushable-cylinder grasps under delay; rests on "
                               "the gain check's assumptions; docs/controllers.md)")
    stall_window_rad: float = param(0.1, "unseen-contact guard: inward motor travel (joint "
                                    "side) over which the proximal joint's advance is measured "
                                    "(0: guard off)", unit="rad", lo=0.0, hi=1.0)
    stall_ratio: float = param(0.3, "unseen-contact guard: a proximal advance below this "
                               "fraction of the motor's, with the cells silent and the distal "
                               "link curled past free_curl_rad, flags the finger; its further "
                               "inward motion is then charged at the servo's torque",
                               lo=0.0, hi=1.0)
    free_curl_rad: float = param(0.45, "unseen-contact guard: the most the motor (joint side) "
                                 "runs ahead of the proximal encoder in free motion (the distal "
                                 "link's curl; 0.385 rad at most on the simulated hand: "
                                 "measure yours closing on nothing)",
                                 unit="rad", lo=0.0, hi=3.0)
    load_torque_nm_per_unit: float = param(0.00347, "gain cross-check: joint torque per unit "
                                           "of the servo's present load (MX-28: 2.5 N m at "
                                           "1023 units, x 1.42; calibrate on the real hand)",
                                           unit="N m", lo=0.0, hi=1.0)
    base_spring_nm_per_rad: float = param(0.0624, "gain cross-check: the base joint's spring "
                                          "(Table 4.2 fit, sim/params.py)", unit="N m/rad",
                                          lo=0.0, hi=100.0)
    base_preload_rad: float = param(1.957, "gain cross-check: the base spring's preload "
                                    "against the open stop", unit="rad", lo=0.0, hi=10.0)
    gain_check_window_s: float = param(0.2, "gain cross-check: how long a grasp must stand "
                                       "still for one comparison of the cells' contact moment "
                                       "with the servo's load (0: check off)", unit="s",
                                       lo=0.0, hi=10.0)
    gain_check_still_rad: float = param(0.02, "gain cross-check: motor (joint side) and "
                                        "proximal encoder stay this close to where the window "
                                        "began", unit="rad", lo=0.0, hi=1.0)
    gain_check_damping_nm_s_per_rad: float = param(4.5, "gain cross-check: the servo's "
                                                   "viscous friction at the joint, upper bound "
                                                   "(Table 4.1's largest: ~900 load units per "
                                                   "shaft rad/s x 1.42)", unit="N m s/rad",
                                                   lo=0.0, hi=1e3)
    gain_check_tolerance_nm: float = param(0.15, "gain cross-check: tolerance on the contact "
                                           "moment the servo's load implies (Coulomb friction, "
                                           "load noise, the spring's and the lever arms' "
                                           "model error)", unit="N m", lo=0.0, hi=100.0)


@dataclass(frozen=True, slots=True)
class TransparencyConfig:
    """What the operator should feel and where the hand should go."""

    finger_enable: tuple[bool, ...] = param((True, True, True), "fingers driven by the trigger",
                                            size=3)
    trigger_travel_m: float = param(0.025, "trigger travel mapped onto the finger range",
                                    unit="m", lo=1e-3, hi=0.2)
    open_angle_rad: float = param(0.0, "finger set-point with the trigger open", unit="rad",
                                  lo=-1.0, hi=4.0)
    closed_angle_rad: float = param(3.0, "finger set-point with the trigger closed", unit="rad",
                                    lo=-1.0, hi=4.0)
    map_exponent: float = param(1.0, "shape of the trigger-to-finger map: set-point = open + "
                                "(closed - open) * fraction ** exponent", lo=0.1, hi=10.0)
    preshape_rad: float = param(0.0, "preshape joint set-point", unit="rad", lo=0.0, hi=1.75)
    force_per_pressure_n: float = param(0.02, "trigger force per unit of the combined maximum "
                                        "pressure", unit="N", lo=0.0, hi=10.0)
    pressure_deadband: float = param(10.0, "tactile noise not displayed: combined pressures "
                                     "at or below this give no force, rising to the full "
                                     "map at twice it (continuous; 2 x 10 = the stock driver's "
                                     "contact threshold)", lo=0.0, hi=1e4)
    force_combine: str = param("max", "how per-finger maximum pressures combine",
                               choices=("max", "mean", "sum"))
    force_filter_hz: float = param(20.0, "low-pass cut-off of the displayed force", unit="Hz",
                                   lo=0.1, hi=1000.0)


@dataclass(frozen=True, slots=True)
class DelayAdaptConfig:
    """Delay-aware transparency layer of ``two-layer``: the displayed-force gain is scheduled
    on the measured round-trip delay so that the linearised loop (design plant below) keeps a
    gain margin at that delay (docs/controllers.md)."""

    enabled: bool = param(True, "schedule the force-feedback gain on the measured round trip")
    gain_margin: float = param(2.0, "gain margin kept at the measured delay: gain = min(1, "
                               "critical gain / margin)", lo=1.0, hi=100.0)
    gain_rise_per_s: float = param(4.0, "how fast the gain may rise again (it drops at once)",
                                   unit="1/s", lo=1e-3, hi=1e6)
    delay_window_s: float = param(0.2, "the round-trip estimate is the largest measurement "
                                  "within about this window (rises at once, falls after it)",
                                  unit="s", lo=1e-3, hi=100.0)
    stale_cap_s: float = param(0.1, "a message held longer than this counts as an outage (left "
                               "to the watchdogs), not as more delay", unit="s", lo=0.0,
                               hi=100.0)
    operator_mass_kg: float = param(0.05, "design plant: trigger + operator finger mass",
                                    unit="kg", lo=1e-4, hi=10.0)
    operator_damping_n_s_per_m: float = param(6.0, "design plant: operator finger damping "
                                              "(relaxed grasp)", unit="N s/m", lo=0.0, hi=1e4)
    operator_stiffness_n_per_m: float = param(500.0, "design plant: operator finger stiffness "
                                              "(relaxed grasp)", unit="N/m", lo=1.0, hi=1e6)
    servo_damping_nm_s_per_rad: float = param(1.6, "design plant: finger servo damping at its "
                                              "torque limit (joint side)", unit="N m s/rad",
                                              lo=1e-3, hi=1e3)
    contact_stiffness_nm_per_rad: float = param(0.57, "design plant: stiffness behind the servo "
                                                "in contact (joint side)", unit="N m/rad",
                                                lo=1e-3, hi=1e4)
    pressure_per_nm: float = param(1810.0, "design plant: peak pressure units per N m of "
                                   "contact torque", lo=1e-3, hi=1e7)


@dataclass(frozen=True, slots=True)
class ContactModelConfig:
    """Model-mediated rendering (two-layer): the hand estimates a contact model per finger,
    the master renders it locally; see docs/controllers.md."""

    enabled: bool = param(True, "two-layer: the hand estimates a contact model per finger and "
                          "the master renders it at its own rate (off: the delayed measured "
                          "force only)")
    contact_pressure: float = param(20.0, "peak pressure at which a finger counts as touching "
                                    "(it lets go below half of it)", lo=0.0, hi=1e5)
    static_speed_rad_s: float = param(0.2, "a motor angle moving slower than this counts as "
                                      "held", unit="rad/s", lo=0.0, hi=10.0)
    settle_rate_per_s: float = param(0.5, "a held grasp has settled when its peak pressure "
                                     "changes by less than this fraction per second", unit="1/s",
                                     lo=0.0, hi=100.0)
    settle_noise: float = param(5.0, "peak-pressure change between samples that the sensor "
                                "noise alone makes, allowed on top of the settle rate (raw "
                                "units)", lo=0.0, hi=1e4)
    memory_s: float = param(0.5, "time constant over which settled samples are remembered "
                                 "(forgetting)", unit="s", lo=0.01, hi=1000.0)
    evidence_s: float = param(0.05, "settled grasp time before the fitted stiffness replaces "
                              "the prior", unit="s", lo=0.0, hi=100.0)
    prior_stiffness: float = param(800.0, "stiffness sent from a finger's first touch until "
                                   "settled samples give a fit (pressure units per rad; 0: send "
                                   "nothing before a fit)", lo=0.0, hi=1e6)
    min_deflection_rad: float = param(0.03, "settled samples closer than this to the contact "
                                      "angle are not used for the stiffness", unit="rad", lo=0.0,
                              hi=3.0)
    removal_margin_rad: float = param(0.15, "a finger this far past its contact angle without "
                                      "touching: the object is gone, the model dropped",
                                      unit="rad", lo=0.0, hi=3.0)
    stiffness_max: float = param(20000.0, "largest plausible stiffness (pressure units per rad); "
                                 "above it the estimate counts as diverged", lo=0.0, hi=1e6)
    force_rate_n_per_s: float = param(80.0, "a model update changes the rendered force at most "
                                      "this fast", unit="N/s", lo=0.0, hi=1e5)
    force_drop_rate_n_per_s: float = param(320.0, "a model update lowers the rendered force "
                                           "at most this fast (the trigger's 8 N in one 25 ms "
                                           "hand sample: a hand that stops pressing is felt to "
                                           "let go, not phased out over 0.1 s)", unit="N/s",
                                           lo=0.0, hi=1e5)
    touch_force_n: float = param(2.0, "trigger force at which a finger's new touch is held "
                                 "until the operator can have felt it: a light touch, a "
                                 "quarter of the trigger's largest force (the touch caps of "
                                 "docs/controllers.md; at most the trigger's largest force)",
                                 unit="N", lo=0.0, hi=100.0)
    touch_feel_s: float = param(0.3, "the controller's cap on a new touch opens once the "
                                "master has rendered it this long (a human's voluntary answer "
                                "to a felt force takes 0.15-0.3 s: the trigger then shows the "
                                "operator's answer, not his blind squeeze)", unit="s",
                                lo=0.0, hi=10.0)
    follow_held_back: bool = param(True, "the model's contact angle goes on the wire moved "
                                   "out by how far the hand's tank holds the set-points back, "
                                   "so the operator feels what the hand presses (off: the "
                                   "object's model as estimated; a starved hand is then felt "
                                   "as a firm grasp)")
    damping_periods: float = param(1.0, "rendered contact damping, in master periods times the "
                                   "rendered stiffness (Colgate: more than half a period keeps a "
                                   "sampled spring passive)", lo=0.0, hi=100.0)


@dataclass(frozen=True, slots=True)
class ControllerConfig:
    """Which controller runs and how."""

    kind: str = param("two-layer", "controller (registry key)",
                      choices=("two-layer", "direct", "tdpa"))
    rate_hz: float = param(1000.0, "controller loop rate", unit="Hz", lo=1.0, hi=10000.0)
    tank: TankConfig = section(TankConfig, "energy tanks of the passivity layer")
    ports: PortModelConfig = section(PortModelConfig, "port models the passivity layers rely on")
    tactile: TactileConfig = section(TactileConfig, "tactile cells as the hand's passivity layer "
                                     "reads them")
    transparency: TransparencyConfig = section(TransparencyConfig, "transparency layer")
    delay_adapt: DelayAdaptConfig = section(DelayAdaptConfig, "delay-aware force-feedback gain "
                                            "(two-layer's transparency layer)")
    contact_model: ContactModelConfig = section(ContactModelConfig, "model-mediated rendering "
                                                "(two-layer)")
