"""A closed loop for controller tests: operator + trigger, impaired links, controller, a
first-order finger servo against a spring wall.  Exact energy bookkeeping of the physics.

Physics (test side; nothing here is computed with controller code):
* operator: mass-spring-damper finger on the trigger following a reference, plus random
  forcing; speed kept within the trigger's speed bound; hard stops at 0 and ``travel``;
  the device force is held over each 1 ms step, so its work on the operator is exactly
  ``-F dx`` (the operator port of the energy audit).
* finger i: massless first-order servo ``B xdot = sat(K (y - x)) - k_e max(0, x - wall)``
  (torque saturating at ``tau_max``, pulling both ways; no return spring) integrated by
  implicit Euler.  The environment is the spring wall on the closing side; the work the
  finger does on it over a step is exactly ``k_e/2 (pen1^2 - pen0^2)`` (the environment port
  of the audit: positive delivered, negative taken back).

The audit (:class:`Trace` ``op_*``/``env_*``) is the physical truth the tests judge by:
passive = energy delivered at both ports <= initial tank energy + energy taken from them, at
every sample.  It does not model the servo's own storage, so it is valid whatever potential
the hand's passivity layer assumes for the servo (two-sided, or one-sided as for a tendon
that only pulls).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

from teleop.control.energy_channel import EnergyLedger
from teleop.control.interface import ControllerSuite, ControlParams
from teleop.messages import FingerState, HandState, Header

DT = 1e-3


@dataclass
class Link:
    """Per-message delay (steps), loss, duplication; reordering if delays differ."""

    rng: np.random.Generator
    delay_steps: int = 0
    jitter_steps: int = 0
    loss: float = 0.0
    dup: float = 0.0
    fifo: bool = False
    queue: list[tuple[int, int, object]] = field(default_factory=list)
    count: int = 0
    last_due: int = 0

    def send(self, k: int, msg: object) -> None:
        copies = 0 if self.rng.random() < self.loss else 1
        if copies and self.rng.random() < self.dup:
            copies = 2
        for _ in range(copies):
            due = k + self.delay_steps + int(self.rng.integers(0, self.jitter_steps + 1))
            if self.fifo:
                due = max(due, self.last_due)
                self.last_due = due
            self.count += 1
            self.queue.append((due, self.count, msg))

    def deliver(self, k: int) -> object | None:
        """The last message arriving at step ``k`` (latest-wins), or None."""
        ready = sorted((d, c, m) for d, c, m in self.queue if d <= k)
        if not ready:
            return None
        self.queue = [e for e in self.queue if e[0] > k]
        return ready[-1][2]


@dataclass(frozen=True)
class Scenario:
    """Everything random about one closed-loop run."""

    seed: int = 0
    steps: int = 1500
    delay_steps: int = 0  # one way, each of the 4 link directions
    jitter_steps: int = 0
    loss: float = 0.0
    dup: float = 0.0
    hand_every: int = 1  # hand sample period in 1 ms steps
    op_mass_kg: float = 0.05
    op_stiffness: float = 500.0
    op_damping: float = 6.0
    op_force_n: float = 0.0  # amplitude of random forcing
    ref_fraction: float = 1.0  # how far the reference closes (0-1)
    ref_period_s: float = 1.0
    random_ref: bool = False
    wall_rad: tuple[float, float, float] = (1.5, 1.5, 1.5)
    #: a yielding object (a box pushed across a table): while pressed, the wall retreats at
    #: this speed and the table's friction takes the energy (0: a fixed wall)
    wall_speed_rad_s: float = 0.0
    contact_stiffness: float = 3.2  # N m / rad
    pressure_per_nm: float = 200.0  # sensor units per N m of contact torque
    servo_damping_factor: float = 1.0  # true B / assumed lower bound B
    servo_stiffness_factor: float = 1.0  # true K / the port model's K (assumption: <= 1)
    servo_torque_factor: float = 1.0  # true torque limit / the port model's (assumption: <= 1)
    sensor_gain_factor: float = 1.0  # true tactile gain / the controller's calibration


@dataclass
class Trace:
    """Per-step records of one run."""

    t: list[float] = field(default_factory=list)
    x_m: list[float] = field(default_factory=list)
    force_n: list[float] = field(default_factory=list)
    setpoint: list[tuple[float, float, float]] = field(default_factory=list)
    finger: list[tuple[float, float, float]] = field(default_factory=list)
    # physical energy audit, cumulative (J): work done on the operator / taken from it, and
    # work the fingers did on the wall / the wall gave back
    op_delivered_j: list[float] = field(default_factory=list)
    op_taken_j: list[float] = field(default_factory=list)
    env_delivered_j: list[float] = field(default_factory=list)
    env_taken_j: list[float] = field(default_factory=list)
    servo_storage_j: list[float] = field(default_factory=list)  # harness servo springs
    ledgers: list[tuple[EnergyLedger, EnergyLedger, EnergyLedger]] = field(default_factory=list)
    limited_master: int = 0
    limited_hand: int = 0
    yielding_hand: int = 0  # most fingers the hand side flagged as yielding at once

    @property
    def master_net_out_j(self) -> list[float]:
        """Net work done on the operator so far (delivered - taken)."""
        return [a - b for a, b in zip(self.op_delivered_j, self.op_taken_j, strict=True)]

    @property
    def env_net_out_j(self) -> list[float]:
        """Net work done on the environment so far (delivered - taken)."""
        return [a - b for a, b in zip(self.env_delivered_j, self.env_taken_j, strict=True)]

    @property
    def storage_j(self) -> list[float]:
        """Physical storage of the hand side: the harness servo's (two-way, saturating)
        spring energy plus the wall's ``k_e/2 pen^2`` (harness physics, not the controllers'
        servo model).  Not part of the audit; for tests that look at how much the loop has
        pumped into the hand."""
        return [a + b for a, b in zip(self.servo_storage_j, self.env_net_out_j, strict=True)]

    def audit_margin_j(self, initial_j: float, rho: float = 1.0) -> list[float]:
        """``initial + taken - delivered`` at every sample (operator port weighted by
        ``rho``, the power scale): >= 0 when the loop was passive."""
        return [initial_j + rho * (ot - od) + (et - ed) for od, ot, ed, et in
                zip(self.op_delivered_j, self.op_taken_j, self.env_delivered_j,
                    self.env_taken_j, strict=True)]


def initial_tank_j(suite: ControllerSuite, p: ControlParams) -> float:
    """Initial tank energy of the loop from the configuration, in hand-side joules: one
    ``initial_j`` tank per port (the master's weighted by the power scale), an empty
    controller store; no tanks for a non-passive controller."""
    return (p.energy_scale + 1.0) * p.initial_j if suite.passive else 0.0


def audit_failure(tr: Trace, initial_j: float, rho: float = 1.0,
                  tol_j: float = 1e-9) -> str:
    """The first sample at which the physical audit shows energy generated (delivered >
    initial + taken, or a non-finite value), described; "" when passive throughout."""
    for k, m in enumerate(tr.audit_margin_j(initial_j, rho)):
        if not math.isfinite(m):
            return f"non-finite audit at sample {k}"
        if m < -tol_j * max(1.0, initial_j):
            return (f"sample {k}: delivered exceeds initial {initial_j:.4g} J + taken by "
                    f"{-m:.4g} J")
    return ""


def reference(sc: Scenario, t: float, rng_ref: list[float]) -> float:
    if sc.random_ref:
        i = int(t / sc.ref_period_s) % len(rng_ref)
        return rng_ref[i]
    ph = (t % sc.ref_period_s) / sc.ref_period_s
    return sc.ref_fraction * (0.5 - 0.5 * math.cos(2 * math.pi * ph))


def servo_substep(x: float, y: float, wall: float, k: float, b: float, ke: float,
                  h: float, tau: float = math.inf) -> float:
    """Implicit Euler step of ``B xdot = sat_tau(K (y - x)) - ke max(0, x - wall)``.

    The residual is strictly increasing in the new ``x``, so exactly one of the six linear
    pieces (servo linear / saturated either way, in contact or free) is consistent.
    """
    c = b / h
    for mode in ("lin", "+", "-"):
        for ct in (0.0, 1.0):
            if mode == "lin":
                x1 = (c * x + k * y + ke * wall * ct) / (c + k + ke * ct)
            else:
                t = tau if mode == "+" else -tau
                x1 = (c * x + t + ke * wall * ct) / (c + ke * ct)
            u = k * (y - x1)
            tol = 1e-12 * (1.0 + abs(u))
            if mode == "lin" and abs(u) > tau + tol:
                continue
            if mode == "+" and u < tau - tol:
                continue
            if mode == "-" and u > -tau + tol:
                continue
            if (ct and x1 < wall - 1e-12) or (not ct and x1 > wall + 1e-12):
                continue
            return x1
    raise AssertionError("no consistent servo piece")  # pragma: no cover


def servo_spring_j(e: float, k: float, tau: float) -> float:
    """Energy of the harness servo's spring (``sat_tau(K e)``, both ways) stretched by ``e``."""
    a, e_s = abs(e), tau / k
    return 0.5 * k * a * a if a <= e_s else tau * (a - 0.5 * e_s)


#: the harness's tactile pad: the wall pushes at this point of the proximal link, and the
#: cells (at the ReFlex positions) read a Gaussian-plus-tail spread of that force
CONTACT_AT_M = 0.0347
CELLS_M = (0.0189, 0.0268, 0.0347, 0.0426, 0.0506)


def _cell_response(d: float) -> float:
    return math.exp(-d * d / (2.0 * 0.004 ** 2)) + 0.08 * math.exp(-abs(d) / 0.010)


def harness_tactile(p: ControlParams, sc: Scenario) -> ControlParams:
    """``p`` with its tactile calibration matched to the harness's pad (the peak cell reads
    ``pressure_per_nm`` per N m of contact torque)."""
    gain = sc.pressure_per_nm * CONTACT_AT_M / _cell_response(0.0) / sc.sensor_gain_factor
    return replace(p, tactile=replace(p.tactile, pressure_per_n=gain))


def finger_state(x: float, pen: float, sc: Scenario, load: float) -> FingerState:
    torque = sc.contact_stiffness * pen
    p = sc.pressure_per_nm * torque / _cell_response(0.0)
    pressure = tuple(p * _cell_response(c - CONTACT_AT_M) for c in CELLS_M) + (0.0,) * 4
    return FingerState(proximal_rad=x, distal_rad=0.0, motor_angle_rad=x, load_units=load,
                       pressure=pressure, contact=tuple(v > 1.0 for v in pressure))


def run_loop(suite: ControllerSuite, p: ControlParams, sc: Scenario,
             travel_m: float = 0.025) -> Trace:
    """Run the closed loop for ``sc.steps`` 1 ms steps and record everything."""
    p = harness_tactile(p, sc)
    rng = np.random.default_rng(sc.seed)
    links = [Link(np.random.default_rng(sc.seed * 7 + i + 1), sc.delay_steps, sc.jitter_steps,
                  sc.loss, sc.dup) for i in range(4)]
    m2c, c2h, h2c, c2m = links
    rng_ref = list(rng.uniform(0.0, 1.0, 64))
    forcing = rng.uniform(-1.0, 1.0, sc.steps // 20 + 2) * sc.op_force_n
    vmax = 0.95 * p.trigger_max_speed_m_s
    k_s = p.servo_stiffness_nm_per_rad * sc.servo_stiffness_factor
    b_s = p.servo_damping_nm_s_per_rad * sc.servo_damping_factor
    tau_s = p.servo_torque_max_nm * sc.servo_torque_factor
    ms, cs, hs = suite.init_master(p), suite.init_controller(p), suite.init_hand(p)
    x = v = 0.0
    xf = [0.0, 0.0, 0.0]
    y = (0.0, 0.0, 0.0)
    force = 0.0
    op_out = op_in = env_out = env_in = 0.0
    last_fc = last_ms = last_hs = last_hc = None
    fc_rx_t = hc_rx_t = 0.0  # when the latest command arrived (echo hold)
    tr = Trace()
    walls = list(sc.wall_rad)
    hand_out = None
    m_out = None
    for k in range(sc.steps):
        t = k * DT
        # master side samples the trigger and decides the force for the next step
        fc = c2m.deliver(k)
        last_fc = fc if fc is not None else last_fc
        ms, m_out = suite.step_master(ms, p, x, last_fc, DT)
        force = m_out.force_n
        if fc is not None:
            fc_rx_t = t
        m2c.send(k, _master_msg(m_out, k, t, last_fc, t - fc_rx_t))
        # controller
        mm = m2c.deliver(k)
        last_ms = mm if mm is not None else last_ms
        hm = h2c.deliver(k)
        last_hs = hm if hm is not None else last_hs
        cs, c_out = suite.step_controller(cs, p, last_ms, last_hs, t, DT)
        c2m.send(k, c_out.force_command)
        c2h.send(k, c_out.hand_command)
        # hand side at its own rate
        hc = c2h.deliver(k)
        last_hc = hc if hc is not None else last_hc
        if hc is not None:
            hc_rx_t = t
        if k % sc.hand_every == 0:
            fingers = tuple(finger_state(xf[i], max(0.0, xf[i] - walls[i]), sc,
                                         k_s * (y[i] - xf[i])) for i in range(3))
            hs, hand_out = suite.step_hand(hs, p, fingers, last_hc, DT * sc.hand_every, t)
            y = hand_out.setpoint_rad
            h2c.send(k, HandState(header=Header(seq=k, t_s=t,
                                                energy_total_j=hand_out.energy_total_j),
                                  fingers=fingers, preshape_rad=0.0,  # type: ignore[arg-type]
                                  echo_t_s=_echo(last_hc), echo_held_s=t - hc_rx_t,
                                  contact_model=hand_out.contact_model))
        # physics over the next 1 ms with the force and set-points held; a pressed yielding
        # wall first retreats (its spring's energy goes to the table: no work at the port)
        for i in range(3):
            if sc.wall_speed_rad_s > 0.0 and xf[i] > walls[i]:
                walls[i] = min(walls[i] + sc.wall_speed_rad_s * DT, xf[i])
            pen0 = max(0.0, xf[i] - walls[i])
            xf[i] = servo_substep(xf[i], y[i], walls[i], k_s, b_s, sc.contact_stiffness,
                                  DT, tau_s)
            pen1 = max(0.0, xf[i] - walls[i])
            w_env = 0.5 * sc.contact_stiffness * (pen1 * pen1 - pen0 * pen0)
            env_out += max(w_env, 0.0)
            env_in += max(-w_env, 0.0)
        x_ref = reference(sc, t, rng_ref) * travel_m
        f_op = sc.op_stiffness * (x_ref - x) - sc.op_damping * v + forcing[k // 20]
        v += (f_op - force) / sc.op_mass_kg * DT
        v = min(max(v, -vmax), vmax)
        x_new = min(max(x + v * DT, 0.0), travel_m)
        if x_new in (0.0, travel_m):
            v = 0.0
        w_op = -force * (x_new - x)
        op_out += max(w_op, 0.0)
        op_in += max(-w_op, 0.0)
        x = x_new
        tr.t.append(t)
        tr.x_m.append(x)
        tr.force_n.append(force)
        tr.setpoint.append(y)
        tr.finger.append((xf[0], xf[1], xf[2]))
        tr.op_delivered_j.append(op_out)
        tr.op_taken_j.append(op_in)
        tr.env_delivered_j.append(env_out)
        tr.env_taken_j.append(env_in)
        tr.servo_storage_j.append(sum(servo_spring_j(y[i] - xf[i], k_s, tau_s)
                                      for i in range(3)))
        tr.ledgers.append((m_out.ledger, c_out.ledger, hand_out.ledger))  # type: ignore[union-attr]
        tr.limited_master += int(m_out.limited)
        tr.limited_hand += int(hand_out.limited)  # type: ignore[union-attr]
        tr.yielding_hand = max(tr.yielding_hand, getattr(hand_out, "yielding", 0))
    return tr


def _echo(msg: object) -> float:
    """``t_s`` of the latest command received (the echo for round-trip measurement)."""
    return msg.header.t_s if msg is not None else -1.0  # type: ignore[attr-defined]


def _master_msg(out: object, k: int, t: float, last_fc: object, held_s: float) -> object:
    from teleop.control.interface import master_message

    return master_message(out, seq=k, t_s=t, echo_t_s=_echo(last_fc),  # type: ignore[arg-type]
                          echo_held_s=held_s)


@dataclass
class MasterRigTrace:
    """Physical audit of the operator port of a master side driven by a scripted trigger."""

    delivered_j: list[float] = field(default_factory=list)  # cumulative work on the operator
    taken_j: list[float] = field(default_factory=list)  # cumulative work of the operator
    force_n: list[float] = field(default_factory=list)

    def margin_j(self, initial_j: float) -> list[float]:
        """``initial + taken - delivered`` at every sample."""
        return [initial_j + b - a for a, b in zip(self.delivered_j, self.taken_j, strict=True)]


def run_master_rig(suite: ControllerSuite, p: ControlParams, positions_m: list[float],
                   force_n: float, model: tuple[float, ...] | None = None) -> MasterRigTrace:
    """The master side alone, its trigger moved along ``positions_m`` (one per 1 ms sample,
    imposed by a stiff operator) while the controller asks for ``force_n`` in commands that
    carry no energy (running total 0).  The operator-port work is the test's own physics:
    the force the master decided at sample ``k-1`` is held while the trigger moves from
    ``q(k-1)`` to ``q(k)``, so the device does ``-F(k-1) (q(k) - q(k-1))`` on the operator.
    ``model``: a contact model the commands carry for the master to render (none by default)."""
    from teleop.messages import NO_MODEL, ForceCommand

    ms = suite.init_master(p)
    tr = MasterRigTrace()
    out_j = in_j = 0.0
    force = 0.0
    q_prev: float | None = None
    for k, q in enumerate(positions_m):
        if q_prev is not None:
            w = -force * (q - q_prev)
            out_j += max(w, 0.0)
            in_j += max(-w, 0.0)
        cmd = ForceCommand(header=Header(seq=k + 1, t_s=k * DT, energy_total_j=0.0),
                           force_n=force_n, model=model or NO_MODEL)
        ms, mo = suite.step_master(ms, p, q, cmd, DT)
        force = mo.force_n
        q_prev = q
        tr.delivered_j.append(out_j)
        tr.taken_j.append(in_j)
        tr.force_n.append(force)
    return tr
