"""The "hand starved" alarm: a pure per-tick step over the hand layer's ``limited`` flag.

The hand's passivity layer holds a set-point back when its tank cannot cover the energy the
move could put into the object.  A healthy grasp is held back for a moment at most (lockstep:
never, or 0.05 s; live, the first grasp's ~1 s while the energy first arrives); a starved hand,
whose tank no longer refills as fast as the squeezes cost, is held back through every
squeeze (2-3.4 s a grasp: the hard operator on the block, cells reading a third under the hard
operator, the default operator on the dented crushable cylinder after ~5 min).  The master
renders the object's contact model, so the operator may go on feeling a firm grasp the hand
no longer makes; the alarm says so while it happens (``teleop grasps`` names such grasps
after the fact).  Raised once per spell, when a spell has lasted ``alarm_after_s``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass


@dataclass(frozen=True, slots=True)
class StarveAlarm:
    """Where the present spell of held-back set-points began (``nan``: none) and whether it
    has raised its alarm."""

    since_s: float = math.nan
    raised: bool = False
    spells: int = 0  # spells that raised the alarm so far


QUIET = StarveAlarm()


def starve_step(prev: StarveAlarm, limited: bool, t_s: float,
                alarm_after_s: float) -> tuple[StarveAlarm, bool]:
    """One hand tick: ``limited`` whether its layer held the set-point back.  Returns the new
    state and whether to raise the alarm now.  ``alarm_after_s`` 0 turns it off."""
    if not limited or alarm_after_s <= 0.0:
        return (QUIET if prev.spells == 0 else StarveAlarm(spells=prev.spells)), False
    since = t_s if math.isnan(prev.since_s) else prev.since_s
    if prev.raised or t_s - since < alarm_after_s - 1e-9:
        return StarveAlarm(since, prev.raised, prev.spells), False
    return StarveAlarm(since, True, prev.spells + 1), True


def starve_message(held_s: float, model_follows: bool = True) -> str:
    """The alarm's text (an alarm by :data:`services.telemetry.ALARM_WORDS`);
    ``model_follows``: the rendered contact model follows the held-back hand
    (``controller.contact_model.follow_held_back``)."""
    felt = ("the operator feels what they press" if model_follows
            else "the operator may still feel the contact model's full force")
    return (f"hand starved: its tank has held the set-points back for {held_s:.1f} s; the "
            f"fingers squeeze less than commanded ({felt})")


__all__ = ["QUIET", "StarveAlarm", "starve_message", "starve_step"]
