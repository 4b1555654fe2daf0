"""Robots from a standard Denavit–Hartenberg table plus inertial parameters.

Convention (standard DH, as in Corke's Robotics Toolbox): the transform from DH frame ``i-1``
to DH frame ``i`` is

.. math::  {}^{i-1}T_i = R_z(\\theta_i) \\, T_z(d_i) \\, T_x(a_i) \\, R_x(\\alpha_i),

with ``theta_i = q_i + offset_i`` for a revolute joint and ``d_i = q_i + offset_i`` for a
prismatic one. Joint ``i`` moves about (along) ``z_{i-1}``; link ``i`` carries DH frame ``i``, in
which its inertial data are given.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from dynamics.robot import (
    DEFAULT_GRAVITY,
    Joint,
    JointType,
    RobotModel,
    rotation_x,
    rotation_z,
    translation,
)
from dynamics.errors import RobotDescriptionError


@dataclass(frozen=True)
class DHLink:
    """One row of a standard DH table and the inertial data of the link it describes.

    Parameters
    ----------
    a, alpha, d, theta
        DH constants (m, rad). For a revolute joint ``theta`` is the joint offset; for a
        prismatic one ``d`` is.
    inertial
        The ten standard parameters in DH frame ``i`` (see :mod:`dynamics.robot`).
    joint_type
        Revolute or prismatic.
    lower, upper, velocity, effort
        Joint limits.
    """

    a: float
    alpha: float
    d: float
    theta: float = 0.0
    inertial: tuple[float, ...] = (0.0,) * 10
    joint_type: JointType = JointType.REVOLUTE
    lower: float = -np.inf
    upper: float = np.inf
    velocity: float = np.inf
    effort: float = np.inf


def robot_from_dh(
    name: str,
    links: Sequence[DHLink],
    *,
    gravity: ArrayLike = DEFAULT_GRAVITY,
    joint_names: Sequence[str] | None = None,
) -> RobotModel:
    """Build a :class:`~dynamics.robot.RobotModel` from a standard DH table.

    The non-zero lengths ``a_i`` and ``d_i`` are recorded as named geometry so that base
    parameters print as, e.g., ``Izz2 + a2**2*(m2 + m3)``.
    """
    if len(links) == 0:
        raise RobotDescriptionError(f"DH table of {name!r} is empty")
    names = list(joint_names) if joint_names is not None else [f"joint{i}" for i in range(1, len(links) + 1)]
    if len(names) != len(links):
        raise RobotDescriptionError(f"{len(names)} joint names for {len(links)} DH rows")
    joints = []
    geometry: dict[str, float] = {}
    for index, (link, joint_name) in enumerate(zip(links, names), start=1):
        if not isinstance(link, DHLink):
            raise TypeError(f"DH row {index} must be a DHLink, got {type(link).__name__}")
        joint_type = JointType(link.joint_type)
        if joint_type is JointType.REVOLUTE:
            placement = rotation_z(link.theta)
            link_transform = translation(0.0, 0.0, link.d) @ translation(link.a, 0.0, 0.0) @ rotation_x(link.alpha)
            if link.d != 0.0:
                geometry[f"d{index}"] = float(link.d)
        else:
            placement = rotation_z(link.theta) @ translation(0.0, 0.0, link.d)
            link_transform = translation(link.a, 0.0, 0.0) @ rotation_x(link.alpha)
        if link.a != 0.0:
            geometry[f"a{index}"] = float(link.a)
        joints.append(
            Joint(
                name=joint_name,
                joint_type=joint_type,
                axis=np.array([0.0, 0.0, 1.0]),
                placement=placement,
                link_transform=link_transform,
                inertial=np.asarray(link.inertial, dtype=float),
                lower=link.lower,
                upper=link.upper,
                velocity=link.velocity,
                effort=link.effort,
            )
        )
    return RobotModel(name, tuple(joints), np.asarray(gravity, dtype=float), geometry)


def dh_forward_kinematics(links: Sequence[DHLink], q: ArrayLike) -> np.ndarray:
    """Tip transform of a DH chain by the plain product of DH matrices (an independent check)."""
    q = np.asarray(q, dtype=float).reshape(-1)
    transform = np.eye(4)
    for link, value in zip(links, q):
        if JointType(link.joint_type) is JointType.REVOLUTE:
            theta, d = link.theta + value, link.d
        else:
            theta, d = link.theta, link.d + value
        transform = transform @ rotation_z(theta) @ translation(0, 0, d) @ translation(link.a, 0, 0) @ rotation_x(link.alpha)
    return transform


