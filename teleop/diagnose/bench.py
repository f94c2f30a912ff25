"""``teleop bench diagnose``: time to diagnose a 60 s, 1 kHz recording with a concealed effect."""

from __future__ import annotations

import os
import time
from typing import Any


def bench_diagnose() -> dict[str, Any]:
    """Diagnose a synthetic 60 s, 1 kHz axis recording (random input, Coulomb friction)."""
    from teleop.diagnose.diagnose import DiagnoseOptions, diagnose
    from teleop.diagnose.model import AxisNominal
    from teleop.diagnose.synth import INPUT_COL, OUTPUT_COL, make_case

    case = make_case(("coulomb_friction",), "random", seed=7, duration_s=60.0, rate_hz=1000.0)
    p = case.params
    nominal = AxisNominal(("inertia", "viscous", "stiffness"), (p.inertia, None, p.stiffness),
                          0.1)
    t0, c0 = time.perf_counter(), time.process_time()
    d = diagnose([case.recording], DiagnoseOptions(nominal, INPUT_COL, OUTPUT_COL))
    elapsed, cpu = time.perf_counter() - t0, time.process_time() - c0
    return {"recording_s": 60.0, "rate_hz": 1000.0, "samples": len(case.recording),
            "diagnose_s": elapsed, "realtime_factor": 60.0 / elapsed,
            # on a shared machine wall time is mostly waiting for a core: the CPU time and
            # the load average say how much of it was the diagnosis
            "diagnose_cpu_s": cpu, "load_average_1min": os.getloadavg()[0],
            "found_first": d.effects[0].name if d.effects else "none",
            "concealed": "coulomb_friction", "nrmse_before": d.nrmse_before,
            "nrmse_after": d.nrmse_after}
