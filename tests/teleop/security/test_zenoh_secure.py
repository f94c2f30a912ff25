"""``secure_zenoh_config``: the zenoh keys of secure mode, and plaintext refused."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import pytest
import zenoh

from teleop.cli import main
from teleop.config import load_config
from teleop.errors import ConfigError
from teleop.security.certs import create_certs, read_credentials
from teleop.security.zenoh_secure import (
    SECURE_ROLES,
    access_control,
    apply_secure_config,
    is_listener,
    secure_zenoh_config,
    validate_security,
)
from teleop.transport.keys import data_key

REPO = Path(__file__).resolve().parents[3]


@pytest.fixture(scope="module")
def cert_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    d = tmp_path_factory.mktemp("zs")
    create_certs(d)
    return d


def _secure(cert_dir: Path, *more: str):  # noqa: ANN202
    return load_config(REPO / "config" / "secure.toml",
                       [f"security.cert_dir='{cert_dir}'", *more])


def test_disabled_by_default_adds_nothing() -> None:
    assert secure_zenoh_config(load_config(), "hand") == {}


def test_secure_toml_yields_mtls_auth_acl_and_tls_only(cert_dir: Path) -> None:
    cfg = _secure(cert_dir)
    validate_security(cfg)
    keys = {k: json.loads(v) for k, v in secure_zenoh_config(cfg, "hand").items()}
    assert keys["transport/link/protocols"] == ["tls"]
    assert keys["transport/link/tls/enable_mtls"] is True
    assert keys["transport/link/tls/listen_certificate"] == str(cert_dir / "hand.pem")
    assert keys["transport/link/tls/connect_private_key"] == str(cert_dir / "hand.key")
    assert keys["transport/link/tls/root_ca_certificate"] == str(cert_dir / "ca.pem")
    assert keys["transport/auth/usrpwd/user"] == "hand"
    assert keys["transport/auth/usrpwd/password"] == read_credentials(
        cert_dir / "credentials.txt")["hand"]
    assert keys["adminspace/enabled"] is False
    assert keys["access_control"]["default_permission"] == "deny"


def test_values_are_accepted_by_zenoh(cert_dir: Path) -> None:
    cfg = _secure(cert_dir)
    for role in SECURE_ROLES:
        zc = zenoh.Config()
        apply_secure_config(zc, cfg, role)  # insert_json5 raises on an unknown key or bad value
        assert json.loads(zc.get_json("transport/auth/usrpwd/user")) == role
        assert json.loads(zc.get_json("access_control/enabled")) is True


def _write_allowed(acl: dict, key: str) -> set[str]:
    """Subjects whose put on ``key`` is allowed on ingress, by the ACL's policies."""
    rules = {r["id"]: r for r in acl["rules"]}
    who: set[str] = set()
    for pol in acl["policies"]:
        for rid in pol["rules"]:
            r = rules[rid]
            if (r["permission"] == "allow" and "put" in r["messages"]
                    and "ingress" in r["flows"]
                    and any(zenoh.KeyExpr(k).includes(zenoh.KeyExpr(key))
                            for k in r["key_exprs"])):
                who |= set(pol["subjects"])
    return who


def test_acl_only_owner_role_may_publish(cert_dir: Path) -> None:
    cfg = _secure(cert_dir, "session.name=lab")
    acl = access_control(cfg)
    assert _write_allowed(acl, data_key("lab", "master_state")) == {"master"}
    assert _write_allowed(acl, data_key("lab", "hand_command")) == {"controller"}
    assert _write_allowed(acl, data_key("lab", "hand_state")) == {"hand"}
    assert _write_allowed(acl, data_key("other", "hand_command")) == set()
    for signal in ("master_state", "force_command", "hand_command", "hand_state"):
        assert "observer" not in _write_allowed(acl, data_key("lab", signal))
    # the observer may subscribe to the whole session, and is confined by no egress rule
    rules = {r["id"]: r for r in acl["rules"]}
    reads = [p for p in acl["policies"] if "observer" in p["subjects"]]
    assert [p["rules"] for p in reads] == [["send", "read"]]
    assert rules["read"]["key_exprs"] == ["teleop/lab/**"]
    assert "declare_subscriber" in rules["read"]["messages"]
    # the services' lists are the same; the observer's own session also takes what the
    # controller relays to it (its link is then the sender), yet never lets itself publish
    assert access_control(cfg, "hand") == acl
    obs = access_control(cfg, "observer")
    assert _write_allowed(obs, data_key("lab", "master_state")) == {"master", "controller", "hand"}
    assert _write_allowed(obs, data_key("other", "master_state")) == set()
    subjects = {s["id"]: s for s in acl["subjects"]}
    assert subjects["controller"]["cert_common_names"] == ["controller"]


@pytest.mark.parametrize("override", [
    "zenoh.endpoint='tcp/127.0.0.1:7447'",
    "zenoh.listen=['tls/127.0.0.1:7448', 'tcp/0.0.0.0:7449']",
    "zenoh.connect=['udp/10.0.0.2:7447']",
    "zenoh.endpoint='127.0.0.1:7447'",
])
def test_plaintext_endpoints_refused(cert_dir: Path, override: str) -> None:
    with pytest.raises(ConfigError, match="plaintext endpoint refused") as exc:
        _secure(cert_dir, override)  # refused as the config loads, by every command
    assert "\n" not in str(exc.value)
    # and by secure_zenoh_config itself, for a config built some other way
    cfg = dataclasses.replace(_secure(cert_dir), zenoh=load_config(None, [override]).zenoh)
    with pytest.raises(ConfigError, match="plaintext endpoint refused"):
        secure_zenoh_config(cfg, "master")


def test_cli_refuses_plaintext_in_secure_mode(capsys: pytest.CaptureFixture[str]) -> None:
    argv = ["config", "--config", str(REPO / "config" / "secure.toml"),
            "--set", "zenoh.endpoint=tcp/127.0.0.1:7447"]
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert "plaintext endpoint refused" in err and "\n" not in err


def test_missing_files_and_passwords_are_config_errors(cert_dir: Path, tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match="teleop certs"):
        validate_security(_secure(tmp_path / "nowhere"))
    (tmp_path / "c").mkdir()
    for f in cert_dir.iterdir():
        (tmp_path / "c" / f.name).write_bytes(f.read_bytes())
    (tmp_path / "c" / "hand.credentials").write_text("master:x\n")
    with pytest.raises(ConfigError, match="no line for user 'hand'"):
        secure_zenoh_config(_secure(tmp_path / "c"), "hand")
    cfg = _secure(tmp_path / "c", "security.hand.password=given")
    assert json.loads(secure_zenoh_config(cfg, "hand")["transport/auth/usrpwd/password"]) == "given"


def test_role_identity_overrides(cert_dir: Path) -> None:
    cfg = _secure(cert_dir, "security.hand.user=hand", "security.hand.password=pw",
                  "security.controller.common_name=nuc-controller")
    subjects = {s["id"]: s for s in access_control(cfg)["subjects"]}
    assert subjects["controller"]["cert_common_names"] == ["nuc-controller"]


def test_config_command_accepts_secure_toml(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["config", "--config", str(REPO / "config" / "secure.toml")]) == 0


def test_connecting_roles_hold_only_their_own_password(cert_dir: Path) -> None:
    cfg = _secure(cert_dir)
    creds = read_credentials(cert_dir / "credentials.txt")
    assert set(creds) == set(SECURE_ROLES)
    for role in ("master", "hand", "observer"):  # they connect to the controller
        assert not is_listener(cfg, role)
        keys = secure_zenoh_config(cfg, role)
        assert "transport/auth/usrpwd/dictionary_file" not in keys
        assert json.loads(keys["transport/auth/usrpwd/password"]) == creds[role]
        text = json.dumps(keys)
        assert "credentials.txt" not in text
        for other, password in creds.items():
            if other != role:
                assert password not in text, (role, other)
        for other in SECURE_ROLES:  # nor another role's certificate or key
            if other != role:
                assert f"{other}.key" not in text and f"{other}.pem" not in text
    # the listener (the controller, on zenoh.endpoint) gets the dictionary of the users it checks
    assert is_listener(cfg, "controller")
    keys = secure_zenoh_config(cfg, "controller")
    assert json.loads(keys["transport/auth/usrpwd/dictionary_file"]) == str(
        cert_dir / "credentials.txt")
    # a role given zenoh.listen listens too, and so needs the dictionary
    cfg = _secure(cert_dir, "zenoh.listen=['tls/127.0.0.1:7448']")
    assert is_listener(cfg, "hand")
    assert "transport/auth/usrpwd/dictionary_file" in secure_zenoh_config(cfg, "hand")
    assert "transport/auth/usrpwd/dictionary_file" not in secure_zenoh_config(
        cfg, "hand", listening=False)


def test_a_connecting_role_runs_on_its_own_files(cert_dir: Path, tmp_path: Path) -> None:
    # each machine holds the CA and its own certificate, key and password file: nothing else
    for role in ("hand", "controller"):
        for name in ("ca.pem", f"{role}.pem", f"{role}.key", f"{role}.credentials"):
            (tmp_path / name).write_bytes((cert_dir / name).read_bytes())
    cfg = _secure(tmp_path)
    keys = secure_zenoh_config(cfg, "hand")
    assert json.loads(keys["transport/auth/usrpwd/user"]) == "hand"
    # the listener cannot check anybody without the dictionary
    with pytest.raises(ConfigError, match="credentials file .*credentials.txt for controller"):
        secure_zenoh_config(cfg, "controller")
    with pytest.raises(ConfigError, match="credentials file"):  # the hand listening: it checks
        secure_zenoh_config(_secure(tmp_path, "zenoh.listen=['tls/127.0.0.1:7448']"), "hand")
    (tmp_path / "hand.credentials").unlink()
    with pytest.raises(ConfigError, match="password file .*hand.credentials for hand"):
        secure_zenoh_config(cfg, "hand")


def test_unknown_role_refused(cert_dir: Path) -> None:
    with pytest.raises(ConfigError, match="unknown role 'dashboard'"):
        secure_zenoh_config(_secure(cert_dir), "dashboard")
