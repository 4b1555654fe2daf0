"""``oed model``: the base parameters of the internal, external and combined models of a robot."""

from __future__ import annotations

import argparse

from dynamics.models import ModelKind, build_model
from oed.cli.shared.common import add_robot_arguments, json_text, robot_from_arguments
from oed.cli.shared.verbs import verb_summary


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


def summary(robot, effects: str) -> dict[str, dict]:
    """The ``--json`` document: per model ``n_base`` and ``parameters`` ``[{name, expression}]``."""
    document = {}
    for kind in ModelKind:
        model = build_model(robot, kind, effects)
        document[kind.value] = {
            "n_base": model.n_base,
            "channels": list(model.channels),
            "parameters": [
                {"name": name, "expression": expression}
                for name, expression in zip(model.base.names, model.base.expressions)
            ],
            "unidentifiable": list(model.base.unidentifiable),
        }
    return document


def run(args: argparse.Namespace) -> int:
    robot = robot_from_arguments(args)
    document = summary(robot, args.friction)
    if args.json:
        print(json_text(document), end="")
        return 0
    print(f"{robot.name}: {robot.n_joints} joints ({', '.join(robot.joint_names)}), effects: {args.friction}")
    for kind, entry in document.items():
        print(f"\n{kind} model: {entry['n_base']} base parameters (rows: {' '.join(entry['channels'])})")
        width = max(len(parameter["name"]) for parameter in entry["parameters"])
        for index, parameter in enumerate(entry["parameters"], start=1):
            print(f"  {index:3d}  {parameter['name']:<{width}}  = {parameter['expression']}")
    return 0
