"""Fuzzing the input boundaries: the recording reader and the config loader.

Property: whatever the bytes of a recording file, ``read_recording`` returns a valid
:class:`Recording` or raises :class:`RecordingError` (one line) - never anything else; whatever
the text of a config file or of a ``--set`` override, ``load_config`` returns a config or raises
:class:`ConfigError`.  Example counts are bounded so the module runs in a few seconds.
"""

from __future__ import annotations

import dataclasses
import math
import tempfile
import typing
from pathlib import Path

import numpy as np
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st

from teleop.config import TeleopConfig, load_config
from teleop.errors import ConfigError, RecordingError
from teleop.recording import Recording, read_recording, write_recording

FUZZ = settings(max_examples=150, deadline=None,
                suppress_health_check=[HealthCheck.too_slow])
_DIR = Path(tempfile.mkdtemp(prefix="teleop-fuzz-"))


def _file(data: bytes, name: str) -> Path:
    path = _DIR / name
    path.write_bytes(data)
    return path


# ------------------------------------------------------------------------ recordings

def _check_recording_or_error(path: Path, allow_nan: bool = True) -> Recording | None:
    try:
        rec = read_recording(path, allow_nan=allow_nan)
    except RecordingError as exc:
        assert "\n" not in str(exc)
        return None
    t = rec.t_s
    assert rec.data.shape == (len(rec), len(rec.columns)) and len(rec) >= 1
    assert np.all(np.isfinite(t)) and np.all(np.diff(t) > 0)
    if not allow_nan:
        assert np.all(np.isfinite(rec.data))
    return rec


_CELLS = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True).map(repr),
    st.integers(-10**30, 10**30).map(str),
    st.sampled_from(["", " ", "nan", "-inf", "1e999", "1_0", "0x10", "1,5", "t_s", "#", "\x00",
                     "\ufeff1", "１２", "--1", "1e", ".", "inf\r"]),
    st.text(max_size=6),
)
_NAMES = st.one_of(st.sampled_from(["t_s", "x_m", "tendon_force_n", "", " t_s ", "t_s\ufeff"]),
                   st.text(max_size=5))


@st.composite
def _csv_text(draw: st.DrawFn) -> str:
    """CSV-shaped text: comments, a header, rows of plausible and broken cells."""
    ncol = draw(st.integers(1, 4))
    lines: list[str] = []
    for _ in range(draw(st.integers(0, 2))):
        lines.append("#" + draw(st.text(max_size=12)))
    if draw(st.booleans()):
        lines.append(",".join(draw(st.lists(_NAMES, min_size=ncol, max_size=ncol))))
    else:
        lines.append(",".join(["t_s"] + [f"c{i}" for i in range(ncol - 1)]))
    t = draw(st.floats(-1e3, 1e3))
    for _ in range(draw(st.integers(0, 6))):
        if draw(st.booleans()):
            t += draw(st.floats(0.0, 1.0))
            cells = [repr(t)] + [draw(_CELLS) for _ in range(ncol - 1)]
        else:
            cells = draw(st.lists(_CELLS, min_size=0, max_size=ncol + 1))
        lines.append(",".join(cells))
    sep = draw(st.sampled_from(["\n", "\r\n", "\r", "\x0b", "\u2028"]))
    return sep.join(lines)


@FUZZ
@given(st.binary(max_size=1500))
@example(b"\xff\xfe\x00\x00")
@example(b"\xef\xbb\xbft_s,x\n0,1\n1,2\n")
@example(b"t_s\n" + b"9" * 5000 + b"\n")
def test_recording_arbitrary_bytes(data: bytes) -> None:
    _check_recording_or_error(_file(data, "bytes.csv"))


@FUZZ
@given(_csv_text(), st.booleans())
@example("t_s,x\n0,1\n0,2", True)
@example("t_s,t_s\n0,1", True)
@example("t_s\nnan", True)
@example("x\n1", True)
@example("t_s,x\n0,", False)
def test_recording_csv_like_text(text: str, allow_nan: bool) -> None:
    _check_recording_or_error(_file(text.encode("utf-8", "surrogatepass"), "text.csv"),
                              allow_nan)


@FUZZ
@given(st.text(max_size=400))
def test_recording_arbitrary_text(text: str) -> None:
    _check_recording_or_error(_file(text.encode("utf-8", "surrogatepass"), "any.csv"))


@FUZZ
@given(
    st.floats(0.0, 1e7),
    st.lists(st.floats(1e-4, 10.0), min_size=1, max_size=30),
    st.lists(st.floats(allow_nan=False, allow_infinity=False, width=64), min_size=30,
             max_size=30),
)
@example(1e6, [1e-3, 1e-3], [0.0] * 30)  # 1 kHz on a monotonic clock a long time up
def test_recording_round_trip(t0_s: float, steps_s: list[float], values: list[float]) -> None:
    t = t0_s + np.cumsum(steps_s)
    if not np.all(np.diff(t) > 0):
        return  # float addition collapsed two samples: not a valid recording to start with
    x = np.asarray(values[: len(t)])
    rec = Recording.from_columns({"t_s": t, "x_m": x}, meta=[("source", "fuzz")])
    path = _DIR / "round.csv"
    write_recording(path, rec)
    back = read_recording(path)
    assert back.columns == rec.columns and back.meta == rec.meta
    np.testing.assert_array_equal(back.t_s, t)  # time is written exactly
    np.testing.assert_allclose(back.column("x_m"), x, rtol=1e-8, atol=0.0)


# ------------------------------------------------------------------------ config

def _leaf_keys(cls: type, prefix: str = "") -> list[str]:
    hints = typing.get_type_hints(cls)
    keys: list[str] = []
    for f in dataclasses.fields(cls):
        if f.metadata.get("section"):
            keys += _leaf_keys(hints[f.name], f"{prefix}{f.name}.")
        else:
            keys.append(f"{prefix}{f.name}")
    return keys


KEYS = _leaf_keys(TeleopConfig)

_TOML_VALUES = st.recursive(
    st.one_of(
        st.integers(-2**64, 2**64).map(str),
        st.sampled_from(["9" * 400, "9" * 5000, "-0", "0x7f", "1_000", "nan", "-inf", "inf",
                         "1e400", "true", "false", '""', "''", '"tcp/1.2.3.4:1"',
                         "1979-05-27T07:32:00Z", "07:32:00", "[" * 3000, "{a=" * 2000]),
        st.floats().map(lambda v: repr(v) if math.isfinite(v) else "nan"),
        st.text(max_size=8).map(lambda s: '"' + s.replace("\\", "\\\\").replace('"', '\\"')
                                + '"'),
    ),
    lambda inner: st.one_of(
        st.lists(inner, max_size=4).map(lambda xs: "[" + ", ".join(xs) + "]"),
        st.lists(st.tuples(st.sampled_from(["a", "b", "x_s"]), inner), max_size=3).map(
            lambda kv: "{" + ", ".join(f"{k} = {v}" for k, v in dict(kv).items()) + "}")),
    max_leaves=6,
)


def _check_config_or_error(path: Path | None, overrides: list[str]) -> None:
    try:
        cfg = load_config(path, overrides)
    except ConfigError as exc:
        assert "\n" not in str(exc)  # one line, TOML syntax errors included
        return
    assert isinstance(cfg, TeleopConfig)


@st.composite
def _toml_doc(draw: st.DrawFn) -> str:
    """A TOML-ish document over the real keys, with plausible and hostile values."""
    lines: list[str] = []
    for _ in range(draw(st.integers(0, 5))):
        key = draw(st.one_of(st.sampled_from(KEYS), st.text(max_size=6)))
        section, _, leaf = key.rpartition(".")
        if section and draw(st.booleans()):
            lines.append(f"[{section}]")
            lines.append(f"{leaf or 'x'} = {draw(_TOML_VALUES)}")
        else:
            lines.append(f"{key or 'k'} = {draw(_TOML_VALUES)}")
    return "\n".join(lines)


@FUZZ
@given(st.binary(max_size=600))
@example(b"\xff\xfe\x00")
@example(b"[session]\nseed = 1\n\xc3")
def test_config_arbitrary_bytes(data: bytes) -> None:
    _check_config_or_error(_file(data, "cfg.toml"), [])


@FUZZ
@given(_toml_doc())
@example("[links.master_controller]\ndelay_s = " + "9" * 400)
@example("[session]\nseed = " + "9" * 5000)
@example("v = " + "[" * 3000)
@example("zenoh = 1")
@example("[sweep]\ndelays_s = [[1]]")
@example('"a\\nb" = 1')  # a quoted key with an escaped newline
def test_config_toml_like_documents(text: str) -> None:
    _check_config_or_error(_file(text.encode("utf-8", "surrogatepass"), "doc.toml"), [])


@FUZZ
@given(st.lists(st.text(max_size=30), max_size=3))
@example(["=", "a..b=1", ".=1", "session=1", "session.name.x=1"])
@example(["a\nb=1"])  # a newline in an unknown key must not break the one-line error
def test_config_arbitrary_overrides(overrides: list[str]) -> None:
    _check_config_or_error(None, overrides)


@FUZZ
@given(st.lists(st.tuples(st.sampled_from(KEYS), _TOML_VALUES), max_size=3))
@example([("links.master_controller.delay_s", "9" * 400)])
@example([("session.seed", "9" * 5000)])
@example([("session.seed", "[" * 3000)])
@example([("security.enabled", "{a=" * 2000)])
def test_config_overrides_on_real_keys(pairs: list[tuple[str, str]]) -> None:
    _check_config_or_error(None, [f"{k}={v}" for k, v in pairs])


def test_unwritable_recording_path_is_one_line_error(tmp_path: Path) -> None:
    """Writers name the path in one line (a RecordingError, exit 2), never an OSError."""
    from teleop.recording import RecordingWriter

    blocker = tmp_path / "file.txt"
    blocker.write_text("x")
    rec = Recording.from_columns({"t_s": [0.0, 1.0], "x_m": [0.0, 0.5]})
    for target in (blocker / "sub" / "rec.csv", tmp_path):  # parent is a file; a directory
        try:
            write_recording(target, rec)
        except RecordingError as exc:
            assert str(target) in str(exc) and "\n" not in str(exc)
        else:
            raise AssertionError(f"writing {target} did not fail")
        try:
            RecordingWriter(target, ("t_s", "x_m"))
        except RecordingError as exc:
            assert str(target) in str(exc) and "\n" not in str(exc)
        else:
            raise AssertionError(f"opening {target} did not fail")
