"""Symbolic recursive Newton–Euler regressors in CasADi (PUMA paper, section III, eqs. 1–13).

For each link ``i`` the spatial velocity ``v_i = (v, ω)`` and spatial acceleration ``a_i`` of the
origin of the link frame ``F_i`` are propagated from the base, expressed in ``F_i``:

.. math::
    v_i = X_i v_{i-1} + S_i \\dot q_i, \\qquad
    a_i = X_i a_{i-1} + S_i \\ddot q_i + v_i \\times S_i \\dot q_i ,

with the base acceleration ``a_0 = (−g, 0)`` standing for gravity. The wrench the link needs,
``W_{i,i} = A_i π_i`` (eq. 1–2), is linear in its ten standard parameters ``π_i``. Wrenches are
carried towards the base by the transmission ``T`` (eqs. 4–6), giving the upper block-triangular
matrix ``U`` of eq. 7; the joint torque is the projection on the motion subspace (eq. 11) and the
base wrench is the transmission of ``W_1`` into the base frame (eqs. 8–10).

Both are built here by the equivalent forward projection ``S_iᵀ X*_{i←j} A_j = (X_{j←i} S_i)ᵀ A_j``
(``j ≥ i``): each joint axis ``S_i``, and each of the six base-frame unit motions for the wrench
rows, is carried as a motion vector out to the later links and dotted with their 6x10 blocks,
instead of carrying every later link's 6x10 block back towards the base. Same numbers, fewer
operations: a 6-joint PUMA internal regressor drops from 2013 to 1514 CasADi instructions
(the external one from 2728 to 2174).

Sign conventions: ``tau_i`` is the torque (force) the actuator of joint ``i`` applies to link
``i``; the base wrench ``(fx, fy, fz, mx, my, mz)`` is the wrench the base applies **to the
robot**, in the base frame, moments about the base origin (a robot at rest reads ``fz = +m g``
with z up).
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import casadi
import numpy as np

from dynamics.robot import N_LINK_PARAMETERS, ByDescription, JointType, RobotModel


def _skew(vector: casadi.SX) -> casadi.SX:
    x, y, z = vector[0], vector[1], vector[2]
    return casadi.vertcat(
        casadi.horzcat(0, -z, y),
        casadi.horzcat(z, 0, -x),
        casadi.horzcat(-y, x, 0),
    )


def _inertia_map(w: casadi.SX) -> casadi.SX:
    """``L(w)`` with ``I w = L(w) [Ixx, Ixy, Iyy, Ixz, Iyz, Izz]ᵀ``."""
    wx, wy, wz = w[0], w[1], w[2]
    return casadi.vertcat(
        casadi.horzcat(wx, wy, 0, wz, 0, 0),
        casadi.horzcat(0, wx, wy, 0, wz, 0),
        casadi.horzcat(0, 0, 0, wx, wy, wz),
    )


def _rodrigues(axis: np.ndarray, angle: casadi.SX) -> casadi.SX:
    """Rotation by ``angle`` about the unit ``axis``: ``u uᵀ + cos (1 − u uᵀ) + sin [u]×``.

    Built entry by entry with the zero coefficients left out, so that an axis-aligned joint
    gives the plain ``cos``/``sin`` matrix (fewer operations in the generated code).
    """
    outer = np.outer(axis, axis)
    skew = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    identity = np.eye(3)
    cos, sin = casadi.cos(angle), casadi.sin(angle)
    rotation = casadi.SX.zeros(3, 3)
    for row in range(3):
        for column in range(3):
            entry = casadi.SX(0)
            if abs(outer[row, column]) > 1e-15:
                entry += outer[row, column]
            if abs(identity[row, column] - outer[row, column]) > 1e-15:
                entry += (identity[row, column] - outer[row, column]) * cos
            if abs(skew[row, column]) > 1e-15:
                entry += skew[row, column] * sin
            rotation[row, column] = entry
    return rotation


def link_regressor(velocity: casadi.SX, acceleration: casadi.SX) -> casadi.SX:
    """The 6x10 matrix ``A`` with ``(f, n) = A π`` for one rigid body (eq. 1).

    ``velocity``/``acceleration`` are spatial ``(linear, angular)`` at the frame origin; the
    result gives the net force and the net moment about the origin, in the same frame.
    """
    linear_velocity, omega = velocity[0:3], velocity[3:6]
    alpha = acceleration[3:6]
    classical = acceleration[0:3] + casadi.cross(omega, linear_velocity)  # acceleration of the origin
    omega_skew = _skew(omega)
    zeros31 = casadi.SX.zeros(3, 1)
    force = casadi.horzcat(classical, _skew(alpha) + omega_skew @ omega_skew, casadi.SX.zeros(3, 6))
    moment = casadi.horzcat(
        zeros31, -_skew(classical), _inertia_map(alpha) + omega_skew @ _inertia_map(omega)
    )
    return casadi.vertcat(force, moment)


@dataclass(frozen=True)
class RigidBodyRegressors:
    """Symbolic regressors of the rigid-body dynamics in the standard parameters (``10 n`` columns).

    Attributes
    ----------
    q, dq, ddq
        The ``n x 1`` symbols.
    joint
        ``n x 10n``: ``tau = joint @ theta`` (eq. 11–12).
    wrench
        ``6 x 10n``: ``(fx, fy, fz, mx, my, mz) = wrench @ theta`` (eq. 9–10).
    """

    q: casadi.SX
    dq: casadi.SX
    ddq: casadi.SX
    joint: casadi.SX
    wrench: casadi.SX


def rigid_body_regressors(robot: RobotModel) -> RigidBodyRegressors:
    """Build the symbolic internal and external regressors of ``robot`` by recursive Newton–Euler.

    Built once per robot description (:class:`~dynamics.robot.ByDescription`, cached): a robot read again, or
    another robot with the same joints, bodies and gravity, gets the same (immutable) expressions.
    """
    return _rigid_body_regressors(ByDescription(robot))


@functools.lru_cache(maxsize=32)
def _rigid_body_regressors(described: ByDescription) -> RigidBodyRegressors:
    robot = described.robot
    n = robot.n_joints
    q = casadi.SX.sym("q", n)
    dq = casadi.SX.sym("dq", n)
    ddq = casadi.SX.sym("ddq", n)

    velocity = casadi.SX.zeros(6, 1)
    acceleration = casadi.vertcat(casadi.DM(-robot.gravity), casadi.DM.zeros(3))
    joint_blocks = [[casadi.SX.zeros(1, N_LINK_PARAMETERS)] * n for _ in range(n)]
    axes: list[casadi.SX | casadi.DM] = []  # X_{j←i} S_i for i <= j, in the current link frame F_j
    base_axes = [casadi.DM.eye(6)[:, k] for k in range(6)]  # X_{j←0} e_k, in F_j
    wrench_blocks = []
    for index, joint in enumerate(robot.joints):
        rotation_a, position_a = casadi.DM(joint.placement[:3, :3]), casadi.DM(joint.placement[:3, 3])
        rotation_b, position_b = joint.link_transform[:3, :3], joint.link_transform[:3, 3]
        if joint.joint_type is JointType.REVOLUTE:
            rotation_joint, position_joint = _rodrigues(joint.axis, q[index]), casadi.SX.zeros(3, 1)
        else:
            rotation_joint, position_joint = casadi.SX.eye(3), casadi.DM(joint.axis) * q[index]
        # F_{i-1} -> F_i: rotation of F_i in F_{i-1}, origin of F_i in F_{i-1}
        rotation = rotation_a @ rotation_joint @ casadi.DM(rotation_b)
        position = position_a + rotation_a @ (position_joint + rotation_joint @ casadi.DM(position_b))
        axis_in_link = rotation_b.T @ joint.axis
        if joint.joint_type is JointType.REVOLUTE:
            point_on_axis = -rotation_b.T @ position_b
            subspace = np.concatenate([np.cross(point_on_axis, axis_in_link), axis_in_link])
        else:
            subspace = np.concatenate([axis_in_link, np.zeros(3)])
        subspace = casadi.DM(subspace)

        velocity = _transform_motion(rotation, position, velocity) + subspace * dq[index]
        acceleration = (
            _transform_motion(rotation, position, acceleration)
            + subspace * ddq[index]
            + _cross_motion(velocity, subspace * dq[index])
        )
        link_matrix = link_regressor(velocity, acceleration)
        # eq. 11 for every joint i <= index at once: S_iᵀ X*_{i←j} A_j = (X_{j←i} S_i)ᵀ A_j
        axes = [_transform_motion(rotation, position, axis) for axis in axes] + [subspace]
        for row, axis in enumerate(axes):
            joint_blocks[row][index] = axis.T @ link_matrix
        base_axes = [_transform_motion(rotation, position, axis) for axis in base_axes]
        wrench_blocks.append(casadi.vertcat(*(axis.T @ link_matrix for axis in base_axes)))
    joint = casadi.densify(casadi.vertcat(*(casadi.horzcat(*blocks) for blocks in joint_blocks)))
    wrench = casadi.densify(casadi.horzcat(*wrench_blocks))
    return RigidBodyRegressors(q, dq, ddq, joint, wrench)


def _transform_motion(rotation: casadi.SX, position: casadi.SX, motion: casadi.SX) -> casadi.SX:
    """Motion vector at the origin of ``F_{i-1}`` to the origin of ``F_i``, in ``F_i``."""
    linear, angular = motion[0:3], motion[3:6]
    return casadi.vertcat(
        rotation.T @ (linear + casadi.cross(angular, position)),
        rotation.T @ angular,
    )


def _cross_motion(velocity: casadi.SX, motion: casadi.SX) -> casadi.SX:
    """Spatial cross product ``v × m`` of motion vectors (linear, angular)."""
    linear, angular = velocity[0:3], velocity[3:6]
    return casadi.vertcat(
        casadi.cross(angular, motion[0:3]) + casadi.cross(linear, motion[3:6]),
        casadi.cross(angular, motion[3:6]),
    )
