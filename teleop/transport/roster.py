"""Who already runs in a session, asked before a service starts: a second master or hand is
refused at its start instead of joining.

Why: zenoh gives a liveliness subscriber one token per key, not one per session
(docs/faults.md, "Two services of one role"), so a second ``teleop run master`` against a
running session joins silently; its numbering is rejected as stale, its exit does not make
the master look dead, but its 1 kHz loop at real-time priority starves the running services
on a 2-core machine, and while it holds the key a genuine restart of the master starts no
new epoch.  In peer mode a newcomer sees only the peers it connects to (in the ``teleop up``
star, the controller), not the other master, so it cannot see that master's token itself.

So every service answers a query on ``teleop/<session>/<role>/roster`` with its own role and
the roles whose liveliness tokens it sees (:class:`~teleop.transport.zenoh_bus.ZenohBus`
serves it from the moment its session opens).  A starting service asks first
(:func:`check_role_free`: a short session of its own, on its connect endpoints only, while
its backend is built and before its device is started) and refuses to start, one line and
exit status 2, when any answer has its role.

What it cannot see: a session whose listener (the controller, in the star) is down, so there
is nobody to ask; a service of the role that none of the newcomer's peers sees.  A genuine
restart after a crash is not refused (the dead process's token goes as soon as its link
drops); a restart while the old process is cut off but its link not yet timed out (zenoh's
lease, 10 s by default) is refused until then, with the same message.
"""

from __future__ import annotations

import json
import threading
import time
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from typing import Any

from teleop.errors import UserInputError
from teleop.transport.keys import ROLES, check_role, roster_pattern

#: how long a starting service waits to reach a peer to ask (loopback: 3 ms; the default
#: wait of zenoh's own peer sessions before they start is the same 0.5 s)
CONNECT_WINDOW_S = 0.5
#: after the first peer is connected, how long its answer may take to come (3-6 ms here)
ANSWER_GRACE_S = 0.05
#: how often the probe retries a connect that was refused (the listener not up yet)
RETRY_MS = 25
_GET_TIMEOUT_S = 0.2
_POLL_S = 0.002


def _every_answer() -> Any:
    """Keep every reply (zenoh's default consolidation keeps one per key)."""
    import zenoh

    return zenoh.ConsolidationMode.NONE


@dataclass(frozen=True, slots=True)
class RosterReply:
    """One running service's answer: its role and the roles it sees running (its own too)."""

    replier: str
    running: tuple[str, ...]


def encode_reply(role: str, running: Iterable[str]) -> bytes:
    """The answer of the service ``role`` that sees ``running`` (its own role is added)."""
    roles = sorted({role, *running} & set(ROLES))
    return json.dumps({"role": check_role(role), "running": roles}).encode()


def decode_reply(payload: bytes) -> RosterReply | None:
    """An answer, or None for anything that is not one (never raises)."""
    try:
        obj = json.loads(payload)
        role, running = obj["role"], obj["running"]
    except (ValueError, TypeError, KeyError, UnicodeDecodeError):
        return None
    if role not in ROLES or not isinstance(running, list):
        return None
    return RosterReply(role, tuple(r for r in running if r in ROLES))


def refusal(role: str, session: str, replies: Iterable[RosterReply]) -> str | None:
    """Why ``role`` may not start in ``session`` given the answers, or None if it may."""
    seen = sorted({r.replier for r in replies if role in r.running})
    if not seen:
        return None
    others = [s for s in seen if s != role]
    who = ("it answered" if not others else
           f"the {' and the '.join(others)} {'sees' if len(others) == 1 else 'see'} it")
    return (f"a {role} is already running in session {session!r} ({who}): stop it first "
            f"(a crashed one's link times out within zenoh's 10 s lease), or run this one "
            f"with another session.name")


def ask(session: Any, session_name: str, peers: Callable[[], set[str]], expected: int = 1,
        window_s: float = CONNECT_WINDOW_S, grace_s: float = ANSWER_GRACE_S,
        clock: Callable[[], float] = time.monotonic) -> tuple[RosterReply, ...]:
    """Query every roster in ``session_name`` over the open zenoh ``session`` until every
    connected peer (``peers()``: their ids) has answered once ``expected`` of them are
    connected (one per connect endpoint), or ``grace_s`` after that for a peer that does not
    answer, or ``window_s`` in all; the last query's answers.

    Not the first answer alone: with two endpoints the first link up answers before the
    second is connected, and the services only the second reaches went unasked (a CI run
    got the controller's answer without the hand's)."""
    t0 = clock()
    all_connected_s: float | None = None
    pattern = roster_pattern(session_name)
    while True:
        connected = peers()  # before the query: a peer counted here is asked by it
        answers: dict[str, RosterReply] = {}  # one query's: a snapshot, not a collection
        for r in session.get(pattern, timeout=_GET_TIMEOUT_S,
                             consolidation=_every_answer()):
            ok = r.ok
            if ok is not None and (rep := decode_reply(ok.payload.to_bytes())) is not None:
                answers[str(r.replier_id)] = rep
        now = clock()
        if all_connected_s is None and len(connected) >= expected:
            all_connected_s = now
        if all_connected_s is not None and connected <= answers.keys():
            return tuple(answers.values())
        if (all_connected_s is not None and now - all_connected_s >= grace_s) or (
                now - t0 >= window_s):
            return tuple(answers.values())
        time.sleep(_POLL_S)


def probe(cfg: Any, role: str, window_s: float = CONNECT_WINDOW_S) -> tuple[RosterReply, ...]:
    """The answers of the services ``role``'s connect endpoints reach (a short session of
    its own: no listening, no token, closed before returning); ``()`` with no endpoint."""
    import zenoh

    from teleop.security.zenoh_secure import secure_zenoh_config
    from teleop.transport.endpoint_check import role_endpoints
    from teleop.transport.zenoh_bus import zenoh_config

    connect = role_endpoints(role, cfg.zenoh)[1]
    if not connect:
        return ()
    try:
        conf = zenoh_config(cfg.zenoh.mode, [], connect, cfg.zenoh.multicast_scouting)
        conf.insert_json5("scouting/delay", "0")  # ask as soon as connected (ask polls)
        # retry a refused connect within the window (zenoh's first retry is after ~1 s)
        conf.insert_json5("connect/retry", json.dumps({
            "period_init_ms": RETRY_MS, "period_max_ms": RETRY_MS,
            "period_increase_factor": 1.0}))
        for key, value in secure_zenoh_config(cfg, role, listening=False).items():
            conf.insert_json5(key, value)
        session = zenoh.open(conf)
    except zenoh.ZError:
        return ()  # the bus itself reports a session that cannot open, in its own words
    try:
        return ask(session, cfg.session.name,
                   lambda: {str(z) for z in session.info.peers_zid()}, len(set(connect)),
                   window_s)
    finally:
        session.close()


def check_role_free(cfg: Any, role: str) -> None:
    """Raise :class:`UserInputError` (one line) when ``role`` already runs in the session."""
    why = refusal(role, cfg.session.name, probe(cfg, role))
    if why is not None:
        raise UserInputError(why)


def checking_role_free(cfg: Any, role: str) -> Callable[[], None]:
    """:func:`check_role_free` started in a thread, so the service can build its backend
    meanwhile (imports, compiled kernels; nothing that touches a device); the returned
    function waits for it and raises as it would."""
    done: list[BaseException | None] = []

    def run() -> None:
        try:
            check_role_free(cfg, role)
        except BaseException as exc:  # handed to the waiting thread
            done.append(exc)
        else:
            done.append(None)

    thread = threading.Thread(target=run, name="roster-check", daemon=True)
    thread.start()

    def wait() -> None:
        thread.join()
        if done and done[0] is not None:
            raise done[0]

    return wait


__all__ = ["RosterReply", "ask", "check_role_free", "checking_role_free", "decode_reply",
           "encode_reply", "probe", "refusal"]
