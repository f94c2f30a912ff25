"""The servo emulator on a pseudo-terminal: real-time loop, thread or foreground.

:class:`PtyServoEmulator` opens a pty (raw mode; it keeps the slave end open so the port
survives the driver closing and reopening it), reads instruction packets from the master end,
answers them through a :class:`~sim.servo_emulator_bus.ServoBusEmulator` and advances the
physics in real time at ``physics_rate_hz``.  :meth:`vanish` closes both ends, which is what a
driver sees when a USB adapter is unplugged.

Example::

    emu = PtyServoEmulator(make_bus_emulator(protocol=1, ids=(1, 2, 3, 4)))
    path = emu.start()          # background thread
    ...                         # dynamixel_sdk.PortHandler(path) ...
    emu.stop()
"""

from __future__ import annotations

import contextlib
import os
import select
import threading
import time
import tty
from collections.abc import Sequence
from typing import Any

from sim.dynamixel_packets import PacketReader
from sim.servo_emulator_bus import FaultConfig, ServoBusEmulator
from sim.servo_emulator_physics import build_physics
from teleop.devices import dynamixel_tables as T

MAX_CATCH_UP_S = 0.05  # physics time dropped when the loop falls further behind than this
STEPS_PER_WAKE = 5  # physics steps at most between two looks at the port


def make_bus_emulator(protocol: int = 1, ids: Sequence[int] = (1, 2, 3, 4),
                      inversions: Sequence[int] = (1, -1, 1, -1),
                      homes_counts: Sequence[int] | None = None, object_cfg: Any = None,
                      faults: FaultConfig = FaultConfig(), return_delay_us: int = 0,
                      physics: str = "finger", effects: Any = None,
                      engine_name: str = "compiled") -> ServoBusEmulator:
    """A bus of emulated MX-28s with the finger model (or the fallback) as physics."""
    n = len(ids)
    inv = tuple(inversions[:n]) + (1,) * max(0, n - len(inversions))
    homes = tuple(homes_counts) if homes_counts is not None else (0,) * n
    if len(homes) != n:
        raise ValueError(f"need {n} home positions, got {len(homes)}")
    scale = T.P1_RAD_PER_COUNT if protocol == 1 else T.P2_RAD_PER_COUNT
    model = build_physics([h * scale for h in homes], inv, object_cfg,
                          prefer_finger=physics == "finger", effects=effects,
                          engine_name=engine_name)
    return ServoBusEmulator(protocol, ids, model, homes, inv, faults, return_delay_us)


class PtyServoEmulator:
    """Serve a :class:`ServoBusEmulator` on a pty in real time."""

    def __init__(self, bus: ServoBusEmulator, physics_rate_hz: float = 1000.0) -> None:
        self.bus = bus
        self.dt_s = 1.0 / physics_rate_hz
        self.path = ""
        self.lock = threading.Lock()  # held while packets are handled or physics steps
        self.error: BaseException | None = None
        self._master = -1
        self._slave = -1
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._t_phys = 0.0
        self.dropped_time_s = 0.0

    def open(self) -> str:
        """Create the pty; returns the slave path the driver should open."""
        self._master, self._slave = os.openpty()
        tty.setraw(self._slave)
        os.set_blocking(self._master, False)
        self.path = os.ttyname(self._slave)
        return self.path

    def _advance(self, now: float, max_steps: int) -> None:
        """Step the physics towards ``now``, at most ``max_steps`` steps (replies come first).

        When the machine cannot keep up, physics time falls behind; beyond
        ``MAX_CATCH_UP_S`` the lag is dropped (the physics then runs slower than real time;
        ``dropped_time_s`` counts it).
        """
        lag = now - self._t_phys
        if lag > MAX_CATCH_UP_S:
            self.dropped_time_s += lag - MAX_CATCH_UP_S
            self._t_phys = now - MAX_CATCH_UP_S
        n = min(max_steps, int((now - self._t_phys) / self.dt_s + 1e-9))
        if n > 0:  # the control tables only change between batches (packets come first)
            self.bus.step(self.dt_s, n)
            self._t_phys += n * self.dt_s

    def serve(self, duration_s: float | None = None) -> None:
        """Run until :meth:`stop`, :meth:`vanish` or ``duration_s`` has passed."""
        if self._master < 0:
            self.open()
        reader = PacketReader(self.bus.protocol)
        t0 = self._t_phys = time.monotonic()
        while not self._stop.is_set():
            now = time.monotonic()
            if duration_s is not None and now - t0 >= duration_s:
                return
            wait = max(0.0, self._t_phys + self.dt_s - now)
            try:
                ready, _, _ = select.select([self._master], [], [], wait)
            except (OSError, ValueError):  # closed by vanish()
                return
            with self.lock:
                if ready and not self._answer(reader):
                    return
                self._advance(time.monotonic(), 1 if ready else STEPS_PER_WAKE)

    def _answer(self, reader: PacketReader) -> bool:
        """Read what the driver sent and answer it; False when the pty is gone."""
        try:
            data = os.read(self._master, 4096)
        except BlockingIOError:
            return True
        except OSError:
            return False
        for pkt in reader.feed(data):
            for reply in self.bus.handle(pkt):
                if reply.delay_s > 0:
                    time.sleep(reply.delay_s)
                try:
                    os.write(self._master, reply.data)
                except OSError:
                    return False
        return True

    def _run(self, duration_s: float | None) -> None:
        try:
            self.serve(duration_s)
        except BaseException as exc:  # noqa: BLE001 - kept for the test that started us
            self.error = exc

    def start(self, duration_s: float | None = None) -> str:
        """Open the pty and serve it from a daemon thread; returns the path."""
        path = self.open()
        self._thread = threading.Thread(target=self._run, args=(duration_s,),
                                        name="servo-emulator", daemon=True)
        self._thread.start()
        return path

    def stop(self) -> None:
        """Stop serving and close the pty."""
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=2.0)
        self._close()

    def vanish(self) -> None:
        """Close the pty under the driver's feet (an unplugged adapter)."""
        self._stop.set()
        self._close()
        if self._thread is not None:
            self._thread.join(timeout=2.0)

    def _close(self) -> None:
        for fd in (self._master, self._slave):
            if fd >= 0:
                with contextlib.suppress(OSError):
                    os.close(fd)
        self._master = self._slave = -1

    def __enter__(self) -> PtyServoEmulator:
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()
