"""The true motor-side friction of a simulated robot with a transmission (a coupled wrist).

Each motor ``k`` turns at ``θ̇_mk = r_k q̇`` (``r_k`` the row ``k`` of the transmission's ``R``,
:mod:`dynamics.transmission`) and dissipates ``τ_mk = fv_k θ̇_mk + fc_k tanh(θ̇_mk / s_k)``; the
joints feel ``τ = Rᵀ τ_m``::

    tau_applied = M(q) ddq + h(q, dq) + Rᵀ τ_m(R dq)  (+ the other joint effects)

With a coupled wrist one motor's friction acts on two or three joint rows at once. The smoothing
``s_k`` is a motor-side velocity (the integrator needs a continuous law, as for
:class:`dynamics.simulation.joint_effects.Coulomb`); the identification model
:class:`dynamics.effects.motor.CombinationEffect` with the same ``smoothing`` reproduces it.

Rotor inertia is not simulated here: ``Rᵀ J R`` is not diagonal for a coupled wrist, and the
simulator adds armature to the mass matrix diagonal only (use
:class:`dynamics.simulation.joint_effects.SimulatedArmature` with ``diag(Rᵀ J R)``).

PUMA 560 defaults (:meth:`MotorFriction.default`): the motor data of Corke's Robotics Toolbox
(``mdl_puma560``: viscous ``B``, Coulomb ``(Tc⁺ − Tc⁻)/2``) and
:func:`dynamics.transmission.puma560_transmission`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np
from numpy.typing import NDArray

from dynamics.robot import RobotModel
from dynamics.simulation.joint_effects import PUMA560_MOTOR_COULOMB, PUMA560_MOTOR_VISCOUS, finite_floats, is_puma560
from dynamics.transmission import Transmission, puma560_transmission


@dataclass(frozen=True)
class MotorFriction:
    """Viscous and Coulomb friction of each motor of a transmission (motor-side values, SI).

    Parameters
    ----------
    matrix
        The transmission's ``R`` (rows: motors), as nested tuples.
    viscous, coulomb
        ``fv_k`` (N·m·s/rad) and ``fc_k`` (N·m) per motor, non-negative.
    smoothing
        Motor-side velocity (rad/s) of the ``tanh`` Coulomb law, one per motor or one for all.
    """

    matrix: tuple[tuple[float, ...], ...]
    viscous: tuple[float, ...]
    coulomb: tuple[float, ...]
    smoothing: tuple[float, ...] = (1.0,)
    name: ClassVar[str] = "motor_friction"

    def __post_init__(self) -> None:
        matrix = Transmission(np.array(self.matrix, dtype=float)).matrix  # checks square, finite, invertible
        n = matrix.shape[0]
        object.__setattr__(self, "matrix", tuple(tuple(float(v) for v in row) for row in matrix))
        for label in ("viscous", "coulomb", "smoothing"):
            values = np.broadcast_to(np.asarray(finite_floats(getattr(self, label), f"motor {label}")), (n,))
            if label == "smoothing" and not np.all(values > 0):
                raise ValueError("motor Coulomb smoothing must be positive velocities")
            if np.any(values < 0):
                raise ValueError(f"motor {label} friction must be non-negative, got {values.tolist()}")
            object.__setattr__(self, label, tuple(float(v) for v in values))

    @property
    def transmission(self) -> Transmission:
        return Transmission(np.array(self.matrix))

    def _check(self, robot: RobotModel) -> NDArray[np.float64]:
        matrix = np.array(self.matrix)
        if matrix.shape[0] != robot.n_joints:
            raise ValueError(f"effect 'motor_friction': {matrix.shape[0]} motors for a robot of {robot.n_joints} joints")
        return matrix

    def channels(self, robot: RobotModel) -> tuple[str, ...]:
        matrix = self._check(robot)
        return tuple(f"tau{index + 1}" for index in np.flatnonzero(np.any(matrix != 0, axis=0)))

    def parameters(self, robot: RobotModel) -> dict[str, float]:
        """True values named as :func:`dynamics.effects.motor.motor_effects` names them (``fvm6``, ``fcm6``)."""
        self._check(robot)
        named = {f"fvm{index}": value for index, value in enumerate(self.viscous, start=1)}
        named.update({f"fcm{index}": value for index, value in enumerate(self.coulomb, start=1)})
        return named

    def armature(self, robot: RobotModel) -> NDArray[np.float64]:
        return np.zeros(robot.n_joints)

    def joint_torque(self, robot: RobotModel, q: NDArray, dq: NDArray) -> NDArray[np.float64]:
        matrix = self._check(robot)
        velocity = matrix @ dq
        torque_m = np.array(self.viscous) * velocity + np.array(self.coulomb) * np.tanh(velocity / np.array(self.smoothing))
        return matrix.T @ torque_m

    def damping(self, robot: RobotModel) -> NDArray[np.float64]:
        """Joint-side friction stiffness ``Σ_k R_kj² (fv_k + fc_k / s_k)`` (the simulator's step-size rule)."""
        matrix = self._check(robot)
        motor = np.array(self.viscous) + np.array(self.coulomb) / np.array(self.smoothing)
        return (matrix**2).T @ motor

    def model_effect(self) -> Any:
        return None

    @classmethod
    def default(cls, robot: RobotModel, *, smoothing: float = 1.0) -> MotorFriction:
        """The PUMA 560's motor friction and transmission (other robots: give the values)."""
        if not (is_puma560(robot) and robot.n_joints <= 6):
            raise ValueError("motor_friction has default values for the PUMA 560 only: give matrix, viscous, coulomb")
        n = robot.n_joints
        tc = np.array(PUMA560_MOTOR_COULOMB[:n])
        matrix = puma560_transmission(n).matrix
        return cls(tuple(map(tuple, matrix)), tuple(PUMA560_MOTOR_VISCOUS[:n]), tuple((tc[:, 0] - tc[:, 1]) / 2),
                   (smoothing,))
