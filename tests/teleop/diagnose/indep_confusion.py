"""Confusion matrix of ``teleop diagnose`` on the independent axis batch (``indep_axis.py``).

    python tests/teleop/diagnose/indep_confusion.py [PER_CLASS] [SEED]

Case ``i`` of class ``j`` uses seed ``SEED + 11 i + j`` (the scheme of
``test_diagnose_indep.py``; the stride 11 gives every class both input kinds).  Prints one markdown table: per concealed class, how often it was
ranked first, what else was named (false discoveries), clean recordings called clean, and
out-of-catalog (cogging) recordings named as a catalog effect with confidence (no
unexplained-residual warning) or explained by a proposed library term.
"""

from __future__ import annotations

import sys
from collections import Counter
from dataclasses import dataclass
from pathlib import Path

sys.path.insert(0, str(Path(__file__).parent))

from indep_axis import make  # noqa: E402

from teleop.diagnose.diagnose import DiagnoseOptions, Diagnosis, diagnose  # noqa: E402
from teleop.diagnose.report import to_json  # noqa: E402

CONCEALED = ("coulomb_friction", "dead_time", "sensor_offset", "actuator_gain",
             "actuator_saturation")
CLASSES: tuple[str | None, ...] = (None, *CONCEALED, "cogging")


@dataclass(frozen=True)
class Outcome:
    """What diagnose said about one generated case."""

    concealed: str | None
    seed: int
    named: tuple[str, ...]
    confident: bool          # effects named and no unexplained-residual warning
    proposed: tuple[str, ...]


def run_case(concealed: str | None, seed: int) -> Outcome:
    """Generate one case and diagnose it."""
    c = make(concealed, seed)
    d: Diagnosis = diagnose([c.recording], DiagnoseOptions(c.nominal, "torque_nm", "angle_rad"))
    js = to_json(d)
    return Outcome(concealed, seed, tuple(e.name for e in d.effects),
                   bool(d.effects) and js["unexplained"] is None,
                   tuple(k for p in js["proposed"] for k in p["keys"]))


def batch(per_class: int, seed: int) -> list[Outcome]:
    """Every class ``per_class`` times."""
    return [run_case(name, seed + 11 * i + j) for i in range(per_class)
            for j, name in enumerate(CLASSES)]


def _terms(cs: list[Outcome]) -> str:
    kinds = Counter(k.split(":")[1] for o in cs for k in o.proposed if not k.startswith(
        "term:cos"))
    return f"{sum(bool(o.proposed) for o in cs)}/{len(cs)} {dict(kinds) or ''}".strip()


def table(out: list[Outcome]) -> str:
    """The confusion matrix as markdown."""
    rows = ["| concealed | n | ranked first | named at all | other catalog names (false "
            "discoveries) | library terms proposed |", "|---|---|---|---|---|---|"]
    for name in CLASSES:
        cs = [o for o in out if o.concealed == name]
        if not cs:
            continue
        fd = Counter(n for o in cs for n in o.named if n != name)
        if name is None:
            clean = sum(not o.named and not o.proposed for o in cs)
            rows.append(f"| none (clean) | {len(cs)} | called clean **{clean}/{len(cs)}** | - | "
                        f"{dict(fd) or '-'} | {_terms(cs)} |")
        elif name == "cogging":
            conf = sum(o.confident for o in cs)
            named = sum(bool(o.named) for o in cs)
            prop = sum(any(p.startswith("term:sin") for p in o.proposed) for o in cs)
            rows.append(f"| cogging (outside the catalog) | {len(cs)} | named as a catalog effect "
                        f"with confidence **{conf}/{len(cs)}**; position-periodic term proposed "
                        f"**{prop}/{len(cs)}** | {named}/{len(cs)} | {dict(fd) or '-'} | "
                        f"{_terms(cs)} |")
        else:
            first = sum(bool(o.named) and o.named[0] == name for o in cs)
            named = sum(name in o.named for o in cs)
            rows.append(f"| {name} | {len(cs)} | **{first}/{len(cs)}** | {named}/{len(cs)} | "
                        f"{dict(fd) or '-'} | {_terms(cs)} |")
    return "\n".join(rows)


def main(argv: list[str]) -> int:
    per = int(argv[0]) if argv else 3
    seed = int(argv[1]) if len(argv) > 1 else 500
    out = batch(per, seed)
    for o in out:
        print(f"{o.concealed} seed {o.seed}: {o.named} confident={o.confident} "
              f"proposed={o.proposed}", file=sys.stderr)
    print(table(out))
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
