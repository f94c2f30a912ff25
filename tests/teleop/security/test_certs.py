"""``teleop certs``: a CA and per-service certificates fit for zenoh mutual TLS."""

from __future__ import annotations

import ipaddress
import stat
from pathlib import Path

import pytest
from cryptography import x509
from cryptography.x509.oid import ExtendedKeyUsageOID, NameOID

from teleop.cli import main
from teleop.security.certs import ROLES, CertError, cert_common_name, create_certs, read_credentials


@pytest.fixture(scope="module")
def bundle_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    d = tmp_path_factory.mktemp("c") / "certs"
    create_certs(d, hostnames=["nuc.lab", "10.1.2.3", "nuc.lab"])
    return d


def _cert(path: Path) -> x509.Certificate:
    return x509.load_pem_x509_certificate(path.read_bytes())


def test_every_role_certificate_is_signed_by_the_ca(bundle_dir: Path) -> None:
    ca = _cert(bundle_dir / "ca.pem")
    assert ca.extensions.get_extension_for_class(x509.BasicConstraints).value.ca
    for role in ROLES:
        cert = _cert(bundle_dir / f"{role}.pem")
        cert.verify_directly_issued_by(ca)  # raises if the signature or issuer is wrong
        assert cert.subject.get_attributes_for_oid(NameOID.COMMON_NAME)[0].value == role
        assert cert_common_name(bundle_dir / f"{role}.pem") == role
        assert not cert.extensions.get_extension_for_class(x509.BasicConstraints).value.ca
        eku = cert.extensions.get_extension_for_class(x509.ExtendedKeyUsage).value
        assert {ExtendedKeyUsageOID.SERVER_AUTH, ExtendedKeyUsageOID.CLIENT_AUTH} <= set(eku)


def test_sans_cover_loopback_and_the_extra_hostnames(bundle_dir: Path) -> None:
    san = _cert(bundle_dir / "hand.pem").extensions.get_extension_for_class(
        x509.SubjectAlternativeName).value
    assert san.get_values_for_type(x509.DNSName) == ["localhost", "nuc.lab"]
    ips = set(san.get_values_for_type(x509.IPAddress))
    assert ips == {ipaddress.ip_address(a) for a in ("127.0.0.1", "::1", "10.1.2.3")}


def test_private_files_are_owner_only_and_passwords_distinct(bundle_dir: Path) -> None:
    for name in ["ca.key", "credentials.txt"] + [f"{r}{e}" for r in ROLES
                                                 for e in (".key", ".credentials")]:
        assert stat.S_IMODE((bundle_dir / name).stat().st_mode) == 0o600
    creds = read_credentials(bundle_dir / "credentials.txt")
    assert set(creds) == set(ROLES) and "observer" in creds
    assert len(set(creds.values())) == len(ROLES) and min(len(p) for p in creds.values()) >= 24
    for role in ROLES:  # a role's own file holds its own line only
        assert read_credentials(bundle_dir / f"{role}.credentials") == {role: creds[role]}


def test_existing_files_are_not_overwritten_without_force(bundle_dir: Path) -> None:
    before = (bundle_dir / "ca.pem").read_bytes()
    with pytest.raises(CertError, match="--force"):
        create_certs(bundle_dir)
    assert (bundle_dir / "ca.pem").read_bytes() == before


def test_force_overwrite_leaves_keys_owner_only(tmp_path: Path) -> None:
    create_certs(tmp_path)
    (tmp_path / "hand.key").chmod(0o644)  # an existing key someone made readable
    old = (tmp_path / "hand.key").read_bytes()
    create_certs(tmp_path, force=True)
    assert stat.S_IMODE((tmp_path / "hand.key").stat().st_mode) == 0o600
    assert (tmp_path / "hand.key").read_bytes() != old  # a new key was written


@pytest.mark.parametrize("argv_tail, message", [
    (["{file}"], "not a directory"),
    (["{file}/sub"], "cannot create directory"),
    (["{dir}", "--hostname", "bad host"], "not a valid DNS name"),
    (["{dir}", "--days", "0"], "--days 0"),
])
def test_cli_bad_input_is_one_line_exit_2(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                          argv_tail: list[str], message: str) -> None:
    afile = tmp_path / "file.txt"
    afile.write_text("x")
    argv = ["certs"] + [a.format(file=afile, dir=tmp_path / "new") for a in argv_tail]
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert message in err and "\n" not in err and "Traceback" not in err


def test_cli_writes_the_bundle(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["certs", str(tmp_path / "c"), "--json", "-"]) == 0
    out = capsys.readouterr().out
    assert '"ca_cert"' in out
    assert sorted(p.name for p in (tmp_path / "c").iterdir()) == sorted(
        ["ca.pem", "ca.key", "credentials.txt"]
        + [f"{r}{e}" for r in ROLES for e in (".pem", ".key", ".credentials")])


def test_bad_credentials_file(tmp_path: Path) -> None:
    (tmp_path / "creds.txt").write_text("master:pw\nno-colon-here\n")
    with pytest.raises(CertError, match="creds.txt:2"):
        read_credentials(tmp_path / "creds.txt")
    with pytest.raises(CertError, match="not found"):
        read_credentials(tmp_path / "missing.txt")
