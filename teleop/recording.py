"""Recordings: the CSV format shared by `teleop sim`, `teleop up --record` and `teleop diagnose`.

One row per sample; a header row of column names with SI units in the name (``t_s``,
``tendon_force_n``, ...); ``t_s`` is required and strictly increasing; lines starting with ``#``
are comments (``# key: value`` lines are kept as metadata).
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TextIO

import numpy as np
from numpy.typing import NDArray

from teleop.errors import RecordingError

__all__ = ["Recording", "read_recording", "write_recording", "RecordingWriter"]


@dataclass(frozen=True)
class Recording:
    """Named columns sampled at ``t_s``; ``data`` has one column per name."""

    columns: tuple[str, ...]
    data: NDArray[np.float64]
    meta: tuple[tuple[str, str], ...] = ()
    source: str = field(default="<memory>", compare=False)

    def __post_init__(self) -> None:
        if self.data.ndim != 2 or self.data.shape[1] != len(self.columns):
            raise RecordingError(f"{self.source}: data shape {self.data.shape} does not match "
                                 f"{len(self.columns)} columns")

    @property
    def t_s(self) -> NDArray[np.float64]:
        """Sample times."""
        return self.column("t_s")

    def __len__(self) -> int:
        return int(self.data.shape[0])

    def has(self, name: str) -> bool:
        """Whether column ``name`` exists."""
        return name in self.columns

    def column(self, name: str) -> NDArray[np.float64]:
        """The values of column ``name`` (a RecordingError naming it when missing)."""
        try:
            idx = self.columns.index(name)
        except ValueError:
            raise RecordingError(f"{self.source}: no column {name!r} (columns: "
                                 f"{', '.join(self.columns)})") from None
        return self.data[:, idx]

    def held(self, name: str, t_s: NDArray[np.float64]) -> NDArray[np.float64]:
        """Column ``name`` held from each sample to the next, read at the times ``t_s`` (NaN
        before the first sample): another service's recording on this one's clock."""
        idx = np.searchsorted(self.t_s, t_s, side="right") - 1
        out = self.column(name)[np.clip(idx, 0, len(self.t_s) - 1)].astype(float)
        out[idx < 0] = np.nan
        return out

    def meta_value(self, key: str, default: str | None = None) -> str | None:
        """A metadata value from a ``# key: value`` comment."""
        for k, v in self.meta:
            if k == key:
                return v
        return default

    def skip(self, skip_s: float, flag: str = "--skip") -> Recording:
        """This recording without its first ``skip_s`` seconds (e.g. a start-up transient)."""
        if skip_s <= 0:
            return self
        keep = self.t_s >= self.t_s[0] + skip_s
        if not keep.any():
            raise RecordingError(f"{self.source}: {flag} {skip_s:g} s leaves no data")
        return Recording(self.columns, self.data[keep], self.meta, source=self.source)

    @classmethod
    def from_columns(cls, columns: Mapping[str, Sequence[float] | NDArray[np.float64]],
                     meta: Iterable[tuple[str, str]] = ()) -> Recording:
        """Build from a mapping of equal-length columns (``t_s`` first is conventional)."""
        names = tuple(columns)
        data = np.column_stack([np.asarray(columns[n], dtype=float) for n in names])
        return cls(names, data, tuple(meta))


def _check_time(t: NDArray[np.float64], where: str) -> None:
    if not np.all(np.isfinite(t)):
        bad = int(np.argmax(~np.isfinite(t)))
        raise RecordingError(f"{where}: t_s is not finite at row {bad + 1}")
    steps = np.diff(t)
    if np.any(steps <= 0):
        bad = int(np.argmax(steps <= 0))
        raise RecordingError(f"{where}: t_s is not strictly increasing at row {bad + 2} "
                             f"({t[bad]} then {t[bad + 1]})")


def read_recording(path: Path | str, *, allow_nan: bool = True) -> Recording:
    """Read and validate a recording CSV; every problem is a one-line RecordingError."""
    path = Path(path)
    where = str(path)
    try:
        text = path.read_text(encoding="utf-8-sig")  # a leading BOM (spreadsheets) is skipped
    except FileNotFoundError:
        raise RecordingError(f"{where}: file not found") from None
    except IsADirectoryError:
        raise RecordingError(f"{where}: is a directory, expected a CSV file") from None
    except UnicodeDecodeError:
        raise RecordingError(f"{where}: not a text CSV file") from None
    except OSError as exc:
        raise RecordingError(f"{where}: cannot read ({exc.strerror})") from None
    meta: list[tuple[str, str]] = []
    header: list[str] | None = None
    rows: list[list[float]] = []
    for lineno, raw in enumerate(text.splitlines(), start=1):
        line = raw.strip()
        if not line:
            continue
        if line.startswith("#"):
            body = line[1:].strip()
            if ":" in body:
                k, v = body.split(":", 1)
                meta.append((k.strip(), v.strip()))
            continue
        cells = [c.strip() for c in line.split(",")]
        if header is None:
            if any(not c for c in cells):
                raise RecordingError(f"{where}:{lineno}: empty column name in header")
            if len(set(cells)) != len(cells):
                raise RecordingError(f"{where}:{lineno}: duplicate column name in header")
            header = cells
            continue
        if len(cells) != len(header):
            raise RecordingError(f"{where}:{lineno}: {len(cells)} values, header has "
                                 f"{len(header)} columns")
        try:
            row = [float(c) if c else math.nan for c in cells]
        except ValueError:
            raise RecordingError(f"{where}:{lineno}: not a number in {line[:60]!r}") from None
        rows.append(row)
    if header is None:
        raise RecordingError(f"{where}: no header row")
    if "t_s" not in header:
        raise RecordingError(f"{where}: no t_s column (columns: {', '.join(header)})")
    if not rows:
        raise RecordingError(f"{where}: no data rows")
    data = np.asarray(rows, dtype=float)
    rec = Recording(tuple(header), data, tuple(meta), source=where)
    _check_time(rec.t_s, where)
    if not allow_nan and not np.all(np.isfinite(data)):
        r, c = np.argwhere(~np.isfinite(data))[0]
        raise RecordingError(f"{where}: missing or non-finite value in column {header[c]!r} "
                             f"at data row {r + 1}")
    return rec


def _fmt_row(values: Iterable[float], exact: int = -1) -> str:
    """CSV cells with 9 significant digits; column ``exact`` (the time) round-trips exactly,
    so strictly increasing times stay strictly increasing (1 kHz at t = 1e6 s needs 10)."""
    return ",".join(repr(float(v)) if i == exact else f"{v:.9g}" for i, v in enumerate(values))


def write_recording(path: Path | str, rec: Recording) -> None:
    """Write ``rec`` as CSV (metadata first as ``# key: value`` comments)."""
    _check_time(rec.t_s, str(path))
    path = Path(path)
    with _open_for_writing(path) as fh:
        for k, v in rec.meta:
            fh.write(f"# {k}: {v}\n")
        fh.write(",".join(rec.columns) + "\n")
        t_idx = rec.columns.index("t_s")
        for row in rec.data:
            fh.write(_fmt_row(row, t_idx) + "\n")


def _open_for_writing(path: Path) -> TextIO:
    """``path`` opened for writing (parent directories created); a one-line RecordingError
    naming the path when that is impossible."""
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        return path.open("w", encoding="utf-8")
    except OSError as exc:
        raise RecordingError(f"{path}: cannot write recording "
                             f"({exc.strerror or type(exc).__name__})") from None


class RecordingWriter:
    """Streams rows to a recording CSV (used by live services); flushes on close."""

    def __init__(self, path: Path | str, columns: Sequence[str],
                 meta: Iterable[tuple[str, str]] = ()) -> None:
        if "t_s" not in columns:
            raise RecordingError(f"{path}: a recording needs a t_s column")
        self.path = Path(path)
        self.columns = tuple(columns)
        self._fh = _open_for_writing(self.path)
        for k, v in meta:
            self._fh.write(f"# {k}: {v}\n")
        self._fh.write(",".join(self.columns) + "\n")
        self._last_t = -math.inf

    def write(self, values: Sequence[float]) -> None:
        """Append one row; rows whose time does not increase (or is not finite) are skipped."""
        if len(values) != len(self.columns):
            raise ValueError(f"{len(values)} values for {len(self.columns)} columns")
        t_idx = self.columns.index("t_s")
        t = float(values[t_idx])
        if not math.isfinite(t) or t <= self._last_t:
            return
        self._last_t = t
        self._fh.write(_fmt_row(values, t_idx) + "\n")

    def close(self) -> None:
        """Flush and close the file."""
        if not self._fh.closed:
            self._fh.close()

    def __enter__(self) -> RecordingWriter:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
