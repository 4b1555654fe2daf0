"""``oed payload``: the mass, centre of mass and inertia of a payload from records made with it, the robot's model
held fixed (the work: :func:`oed.workflows.payload.payload`)."""

from __future__ import annotations

import argparse
from pathlib import Path

from oed.cli.shared.common import print_lines
from oed.cli.shared.verbs import verb_summary
from oed.workflows.options import check_json_path
from oed.workflows.payload import payload


def register(subparsers: argparse._SubParsersAction) -> argparse.ArgumentParser:
    parser = subparsers.add_parser(
        "payload",
        help=verb_summary("payload"),
        description="Identify the 10 inertial parameters of a rigid payload fixed to the last link (or --link) from "
        "records made with it, the robot's identified model (result.json of oed identify, report.json of oed "
        "diagnose) held fixed: a physically consistent body, its standard deviations with the robot model's own "
        "uncertainty propagated, what the data did not determine, and the validation error before and after. "
        "payload.json also holds the model with the payload (oed predict --model payload.json).",
    )
    parser.add_argument("--model", type=Path, required=True, help="the robot's result.json or report.json")
    parser.add_argument("--data", type=Path, required=True, action="append",
                        help="a record made with the payload (.csv or .parquet); repeat for several")
    parser.add_argument("--validate", type=Path, action="append", help="a held-out record with the payload")
    parser.add_argument("--link", help="the link the payload is fixed to: its URDF name, the joint that moves it, or "
                                       "link<k> (default: the last)")
    parser.add_argument("--mass", type=float, help="the payload's known (weighed) mass, kg: the rest is identified")
    parser.add_argument("--out", type=Path, required=True, help="payload.json")
    return parser


def run(args: argparse.Namespace) -> int:
    check_json_path(args.out)
    if args.out.expanduser().resolve() == args.model.expanduser().resolve():
        raise ValueError(f"--out {args.out} is the model file (--model): it would be overwritten; write elsewhere")
    result = payload(model=args.model, data=args.data, validate=args.validate, link=args.link, mass=args.mass)
    result.write(args.out)
    print_lines(result.summary())
    print(f"wrote {args.out}")
    return 0
