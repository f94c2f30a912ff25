"""A local certificate authority and per-service certificates for zenoh TLS.

``create_certs(DIR)`` writes::

    DIR/ca.pem            CA certificate (every service trusts it)
    DIR/ca.key            CA private key (keep it offline; needed only to issue more certificates)
    DIR/<role>.pem        service certificate, common name = role, SANs localhost/127.0.0.1/::1
                          plus the given hostnames; usable as TLS server and client (mTLS)
    DIR/<role>.key        service private key (PKCS#8 PEM, mode 0600)
    DIR/<role>.credentials  the role's own ``user:password`` line (mode 0600): all a
                          connecting service needs
    DIR/credentials.txt   zenoh user/password dictionary, one ``user:password`` line per role
                          (mode 0600): only the listening service (the controller) needs it

Keys are ECDSA P-256; the zenoh ACL identifies a peer by its certificate common name.
"""

from __future__ import annotations

import datetime as dt
import ipaddress
import os
import re
import secrets
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from teleop.errors import UserInputError

__all__ = ["ROLES", "CertError", "CertBundle", "create_certs", "read_credentials",
           "cert_common_name"]

#: The three services and the observer (a dashboard session that may only subscribe), each
#: with its own certificate, key and zenoh user.
ROLES: tuple[str, ...] = ("master", "controller", "hand", "observer")

_HOST_RE = re.compile(r"^(?=.{1,253}$)(\*\.)?[A-Za-z0-9]([A-Za-z0-9-]{0,61}[A-Za-z0-9])?"
                      r"(\.[A-Za-z0-9]([A-Za-z0-9-]{0,61}[A-Za-z0-9])?)*$")
_USER_RE = re.compile(r"^[A-Za-z0-9_.-]{1,64}$")


class CertError(UserInputError, ValueError):
    """A bad certificate directory, hostname or credentials file."""


@dataclass(frozen=True, slots=True)
class CertBundle:
    """Paths written by :func:`create_certs`."""

    directory: Path
    ca_cert: Path
    ca_key: Path
    certs: tuple[tuple[str, Path, Path], ...]  # (role, certificate, private key)
    credentials: Path
    role_credentials: tuple[tuple[str, Path], ...] = ()  # (role, its own user:password file)


def _check_hostnames(hostnames: Sequence[str]) -> list[str]:
    out: list[str] = []
    for h in hostnames:
        h = h.strip()
        try:
            ipaddress.ip_address(h)
        except ValueError:
            if not _HOST_RE.match(h):
                raise CertError(f"--hostname {h!r}: not a valid DNS name or IP address") from None
        if h not in out:
            out.append(h)
    return out


def _check_dir(directory: Path, names: Sequence[str], force: bool) -> None:
    if directory.exists() and not directory.is_dir():
        raise CertError(f"{directory}: exists and is not a directory")
    try:
        directory.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise CertError(f"{directory}: cannot create directory ({exc.strerror})") from None
    if not os.access(directory, os.W_OK | os.X_OK):
        raise CertError(f"{directory}: directory is not writable")
    if not force:
        taken = [n for n in names if (directory / n).exists()]
        if taken:
            raise CertError(f"{directory}: already holds {', '.join(taken)} "
                            "(use --force to overwrite)")


def _write(path: Path, data: bytes, private: bool) -> None:
    flags = os.O_WRONLY | os.O_CREAT | os.O_TRUNC
    try:
        fd = os.open(path, flags, 0o600 if private else 0o644)
        if private:  # before the key is written: an existing file (--force) keeps its mode
            os.fchmod(fd, 0o600)
        with os.fdopen(fd, "wb") as fh:
            fh.write(data)
    except OSError as exc:
        raise CertError(f"{path}: cannot write ({exc.strerror})") from None


def create_certs(directory: Path | str, *, hostnames: Sequence[str] = (),
                 roles: Sequence[str] = ROLES, days: int = 825, force: bool = False,
                 organisation: str = "teleop") -> CertBundle:
    """Create a CA, a certificate, key and own password file per role, and the credentials
    dictionary in ``directory``."""
    from cryptography import x509
    from cryptography.hazmat.primitives import hashes, serialization
    from cryptography.hazmat.primitives.asymmetric import ec
    from cryptography.x509.oid import ExtendedKeyUsageOID, NameOID

    if days < 1 or days > 36500:
        raise CertError(f"--days {days}: must be between 1 and 36500")
    for role in roles:
        if not _USER_RE.match(role):
            raise CertError(f"role {role!r}: only letters, digits, '_', '.', '-' allowed")
    hosts = _check_hostnames(hostnames)
    directory = Path(directory)
    names = ["ca.pem", "ca.key", "credentials.txt"]
    names += [f"{r}{ext}" for r in roles for ext in (".pem", ".key", ".credentials")]
    _check_dir(directory, names, force)

    now = dt.datetime.now(dt.UTC)
    not_before, not_after = now - dt.timedelta(hours=1), now + dt.timedelta(days=days)
    pem = serialization.Encoding.PEM
    pkcs8 = serialization.PrivateFormat.PKCS8
    nocrypt = serialization.NoEncryption()

    ca_key = ec.generate_private_key(ec.SECP256R1())
    ca_name = x509.Name([x509.NameAttribute(NameOID.ORGANIZATION_NAME, organisation),
                         x509.NameAttribute(NameOID.COMMON_NAME, f"{organisation} local CA")])
    ca_ski = x509.SubjectKeyIdentifier.from_public_key(ca_key.public_key())
    ca_cert = (
        x509.CertificateBuilder().subject_name(ca_name).issuer_name(ca_name)
        .public_key(ca_key.public_key()).serial_number(x509.random_serial_number())
        .not_valid_before(not_before).not_valid_after(not_after)
        .add_extension(x509.BasicConstraints(ca=True, path_length=0), critical=True)
        .add_extension(x509.KeyUsage(digital_signature=True, key_cert_sign=True, crl_sign=True,
                                     content_commitment=False, key_encipherment=False,
                                     data_encipherment=False, key_agreement=False,
                                     encipher_only=False, decipher_only=False), critical=True)
        .add_extension(ca_ski, critical=False)
        .sign(ca_key, hashes.SHA256())
    )
    _write(directory / "ca.key", ca_key.private_bytes(pem, pkcs8, nocrypt), private=True)
    _write(directory / "ca.pem", ca_cert.public_bytes(pem), private=False)

    sans: list[x509.GeneralName] = [x509.DNSName("localhost"),
                                    x509.IPAddress(ipaddress.ip_address("127.0.0.1")),
                                    x509.IPAddress(ipaddress.ip_address("::1"))]
    for h in hosts:
        try:
            name: x509.GeneralName = x509.IPAddress(ipaddress.ip_address(h))
        except ValueError:
            name = x509.DNSName(h)
        if name not in sans:
            sans.append(name)
    written: list[tuple[str, Path, Path]] = []
    for role in roles:
        key = ec.generate_private_key(ec.SECP256R1())
        subject = x509.Name([x509.NameAttribute(NameOID.ORGANIZATION_NAME, organisation),
                             x509.NameAttribute(NameOID.COMMON_NAME, role)])
        cert = (
            x509.CertificateBuilder().subject_name(subject).issuer_name(ca_name)
            .public_key(key.public_key()).serial_number(x509.random_serial_number())
            .not_valid_before(not_before).not_valid_after(not_after)
            .add_extension(x509.BasicConstraints(ca=False, path_length=None), critical=True)
            .add_extension(x509.KeyUsage(digital_signature=True, key_cert_sign=False,
                                         crl_sign=False, content_commitment=False,
                                         key_encipherment=False, data_encipherment=False,
                                         key_agreement=False, encipher_only=False,
                                         decipher_only=False), critical=True)
            .add_extension(x509.ExtendedKeyUsage([ExtendedKeyUsageOID.SERVER_AUTH,
                                                  ExtendedKeyUsageOID.CLIENT_AUTH]),
                           critical=False)
            .add_extension(x509.SubjectAlternativeName(sans), critical=False)
            .add_extension(x509.SubjectKeyIdentifier.from_public_key(key.public_key()),
                           critical=False)
            .add_extension(x509.AuthorityKeyIdentifier.from_issuer_subject_key_identifier(
                ca_ski), critical=False)
            .sign(ca_key, hashes.SHA256())
        )
        key_path, cert_path = directory / f"{role}.key", directory / f"{role}.pem"
        _write(key_path, key.private_bytes(pem, pkcs8, nocrypt), private=True)
        _write(cert_path, cert.public_bytes(pem), private=False)
        written.append((role, cert_path, key_path))

    lines = [f"{role}:{secrets.token_urlsafe(24)}\n" for role in roles]
    own: list[tuple[str, Path]] = []
    for role, line in zip(roles, lines, strict=True):  # each role's own line, alone
        own_path = directory / f"{role}.credentials"
        _write(own_path, line.encode("ascii"), private=True)
        own.append((role, own_path))
    cred_path = directory / "credentials.txt"
    _write(cred_path, "".join(lines).encode("ascii"), private=True)
    return CertBundle(directory, directory / "ca.pem", directory / "ca.key", tuple(written),
                      cred_path, tuple(own))


def read_credentials(path: Path | str) -> dict[str, str]:
    """Read a zenoh ``user:password`` dictionary file into ``{user: password}``."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise CertError(f"{path}: credentials file not found (create it with "
                        "`teleop certs DIR`)") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise CertError(f"{path}: cannot read credentials file ({exc})") from None
    out: dict[str, str] = {}
    for lineno, raw in enumerate(text.splitlines(), start=1):
        line = raw.strip()
        if not line or line.startswith("#"):
            continue
        user, sep, password = line.partition(":")
        if not sep or not _USER_RE.match(user) or not password:
            raise CertError(f"{path}:{lineno}: expected user:password")
        out[user] = password
    return out


def cert_common_name(path: Path | str) -> str:
    """The subject common name of the PEM certificate at ``path``."""
    from cryptography import x509
    from cryptography.x509.oid import NameOID

    path = Path(path)
    try:
        cert = x509.load_pem_x509_certificate(path.read_bytes())
    except FileNotFoundError:
        raise CertError(f"{path}: certificate not found (create it with "
                        "`teleop certs DIR`)") from None
    except (OSError, ValueError) as exc:
        raise CertError(f"{path}: not a PEM certificate ({exc})") from None
    attrs = cert.subject.get_attributes_for_oid(NameOID.COMMON_NAME)
    if not attrs:
        raise CertError(f"{path}: certificate has no common name")
    return str(attrs[0].value)
