"""``teleop sim EXPERIMENT``: drive the simulated finger with one of the report's experiments.

Examples::

    teleop sim weight --force-n 9.8 --json -
    teleop sim pull-unloaded --units 100 --json -
    teleop sim force-step --out runs/force_step.csv
    teleop sim position --effect backlash=0.05 --effect dead_time=0.1 --out rec.csv
"""

from __future__ import annotations

import argparse
import math

from teleop.commands.common import (
    add_config_options,
    add_json_option,
    add_output_option,
    config_from_args,
    info,
)
from teleop.errors import ExperimentError

EXPERIMENT_HELP = ("weight, pull-unloaded, force-step, force-blocks, position, grasp")


def _number(text: str, label: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise ExperimentError(f"{label} {text!r}: not a number") from None
    if not math.isfinite(value):
        raise ExperimentError(f"{label} {text!r}: must be finite")
    return value


def register(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Add the ``sim`` subcommand."""
    p = sub.add_parser("sim", help="run an experiment on the simulated finger, write a recording",
                       description="Run one of the seed report's experiments on the physical "
                       "finger model: " + EXPERIMENT_HELP + ".")
    p.add_argument("experiment", metavar="EXPERIMENT", help=EXPERIMENT_HELP)
    p.add_argument("--force-n", default="9.8", metavar="F",
                   help="weight experiment: tendon force in N (default 9.8)")
    p.add_argument("--units", default="100", metavar="U",
                   help="pull-unloaded: motor input in servo units (default 100)")
    add_output_option(p, "--out", what="the recording", default=None, metavar="PATH",
                      help="write the recording CSV here")
    p.add_argument("--effect", action="append", default=[], metavar="NAME=VALUE",
                   help="add a physical effect to the simulated truth (repeatable)")
    p.add_argument("--duration", default=None, metavar="S", help="simulated time in s")
    p.add_argument("--rate-hz", default="100", metavar="HZ", help="recording sample rate")
    p.add_argument("--seed", type=int, default=0, help="noise seed (default 0)")
    p.add_argument("--noise", action="store_true", help="add sensor noise and quantisation")
    p.add_argument("--driver-delay", action="store_true",
                   help="reproduce the stock driver's 0.09 s command delay")
    add_json_option(p)
    add_config_options(p)
    p.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    """Run the experiment; print a summary, write the recording and JSON."""
    import time
    from dataclasses import replace

    from sim.contact import contact_object_from_config
    from sim.experiments import ExperimentSpec, check_spec, run_experiment
    from sim.finger import default_finger_params, weight_equilibrium
    from sim.params import with_tactile_gain
    from teleop.commands.common import write_json
    from teleop.effects import parse_effects
    from teleop.recording import write_recording

    spec = ExperimentSpec(
        name=args.experiment,
        duration_s=None if args.duration is None else _number(args.duration, "--duration"),
        force_n=_number(args.force_n, "--force-n"), units=_number(args.units, "--units"),
        rate_hz=_number(args.rate_hz, "--rate-hz"), noise=args.noise, seed=args.seed)
    check_spec(spec)
    effects = parse_effects(args.effect)
    cfg = config_from_args(args)
    params = default_finger_params(cfg.hand.sim.calibration)
    if cfg.hand.sim.model:  # refined by teleop diagnose --write-params; --effect adds to it
        from sim.finger_model_file import load_model

        params, found = load_model(cfg.hand.sim.model, params)
        for name in effects.active():
            found = found.with_effect(name, getattr(effects, name))
        effects = found
    if args.driver_delay or cfg.hand.sim.command_delay:
        params = replace(params, command_delay_s=0.09)
    params = with_tactile_gain(params, cfg.hand.sim.tactile_gain)
    obj = contact_object_from_config(cfg.hand.sim.object)
    if spec.name == "grasp" and obj.kind == "none":
        raise ExperimentError("grasp needs an object: set hand.sim.object.kind to cylinder "
                              "or block")
    if spec.name == "weight" and args.out is None:
        prox, dist = weight_equilibrium(params, spec.force_n, effects=effects,
                                        engine_name=cfg.hand.sim.engine)
        summary: dict[str, float | str] = {"force_n": spec.force_n, "proximal_angle_rad": prox,
                                           "distal_angle_rad": dist}
    else:
        last_report = [time.monotonic()]

        def progress(frac: float) -> None:
            now = time.monotonic()
            if now - last_report[0] >= 1.0:  # only long runs report, about once a second
                last_report[0] = now
                info(args, f"teleop sim {spec.name}: {100.0 * frac:.0f} %")

        result = run_experiment(spec, params, obj, effects, progress=progress,
                                engine_name=cfg.hand.sim.engine)
        summary = result.summary
        if spec.name == "weight":
            summary = {k: summary[k] for k in ("force_n", "proximal_angle_rad",
                                                "distal_angle_rad")}
        if args.out is not None:
            try:
                write_recording(args.out, result.recording)
            except OSError as exc:
                raise ExperimentError(f"{args.out}: cannot write ({exc.strerror})") from None
            info(args, f"teleop sim {spec.name}: wrote {len(result.recording)} rows to "
                 f"{args.out}")
    if args.json_path is not None:
        write_json(args.json_path, summary)
    else:
        for key, value in summary.items():
            text = f"{value:.6g}" if isinstance(value, float) else str(value)
            print(f"{key}: {text}")
    return 0
