"""The ``omega7`` master backend: the Force Dimension Omega 7's grasp trigger (7th DoF).

Uses the Force Dimension haptic SDK through the ``forcedimension-core`` Python package
(``pip install 'teleop[omega7]'``), imported only when this backend is chosen
(``master.backend = "omega7"``).  The trigger's opening is read with the DHD gripper-gap call
and converted to the closing used everywhere else (0 = open, ``travel_m`` = closed); the
displayed force goes out with the combined force-and-gripper-force call, with zero force on the
translation axes, so the arm floats under the SDK's gravity compensation.

Not tested in CI: it needs the device and its USB driver (``@pytest.mark.hardware``).
"""

from __future__ import annotations

import math

from teleop.config import TeleopConfig
from teleop.devices.base import MasterReading
from teleop.errors import DeviceError, DeviceNotConnected, UserInputError


def _import_dhd():  # noqa: ANN202 - the SDK module has no stubs
    try:
        from forcedimension_core import dhd
    except ImportError:
        raise UserInputError("master.backend = 'omega7' needs the Force Dimension SDK: "
                             "pip install 'teleop[omega7]' (package forcedimension-core)") from None
    return dhd


class Omega7Master:
    """A :class:`teleop.devices.base.MasterBackend` for the Omega 7 grasp trigger."""

    def __init__(self, cfg: TeleopConfig) -> None:
        self.travel_m = cfg.master.travel_m
        self.force_max_n = cfg.master.force_max_n
        self._dhd = None
        self._open_gap_m: float | None = None
        self._last: tuple[float, float] | None = None

    def start(self) -> None:
        """Open the first device found, enable forces and calibrate the open position."""
        dhd = _import_dhd()
        if dhd.open() < 0:
            raise DeviceNotConnected(f"Omega 7: no device found ({dhd.errorGetLastStr()})")
        self._dhd = dhd
        dhd.enableForce(True)
        self._open_gap_m = self._gap_m()

    def _gap_m(self) -> float:
        assert self._dhd is not None
        out = [0.0]
        if self._dhd.getGripperGap(out) < 0:
            raise DeviceError(f"Omega 7: gripper read failed ({self._dhd.errorGetLastStr()})")
        return float(out[0])

    def read(self, t_s: float) -> MasterReading:
        """The trigger's closing (m from the open position) and its rate."""
        if self._dhd is None or self._open_gap_m is None:
            raise DeviceNotConnected("Omega 7: read before start()")
        x = min(max(self._open_gap_m - self._gap_m(), 0.0), self.travel_m)
        v = 0.0
        if self._last is not None and t_s > self._last[0]:
            v = (x - self._last[1]) / (t_s - self._last[0])
        self._last = (t_s, x)
        return MasterReading(t_s=t_s, grip_position_m=x, grip_velocity_m_s=v)

    def apply_force(self, force_n: float) -> None:
        """Display ``force_n`` (positive resists closing: it pushes the trigger open)."""
        if self._dhd is None:
            return
        f = force_n if math.isfinite(force_n) else 0.0
        f = min(max(f, -self.force_max_n), self.force_max_n)
        if self._dhd.setForceAndGripperForce(0.0, 0.0, 0.0, f) < 0:
            raise DeviceError(f"Omega 7: force write failed ({self._dhd.errorGetLastStr()})")

    def close(self) -> None:
        """Force off and release the device."""
        if self._dhd is not None:
            try:
                self._dhd.setForceAndGripperForce(0.0, 0.0, 0.0, 0.0)
                self._dhd.enableForce(False)
            finally:
                self._dhd.close()
                self._dhd = None
