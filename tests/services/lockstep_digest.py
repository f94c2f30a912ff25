"""Digests of lockstep runs: the bit-for-bit record that holds faster code to the same answer.

``digest(result)`` hashes every series and scalar of a :class:`~services.lockstep.LockstepResult`
(SHA-256 of the raw float64 bytes, field by field), so a test can compare a run with the one
recorded from an earlier implementation without storing the series.  ``SCENARIOS`` are the
recorded runs (short, different controllers and link impairments).

Regenerate the record (only when a behaviour change is intended, and say so in the commit)::

    python tests/services/lockstep_digest.py > tests/services/data/lockstep_digests.json
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import sys

import numpy as np

#: name -> (config overrides, simulated seconds, seed)
SCENARIOS: dict[str, tuple[tuple[str, ...], float, int]] = {
    "two-layer": ((), 1.5, 1),
    "direct-delay-loss": (("controller.kind=direct", "links.master_controller.delay_s=0.05",
                           "links.master_controller.loss=0.2",
                           "links.controller_hand.loss=0.2"), 1.5, 2),
    "tdpa-jitter": (("controller.kind=tdpa", "links.master_controller.delay_s=0.02",
                     "links.master_controller.jitter=uniform",
                     "links.master_controller.jitter_s=0.01"), 1.5, 3),
    "two-layer-python-engine": (("hand.sim.engine=python",), 1.0, 4),
    "two-layer-sum-two-fingers": (("controller.transparency.force_combine=sum",
                                   "controller.transparency.finger_enable=[true, false, true]",
                                   "links.master_controller.delay_s=0.2"), 2.0, 5),
    "two-layer-mean-long-delay": (("controller.transparency.force_combine=mean",
                                   "links.master_controller.delay_s=0.5",
                                   "links.master_controller.duplicate=0.1",
                                   "links.controller_hand.jitter=normal",
                                   "links.controller_hand.jitter_s=0.005"), 2.0, 6),
}


def digest(res: object) -> dict[str, str]:
    """Field name -> SHA-256 (hex, first 16 digits) of the field's float64 bytes or repr."""
    out: dict[str, str] = {}
    for f in dataclasses.fields(res):  # type: ignore[arg-type]
        v = getattr(res, f.name)
        if isinstance(v, np.ndarray):
            data = np.ascontiguousarray(v, dtype=np.float64).tobytes() + repr(v.shape).encode()
        else:
            data = repr(v).encode()
        out[f.name] = hashlib.sha256(data).hexdigest()[:16]
    return out


def run_scenario(name: str) -> dict[str, str]:
    """The digest of scenario ``name``'s lockstep run."""
    from services.lockstep import run_lockstep
    from teleop.config import load_config

    overrides, seconds, seed = SCENARIOS[name]
    return digest(run_lockstep(load_config(None, list(overrides)), seconds, seed=seed))


if __name__ == "__main__":
    json.dump({n: run_scenario(n) for n in SCENARIOS}, sys.stdout, indent=1, sort_keys=True)
    sys.stdout.write("\n")
