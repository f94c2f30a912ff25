"""Config section for transport security: zenoh mutual TLS, user/password auth and the ACL."""

from __future__ import annotations

from dataclasses import dataclass

from teleop.config.loader import param, section


@dataclass(frozen=True, slots=True)
class RoleIdentity:
    """How one service identifies itself and is recognised by the others."""

    user: str = param("", "zenoh user name (empty: the role name)")
    password: str = param("", "zenoh password (empty: this user's line in password_file)")
    common_name: str = param("", "common name of this role's certificate, used by the "
                             "access-control list (empty: the role name)")


@dataclass(frozen=True, slots=True)
class SecurityConfig:
    """Zenoh over mutual TLS, user/password authentication and a per-role access-control list.

    Relative paths are taken from ``cert_dir``; a relative ``cert_dir`` from the working
    directory.  ``teleop certs DIR`` writes every file named here.
    """

    enabled: bool = param(False, "secure mode: TLS-only endpoints, mutual TLS, user/password "
                          "authentication and the per-role access-control list")
    cert_dir: str = param("certs", "directory written by `teleop certs DIR`")
    ca_file: str = param("ca.pem", "CA certificate every service trusts")
    cert_file: str = param("{role}.pem", "this service's certificate ({role} becomes master, "
                           "controller, hand or observer)")
    key_file: str = param("{role}.key", "this service's private key ({role} as above)")
    credentials_file: str = param("credentials.txt", "zenoh user:password dictionary the "
                                  "listening service checks peers against (only a service "
                                  "that listens reads it)")
    password_file: str = param("{role}.credentials", "this service's own user:password line "
                               "({role} as above; all a connecting service needs)")
    verify_hostname: bool = param(True, "check that a peer's certificate names the host "
                                  "connected to")
    access_control: bool = param(True, "enforce the access-control list: only the master "
                                 "publishes master state, only the controller commands the "
                                 "hand, only the hand publishes hand state")
    master: RoleIdentity = section(RoleIdentity, "identity of the master service")
    controller: RoleIdentity = section(RoleIdentity, "identity of the controller service")
    hand: RoleIdentity = section(RoleIdentity, "identity of the hand service")
    observer: RoleIdentity = section(RoleIdentity, "identity of an observer session (a "
                                     "dashboard): may subscribe to everything, publish nothing")
