"""Forward kinematics of a serial chain in CasADi: the pose of every joint frame in the base frame.

The frame of joint ``i`` after its motion is ``T_i = L_{i-1} A_i J(q_i)`` and the frame of its link
``L_i = T_i B_i`` (``A_i`` the joint placement, ``J`` the rotation about or translation along the
joint axis, ``B_i`` the link transform of :class:`dynamics.robot.Joint`; ``L_0`` the base frame).
For a URDF read by :func:`dynamics.urdf.robot_from_urdf`, ``T_i`` is Pinocchio's ``oMi`` of joint
``i``, the frame in which the URDF's collision geometry of the joint's child link is placed.
"""

from __future__ import annotations

import casadi
import numpy as np

from dynamics.robot import JointType, RobotModel


def axis_rotation(axis: np.ndarray, angle: casadi.SX) -> casadi.SX:
    """Rotation by ``angle`` about the unit ``axis`` (Rodrigues: ``u uᵀ + cos (1 − u uᵀ) + sin [u]×``)."""
    u = np.asarray(axis, dtype=float).reshape(3)
    outer = np.outer(u, u)
    skew = np.array([[0, -u[2], u[1]], [u[2], 0, -u[0]], [-u[1], u[0], 0]])
    return casadi.DM(outer) + casadi.cos(angle) * casadi.DM(np.eye(3) - outer) + casadi.sin(angle) * casadi.DM(skew)


def joint_frames(robot: RobotModel) -> casadi.Function:
    """``joint_frames(q) -> (R, p)``: rotations ``R`` (``3 x 3n``, joint ``i`` in columns ``3i..3i+2``)
    and origins ``p`` (``3 x n``) of the moved joint frames ``T_i`` in the base frame.

    The function is built once per robot (cached on the robot's identity by the callers that need it).
    """
    n = robot.n_joints
    q = casadi.SX.sym("q", n)
    rotation, position = casadi.SX.eye(3), casadi.SX.zeros(3, 1)
    rotations, positions = [], []
    for index, joint in enumerate(robot.joints):
        placement = joint.placement
        position = position + rotation @ casadi.DM(placement[:3, 3])
        rotation = rotation @ casadi.DM(placement[:3, :3])
        if joint.joint_type is JointType.REVOLUTE:
            rotation = rotation @ axis_rotation(joint.axis, q[index])
        else:
            position = position + rotation @ (casadi.DM(joint.axis) * q[index])
        rotations.append(rotation)
        positions.append(position)
        link = joint.link_transform
        position = position + rotation @ casadi.DM(link[:3, 3])
        rotation = rotation @ casadi.DM(link[:3, :3])
    return casadi.Function("joint_frames", [q], [casadi.horzcat(*rotations), casadi.horzcat(*positions)],
                           ["q"], ["R", "p"])
