"""``oed demo``: the main job on the built-in PUMA 560 (``make demo``)."""

from __future__ import annotations

import argparse

from dynamics.robots import load_robot
from oed.cli.model import summary


def register(subparsers: argparse._SubParsersAction) -> argparse.ArgumentParser:
    parser = subparsers.add_parser("demo", help="run the main job on the built-in PUMA 560")
    parser.add_argument("--out", default="out/demo", help="folder for the report and figures (default: out/demo)")
    return parser


def run(args: argparse.Namespace) -> int:
    robot = load_robot("puma560", joints=3)
    document = summary(robot, "viscous")
    print(f"PUMA 560, first three joints (the paper's case), viscous friction:")
    for kind, entry in document.items():
        print(f"  {kind:<9s} model: {entry['n_base']:3d} base parameters")
    return 0
