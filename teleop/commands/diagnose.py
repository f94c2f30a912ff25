"""``teleop diagnose``: where and why a model and a recording disagree; model it; show the fit.

Examples::

    teleop diagnose rec.csv --model axis --nominal inertia=0.02,viscous,stiffness \\
        --input torque_nm --output angle_rad --json out.json --plot out.png
    teleop diagnose swing_id0.csv swing_id1.csv --nominal viscous,gravity \\
        --output theta_rad --validate swing_val0.csv
"""

from __future__ import annotations

import argparse
from pathlib import Path

from teleop.commands.common import (
    add_json_option,
    add_output_option,
    info,
    nonneg_float,
    write_json,
)


def register(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Add the ``diagnose`` subcommand."""
    p = sub.add_parser("diagnose", help="find what physics a model leaves out of a recording",
                       description="Fit a nominal model to recordings, locate where the residual "
                       "exceeds the noise, fit catalog effects as augmentations, keep what the "
                       "data support, propose terms outside the catalog where they explain "
                       "more (the axis: a typed library; the finger: a position-periodic "
                       "shaft force), and report the fit before and after.")
    p.add_argument("recordings", nargs="+", type=Path, metavar="REC.csv",
                   help="recording(s) (one joint fit; each has its own initial state)")
    p.add_argument("--model", choices=("axis", "finger"), default="axis",
                   help="nominal model: a generic 1-DoF axis, or the finger model")
    p.add_argument("--finger", type=int, default=None, metavar="N",
                   help="--model finger on a 'teleop up --record' hand recording: which finger "
                   "(1-3); its set-points are the commands, contact rows are excluded")
    p.add_argument("--split-gaps", action="store_true",
                   help="--model finger --finger N: a gap in the hand recording's time (a "
                   "stalled tick, e.g. bus retries) restarts the simulation instead of being "
                   "refused")
    p.add_argument("--nominal", default="inertia,viscous,stiffness", metavar="TERMS",
                   help="axis terms the nominal model has: inertia, viscous, stiffness, gravity, "
                   "coulomb, offset; TERM=VALUE gives a nominal value refined within "
                   "--tolerance (default: inertia,viscous,stiffness, all free)")
    p.add_argument("--tolerance", type=nonneg_float, default=0.2, metavar="FRAC",
                   help="relative range within which stated nominal values are refined "
                   "(default 0.2)")
    p.add_argument("--input", dest="input_col", default=None, metavar="COL",
                   help="force/torque input column (omit for a free response)")
    p.add_argument("--output", dest="output_col", default=None, metavar="COL",
                   help="measured position column (default: the first column after t_s "
                   "ending in _rad or _m)")
    p.add_argument("--analysis", choices=("auto", "output-error", "equation-error"),
                   default="auto", help="force the analysis mode (default: automatic)")
    p.add_argument("--skip", type=nonneg_float, default=0.0, metavar="S",
                   help="ignore the first S seconds of every recording (e.g. a release "
                   "transient)")
    p.add_argument("--validate", type=Path, default=None, metavar="REC",
                   help="held-out recording: report NRMSE of both models on it")
    add_json_option(p)
    add_output_option(p, "--write-params", what="--write-params", type=Path, default=None,
                      metavar="FILE",
                      help="--model finger: write the refined finger parameters and the "
                      "effects found as TOML that teleop sim and the simulated hand load "
                      "(--set hand.sim.model=FILE)")
    add_output_option(p, "--plot", what="plot", type=Path, default=None, metavar="PNG",
                      help="write a plot: measured vs nominal vs augmented, residual, windows")
    p.set_defaults(run=run)


def _default_output(columns: tuple[str, ...], input_col: str | None) -> str:
    from teleop.errors import UserInputError

    for c in columns:
        if c not in ("t_s", input_col) and c.endswith(("_rad", "_m")):
            return c
    raise UserInputError("--output not given and no column ending in _rad or _m to default to")


def run(args: argparse.Namespace) -> int:
    """Run the diagnosis and print/write the results."""
    from teleop.diagnose.diagnose import DiagnoseOptions, diagnose
    from teleop.diagnose.fit import NUMERIC_FAILURES
    from teleop.diagnose.model import parse_nominal
    from teleop.diagnose.report import to_json, to_text
    from teleop.errors import RecordingError, UserInputError
    from teleop.recording import read_recording

    if args.write_params is not None and args.model != "finger":
        raise UserInputError("--write-params: only --model finger has parameters the "
                             "simulation loads")
    if args.model == "finger":
        try:
            from sim.finger_diagnose import diagnose_finger  # type: ignore[import-not-found]
        except ImportError:
            raise UserInputError("--model finger: the finger model adapter "
                                 "(sim/finger_diagnose.py) is not available in this "
                                 "build") from None
        return int(diagnose_finger(args))
    recs = [read_recording(p, allow_nan=True).skip(args.skip) for p in args.recordings]
    output = args.output_col or _default_output(recs[0].columns, args.input_col)
    for r in recs:
        r.column(output)
        if args.input_col:
            r.column(args.input_col)
    nominal = parse_nominal(args.nominal, args.tolerance)
    opts = DiagnoseOptions(nominal, args.input_col, output, analysis=args.analysis)
    val = (read_recording(args.validate, allow_nan=True).skip(args.skip) if args.validate
           else None)
    try:
        d = diagnose(recs, opts, val)
    except RecordingError:  # the recording's own fault, already said in one line
        raise
    except NUMERIC_FAILURES as e:  # candidates that fail are disqualified; this is the nominal
        raise RecordingError(f"{args.recordings[0]}: the nominal {args.model} model cannot be "
                             f"fitted to this recording ({type(e).__name__}: {e}); check "
                             "--input/--output/--nominal") from None
    src = " ".join(str(p) for p in args.recordings)
    info(args, to_text(d, src))
    write_json(args.json_path, to_json(d, args.model))
    if args.plot is not None:
        from teleop.diagnose.plot import plot_diagnosis

        plot_diagnosis(d, args.plot, title=f"teleop diagnose {src}"[:100])
        info(args, f"plot: {args.plot}")
    return 0
