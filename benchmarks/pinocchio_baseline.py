"""The regressor a user without this toolkit computes: Pinocchio in a Python loop over the samples.

Shared by the benchmarks whose baseline is "plain numpy/Pinocchio": ``pinocchio.computeJointTorqueRegressor``
on the free-flyer model with the root held still (its first six rows are the base wrench, the others
the joint torques), Pinocchio's joint-frame inertial parameters mapped to ours (link frames), viscous
friction columns added in numpy, and the base-column selection of our model.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin
from numpy.typing import NDArray

from dynamics.pinocchio_bridge import to_pinocchio


def parameter_map(robot) -> NDArray[np.float64]:
    """``(10 n, 10 n)`` map from our standard parameters (link frames) to Pinocchio's (joint frames)."""
    reference = np.array([2.0, 0, 0, 0, 5.0, 0, 5.0, 0, 0, 5.0])
    blocks = []
    for joint in robot.joints:
        placement = pin.SE3(joint.link_transform)

        def to_joint(parameters, placement=placement):
            return pin.Inertia.FromDynamicParameters(parameters).se3Action(placement).toDynamicParameters()

        base = to_joint(reference)
        blocks.append(np.column_stack([to_joint(reference + np.eye(10)[k]) - base for k in range(10)]))
    n = robot.n_joints
    mapping = np.zeros((10 * n, 10 * n))
    for index, block in enumerate(blocks):
        mapping[10 * index : 10 * index + 10, 10 * index : 10 * index + 10] = block
    return mapping


class PinocchioRegressor:
    """``(q, dq, ddq) -> Y`` of a rigid-body model with optional viscous friction, by a Pinocchio loop.

    Parameters
    ----------
    model
        Our identification model (:func:`dynamics.models.build_model`); only its robot, channels,
        effects and base columns are used. Supported: internal, external or combined rows, rigid
        parameters plus at most viscous friction.
    """

    def __init__(self, model) -> None:
        robot = model.robot
        effects = {effect.name for effect in model.effects}
        if not effects <= {"viscous"}:
            raise ValueError(f"the Pinocchio baseline covers rigid bodies and viscous friction, not {sorted(effects)}")
        self.n = robot.n_joints
        self.pin_model = to_pinocchio(robot, free_flyer=True)
        self.pin_data = self.pin_model.createData()
        self.mapping = parameter_map(robot)
        self.viscous = "viscous" in effects
        channels = tuple(model.channels)
        self.wrench_rows = channels[:1] == ("fx",)
        self.joint_rows = channels[-1].startswith("tau")
        self.rows = np.r_[np.arange(6)[: 6 if self.wrench_rows else 0], 6 + np.arange(self.n)[: self.n if self.joint_rows else 0]]
        self.independent = list(model.base.independent)
        self.root = np.array([0, 0, 0, 0, 0, 0, 1.0])

    def full(self, q: NDArray, dq: NDArray, ddq: NDArray) -> NDArray[np.float64]:
        """``(N, rows, 10 n [+ n])``: the standard regressor of every sample."""
        n, samples = self.n, len(q)
        Y = np.zeros((samples, 6 + n, 10 * n + (n if self.viscous else 0)))
        zeros = np.zeros(6)
        for k in range(samples):
            regressor = pin.computeJointTorqueRegressor(
                self.pin_model, self.pin_data, np.concatenate([self.root, q[k]]),
                np.concatenate([zeros, dq[k]]), np.concatenate([zeros, ddq[k]]),
            )
            Y[k, :, : 10 * n] = regressor[:, 10:] @ self.mapping
        if self.viscous:
            Y[:, 6 + np.arange(n), 10 * n + np.arange(n)] = dq
        return Y[:, self.rows, :]

    def base(self, q: NDArray, dq: NDArray, ddq: NDArray) -> NDArray[np.float64]:
        """``(N, rows, r)``: the base regressor (our base columns) of every sample."""
        return self.full(q, dq, ddq)[:, :, self.independent]
