"""The same robot as a Pinocchio model: the independent reference for rigid-body dynamics.

Used by the tests (to check the CasADi regressors) and by the simulator (forward dynamics).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from dynamics.robot import JointType, RobotModel


def _joint_model(pin, joint_type: JointType, axis: np.ndarray):
    if joint_type is JointType.REVOLUTE:
        return pin.JointModelRevoluteUnaligned(*axis)
    return pin.JointModelPrismaticUnaligned(*axis)


def _inertia(pin, parameters: np.ndarray):
    """``pinocchio.Inertia`` from ten standard parameters; a massless link keeps its rotational inertia."""
    mass = float(parameters[0])
    if mass > 0.0:
        return pin.Inertia.FromDynamicParameters(parameters)
    ixx, ixy, iyy, ixz, iyz, izz = parameters[4:]
    rotational = np.array([[ixx, ixy, ixz], [ixy, iyy, iyz], [ixz, iyz, izz]])
    return pin.Inertia(0.0, np.zeros(3), rotational)


def to_pinocchio(robot: RobotModel, *, free_flyer: bool = False, theta: ArrayLike | None = None):
    """Build a ``pinocchio.Model`` of ``robot``.

    Parameters
    ----------
    robot
        The chain.
    free_flyer
        Put a free-flyer joint between the world and the base, so that ``rnea`` with the root
        held still returns, in its first six entries, the wrench the world applies to the base
        (forces then moments about the base origin, in the base frame).
    theta
        Standard parameters (``10 n``) to use instead of the robot's own.

    Returns
    -------
    pinocchio.Model
        Joint ``i`` of the model is joint ``i`` of the chain (``+1`` with a free flyer). Joint
        positions are the chain's ``q`` (angles or displacements), ``nq = nv = n`` (``+7/+6``).
    """
    import pinocchio as pin

    theta = robot.standard_parameters if theta is None else np.asarray(theta, dtype=float).reshape(-1)
    model = pin.Model()
    model.name = robot.name
    model.gravity = pin.Motion(np.asarray(robot.gravity, dtype=float), np.zeros(3))
    parent = 0
    if free_flyer:
        parent = model.addJoint(0, pin.JointModelFreeFlyer(), pin.SE3.Identity(), "base_free_flyer")
        model.appendBodyToJoint(parent, pin.Inertia.Zero(), pin.SE3.Identity())
    previous_link = np.eye(4)
    for index, joint in enumerate(robot.joints):
        placement = pin.SE3(previous_link @ joint.placement)
        joint_id = model.addJoint(
            parent,
            _joint_model(pin, joint.joint_type, joint.axis),
            placement,
            joint.name,
            np.array([1e10]),
            np.array([1e10]),
            np.array([-1e10]),
            np.array([1e10]),
        )
        inertia = _inertia(pin, theta[10 * index : 10 * index + 10])
        model.appendBodyToJoint(joint_id, inertia, pin.SE3(joint.link_transform))
        previous_link = joint.link_transform
        parent = joint_id
    return model
