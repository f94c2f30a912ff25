"""An emulated ReFlex TakkTile brain board: the simulated hand behind the board's packets.

:class:`BrainBoardModel` holds no sockets: :meth:`handle` takes a PC -> board packet,
:meth:`state_at` advances the physics (:class:`sim.sim_hand.SimHand`: the finger model and the
contact object, so pressures are model outputs) and returns the raw state the board would
send; :meth:`period_s` is the time to the next state packet.  The UDP loop is
:mod:`sim.hand_emulator_udp`, the fault injection :mod:`sim.hand_emulator_faults`.

What is emulated (and what is assumed, see docs/takktile.md):

* modes: 0 idle (torque off), 1 velocity (torque off; targets set the moving speed, as the
  reference describes), 2 position (torque on; targets are goal positions);
* raw fields in the stock driver's units (takktile_units), each servo with a home count (its
  raw position with the finger open) and the driver's inversion; proximal encoders with a
  seeded offset; each tactile sensor with a seeded resting value (the driver's tactile
  offsets) and read noise; the load estimate with Gaussian noise (``load_noise_units``);
* the state rate: 40 Hz free, dropping linearly with the number of fingers in contact to
  28 Hz with all three (seed ch. 3: 40 Hz, 28 Hz while grasping; the linear law is assumed);
* servo overload: a load above ``overload_units`` for ``overload_s`` sets error bit 5 and
  switches the servo's torque off (MX-28 alarm shutdown) until the PC sends modes again.
"""

from __future__ import annotations

import random
from dataclasses import dataclass, replace

from sim.hand import HandMotorCommand
from sim.motor import MotorCommand
from sim.sim_hand import SimHand
from teleop.config.hand import HandConfig
from teleop.devices import takktile_units as U
from teleop.devices.brain_board_packets import (
    MODE_POSITION,
    MODE_VELOCITY,
    N_TACTILE,
    BoardState,
    ModesPacket,
    TargetsPacket,
)
from teleop.messages import N_PRESSURE

FREE_RATE_HZ = 40.0
GRASP_RATE_HZ = 28.0
OVERLOAD_BIT = 1 << 5


@dataclass(frozen=True, slots=True)
class BoardParams:
    """The emulated board's constants."""

    homes_counts: tuple[int, int, int, int] = (0, 0, 0, 0)
    inversion: tuple[int, int, int, int] = (1, -1, 1, -1)
    finger_ratio: float = 1.42
    preshape_ratio: float = 1.5
    load_noise_units: float = 8.0
    pressure_noise: float = 1.5
    overload_units: float = 1000.0
    overload_s: float = 0.2
    seed: int = 0


class BrainBoardModel:
    """The board and its hand (no I/O)."""

    def __init__(self, hand_cfg: HandConfig, params: BoardParams) -> None:
        self.p = params
        cfg = replace(hand_cfg, sim=replace(hand_cfg.sim, noise=False))
        self.hand = SimHand(cfg, seed=params.seed)
        self.rng = random.Random(params.seed)
        self.ratio = (params.finger_ratio,) * 3 + (params.preshape_ratio,)
        self.modes = [0, 0, 0, 0]  # idle until the PC says otherwise
        self.goals = list(params.homes_counts)
        self.speeds = [0, 0, 0, 0]  # 0 = full speed
        self.tactile_rest = tuple(self.rng.randint(150, 600) for _ in range(N_TACTILE))
        self.encoder_offset = tuple(self.rng.randint(0, U.ENCODER_COUNTS - 1) for _ in range(3))
        self.overloaded = [False] * 4
        self._over_since: list[float | None] = [None] * 4
        self.contacts = 0  # fingers in contact at the last state
        self.t_s = 0.0
        self.packets_in = 0

    def start(self) -> None:
        """Compile or load the physics engine."""
        self.hand.start()

    # ---- PC -> board
    def handle(self, pkt: ModesPacket | TargetsPacket, t_s: float) -> None:
        """Apply one packet at ``t_s`` (the physics first runs up to then)."""
        self.advance(t_s)
        self.packets_in += 1
        if isinstance(pkt, ModesPacket):
            self.modes = list(pkt.modes)
            self.overloaded = [False] * 4  # torque written again: the alarm is cleared
            self._over_since = [None] * 4
        else:
            for k, target in enumerate(pkt.targets):
                if self.modes[k] == MODE_POSITION:
                    self.goals[k] = target
                elif self.modes[k] == MODE_VELOCITY:
                    self.speeds[k] = target
        self._command()

    def _torque(self, k: int) -> bool:
        return self.modes[k] == MODE_POSITION and not self.overloaded[k]

    def _command(self) -> None:
        p = self.p
        cmds = []
        for k in range(3):
            shaft = p.inversion[k] * (U.signed_counts(self.goals[k]) - p.homes_counts[k]) \
                * U.RAD_PER_COUNT
            speed = abs(U.shaft_speed_from_raw(self.speeds[k]))
            cmds.append(MotorCommand("position", shaft, speed_rad_s=speed,
                                     torque_limit=1.0 if self._torque(k) else 0.0))
        pre = p.inversion[3] * (U.signed_counts(self.goals[3]) - p.homes_counts[3]) \
            * U.RAD_PER_COUNT / self.ratio[3]
        if not self._torque(3):
            pre = self.hand.state.preshape_rad  # no torque: the swivel stays where it is
        self.hand.set_motor_commands(HandMotorCommand((cmds[0], cmds[1], cmds[2]), pre))

    # ---- physics and board -> PC
    def advance(self, t_s: float) -> None:
        """Run the physics to ``t_s`` (never backwards)."""
        if t_s > self.t_s:
            self.hand.read(t_s)
            self.t_s = t_s

    def period_s(self) -> float:
        """Time to the next state packet: 40 Hz free, towards 28 Hz while grasping."""
        rate = FREE_RATE_HZ - (FREE_RATE_HZ - GRASP_RATE_HZ) * self.contacts / 3.0
        return 1.0 / rate

    def state_at(self, t_s: float) -> BoardState:
        """Advance to ``t_s`` and read the board's state packet there (noise drawn here)."""
        self.advance(t_s)
        out = self.hand.truth()
        p, rng = self.p, self.rng
        thr = self.hand.params.finger.contact_threshold
        pressures = list(self.tactile_rest)
        angle, speed, load, error = [0] * 4, [0] * 4, [0] * 4, [0] * 4
        enc = [0, 0, 0]
        contacts = 0
        for k, f in enumerate(out.fingers):
            contacts += any(v > thr for v in f.pressure)
            for j in range(N_PRESSURE):
                noisy = f.pressure[j] + rng.gauss(0.0, p.pressure_noise)
                pressures[9 * k + j] = max(0, min(65535, round(self.tactile_rest[9 * k + j]
                                                               + noisy)))
            enc[k] = U.encoder_counts(f.proximal_rad, self.encoder_offset[k])
            inv = p.inversion[k]
            angle[k] = U.wire_counts(p.homes_counts[k]
                                     + round(inv * f.motor_angle_rad / U.RAD_PER_COUNT))
            v = inv * f.motor_velocity_rad_s
            speed[k] = min(1023, round(abs(v) / U.RAD_S_PER_SPEED_UNIT)) \
                + (U.SPEED_REVERSE if v < 0 else 0)
            pull = f.motor_load_units + rng.gauss(0.0, p.load_noise_units)
            self._overload(k, pull, t_s)
            load[k] = U.raw_load(pull, inv)
        inv3 = p.inversion[3]
        angle[3] = U.wire_counts(p.homes_counts[3] + round(
            inv3 * out.preshape_rad * self.ratio[3] / U.RAD_PER_COUNT))
        error = [OVERLOAD_BIT if o else 0 for o in self.overloaded]
        self.contacts = contacts
        return BoardState(
            header=(1, 0, 0, 0), systime_us=round(t_s * 1e6) % (1 << 32),
            pressures=tuple(pressures), temperatures=(2500,) * N_TACTILE,
            encoders=(enc[0], enc[1], enc[2]), dxl_error=tuple(error),  # type: ignore[arg-type]
            dxl_angle=tuple(angle), dxl_speed=tuple(speed),  # type: ignore[arg-type]
            dxl_load=tuple(load), dxl_voltage=(120,) * 4,  # type: ignore[arg-type]
            dxl_temperature=(35,) * 4)

    def _overload(self, k: int, pull: float, t_s: float) -> None:
        if abs(pull) <= self.p.overload_units or self.overloaded[k]:
            self._over_since[k] = None
            return
        since = self._over_since[k]
        if since is None:
            self._over_since[k] = t_s
        elif t_s - since >= self.p.overload_s:
            self.overloaded[k] = True  # alarm shutdown: torque off until modes are re-sent
            self._command()
