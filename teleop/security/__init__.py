"""Security: a local certificate authority for zenoh TLS and the secure zenoh configuration."""

from __future__ import annotations
