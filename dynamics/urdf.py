"""Robots from a URDF file, parsed with Pinocchio.

Only serial chains of one-degree-of-freedom revolute (including ``continuous``) and prismatic
joints are accepted; fixed joints are merged by Pinocchio. The inertia of the root link is
ignored: it does not move, so it adds only a constant to the base wrench, which the plate-offset
columns absorb.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from dynamics.errors import RobotDescriptionError
from dynamics.robot import DEFAULT_GRAVITY, Joint, JointType, RobotModel


def robot_from_urdf(path: str | Path, *, gravity: np.ndarray | None = None) -> RobotModel:
    """Read a serial chain from a URDF file.

    Parameters
    ----------
    path
        The URDF file.
    gravity
        Gravity in the base frame; default ``(0, 0, -9.81)``.

    Raises
    ------
    RobotDescriptionError
        If the file cannot be parsed, or the chain branches, or holds a joint that is not a
        one-degree-of-freedom revolute or prismatic joint (floating, planar, spherical…).
    """
    import pinocchio as pin

    path = Path(path)
    if not path.is_file():
        raise RobotDescriptionError(f"URDF file {path} is a folder" if path.is_dir() else f"URDF file not found: {path}")
    try:
        model = pin.buildModelFromUrdf(str(path))
    except (RuntimeError, ValueError) as error:
        raise RobotDescriptionError(f"cannot parse URDF {path}: {error}") from None
    if model.njoints <= 1:
        raise RobotDescriptionError(f"URDF {path} has no movable joint")
    for joint_id in range(1, model.njoints):
        parent = model.parents[joint_id]
        if parent != joint_id - 1:
            raise RobotDescriptionError(
                f"URDF {path}: joint {model.names[joint_id]!r} hangs from {model.names[parent]!r}, "
                "not from the previous joint: branching chains are not supported (serial chains only)"
            )
    joints = []
    for joint_id in range(1, model.njoints):
        joint_model = model.joints[joint_id]
        name = model.names[joint_id]
        kind = joint_model.shortname()
        if joint_model.nv != 1:
            raise RobotDescriptionError(
                f"URDF {path}: joint {name!r} is a {kind.removeprefix('JointModel')} joint with "
                f"{joint_model.nv} degrees of freedom (floating, planar and spherical joints are not "
                "supported: serial chains of revolute and prismatic joints only)"
            )
        data = joint_model.createData()
        joint_model.calc(data, pin.neutral(model)[joint_model.idx_q : joint_model.idx_q + joint_model.nq])
        subspace = np.asarray(data.S).reshape(6)
        linear, angular = subspace[:3], subspace[3:]
        if np.linalg.norm(angular) > 1e-12 and np.linalg.norm(linear) < 1e-12:
            joint_type, axis = JointType.REVOLUTE, angular
        elif np.linalg.norm(linear) > 1e-12 and np.linalg.norm(angular) < 1e-12:
            joint_type, axis = JointType.PRISMATIC, linear
        else:
            raise RobotDescriptionError(f"URDF {path}: joint {name!r} ({kind}) is neither revolute nor prismatic")
        index_q = joint_model.idx_q
        index_v = joint_model.idx_v
        lower = float(model.lowerPositionLimit[index_q]) if joint_model.nq == 1 else -np.inf
        upper = float(model.upperPositionLimit[index_q]) if joint_model.nq == 1 else np.inf
        if lower >= upper:  # Pinocchio stores unset limits as ±max double, or equal values
            lower, upper = -np.inf, np.inf
        velocity = float(model.velocityLimit[index_v])
        effort = float(model.effortLimit[index_v])
        joints.append(
            Joint(
                name=name,
                joint_type=joint_type,
                axis=axis,
                placement=model.jointPlacements[joint_id].homogeneous,
                link_transform=np.eye(4),
                inertial=np.asarray(model.inertias[joint_id].toDynamicParameters()).reshape(-1),
                lower=lower if np.isfinite(lower) and abs(lower) < 1e30 else -np.inf,
                upper=upper if np.isfinite(upper) and abs(upper) < 1e30 else np.inf,
                velocity=velocity if 0 < velocity < 1e30 else np.inf,
                effort=effort if 0 < effort < 1e30 else np.inf,
            )
        )
    return RobotModel(
        name=model.name or path.stem,
        joints=tuple(joints),
        gravity=np.asarray(DEFAULT_GRAVITY if gravity is None else gravity, dtype=float),
    )
