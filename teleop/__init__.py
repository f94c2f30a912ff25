"""teleop: passive, delay-robust teleoperation of a ReFlex TakkTile hand.

The library (messages, transport, control, analysis, CLI).  Physics lives in ``sim``, the
service wiring in ``services``; this package imports neither (except lazily from the CLI).
"""

from __future__ import annotations

from teleop.errors import (
    ConfigError,
    DecodeError,
    DeviceError,
    DeviceNotConnected,
    ExperimentError,
    RecordingError,
    TeleopError,
    UserInputError,
)

__version__ = "0.1.0"

__all__ = [
    "ConfigError",
    "DecodeError",
    "DeviceError",
    "DeviceNotConnected",
    "ExperimentError",
    "RecordingError",
    "TeleopError",
    "UserInputError",
    "__version__",
]
