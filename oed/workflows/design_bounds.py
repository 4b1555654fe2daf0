"""The motion bounds of ``oed design`` from its options (``bounds``, ``ddq_max`` or the PUMA's eq. 19)."""

from __future__ import annotations

from typing import Any

from oed.bounds import JointBounds
from oed.excitation import default_bounds


def bounds_of(args: Any, robot: Any) -> JointBounds:
    """`--bounds FILE`, else the URDF's limits with `--ddq-max`, else eq. 19 for the PUMA; checked against the robot."""
    if args.bounds is not None:
        if args.ddq_max is not None:
            raise ValueError("--ddq-max completes the URDF's limits; with --bounds give ddq_max in the file")
        bounds = JointBounds.load(args.bounds)
    elif args.ddq_max is not None:
        bounds = JointBounds.from_robot(robot, ddq_max=args.ddq_max)
    else:
        try:
            bounds = default_bounds(robot)
        except ValueError:
            raise ValueError(
                f"no default bounds for {robot.name} ({robot.n_joints} joints; eq. 19's are for the 3-joint PUMA): "
                "give --bounds FILE (q_max, dq_max, ddq_max) or --ddq-max to use the URDF's position and velocity limits"
            ) from None
    bounds.check_joint_count(robot.n_joints)
    return bounds
