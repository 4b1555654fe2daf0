"""``oed model``: the base parameters of the internal, external and combined models of a robot
(the work: :func:`oed.workflows.model.model`)."""

from __future__ import annotations

import argparse

from dynamics.runtime.output_files import json_text
from oed.cli.shared.common import add_robot_arguments, print_lines
from oed.cli.shared.verbs import verb_summary
from oed.workflows.model import model


def register(subparsers: argparse._SubParsersAction) -> argparse.ArgumentParser:
    parser = subparsers.add_parser(
        "model",
        help=verb_summary("model"),
        description="Print the base (minimal) parameters of the internal, external and combined models "
        "as groupings of the standard parameters (PUMA paper, Tables III-V).",
    )
    add_robot_arguments(parser)
    parser.add_argument(
        "--friction",
        default="viscous",
        help="extra columns, comma-separated: viscous, coulomb, offset, armature, wrench_offset "
        "(default: viscous; 'none' for rigid body only)",
    )
    parser.add_argument("--json", action="store_true", help="print one JSON object keyed by model")
    return parser


def run(args: argparse.Namespace) -> int:
    result = model(friction=args.friction, robot=args.robot, urdf=args.urdf, joints=args.joints,
                   joint_names=args.joint_names, locked_at=args.locked_at, passive=args.passive)
    if args.json:
        print(json_text(result.to_dict()), end="")
        return 0
    print_lines(result.summary())
    return 0
