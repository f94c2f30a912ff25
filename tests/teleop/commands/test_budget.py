"""``teleop budget``: progress while it runs, and Ctrl-C reports the grasps completed.

A ``--seconds 600`` budget runs for minutes; before, it printed nothing until the end and a
Ctrl-C lost the whole run.  The real command, interrupted as a terminal does (SIGINT to its
process group) once its progress bar shows a few grasps simulated.
"""

from __future__ import annotations

import json
import re
from pathlib import Path

from ctrl_c import interrupt_when


def _percent(err: str) -> int:
    return max((int(p) for p in re.findall(r"\] +(\d+)% ", err)), default=0)


def test_ctrl_c_on_teleop_budget_reports_the_grasps_done_and_exits_130(tmp_path: Path) -> None:
    out = tmp_path / "budget.json"
    # 12 % of 100 simulated seconds: two whole 4.5 s grasp cycles
    code, stdout, err = interrupt_when(["budget", "--seconds", "100", "--json", str(out)],
                                       lambda err: _percent(err) >= 12)
    assert code == 130, err[-500:]
    assert "interrupted at" in err.splitlines()[-1]
    doc = json.loads(out.read_text())
    assert doc["interrupted"] is True and 12.0 <= doc["seconds"] < 100.0
    assert len(doc["grasps"]) >= 2 and doc["grasps"][-1]["t_end_s"] <= doc["seconds"]
    assert "weakest over the first" in stdout
