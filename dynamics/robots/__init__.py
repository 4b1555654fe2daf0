"""Built-in robot descriptions, as data, and the one place that resolves a robot by name or file."""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from pathlib import Path

import numpy as np

from dynamics.errors import RobotDescriptionError
from dynamics.robot import RobotModel
from importlib import resources

from dynamics.robots.puma560 import puma560
from dynamics.robots.servo_arm import servo_arm
from dynamics.mjcf import is_mjcf, mjcf_actuated_joints, robot_from_mjcf
from dynamics.urdf import robot_from_urdf, urdf_actuated_joints

__all__ = ["BUILT_IN_ROBOTS", "described_unactuated", "emps", "load_robot", "truncate"]


def emps() -> RobotModel:
    """The EMPS linear axis (one prismatic joint), described by the packaged ``emps.urdf``."""
    with resources.as_file(resources.files("dynamics.robots").joinpath("emps.urdf")) as path:
        return robot_from_urdf(path)


BUILT_IN_ROBOTS: dict[str, Callable[[], RobotModel]] = {
    "puma560": puma560,
    "servo_arm": servo_arm,
    "emps": emps,
}


def truncate(robot: RobotModel, joints: int) -> RobotModel:
    """Keep the first ``joints`` joints (and their links) of a chain."""
    if not isinstance(joints, (int, np.integer)) or isinstance(joints, bool):
        raise TypeError(f"joints must be an integer, got {type(joints).__name__}")
    joints = int(joints)
    if not 1 <= joints <= robot.n_joints:
        raise RobotDescriptionError(f"{robot.name} has {robot.n_joints} joints; cannot keep {joints}")
    if joints == robot.n_joints:
        return robot
    kept = robot.joints[:joints]
    geometry = {
        name: value for name, value in robot.geometry.items() if int("".join(filter(str.isdigit, name))) <= joints
    }
    return RobotModel(f"{robot.name}[{joints}]", kept, robot.gravity, geometry)


def load_robot(name: str | None = None, *, urdf: str | Path | None = None, joints: int | None = None,
               joint_names: Sequence[str] | None = None, locked_at: Mapping[str, float] | None = None,
               mjcf: str | Path | None = None, passive: Sequence[str] | None = None) -> RobotModel:
    """Return a built-in robot by name, or one read from a URDF or MuJoCo MJCF file.

    Parameters
    ----------
    name
        One of :data:`BUILT_IN_ROBOTS` (``puma560``, ``servo_arm``, ``emps``). Ignored when ``urdf`` is given.
    urdf
        Path of a URDF file describing a serial chain; a file whose root element is ``<mujoco>`` is read as
        MJCF (:func:`dynamics.mjcf.robot_from_mjcf`), so that a robot's source is one path whatever its format.
    joints
        Keep only the first ``joints`` joints (the PUMA paper uses 3); default all.
    joint_names, locked_at
        With ``urdf``: the logged joints (base to tip) of any URDF, every other joint locked at
        ``locked_at`` (default 0), see :func:`dynamics.urdf.robot_from_urdf`.
    mjcf
        Path of a MuJoCo MJCF file (:func:`dynamics.mjcf.robot_from_mjcf`); not with ``urdf``.
    passive
        The passive (unactuated) joints, by name or number from 1 (:meth:`dynamics.robot.RobotModel.with_passive`):
        their torque is zero by physics. Default none.
    """
    if urdf is not None and mjcf is not None:
        raise RobotDescriptionError("give a URDF or an MJCF file, not both")
    if urdf is None and mjcf is None and (joint_names is not None or locked_at):
        raise RobotDescriptionError("joint names and locked joints select joints of a URDF: give the URDF file")
    if mjcf is not None:
        robot = robot_from_mjcf(mjcf, joint_names=joint_names, locked_at=locked_at)
    elif urdf is not None and is_mjcf(urdf):
        robot = robot_from_mjcf(urdf, joint_names=joint_names, locked_at=locked_at)
    elif urdf is not None:
        robot = robot_from_urdf(urdf, joint_names=joint_names, locked_at=locked_at)
    elif name is None:
        raise RobotDescriptionError("name a robot (one of " + ", ".join(sorted(BUILT_IN_ROBOTS)) + ") or a URDF file")
    else:
        key = name.strip().lower()
        if key not in BUILT_IN_ROBOTS:
            raise RobotDescriptionError(
                f"unknown robot {name!r}; built-in robots are {', '.join(sorted(BUILT_IN_ROBOTS))} "
                "(or pass a URDF file)"
            )
        robot = BUILT_IN_ROBOTS[key]()
    robot = robot if joints is None else truncate(robot, joints)
    return robot.with_passive(passive) if passive else robot


def described_unactuated(path: str | Path | None, robot: RobotModel) -> tuple[str, ...]:
    """The joints of ``robot`` that its description file ``path`` (URDF or MJCF) leaves without a motor, base to tip:
    the file declares some joints driven (a URDF's ``<transmission>`` or ``<ros2_control>`` command interfaces,
    :func:`dynamics.urdf.urdf_actuated_joints`; an MJCF's ``<actuator>`` elements,
    :func:`dynamics.mjcf.mjcf_actuated_joints`) and not these. Empty when the file declares none (it says nothing),
    or for a built-in robot (``path`` ``None``)."""
    if path is None:
        return ()
    driven = mjcf_actuated_joints(path) if is_mjcf(path) else urdf_actuated_joints(path)
    if driven is None:
        return ()
    return tuple(name for name in robot.joint_names if name not in driven)
