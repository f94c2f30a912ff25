"""``teleop certs DIR``: create a local CA, per-service TLS certificates and zenoh passwords."""

from __future__ import annotations

import argparse
from pathlib import Path

from teleop.commands.common import add_json_option, info, write_json


def register(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Add the ``certs`` subcommand."""
    p = sub.add_parser("certs", help="create a local CA and the services' TLS certificates, "
                       "keys and passwords for secure mode (config/secure.toml)")
    p.add_argument("directory", type=Path, metavar="DIR",
                   help="directory to write ca.pem, ca.key, <role>.pem, <role>.key, "
                   "<role>.credentials and credentials.txt into (created if missing)")
    p.add_argument("--hostname", dest="hostnames", action="append", default=[],
                   metavar="NAME", help="extra DNS name or IP address the certificates are "
                   "valid for, besides localhost and 127.0.0.1 (repeatable)")
    p.add_argument("--days", type=int, default=825, help="validity in days (default 825)")
    p.add_argument("--force", action="store_true", help="overwrite existing files in DIR")
    add_json_option(p)
    p.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    """Write the CA, certificates, keys and credentials; print what was written."""
    from teleop.security.certs import create_certs

    bundle = create_certs(args.directory, hostnames=args.hostnames, days=args.days,
                          force=args.force)
    info(args, f"CA certificate   {bundle.ca_cert}")
    info(args, f"CA private key   {bundle.ca_key}  (keep offline; only needed to issue more)")
    own = dict(bundle.role_credentials)
    for role, cert, key in bundle.certs:
        info(args, f"{role:<16} {cert}  {key}  {own[role]}")
    info(args, f"credentials      {bundle.credentials}  (user:password per role: only the "
               f"listening service, the controller, needs it)")
    info(args, f"run securely:    teleop up --config config/secure.toml "
               f"--set security.cert_dir={bundle.directory}")
    write_json(args.json_path, {
        "directory": str(bundle.directory), "ca_cert": str(bundle.ca_cert),
        "ca_key": str(bundle.ca_key), "credentials": str(bundle.credentials),
        "certs": {role: {"cert": str(c), "key": str(k), "credentials": str(own[role])}
                  for role, c, k in bundle.certs},
    })
    return 0
