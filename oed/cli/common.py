"""Options shared by the verbs: which robot; the output-file helpers, re-exported for the verbs."""

from __future__ import annotations

import argparse
from pathlib import Path

from dynamics.robot import RobotModel
from dynamics.robots import BUILT_IN_ROBOTS, load_robot
from dynamics.runtime.output_files import OutputFiles, atomic_output, check_figure_path, json_text

__all__ = [
    "OutputFiles", "add_robot_arguments", "atomic_output", "check_csv_path", "check_figure_path", "check_json_path",
    "json_text", "robot_from_arguments", "seed",
]

#: suffixes that promise another format than the CSV a verb writes
NOT_CSV_SUFFIXES = frozenset({".json", ".parquet", ".png", ".pdf", ".svg", ".npz", ".npy", ".mat", ".xlsx", ".md"})


def add_robot_arguments(parser: argparse.ArgumentParser, *, default: str | None = "puma560") -> None:
    """``--robot NAME``, ``--urdf FILE`` (which wins) and ``--joints N``."""
    group = parser.add_argument_group("robot")
    group.add_argument(
        "--robot", default=default, help=f"built-in robot: {', '.join(sorted(BUILT_IN_ROBOTS))} (default: {default})"
    )
    group.add_argument("--urdf", type=Path, help="URDF file of a serial chain (stands in for --robot)")
    group.add_argument("--joints", type=int, help="keep only the first N joints (the PUMA paper uses 3)")


def seed(text: str) -> int:
    """``--seed`` values: non-negative integers (what ``numpy.random`` accepts), checked by argparse."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be a non-negative integer, got {text!r}") from None
    if value < 0:
        raise argparse.ArgumentTypeError(f"must be a non-negative integer, got {value}")
    return value


def check_csv_path(path: str | Path, option: str = "--out") -> None:
    """Refuse, before any work, a CSV output named like another format (``--out u.json``)."""
    if Path(path).suffix.lower() in NOT_CSV_SUFFIXES:
        raise ValueError(f"{option} {path}: this verb writes CSV; give a .csv file name")


def check_json_path(path: str | Path, option: str = "--out") -> None:
    """Refuse, before any work, a JSON output named like another format (``--out t.csv``)."""
    suffix = Path(path).suffix.lower()
    if suffix in NOT_CSV_SUFFIXES - {".json"} or suffix == ".csv":
        raise ValueError(f"{option} {path}: this writes JSON; give a .json file name")


def robot_from_arguments(args: argparse.Namespace) -> RobotModel:
    return load_robot(args.robot, urdf=args.urdf, joints=args.joints)
