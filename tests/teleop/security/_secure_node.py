"""A zenoh node run as a subprocess by the secure-mode tests (never imported by pytest).

``python _secure_node.py SPEC_JSON``.  SPEC keys:

- ``role``, ``cert_dir``, ``session``, ``listen``, ``connect``: who the node is and its links;
- ``mode``: zenoh mode, ``"peer"`` (default) or ``"client"`` (routed through the peer it
  connects to, as a dashboard would be);
- ``secure`` (bool): apply ``secure_zenoh_config`` (false: a plain, unauthenticated node);
- ``tamper``: ``{"drop_auth": bool, "password": str, "drop_client_cert": bool,
  "drop_acl": bool}`` edits to the secure keys (an intruder's credentials);
- ``pub``: ``[[signal, tag], ...]`` published every 50 ms with payload ``tag``;
  (its own samples are left out of the result);
- ``run_s``: how long to publish; ``null``: until stdin closes (a receiver).
- ``open_only``: only try to open the session and report;
- ``encode_hand_command``: publish valid encoded HandCommands to angle ``float(tag)``
  whose cumulative energy total grows by ``energy_j`` with every message;
- ``token``: declare the role's liveliness token (so a service sees the role alive);
- ``first_seq``: sequence number of the first message (default 5000: ahead of a real
  sender's, within the receiver's ``safety.seq_jump_max`` window).

Prints ``READY`` once subscribed, then one ``RESULT {json}`` line: the ``[key, tag]`` pairs it
received from others (subscribed to ``teleop/<session>/**``) and the most peers it saw.
"""

from __future__ import annotations

import json
import sys
import threading
import time


def _zenoh_config(spec: dict) -> object:  # type: ignore[type-arg]
    import zenoh

    from teleop.config import load_config
    from teleop.security.zenoh_secure import secure_zenoh_config

    zc = zenoh.Config()
    zc.insert_json5("mode", json.dumps(spec.get("mode", "peer")))
    zc.insert_json5("scouting/multicast/enabled", "false")
    zc.insert_json5("listen/endpoints", json.dumps(spec.get("listen", [])))
    zc.insert_json5("connect/endpoints", json.dumps(spec.get("connect", [])))
    if not spec.get("secure", True):
        return zc
    endpoint = (spec.get("listen") or spec.get("connect") or ["tls/127.0.0.1:7447"])[0]
    overrides = [f"session.name={spec['session']}", f"zenoh.endpoint={endpoint!r}",
                 "security.enabled=true", f"security.cert_dir={spec['cert_dir']!r}"]
    overrides += [f"zenoh.listen={json.dumps(spec.get('listen', []))}"]
    cfg = load_config(None, overrides + spec.get("overrides", []))
    keys = secure_zenoh_config(cfg, spec["role"])
    tamper = spec.get("tamper", {})
    if tamper.get("drop_auth"):
        for k in ("user", "password"):
            keys.pop(f"transport/auth/usrpwd/{k}")
    if "password" in tamper:
        keys["transport/auth/usrpwd/password"] = json.dumps(tamper["password"])
    if tamper.get("drop_client_cert"):
        for k in ("connect_certificate", "connect_private_key"):
            keys.pop(f"transport/link/tls/{k}")
    if tamper.get("drop_acl"):
        keys.pop("access_control", None)
    for k, v in keys.items():
        zc.insert_json5(k, v)
    return zc


def _payload(spec: dict, tag: str, seq: int, n_sent: int) -> bytes:  # type: ignore[type-arg]
    """``tag`` itself, or (``encode_hand_command``) a valid HandCommand to angle ``tag``
    (the ``n_sent``-th message: its energy total is ``(n_sent + 1) * energy_j``)."""
    if not spec.get("encode_hand_command"):
        return tag.encode()
    from teleop.messages import HandCommand, Header
    from teleop.transport.codec import encode

    angle = float(tag)
    energy_j = float(spec.get("energy_j", 0.0)) * (n_sent + 1)
    return encode(HandCommand(Header(seq=seq, t_s=time.monotonic(), energy_total_j=energy_j),
                              (angle, angle, angle), 0.0))


def main() -> int:
    """Run the node described by ``sys.argv[1]``."""
    import zenoh

    from teleop.transport.keys import data_key, liveliness_key

    spec = json.loads(sys.argv[1])
    session_name = spec["session"]
    try:
        zc = _zenoh_config(spec)
        session = zenoh.open(zc)
    except Exception as exc:  # reported to the test, which asserts on it
        print("OPEN-ERROR " + str(exc).splitlines()[0], flush=True)
        return 3
    if spec.get("open_only"):
        print("OPENED", flush=True)
        session.close()
        return 0
    got: list[tuple[str, str]] = []
    lock = threading.Lock()

    def on_sample(sample: zenoh.Sample) -> None:
        with lock:
            got.append((str(sample.key_expr), sample.payload.to_bytes().decode()))

    sub = session.declare_subscriber(f"teleop/{session_name}/**", on_sample)
    token = (session.liveliness().declare_token(liveliness_key(session_name, spec["role"]))
             if spec.get("token") else None)
    print("READY", flush=True)
    stop = threading.Event()
    if spec.get("run_s") is None:
        threading.Thread(target=lambda: (sys.stdin.read(), stop.set()), daemon=True).start()
    else:
        threading.Timer(float(spec["run_s"]), stop.set).start()
    pubs = [(data_key(session_name, sig), tag) for sig, tag in spec.get("pub", [])]
    peers = 0
    # default: ahead of a real sender's (which counts from 1 at 50 Hz) and within the jump
    # window, so the receiver's sequence filters pass it and only security can stop it;
    # ``first_seq`` 1 makes the node a sender starting afresh (its energy total is credited)
    seq = int(spec.get("first_seq", 5000))
    n_sent = 0
    while not stop.is_set():
        for key, tag in pubs:
            session.put(key, _payload(spec, tag, seq, n_sent))
        seq += 1
        n_sent += 1
        peers = max(peers, len(list(session.info.peers_zid())))
        stop.wait(0.05)
    sub.undeclare()
    if token is not None:
        token.undeclare()
    session.close()
    with lock:
        own = {tag for _, tag in pubs}
        received = sorted({(k, t) for k, t in got if t not in own})
    print("RESULT " + json.dumps({"got": received, "peers": peers}), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
