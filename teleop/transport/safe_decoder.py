"""A decoder for control loops: never raises, counts and logs every rejection."""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass

from teleop.errors import DecodeError
from teleop.messages import Message
from teleop.transport.codec import decode

_log = logging.getLogger("teleop.transport")


@dataclass(frozen=True, slots=True)
class RejectCounts:
    """A frozen snapshot of what a :class:`SafeDecoder` accepted and rejected."""

    accepted: int
    rejected: int
    by_reason: tuple[tuple[str, int], ...]  # sorted by reason

    def count(self, reason: str) -> int:
        """Rejections with tag ``reason`` (0 if none)."""
        return dict(self.by_reason).get(reason, 0)


class SafeDecoder:
    """Wraps :func:`~teleop.transport.codec.decode`: bad input gives ``None``, never raises.

    Each rejection is counted per reason tag and logged at WARNING, at most once per
    ``log_interval_s`` per reason (with the number suppressed since the last line).
    Callers may also count their own reasons (e.g. ``stale_seq``) with :meth:`reject`.
    """

    def __init__(self, name: str = "", log_interval_s: float = 1.0,
                 logger: logging.Logger | None = None) -> None:
        self.name = name
        self._interval_s = log_interval_s
        self._log = logger or _log
        self._accepted = 0
        self._counts: dict[str, int] = {}
        self._last_log_s: dict[str, float] = {}
        self._suppressed: dict[str, int] = {}

    def decode(self, data: bytes, expected: type | None = None) -> Message | None:
        """The message, or None (counted and logged) if ``data`` is bad."""
        try:
            msg = decode(data, expected)
        except DecodeError as exc:
            self.reject(exc.reason, exc.detail)
            return None
        except Exception as exc:  # a codec bug must not stop a control loop
            self.reject("internal", f"{type(exc).__name__}: {exc}")
            return None
        self._accepted += 1
        return msg

    def accept(self) -> None:
        """Count one message accepted without decoding: an in-process message the codec
        round-trips exactly (:mod:`teleop.transport.exact`), so decoding would accept it."""
        self._accepted += 1

    def reject(self, reason: str, detail: str = "") -> None:
        """Count (and rate-limited log) one rejection with tag ``reason``."""
        self._counts[reason] = self._counts.get(reason, 0) + 1
        now = time.monotonic()
        last = self._last_log_s.get(reason)
        if last is not None and now - last < self._interval_s:
            self._suppressed[reason] = self._suppressed.get(reason, 0) + 1
            return
        self._last_log_s[reason] = now
        n = self._suppressed.pop(reason, 0)
        more = f" (+{n} more since last report)" if n else ""
        where = f"{self.name}: " if self.name else ""
        self._log.warning("%sdropped message: %s %s%s", where, reason, detail, more)

    def counts(self) -> RejectCounts:
        """A frozen snapshot of the counters."""
        return RejectCounts(self._accepted, sum(self._counts.values()),
                            tuple(sorted(self._counts.items())))
