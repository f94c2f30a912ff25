"""Shared fixtures."""

from __future__ import annotations

from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
SHARED = REPO.parent / "shared"


@pytest.fixture
def repo_root() -> Path:
    """The repository root."""
    return REPO


@pytest.fixture
def shared_dir() -> Path:
    """``../shared`` beside the repository (seed report, reference data)."""
    if not SHARED.is_dir():
        pytest.skip("../shared is not beside this checkout")
    return SHARED


# Tests that run in real time (live services, emulators on ptys and sockets, timing
# benchmarks) are marked ``realtime``: CI runs the CPU-bound rest on two xdist workers first,
# then these alone, one after another, on an otherwise idle machine (README, "Tests").
_REALTIME_DIRS = ("tests/teleop/devices/",)
_REALTIME_FILES = {
    "tests/sim/test_servo_emulator.py", "tests/sim/test_servo_emulator_bench.py",
    "tests/sim/test_hand_emulator.py", "tests/teleop/transport/test_bench_transport.py",
    "tests/services/test_soak.py",
}


def is_realtime(item: pytest.Item) -> bool:
    """Does ``item`` run in real time: marked ``network``, or in a real-time module."""
    rel = Path(str(item.fspath)).resolve().relative_to(REPO).as_posix()
    return (item.get_closest_marker("network") is not None
            or rel.startswith(_REALTIME_DIRS) or rel in _REALTIME_FILES)


@pytest.hookimpl(tryfirst=True)  # before ``-m`` deselects by mark
def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """Mark the real-time tests ``realtime``."""
    for item in items:
        if is_realtime(item):
            item.add_marker(pytest.mark.realtime)
