"""A service-side node for the secure-mode tests: the real ZenohBus (subprocess only).

``python _bus_node.py SPEC_JSON`` with ``role`` ("hand" or "controller"), ``overrides``
(``--set`` strings) and ``angle`` (the controller's commanded finger angle).  The hand
receives hand commands until stdin closes and prints ``RESULT {"angles": [...]}``, the distinct
finger set-points that reached it through the bus (decoded, validated, sequence-checked);
the controller publishes ``angle`` every 20 ms until stdin closes.  Both print ``READY``.
"""

from __future__ import annotations

import json
import sys
import threading
import time


def main() -> int:
    """Run the bus node described by ``sys.argv[1]``."""
    from teleop.config import load_config
    from teleop.messages import HandCommand, Header
    from teleop.transport.zenoh_bus import ZenohBus

    spec = json.loads(sys.argv[1])
    cfg = load_config(None, spec["overrides"])
    bus = ZenohBus.from_config(spec["role"], cfg)
    stop = threading.Event()
    threading.Thread(target=lambda: (sys.stdin.read(), stop.set()), daemon=True).start()
    print("READY", flush=True)
    angles: set[float] = set()
    seq = 0
    try:
        while not stop.is_set():
            if spec["role"] == "controller":
                seq += 1
                a = float(spec["angle"])
                bus.publish("hand_command", HandCommand(
                    Header(seq=seq, t_s=time.monotonic(), energy_total_j=0.0), (a, a, a), 0.0))
                stop.wait(0.02)
            else:
                for rec in bus.receive("hand_command"):
                    assert isinstance(rec.message, HandCommand)
                    angles.add(rec.message.finger_setpoint_rad[0])
                bus.wait_for_data(0.01)
    finally:
        bus.close()
    print("RESULT " + json.dumps({"angles": sorted(angles)}), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
