"""``oed design --payload --from robot.json``: a short excitation for a payload's parameters, the robot's model given
(:mod:`oed.payload.design`)."""

from __future__ import annotations

import argparse
import sys

import numpy as np

from estimation.identification.identified_model import IdentifiedModel
from oed.cli.shared.common import OutputFiles, check_csv_path, check_json_path, json_text
from oed.cli.shared.design_bounds import bounds_from_arguments
from oed.cli.shared.options import check_hertz, handover
from oed.design_settings import DesignSettings
from oed.payload import design_payload_excitation
from oed.payload.design import PAYLOAD_FREQUENCY_HZ, PAYLOAD_HARMONICS


def add_payload_arguments(parser: argparse.ArgumentParser) -> None:
    group = parser.add_argument_group("a payload's excitation")
    group.add_argument("--payload", action="store_true",
                       help="design one period (default 10 s) for the mass and centre of mass of a payload on the "
                            "robot of --from (its identified model), within the bounds")
    group.add_argument("--link", help="with --payload: the payload's link (URDF name, joint name or link<k>; "
                                      "default the last)")
    group.add_argument("--payload-mass", type=float, default=None,
                       help="with --payload: the payload's expected mass, kg (default 1)")
    group.add_argument("--payload-noise-only", action="store_true",
                       help="with --payload: design for the record's torque noise alone, not counting the robot "
                            "model's share of the uncertainty (which such a design can let grow)")


def payload_requested(args: argparse.Namespace) -> bool:
    """Whether ``--payload`` was given; its options without it are an error."""
    if not args.payload:
        given = [option for option, value in (("--link", args.link), ("--payload-mass", args.payload_mass))
                 if value is not None] + (["--payload-noise-only"] if args.payload_noise_only else [])
        if given:
            raise ValueError(f"{', '.join(given)} belong to a payload's design: give --payload too")
    return bool(args.payload)


def run_payload(args: argparse.Namespace) -> int:
    """``oed design --payload`` (module docstring): ``--out`` (trajectory JSON with ``payload_design``), ``--csv``."""
    if args.from_model is None:
        raise ValueError("--payload designs for an identified robot: give its result.json or report.json with --from")
    given = [option for option, value in (("--data", args.data), ("--focus", args.focus), ("--periods", args.periods),
                                          ("--rival", args.rival), ("--model", args.model), ("--friction", args.friction),
                                          ("--criterion", args.criterion), ("--plot", args.plot))
             if value is not None] + (["--discriminate"] if args.discriminate else [])
    if given:
        raise ValueError(f"{', '.join(given)}: not with --payload (the model file fixes the model; the criterion is "
                         "the worst relative standard deviation of the mass and the centre of mass)")
    args.frequency = PAYLOAD_FREQUENCY_HZ if args.frequency is None else args.frequency
    args.harmonics = PAYLOAD_HARMONICS if args.harmonics is None else args.harmonics
    check_hertz(args, "frequency")
    check_json_path(args.out)
    if args.csv is not None:
        check_csv_path(args.csv, "--csv")
    model = IdentifiedModel.load(args.from_model)
    bounds = bounds_from_arguments(args, model.robot)
    settings = DesignSettings(frequency_hz=args.frequency, harmonics=args.harmonics, cost_samples=args.samples,
                              constraint_points=args.constraint_points, verbose=args.verbose,
                              max_iter=500 if args.max_iter is None else args.max_iter,
                              sqp_after=handover(args, DesignSettings.sqp_after))

    def progress(start, total) -> None:
        if not args.quiet:
            print(f"start {start.index + 1}/{total}: {start.status}, {start.iterations} iterations, {start.time_s:.2f} s, "
                  f"criterion {start.criterion_value:.4f}" + ("" if start.feasible else " (bounds not met)"),
                  file=sys.stderr, flush=True)

    result = design_payload_excitation(model, bounds=bounds, link=args.link, mass=1.0 if args.payload_mass is None else args.payload_mass,
                                       robot_share=not args.payload_noise_only,
                                       settings=settings, starts=args.starts, seed=args.seed, progress=progress)
    with OutputFiles() as outputs:  # all files or none
        with outputs.open(args.out) as stream:
            stream.write(json_text(result.to_dict()))
        if args.csv is not None:
            header, table = result.table(settings.rate_hz)
            with outputs.open(args.csv) as stream:
                np.savetxt(stream, table, delimiter=",", header=",".join(header), comments="", fmt="%.10g")
    if not args.quiet:
        print(result.summary(), file=sys.stderr)
        print(f"{result.design.total_time_s:.2f} s -> {args.out}", file=sys.stderr)
    return 0
