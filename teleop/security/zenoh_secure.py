"""The zenoh configuration keys of secure mode (``[security] enabled = true``).

:func:`secure_zenoh_config` is pure: it maps a :class:`~teleop.config.TeleopConfig` and a role
to zenoh 1.x config keys (``"transport/link/tls/enable_mtls"``...) and their JSON5 values, which
the zenoh bus inserts into its ``zenoh.Config`` with ``insert_json5``.  Secure mode means:

- only ``tls/`` endpoints (``transport.link.protocols = ["tls"]``); a plaintext endpoint in the
  config is refused with a one-line :class:`~teleop.errors.ConfigError`;
- mutual TLS: every service presents its certificate (signed by the local CA) both when it
  listens and when it connects, and checks the peer's (``enable_mtls``);
- user/password authentication (``transport.auth.usrpwd``) against the credentials dictionary;
- an access-control list (``access_control``), default deny, evaluated by each service on what
  it receives: a peer may publish (put/delete/liveliness token) only under its own role's keys
  ``teleop/<session>/<role>/**``, identified by its certificate common name; subscribing and
  queries are allowed to every authenticated role within ``teleop/<session>/**``; each
  service sends a signal's samples only to that signal's receiver role (keys.SIGNALS), so the
  master never sees hand commands nor the hand master state;
- the admin space is off (the zenoh config holds the password).
"""

from __future__ import annotations

import json
from pathlib import Path

from teleop.config.schema import TeleopConfig
from teleop.config.security import RoleIdentity, SecurityConfig
from teleop.errors import ConfigError, UserInputError
from teleop.security.certs import read_credentials
from teleop.transport.keys import ROLES, SIGNALS, check_role, check_session, data_key

__all__ = ["SECURE_PROTOCOLS", "check_secure_endpoints", "role_identity", "role_files",
           "role_password", "access_control", "secure_zenoh_config", "apply_secure_config",
           "validate_security"]

#: Link protocols allowed in secure mode.
SECURE_PROTOCOLS: tuple[str, ...] = ("tls",)

#: Every message kind zenoh 1.x access control knows.
ALL_MESSAGES: tuple[str, ...] = (
    "put", "delete", "declare_subscriber", "query", "reply", "declare_queryable",
    "liveliness_token", "declare_liveliness_subscriber", "liveliness_query",
)
#: What a peer may send us about keys it does not own (read side).
_READ_MESSAGES: tuple[str, ...] = (
    "declare_subscriber", "declare_liveliness_subscriber", "liveliness_query", "query",
    "reply", "declare_queryable",
)
#: What only the owner of ``teleop/<session>/<role>/**`` may send us.
_WRITE_MESSAGES: tuple[str, ...] = ("put", "delete", "liveliness_token")


def check_secure_endpoints(cfg: TeleopConfig) -> None:
    """Refuse any plaintext endpoint in ``[zenoh]`` (one-line :class:`ConfigError`)."""
    z = cfg.zenoh
    named = [("zenoh.endpoint", z.endpoint)]
    named += [(f"zenoh.listen[{i}]", e) for i, e in enumerate(z.listen)]
    named += [(f"zenoh.connect[{i}]", e) for i, e in enumerate(z.connect)]
    for key, endpoint in named:
        proto = endpoint.split("/", 1)[0].strip().lower() if "/" in endpoint else ""
        if proto not in SECURE_PROTOCOLS:
            raise ConfigError(f"{key} = {endpoint!r}: plaintext endpoint refused in secure mode "
                              f"(security.enabled = true); use tls/<host>:<port>")


def role_identity(sec: SecurityConfig, role: str) -> RoleIdentity:
    """The identity of ``role`` with empty user / common name defaulted to the role name."""
    ident: RoleIdentity = getattr(sec, check_role(role))
    return RoleIdentity(user=ident.user or role, password=ident.password,
                        common_name=ident.common_name or role)


def _in_dir(sec: SecurityConfig, name: str, role: str) -> Path:
    path = Path(name.replace("{role}", role))
    return path if path.is_absolute() else Path(sec.cert_dir) / path


def role_files(sec: SecurityConfig, role: str) -> dict[str, Path]:
    """``{"ca": ..., "cert": ..., "key": ..., "credentials": ...}`` paths of ``role``."""
    check_role(role)
    return {"ca": _in_dir(sec, sec.ca_file, role), "cert": _in_dir(sec, sec.cert_file, role),
            "key": _in_dir(sec, sec.key_file, role),
            "credentials": _in_dir(sec, sec.credentials_file, role)}


def _check_files(sec: SecurityConfig, role: str) -> dict[str, Path]:
    files = role_files(sec, role)
    for what, path in files.items():
        if not path.is_file():
            raise ConfigError(f"security: {what} file {path} for {role} not found (create the "
                              f"files with `teleop certs {sec.cert_dir}`)")
    return files


def role_password(sec: SecurityConfig, role: str) -> str:
    """The password ``role`` presents: from its section, else from the credentials file."""
    ident = role_identity(sec, role)
    if ident.password:
        return ident.password
    path = role_files(sec, role)["credentials"]
    try:
        creds = read_credentials(path)
    except UserInputError as exc:
        raise ConfigError(f"security.credentials_file: {exc}") from None
    if ident.user not in creds:
        raise ConfigError(f"security.credentials_file: {path} has no line for user "
                          f"{ident.user!r} ({role})")
    return creds[ident.user]


def access_control(cfg: TeleopConfig) -> dict[str, object]:
    """The zenoh ``access_control`` object (same for every role; each enforces it on ingress)."""
    sec = cfg.security
    session = check_session(cfg.session.name)
    subjects = [{"id": role, "cert_common_names": [role_identity(sec, role).common_name]}
                for role in ROLES]
    rules: list[dict[str, object]] = [
        {"id": "send", "permission": "allow", "flows": ["egress"],
         "messages": list(ALL_MESSAGES), "key_exprs": [f"teleop/{session}/**"]},
        {"id": "read", "permission": "allow", "flows": ["ingress"],
         "messages": list(_READ_MESSAGES), "key_exprs": [f"teleop/{session}/**"]},
    ]
    policies: list[dict[str, object]] = [
        {"id": "all-roles", "rules": ["send", "read"], "subjects": list(ROLES)},
    ]
    for spec in SIGNALS.values():  # a signal's data goes to its receiver role only
        others = [role for role in ROLES if role != spec.receiver]
        rules.append({"id": f"confine-{spec.name}", "permission": "deny", "flows": ["egress"],
                      "messages": ["put", "delete"],
                      "key_exprs": [data_key(session, spec.name)]})
        policies.append({"id": f"{spec.name}-only-to-{spec.receiver}",
                         "rules": [f"confine-{spec.name}"], "subjects": others})
    for role in ROLES:
        rules.append({"id": f"publish-{role}", "permission": "allow", "flows": ["ingress"],
                      "messages": list(_WRITE_MESSAGES),
                      "key_exprs": [f"teleop/{session}/{role}/**"]})
        policies.append({"id": f"{role}-publishes", "rules": [f"publish-{role}"],
                         "subjects": [role]})
    return {"enabled": True, "default_permission": "deny", "rules": rules,
            "subjects": subjects, "policies": policies}


def secure_zenoh_config(cfg: TeleopConfig, role: str) -> dict[str, str]:
    """Zenoh config keys -> JSON5 values for ``role`` in secure mode; ``{}`` when disabled.

    Raises :class:`ConfigError` for a plaintext endpoint, a missing certificate, key or
    credentials file, or a user without a password.  Endpoints themselves are not set here.
    """
    sec = cfg.security
    check_role(role)
    if not sec.enabled:
        return {}
    check_secure_endpoints(cfg)
    files = _check_files(sec, role)
    ident = role_identity(sec, role)
    password = role_password(sec, role)
    tls = "transport/link/tls/"
    values: dict[str, object] = {
        "transport/link/protocols": list(SECURE_PROTOCOLS),
        tls + "root_ca_certificate": str(files["ca"]),
        tls + "listen_certificate": str(files["cert"]),
        tls + "listen_private_key": str(files["key"]),
        tls + "connect_certificate": str(files["cert"]),
        tls + "connect_private_key": str(files["key"]),
        tls + "enable_mtls": True,
        tls + "verify_name_on_connect": sec.verify_hostname,
        tls + "close_link_on_expiration": True,
        "transport/auth/usrpwd/user": ident.user,
        "transport/auth/usrpwd/password": password,
        "transport/auth/usrpwd/dictionary_file": str(files["credentials"]),
        "adminspace/enabled": False,
    }
    if sec.access_control:
        values["access_control"] = access_control(cfg)
    return {key: json.dumps(value) for key, value in values.items()}


def apply_secure_config(zconf: object, cfg: TeleopConfig, role: str) -> None:
    """Insert :func:`secure_zenoh_config` into a ``zenoh.Config`` (no-op when disabled)."""
    for key, value in secure_zenoh_config(cfg, role).items():
        zconf.insert_json5(key, value)  # type: ignore[attr-defined]


def validate_security(cfg: TeleopConfig, roles: tuple[str, ...] = ROLES) -> None:
    """Check secure mode up front (endpoints, files, passwords) for the CLI; no-op if off."""
    for role in roles:
        secure_zenoh_config(cfg, role)
