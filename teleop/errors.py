"""Domain exceptions.

Hierarchy::

    TeleopError(Exception)
    +-- UserInputError            a user mistake: the CLI prints one line and exits with status 2
    |   +-- ConfigError(ValueError)       bad config file, key, type or range
    |   +-- RecordingError(ValueError)    bad recording CSV (missing column, time not increasing...)
    |   +-- ExperimentError(ValueError)   unknown experiment, bad experiment argument
    +-- DeviceError(RuntimeError)         hardware failed (serial port vanished, servo error)
    |   +-- DeviceNotConnected
    +-- DecodeError(ValueError)           a malformed message; never raised into a control loop

Only ``UserInputError`` (and ``DeviceError`` at start-up) are turned into one-line CLI errors;
anything else is a bug and keeps its traceback.
"""

from __future__ import annotations


class TeleopError(Exception):
    """Base of every error raised on purpose by teleop."""


class UserInputError(TeleopError):
    """A mistake in what the user gave us; reported in one line with exit status 2."""


class ConfigError(UserInputError, ValueError):
    """Bad configuration: unknown key, wrong type or value out of range."""


class RecordingError(UserInputError, ValueError):
    """A recording that cannot be read or is not fit for use."""


class ExperimentError(UserInputError, ValueError):
    """An unknown experiment or a bad experiment argument."""


class DeviceError(TeleopError, RuntimeError):
    """A hardware device failed or is unreachable."""


class DeviceNotConnected(DeviceError):
    """The device (serial port, haptic device) is not present."""


class DecodeError(TeleopError, ValueError):
    """A message that failed validation; ``reason`` is a short stable tag used for counting."""

    def __init__(self, reason: str, detail: str = "") -> None:
        super().__init__(f"{reason}: {detail}" if detail else reason)
        self.reason = reason
        self.detail = detail
