"""Options shared by the verbs: which robot, and writing output files safely."""

from __future__ import annotations

import argparse
import contextlib
import os
import tempfile
from collections.abc import Iterator
from pathlib import Path

from dynamics.robot import RobotModel
from dynamics.robots import BUILT_IN_ROBOTS, load_robot


def add_robot_arguments(parser: argparse.ArgumentParser, *, default: str | None = "puma560") -> None:
    """``--robot NAME``, ``--urdf FILE`` (which wins) and ``--joints N``."""
    group = parser.add_argument_group("robot")
    group.add_argument(
        "--robot", default=default, help=f"built-in robot: {', '.join(sorted(BUILT_IN_ROBOTS))} (default: {default})"
    )
    group.add_argument("--urdf", type=Path, help="URDF file of a serial chain (stands in for --robot)")
    group.add_argument("--joints", type=int, help="keep only the first N joints (the PUMA paper uses 3)")


def robot_from_arguments(args: argparse.Namespace) -> RobotModel:
    return load_robot(args.robot, urdf=args.urdf, joints=args.joints)


@contextlib.contextmanager
def atomic_output(path: str | Path, mode: str = "w") -> Iterator:
    """Write ``path`` through a temporary file renamed on success: no half-written output on error."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    handle, temporary = tempfile.mkstemp(prefix=f".{path.name}.", dir=path.parent)
    try:
        with os.fdopen(handle, mode) as stream:
            yield stream
        os.replace(temporary, path)
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(temporary)
        raise
