"""Where the pad-work estimate's over-reading comes from: force, motion, and sampling rule.

    python tests/teleop/control/pad_work_decompose.py [OBJECT]

The squeeze of ``pad_work_phases.py`` (set-point ramped to 2.5 rad over 1 s, held to 3 s,
released; noise off), stepped at 1 ms.  Prints, for the three fingers over the whole squeeze:

* the work into the object and back, as the contact force times the velocity of the pad's
  material point at the force's resultant along the object's normal (the face's for a block,
  the centre's direction for a cylinder), trapezoidal per 1 ms step;
* the same by the simulator's audit (``SimHand.port_audit_j``);
* the hand's estimate (``teleop.control.object_port.track_fingers`` at 40 Hz, before the
  margin) with its safe-side force (larger in, smaller out), and with the sample pair's mean
  force instead (not sound: for the decomposition only);
* the first finger's distal force as the cells read it against the simulator's, at the hold.

Used for docs/controllers.md, "Hard squeezes over ten minutes" (2026-11-28).
"""

from __future__ import annotations

import math
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[3]))

from sim.params import FingerParams  # noqa: E402
from sim.readout import distal_origin  # noqa: E402
from sim.sim_hand import SimHand  # noqa: E402
from sim.state import FingerState  # noqa: E402
from teleop.config import load_config  # noqa: E402
from teleop.control import object_port  # noqa: E402
from teleop.messages import HandCommand, Header  # noqa: E402

STEP_S = 0.001
STATE_EVERY = 25  # 40 Hz

Pose = tuple[float, float, float, float, float, float]


def _pose(fs: FingerState, p: FingerParams) -> Pose:
    """(cos, sin) of the proximal angle, then the distal link's origin and direction."""
    phi = fs.prox_rad
    return (math.cos(phi), math.sin(phi), *distal_origin(fs, p))


def _point(pose: Pose, p: FingerParams, which: int, x_m: float) -> tuple[float, float]:
    """World position of the material point ``x_m`` along the proximal (0) or distal (1)
    pad at ``pose``."""
    c, s, x, y, ca, sa = pose
    po = p.pad_offset_m
    if which == 0:
        u, v = x_m, po
    else:
        u, v = x + ca * x_m - sa * po, y + sa * x_m + ca * po
    return c * u - s * v, s * u + c * v


def _mean_rule(f0: float, f1: float, ds: float) -> tuple[float, float]:
    w = 0.5 * (f0 + f1) * ds
    return (w, 0.0) if ds > 0.0 else (0.0, -w)


def _tracked(rule: object, model: object, tracks: object, fingers: object) -> tuple:
    """``track_fingers`` with its force rule swapped for ``rule`` (None: as charged)."""
    saved = object_port._safe_work
    if rule is not None:
        object_port._safe_work = rule  # type: ignore[assignment]
    try:
        return object_port.track_fingers(model, tracks, fingers)  # type: ignore[arg-type]
    finally:
        object_port._safe_work = saved


def decompose(obj: str) -> dict[str, tuple[float, float]]:
    """(into, back) J per way of counting; plus the first finger's (read, true) distal
    force at the end of the hold.  One drive: both estimates read the same samples."""
    cfg = load_config(None, [f"hand.sim.object.kind={obj}", "hand.sim.noise=false"])
    hand = SimHand(cfg.hand, seed=1)
    hand.start()
    p = hand.params.finger
    o = hand.obj
    model = object_port.TactileModel()
    tracks: dict[str, object] = {"safe": None, "mean": None}
    est = {"safe": [0.0, 0.0], "mean": [0.0, 0.0]}
    mat = [0.0, 0.0]
    out: dict[str, tuple[float, float]] = {}
    prev = None
    for k in range(1, 6001):
        t = k * STEP_S
        sp = 2.5 * min(t, 1.0) if t < 3.0 else 0.0
        hand.apply(HandCommand(header=Header(seq=k, t_s=t, energy_total_j=0.0),
                               finger_setpoint_rad=(sp, sp, sp), preshape_rad=0.0))
        reading = hand.read(t)
        cur = [(fs.pads, _pose(fs, p)) for fs in hand.state.fingers]
        if prev is not None:
            for (pads0, g0), (pads1, g1) in zip(prev, cur, strict=True):
                for which in (0, 1):
                    f0, f1 = pads0[2 * which], pads1[2 * which]
                    if f0 <= 0.0 and f1 <= 0.0:
                        continue
                    xm = pads1[2 * which + 1] if f1 > 0.0 else pads0[2 * which + 1]
                    a = _point(g0, p, which, xm)
                    b = _point(g1, p, which, xm)
                    if o.kind == "block":
                        n = (0.0, 1.0)
                    else:
                        mx, my = 0.5 * (a[0] + b[0]), 0.5 * (a[1] + b[1])
                        d = math.hypot(o.x_m - mx, o.y_m - my)
                        n = ((o.x_m - mx) / d, (o.y_m - my) / d)
                    w = 0.5 * (f0 + f1) * ((b[0] - a[0]) * n[0] + (b[1] - a[1]) * n[1])
                    mat[0 if w > 0.0 else 1] += abs(w)
        prev = cur
        if k % STATE_EVERY == 0:
            for name, rule in (("safe", None), ("mean", _mean_rule)):
                tracks[name], works = _tracked(rule, model, tracks[name], reading.fingers)
                est[name][0] += sum(w for w, _ in works)
                est[name][1] += sum(w for _, w in works)
            if k == 2975:
                out["first finger distal force at the hold (read, true) N"] = (
                    tracks["safe"][0].dist_force_n, hand.state.fingers[0].pads[2])  # type: ignore[index]
    out["estimate, safe force"] = (est["safe"][0], est["safe"][1])
    out["material point"] = (mat[0], mat[1])
    out["audit"] = hand.port_audit_j()
    out["estimate, mean force"] = (est["mean"][0], est["mean"][1])
    return out


def main(argv: list[str]) -> int:
    obj = argv[0] if argv else "block"
    print(f"{obj}: one squeeze, three fingers")
    for name, (a, b) in decompose(obj).items():
        if name.startswith("first finger"):
            print(f"{name}: {a:.2f}, {b:.2f}")
        else:
            print(f"{name:22s} into {a:.3f} J, back {b:.3f} J, net {a - b:+.3f} J")
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
