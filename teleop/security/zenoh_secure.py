"""The zenoh configuration keys of secure mode (``[security] enabled = true``).

:func:`secure_zenoh_config` is pure: it maps a :class:`~teleop.config.TeleopConfig` and a role
to zenoh 1.x config keys (``"transport/link/tls/enable_mtls"``...) and their JSON5 values, which
the zenoh bus inserts into its ``zenoh.Config`` with ``insert_json5``.  Secure mode means:

- only ``tls/`` endpoints (``transport.link.protocols = ["tls"]``); a plaintext endpoint in the
  config is refused with a one-line :class:`~teleop.errors.ConfigError`;
- mutual TLS: every service presents its certificate (signed by the local CA) both when it
  listens and when it connects, and checks the peer's (``enable_mtls``);
- user/password authentication (``transport.auth.usrpwd``), least privilege: every role holds
  only its own user/password (``password_file``); only a role that listens
  (:func:`is_listener`: the controller on ``zenoh.endpoint``, or any role given
  ``zenoh.listen``) also gets the dictionary of the users it accepts (``credentials_file``);
- an access-control list (``access_control``), default deny, evaluated by each service on what
  it receives: a peer may publish (put/delete/liveliness token) only under its own role's keys
  ``teleop/<session>/<role>/**``, identified by its certificate common name; subscribing and
  queries are allowed to every authenticated role within ``teleop/<session>/**``; each
  service sends a signal's samples only to that signal's receiver role (keys.SIGNALS), so the
  master never sees hand commands nor the hand master state; the ``observer`` role (a dashboard
  session) may subscribe to everything under ``teleop/<session>/**`` and publish nothing;
- the admin space is off (the zenoh config holds the password).
"""

from __future__ import annotations

import json
from pathlib import Path

from teleop.config.schema import TeleopConfig
from teleop.config.security import RoleIdentity, SecurityConfig
from teleop.errors import ConfigError, UserInputError
from teleop.security.certs import read_credentials
from teleop.transport.keys import ROLES, SIGNALS, check_session, data_key

__all__ = ["SECURE_PROTOCOLS", "OBSERVER", "SECURE_ROLES", "check_secure_endpoints",
           "check_secure_role", "role_identity", "role_files", "role_password", "is_listener",
           "access_control", "secure_zenoh_config", "apply_secure_config", "validate_security"]

#: Link protocols allowed in secure mode.
SECURE_PROTOCOLS: tuple[str, ...] = ("tls",)
#: A read-only role for a separate session (a dashboard): subscribes, never publishes.
OBSERVER = "observer"
#: Every role secure mode knows: the three services and the observer.
SECURE_ROLES: tuple[str, ...] = (*ROLES, OBSERVER)

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


def check_secure_role(role: str) -> str:
    """``role`` if it is one of :data:`SECURE_ROLES`, else a one-line :class:`ConfigError`."""
    if role not in SECURE_ROLES:
        raise ConfigError(f"unknown role {role!r}: expected one of {', '.join(SECURE_ROLES)}")
    return role


def role_identity(sec: SecurityConfig, role: str) -> RoleIdentity:
    """The identity of ``role`` with empty user / common name defaulted to the role name."""
    ident: RoleIdentity = getattr(sec, check_secure_role(role))
    return RoleIdentity(user=ident.user or role, password=ident.password,
                        common_name=ident.common_name or role)


def _in_dir(sec: SecurityConfig, name: str, role: str) -> Path:
    path = Path(name.replace("{role}", role))
    return path if path.is_absolute() else Path(sec.cert_dir) / path


def role_files(sec: SecurityConfig, role: str) -> dict[str, Path]:
    """``{"ca", "cert", "key", "password", "credentials"}`` paths of ``role``.

    ``password`` is the role's own ``user:password`` file; ``credentials`` the dictionary only
    a listening role reads.
    """
    check_secure_role(role)
    return {"ca": _in_dir(sec, sec.ca_file, role), "cert": _in_dir(sec, sec.cert_file, role),
            "key": _in_dir(sec, sec.key_file, role),
            "password": _in_dir(sec, sec.password_file, role),
            "credentials": _in_dir(sec, sec.credentials_file, role)}


def _check_files(sec: SecurityConfig, role: str, listening: bool) -> dict[str, Path]:
    files = role_files(sec, role)
    needed = ["ca", "cert", "key"]
    if not role_identity(sec, role).password:
        needed.append("password")
    if listening:
        needed.append("credentials")
    for what in needed:
        path = files[what]
        if not path.is_file():
            raise ConfigError(f"security: {what} file {path} for {role} not found (create the "
                              f"files with `teleop certs {sec.cert_dir}`)")
    return files


def role_password(sec: SecurityConfig, role: str) -> str:
    """The password ``role`` presents: from its section, else from its own password file."""
    ident = role_identity(sec, role)
    if ident.password:
        return ident.password
    path = role_files(sec, role)["password"]
    try:
        creds = read_credentials(path)
    except UserInputError as exc:
        raise ConfigError(f"security.password_file: {exc}") from None
    if ident.user not in creds:
        raise ConfigError(f"security.password_file: {path} has no line for user "
                          f"{ident.user!r} ({role})")
    return creds[ident.user]


def is_listener(cfg: TeleopConfig, role: str) -> bool:
    """Whether ``role`` listens (so must check the users connecting to it).

    As :func:`teleop.transport.endpoint_check.role_endpoints` decides: the controller listens on
    ``zenoh.endpoint``; any role listens on ``zenoh.listen``.  The observer only connects.
    """
    check_secure_role(role)
    from teleop.transport.endpoint_check import role_endpoints

    return bool(role_endpoints(role, cfg.zenoh)[0])


def access_control(cfg: TeleopConfig, role: str | None = None) -> dict[str, object]:
    """The zenoh ``access_control`` object of ``role`` (each enforces it on ingress).

    The same for the three services.  The observer's own session also accepts data and
    liveliness tokens from any service on the whole key space: as a client of the controller it
    receives the others' samples relayed by the controller (whose link is then the sender).
    """
    sec = cfg.security
    session = check_session(cfg.session.name)
    subjects = [{"id": role, "cert_common_names": [role_identity(sec, role).common_name]}
                for role in SECURE_ROLES]
    rules: list[dict[str, object]] = [
        {"id": "send", "permission": "allow", "flows": ["egress"],
         "messages": list(ALL_MESSAGES), "key_exprs": [f"teleop/{session}/**"]},
        {"id": "read", "permission": "allow", "flows": ["ingress"],
         "messages": list(_READ_MESSAGES), "key_exprs": [f"teleop/{session}/**"]},
    ]
    policies: list[dict[str, object]] = [
        {"id": "all-roles", "rules": ["send", "read"], "subjects": list(SECURE_ROLES)},
    ]
    # a signal's data goes to its receiver role only (and to the observer, which reads all)
    for spec in SIGNALS.values():
        others = [r for r in ROLES if r != spec.receiver]
        rules.append({"id": f"confine-{spec.name}", "permission": "deny", "flows": ["egress"],
                      "messages": ["put", "delete"],
                      "key_exprs": [data_key(session, spec.name)]})
        policies.append({"id": f"{spec.name}-only-to-{spec.receiver}",
                         "rules": [f"confine-{spec.name}"], "subjects": others})
    for owner in ROLES:  # the observer publishes nothing: no rule lets its puts in
        rules.append({"id": f"publish-{owner}", "permission": "allow", "flows": ["ingress"],
                      "messages": list(_WRITE_MESSAGES),
                      "key_exprs": [f"teleop/{session}/{owner}/**"]})
        policies.append({"id": f"{owner}-publishes", "rules": [f"publish-{owner}"],
                         "subjects": [owner]})
    if role == OBSERVER:
        rules.append({"id": "relayed", "permission": "allow", "flows": ["ingress"],
                      "messages": list(_WRITE_MESSAGES), "key_exprs": [f"teleop/{session}/**"]})
        policies.append({"id": "observer-reads-relayed", "rules": ["relayed"],
                         "subjects": list(ROLES)})
    return {"enabled": True, "default_permission": "deny", "rules": rules,
            "subjects": subjects, "policies": policies}


def secure_zenoh_config(cfg: TeleopConfig, role: str, *,
                        listening: bool | None = None) -> dict[str, str]:
    """Zenoh config keys -> JSON5 values for ``role`` in secure mode; ``{}`` when disabled.

    ``role`` gets its own certificate, key, user and password only; the dictionary of every
    user (``dictionary_file``) only if it listens (``listening``, default
    :func:`is_listener`).  Raises :class:`ConfigError` for a plaintext endpoint, a missing
    certificate, key, password or (listening) credentials file, or a user without a password.
    Endpoints themselves are not set here.
    """
    sec = cfg.security
    check_secure_role(role)
    if not sec.enabled:
        return {}
    check_secure_endpoints(cfg)
    if listening is None:
        listening = is_listener(cfg, role)
    files = _check_files(sec, role, listening)
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
        "adminspace/enabled": False,
    }
    if listening:  # only a listener checks others: only it holds their passwords
        values["transport/auth/usrpwd/dictionary_file"] = str(files["credentials"])
    if sec.access_control:
        values["access_control"] = access_control(cfg, role)
    return {key: json.dumps(value) for key, value in values.items()}


def apply_secure_config(zconf: object, cfg: TeleopConfig, role: str) -> None:
    """Insert :func:`secure_zenoh_config` into a ``zenoh.Config`` (no-op when disabled)."""
    for key, value in secure_zenoh_config(cfg, role).items():
        zconf.insert_json5(key, value)  # type: ignore[attr-defined]


def validate_security(cfg: TeleopConfig, roles: tuple[str, ...] = ROLES) -> None:
    """Check secure mode up front (endpoints, files, passwords) for the CLI; no-op if off.

    Each role is checked for what it needs where it runs (see :func:`secure_zenoh_config`).
    """
    for role in roles:
        secure_zenoh_config(cfg, role)
