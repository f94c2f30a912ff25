"""Confusion matrix of ``teleop diagnose --model finger`` on the independent finger batch.

    python tests/sim/indep_finger_confusion.py [PER_CLASS] [SEED] [--law speed|effort]

Recordings from ``indep_finger.py`` (own physics and integrator); each is diagnosed as
``teleop diagnose R.csv --model finger`` does (``sim.params.default_finger_params``, the
default ``--tolerance 0.2``, output ``motor_angle_rad``).  Case ``i`` of class ``j`` uses seed
``SEED + 11 i + j`` (the kind alternates with the seed's parity, so every class sees both the
force and the position protocol).  Prints one markdown table: per concealed class how often it
was ranked first, named at all, what else was named (false discoveries), clean recordings called
clean (no catalog effect and no term outside it named), out-of-catalog (cogging) recordings named
as a catalog effect with confidence (no unexplained-residual warning), and where a
position-periodic term (outside the catalog) was found; then the catalog cases ranked first per band
of the concealed effect's own signature (``indep_finger.signature``: the truth with and without
the effect under the same command, rms over the noise; the generator's physics alone), which
says which misses had something in the recording to find.  Per-case lines go to stderr.
"""

from __future__ import annotations

import sys
import time
from collections import Counter
from dataclasses import dataclass
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

from sim.finger_dynamic import PARAMS, FingerDynamicModel, dynamic_data  # noqa: E402
from sim.params import default_finger_params  # noqa: E402
from teleop.diagnose.select_sim import diagnose_dynamic  # noqa: E402
from tests.sim.indep_finger import CATALOG, make, signature  # noqa: E402

CLASSES: tuple[str | None, ...] = (None, *CATALOG, "cogging")
TOLERANCE = 0.2  # the CLI's default --tolerance


@dataclass(frozen=True)
class Outcome:
    """What the diagnosis said about one generated case."""

    concealed: str | None
    seed: int
    kind: str
    value: float
    named: tuple[tuple[str, float], ...]
    warning: bool          # unexplained-residual warning
    ambiguous: tuple[str, ...]
    gap: float = 0.0       # the refined nominal finger's residual rms over the floor
    fraction: float = 0.0  # the final model's speed_law_fraction (motor friction law)
    term: bool = False     # a position-periodic term (outside the catalog) was found
    signature: float = 0.0  # the concealed effect's own rms in the motor angle / noise std

    @property
    def names(self) -> tuple[str, ...]:
        """The chosen effects' names, best first."""
        return tuple(n for n, _ in self.named)


def run_case(concealed: str | None, seed: int, law: str = "speed") -> Outcome:
    """Generate one case and diagnose it as the CLI does."""
    c = make(concealed, seed, law=law)
    model = FingerDynamicModel(default_finger_params(),
                               dynamic_data(c.recording, "motor_angle_rad"), TOLERANCE)
    d = diagnose_dynamic(model)
    gap = float(np.sqrt(d.nominal.rss / len(model.data.split()[0]))) / d.floor_rad
    frac = dict(zip(PARAMS, d.final.theta, strict=True)).get("speed_law_fraction", 0.0)
    return Outcome(concealed, seed, c.kind, c.value, tuple((n, v) for n, v, _ in d.chosen),
                   d.warning is not None, tuple(d.ambiguous), gap, float(frac), bool(d.terms),
                   signature(c))


def batch(per_class: int, seed: int, law: str = "speed") -> list[Outcome]:
    """Every class ``per_class`` times."""
    return [run_case(name, seed + 11 * i + j, law) for i in range(per_class)
            for j, name in enumerate(CLASSES)]


def table(out: list[Outcome]) -> str:
    """The confusion matrix as markdown."""
    rows = ["| concealed | n | ranked first | named at all | other catalog names (false "
            "discoveries) | unexplained-residual warning | periodic term found |",
            "|---|---|---|---|---|---|---|"]
    for name in CLASSES:
        cs = [o for o in out if o.concealed == name]
        if not cs:
            continue
        fd = Counter(n for o in cs for n in o.names if n != name)
        warn = f"{sum(o.warning for o in cs)}/{len(cs)} | {sum(o.term for o in cs)}/{len(cs)}"
        if name is None:
            clean = sum(not o.named and not o.term for o in cs)
            rows.append(f"| none (clean) | {len(cs)} | called clean **{clean}/{len(cs)}** | - | "
                        f"{dict(fd) or '-'} | {warn} |")
        elif name == "cogging":
            conf = sum(bool(o.named) and not o.warning for o in cs)
            named = sum(bool(o.named) for o in cs)
            rows.append(f"| cogging (outside the catalog) | {len(cs)} | named as a catalog effect "
                        f"with confidence **{conf}/{len(cs)}** | {named}/{len(cs)} | "
                        f"{dict(fd) or '-'} | {warn} |")
        else:
            first = sum(bool(o.named) and o.names[0] == name for o in cs)
            named = sum(name in o.names for o in cs)
            rows.append(f"| {name} | {len(cs)} | **{first}/{len(cs)}** | {named}/{len(cs)} | "
                        f"{dict(fd) or '-'} | {warn} |")
    return "\n".join(rows)


def by_kind(out: list[Outcome]) -> str:
    """Catalog effects ranked first and clean called clean, per input kind."""
    parts = []
    for kind in ("force", "position"):
        conc = [o for o in out if o.kind == kind and o.concealed not in (None, "cogging")]
        first = sum(bool(o.named) and o.names[0] == o.concealed for o in conc)
        clean = [o for o in out if o.kind == kind and o.concealed is None]
        parts.append(f"{kind}: ranked first {first}/{len(conc)}, clean "
                     f"{sum(not o.named and not o.term for o in clean)}/{len(clean)}")
    return "; ".join(parts)


def clean_gap(out: list[Outcome]) -> str:
    """The model gap on the clean recordings: nominal-fit residual rms / floor, per kind."""
    parts = []
    for kind in ("force", "position"):
        g = sorted(o.gap for o in out if o.kind == kind and o.concealed is None)
        if g:
            parts.append(f"{kind} median {np.median(g):.2f} (range {g[0]:.2f}-{g[-1]:.2f})")
    return "; ".join(parts)


def floors(out: list[Outcome]) -> str:
    """The issue's three floors against this batch."""
    conc = [o for o in out if o.concealed not in (None, "cogging")]
    first = sum(bool(o.named) and o.names[0] == o.concealed for o in conc)
    clean = [o for o in out if o.concealed is None]
    ok = sum(not o.named and not o.term for o in clean)
    cog = [o for o in out if o.concealed == "cogging"]
    conf = sum(bool(o.named) and not o.warning for o in cog)
    parts = []
    for label, k, n, good in (("ranked first", first, len(conc), lambda r: r >= 0.95),
                              ("clean called clean", ok, len(clean), lambda r: r >= 0.95),
                              ("out-of-catalog named with confidence", conf, len(cog),
                               lambda r: r <= 0.10)):
        if n:
            parts.append(f"{label} {k}/{n} = {k / n:.0%} ({'met' if good(k / n) else 'NOT met'})")
    return "; ".join(parts)


#: signature bands (the concealed effect's own rms / noise std: ``indep_finger.signature``)
BANDS = ((0.0, 1.0), (1.0, 3.0), (3.0, 10.0), (10.0, float("inf")))


def by_signature(out: list[Outcome]) -> str:
    """Catalog effects ranked first per signature band: what the recordings hold to be found
    (the generator's physics alone), against what the diagnosis found."""
    rows = ["| signature (effect rms / noise) | catalog cases | ranked first | classes (first / n) |",
            "|---|---|---|---|"]
    for lo, hi in BANDS:
        cs = [o for o in out if o.concealed not in (None, "cogging") and lo <= o.signature < hi]
        if not cs:
            continue
        first = [o for o in cs if o.named and o.names[0] == o.concealed]
        per = Counter(o.concealed for o in cs)
        hit = Counter(o.concealed for o in first)
        cls = ", ".join(f"{n} {hit[n]}/{k}" for n, k in sorted(per.items()))
        rows.append(f"| {lo:g}-{hi:g} | {len(cs)} | **{len(first)}/{len(cs)}** | {cls} |")
    return "\n".join(rows)


def main(argv: list[str]) -> int:
    pos = [a for a in argv if not a.startswith("--")]
    law = argv[argv.index("--law") + 1] if "--law" in argv else "speed"
    pos = [a for a in pos if a != law] if "--law" in argv else pos
    per = int(pos[0]) if pos else 3
    seed = int(pos[1]) if len(pos) > 1 else 700
    t0 = time.perf_counter()
    out = batch(per, seed, law)
    for o in out:
        print(f"{o.concealed} seed {o.seed} ({o.kind}, value {o.value:.4g}): "
              f"{[(n, round(v, 4)) for n, v in o.named]} warning={o.warning} "
              f"gap={o.gap:.2f} fraction={o.fraction:.2f} term={o.term} "
              f"signature={o.signature:.2f} "
              f"ambiguous={o.ambiguous}",
              file=sys.stderr)
    print(table(out))
    print(f"\nfloors: {floors(out)}")
    print(f"\nby the effect's own signature in the recording:\n{by_signature(out)}")
    print(f"by input kind: {by_kind(out)}")
    print(f"clean recordings, nominal-fit residual rms / floor (the search starts above 2): "
          f"{clean_gap(out)}")
    print(f"law {law}; wall {time.perf_counter() - t0:.0f} s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
