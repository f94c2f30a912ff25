"""Result and option types of ``teleop diagnose`` (frozen dataclasses), and the NRMSE."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from teleop.diagnose.axis_model import Array
from teleop.diagnose.criterion import DEFAULT, Criterion
from teleop.diagnose.model import AxisNominal
from teleop.diagnose.residual import ResidualStats
from teleop.diagnose.windows import Window


@dataclass(frozen=True, slots=True)
class DiagnoseOptions:
    """Settings of one diagnosis."""

    nominal: AxisNominal
    input_col: str | None
    output_col: str
    analysis: str = "auto"            # auto | output-error | equation-error
    criterion: Criterion = DEFAULT    # the one selection rule (teleop.diagnose.criterion)
    max_effects: int = 3
    fit_rate_hz: float = 250.0         # output-error fit grid (the recording is decimated)
    max_fit_samples: int = 10000      # long recordings: lower the fit rate (not below 100 Hz)
    max_nfev: int = 8
    screen_top: int = 3
    refine_top: int = 2               # candidates refitted fully before choosing each effect
    screen_above: int = 7             # screen candidates by equation error above this many
    noise_factor: float = 1.5         # residual rms below this many noise levels: stop adding


@dataclass(frozen=True, slots=True)
class EffectResult:
    """One effect the data support."""

    name: str
    params: tuple[tuple[str, float], ...]
    std: tuple[tuple[str, float], ...]
    delta_bic: float       # the shared rule's score (penalised likelihood gain; JSON "delta_bic")
    holdout_gain: float
    explanation: str


@dataclass(frozen=True, slots=True)
class ProposedTerm:
    """One accepted library term (``teleop.diagnose.library``; a sin/cos pair is one) and its
    evidence under the selection rule."""

    keys: tuple[str, ...]
    coefs: tuple[float, ...]
    score: float
    holdout_gain: float

    def to_json(self, equation: str) -> dict[str, object]:
        """The term as the diagnose JSON's ``proposed`` entries write it."""
        return {"term": ",".join(self.keys), "keys": list(self.keys), "coefs": list(self.coefs),
                "score": self.score, "holdout_gain": self.holdout_gain, "equation": equation}


@dataclass(frozen=True, slots=True)
class Validation:
    """Fit on a held-out recording."""

    nrmse_before: float
    nrmse_after: float


@dataclass(frozen=True, slots=True)
class Traces:
    """Signals for plotting (segments concatenated)."""

    t: Array
    measured: Array
    nominal: Array
    augmented: Array
    residual: Array


@dataclass(frozen=True, slots=True)
class Diagnosis:
    """Everything ``teleop diagnose`` found."""

    analysis: str
    analysis_reason: str
    nominal_params: tuple[tuple[str, float], ...]
    final_params: tuple[tuple[str, float], ...]
    effects: tuple[EffectResult, ...]
    ranking: tuple[tuple[str, float], ...]    # every candidate: (name, delta BIC) best first
    windows: tuple[Window, ...]
    residual_before: ResidualStats
    residual_after: ResidualStats
    nrmse_before: float
    nrmse_after: float
    validation: Validation | None
    traces: Traces
    proposed: tuple[ProposedTerm, ...] = ()   # library terms outside the catalog
    units: tuple[str, str] = ("effort units", "position units")
    ambiguous: tuple[str, ...] = ()           # pairs of effects the data cannot separate
    unexplained_where: tuple[Window, ...] = ()  # where the final residual stays over 3x noise


def nrmse(y: Array, y_hat: Array) -> float:
    """||y - y_hat|| / ||y - mean(y)||."""
    d = float(np.linalg.norm(y - np.mean(y)))
    e = y_hat - y
    if not np.all(np.isfinite(e)):
        return math.inf
    return float(np.linalg.norm(e)) / d if d > 0 else math.inf
