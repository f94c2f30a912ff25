"""The hand's pad-work estimate against the physical audit, phase by phase of one squeeze.

    python tests/teleop/control/pad_work_phases.py [OBJECT] [GOAL_RAD] [--set KEY=VALUE ...]

The simulated hand (``sim.sim_hand.SimHand``, the config's object) is driven straight, without
the control loop: every finger's set-point ramps to ``GOAL_RAD`` (joint, default 2.5: past
any object, the servo at its torque limit) over 1 s, is held for 2 s and drops to 0 at 3 s;
the hand is read at its 40 Hz state rate. Each sample's readings go through
``teleop.control.object_port.track_fingers`` (what the two-layer hand charges, before the
force margin); the physical work on the object over the same sample comes from the
simulator's own audit (``SimHand.port_audit_j``). Prints, per phase (squeeze, hold, release),
the estimate's work into the object and back and the audit's; all three fingers together;
and the servo's worst case over the phase (``controller.ports.servo_torque_max_nm`` times
the motors' inward motion while their cells report contact: the "second bound" of
docs/controllers.md, never the smaller one here).

Used for docs/controllers.md, "Hard squeezes over ten minutes": on the block the estimate
reads 10-15x the work the face exchanges in every phase, both ways, and its safe-side rule
(the larger force and lever in, the smaller out) leaves ~0.6 J per squeeze charged against
~5 mJ of net physical work.
"""

from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[3]))

from sim.sim_hand import SimHand  # noqa: E402
from teleop.config import load_config  # noqa: E402
from teleop.control.object_port import TactileModel, track_fingers  # noqa: E402
from teleop.messages import HandCommand, Header  # noqa: E402

STATE_DT_S = 0.025
PHASES = (("squeeze", 0.0, 1.0), ("hold", 1.0, 3.0), ("release", 3.0, 6.0))


def setpoint_rad(t_s: float, goal_rad: float) -> float:
    """Ramp to ``goal_rad`` over 1 s, hold to 3 s, then open."""
    return goal_rad * min(t_s, 1.0) if t_s < 3.0 else 0.0


def phases(obj: str, goal_rad: float, overrides: list[str]
           ) -> list[tuple[str, float, float, float, float, float]]:
    """(phase, estimated into J, estimated back J, audit into J, audit back J, the servo's
    worst case J)."""
    cfg = load_config(None, [f"hand.sim.object.kind={obj}", *overrides])
    hand = SimHand(cfg.hand, seed=1)
    hand.start()
    model = TactileModel()
    tracks = None
    sums = {name: [0.0, 0.0, 0.0, 0.0, 0.0] for name, _, _ in PHASES}
    d0 = b0 = 0.0
    tau_max = cfg.controller.ports.servo_torque_max_nm
    x_prev: list[float] | None = None
    n = int(round(PHASES[-1][2] / STATE_DT_S))
    for k in range(1, n + 1):
        t = k * STATE_DT_S
        sp = setpoint_rad(t - STATE_DT_S, goal_rad)  # straight to the hand, no loop
        hand.apply(HandCommand(header=Header(seq=k, t_s=t, energy_total_j=0.0),
                               finger_setpoint_rad=(sp, sp, sp), preshape_rad=0.0))
        reading = hand.read(t)
        tracks, works = track_fingers(model, tracks, reading.fingers)
        d1, b1 = hand.port_audit_j()
        name = next(p for p, lo, hi in PHASES if lo < t <= hi + 1e-9)
        s = sums[name]
        x = [f.motor_angle_rad for f in reading.fingers[:3]]
        if x_prev is not None:
            s[4] += tau_max * sum(max(a - b, 0.0) for a, b, f in
                                  zip(x, x_prev, reading.fingers[:3], strict=True)
                                  if any(f.contact))
        x_prev = x
        s[0] += sum(w for w, _ in works)
        s[1] += sum(w for _, w in works)
        s[2] += d1 - d0
        s[3] += b1 - b0
        d0, b0 = d1, b1
    return [(name, *sums[name]) for name, _, _ in PHASES]


def main(argv: list[str]) -> int:
    overrides = [argv[i + 1] for i, a in enumerate(argv) if a == "--set"]
    pos = [a for i, a in enumerate(argv) if a != "--set" and (i == 0 or argv[i - 1] != "--set")]
    obj = pos[0] if pos else "block"
    goal = float(pos[1]) if len(pos) > 1 else 2.5
    print(f"{obj}, set-point {goal} rad; J, all three fingers")
    print("| phase | estimate into | estimate back | estimate net | audit into | audit back "
          "| servo worst case |")
    print("|---|---|---|---|---|---|---|")
    tot = [0.0, 0.0, 0.0, 0.0, 0.0]
    for name, ei, eb, ai, ab, sw in phases(obj, goal, overrides):
        print(f"| {name} | {ei:.3f} | {eb:.3f} | {ei - eb:+.3f} | {ai:.3f} | {ab:.3f} "
              f"| {sw:.3f} |")
        tot = [a + b for a, b in zip(tot, (ei, eb, ai, ab, sw), strict=True)]
    print(f"| all | {tot[0]:.3f} | {tot[1]:.3f} | {tot[0] - tot[1]:+.3f} | {tot[2]:.3f} | "
          f"{tot[3]:.3f} | {tot[4]:.3f} |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
