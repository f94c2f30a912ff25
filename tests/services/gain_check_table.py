"""The gain cross-check's table in docs/controllers.md: first grasps with the check off and on.

    python -m tests.services.gain_check_table

Lockstep, defaults, seed 1, the first grasp of the default script (5 s), for the stiff
cylinder and the crushable skin perfectly plastic or hardening 2,000 / 5,000 N/m, with the
tactile cells reading their true gain, a third or 3x (``hand.sim.tactile_gain``): the object's
net work from the simulator's physical audit beside the hand tank's net charge, and the most
fingers flagged yielding / unseen / with cells reading low (the check changes nothing until
it fires: where nothing is flagged, off and on agree bit for bit).
"""

from __future__ import annotations

from tests.job_pool import JobPool
from tests.services.yield_grasp import first_grasp

OFF = "controller.tactile.gain_check_window_s=0"
SKINS = {
    "stiff cylinder": (),
    "crushing skin": ("hand.sim.object.yield_force_n=5",),
    "hardening 2,000 N/m": ("hand.sim.object.yield_force_n=5",
                            "hand.sim.object.yield_hardening_n_per_m=2000"),
    "hardening 5,000 N/m": ("hand.sim.object.yield_force_n=5",
                            "hand.sim.object.yield_hardening_n_per_m=5000"),
}
GAINS = (1.0, 0.333, 3.0)


def cases() -> list[tuple[str, float, tuple[str, ...]]]:
    """(object, gain, overrides with the check on) for every row of the table."""
    out = []
    for name, skin in SKINS.items():
        for g in GAINS:
            if name == "crushing skin" and g != 0.333:
                continue  # the yield guard's table has these
            out.append((name, g, (*skin, f"hand.sim.tactile_gain={g}")))
    return out


def main() -> None:
    rows = cases()
    print("| object | cells' gain | object took | tank paid, check off | tank paid, check on "
          "| flagged, check on (yielding / unseen / cells low) |")
    print("|---|---|---|---|---|---|")
    jobs = {o: (first_grasp, o) for *_, on in rows for o in ((*on, OFF), on)}
    with JobPool(jobs) as pool:
        for name, g, on in rows:
            obj, paid_off, *_ = pool.result((*on, OFF))
            obj_on, paid, yielding, unseen, low = pool.result(on)
            took = f"{obj:.4f}" if f"{obj:.4f}" == f"{obj_on:.4f}" else f"{obj:.4f} / {obj_on:.4f}"
            print(f"| {name} | {g:g} | {took} J | {paid_off:.4f} J | {paid:.4f} J "
                  f"| {yielding} / {unseen} / {low} |", flush=True)


if __name__ == "__main__":
    main()
