"""One generated case of the diagnose proof batch and its diagnosis (top-level functions, so
``test_diagnose_proof`` can run its batch on the tests' job pool, ``tests/job_pool.py``)."""

from __future__ import annotations

from teleop.diagnose.diagnose import DiagnoseOptions, Diagnosis, diagnose
from teleop.diagnose.model import AxisNominal
from teleop.diagnose.synth import INPUT_COL, OUTPUT_COL, SynthCase, make_case


def nominal(case: SynthCase) -> AxisNominal:
    """The nominal model knows inertia and stiffness to +-10 % (CAD / datasheet); damping is
    free."""
    p = case.params
    return AxisNominal(("inertia", "viscous", "stiffness"), (p.inertia, None, p.stiffness), 0.1)


def run_case(case: SynthCase, validate: SynthCase | None = None) -> Diagnosis:
    """``teleop diagnose`` of ``case`` against its nominal model."""
    opts = DiagnoseOptions(nominal(case), INPUT_COL, OUTPUT_COL)
    return diagnose([case.recording], opts, validate.recording if validate else None)


def case_and_diagnosis(effects: tuple[str, ...], signal: str, seed: int,
                       duration_s: float) -> tuple[SynthCase, Diagnosis]:
    """The case ``make_case(effects, signal, seed)`` and its diagnosis."""
    case = make_case(effects, signal, seed, duration_s=duration_s)
    return case, run_case(case)


def indep_case_and_diagnosis(name: str | None, seed: int) -> tuple[object, Diagnosis]:
    """The independent case ``indep_axis.make(name, seed)`` and its diagnosis against the
    case's own nominal model (``test_diagnose_indep``'s batch)."""
    from tests.teleop.diagnose.indep_axis import make

    c = make(name, seed)
    return c, diagnose([c.recording], DiagnoseOptions(c.nominal, "torque_nm", "angle_rad"))
