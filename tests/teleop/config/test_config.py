"""Config loading: defaults, overrides, and one-line errors for every bad input."""

from __future__ import annotations

from pathlib import Path

import pytest

from teleop.cli import main
from teleop.config import TeleopConfig, default_toml, load_config
from teleop.errors import ConfigError


def test_default_toml_in_repo_matches_code(repo_root: Path) -> None:
    assert (repo_root / "config" / "default.toml").read_text() == default_toml()


def test_default_toml_round_trips_to_defaults(repo_root: Path) -> None:
    assert load_config(repo_root / "config" / "default.toml") == TeleopConfig()


def test_every_config_file_in_repo_loads(repo_root: Path) -> None:
    for path in (repo_root / "config").glob("*.toml"):
        load_config(path)


def test_override_sets_nested_value() -> None:
    cfg = load_config(None, ["links.master_controller.delay_s=0.25", "controller.kind=direct"])
    assert cfg.links.master_controller.delay_s == 0.25
    assert cfg.controller.kind == "direct"
    assert cfg.links.controller_hand.delay_s == 0.0


def test_int_accepted_for_float_but_not_bool() -> None:
    assert load_config(None, ["links.master_controller.delay_s=1"]).links.master_controller.delay_s == 1.0
    with pytest.raises(ConfigError, match="must be a number"):
        load_config(None, ["links.master_controller.delay_s=true"])


@pytest.mark.parametrize(
    ("text", "match"),
    [
        ("[links.master_controller]\ndelay_z = 1\n", "links.master_controller.delay_z is not a known key"),
        ("[links.master_controller]\ndelay_s = 'x'\n", "links.master_controller.delay_s must be a number"),
        ("[links.master_controller]\ndelay_s = -1\n", "out of range"),
        ("[controller]\nkind = 'magic'\n", "controller.kind = 'magic' is not one of"),
        ("[bogus]\nx = 1\n", "bogus is not a known key"),
        ("links = 3\n", "links must be a table"),
        ("this is not toml", "not valid TOML"),
        ("[controller.transparency]\nfinger_enable = [true]\n",
         "controller.transparency.finger_enable must have 3 items, got 1"),
        ("[hand.dynamixel]\nids = [1, 2, 3]\n", "hand.dynamixel.ids must have 4 items, got 3"),
        ("[hand.dynamixel]\nzeros_rad = [0.0, 0.0, 0.0, 0.0, 0.0]\n",
         "hand.dynamixel.zeros_rad must have 4 items, got 5"),
    ],
)
def test_bad_file_names_key_and_file(tmp_path: Path, text: str, match: str) -> None:
    path = tmp_path / "bad.toml"
    path.write_text(text)
    with pytest.raises(ConfigError, match=match) as info:
        load_config(path)
    assert str(path) in str(info.value)
    assert "\n" not in str(info.value)


def test_cli_bad_config_exits_2_with_one_line(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / "bad.toml"
    path.write_text("[hand]\nstate_rate_hz = 0\n")
    assert main(["config", "--config", str(path)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "hand.state_rate_hz" in err[0] and str(path) in err[0]


def test_cli_missing_config_file(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["config", "--config", str(tmp_path / "nope.toml")]) == 2
    assert "config file not found" in capsys.readouterr().err


def test_cli_bad_set_names_set(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["config", "--set", "hand.nope=1"]) == 2
    assert "--set: hand.nope is not a known key" in capsys.readouterr().err


def test_cli_wrong_list_length_is_one_line(capsys: pytest.CaptureFixture[str]) -> None:
    # one flag per finger: a short list must not be padded silently
    assert main(["config", "--set", "controller.transparency.finger_enable=[true]"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "finger_enable must have 3 items, got 1" in err[0]
