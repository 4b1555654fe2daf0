"""The simulated robot's plant: Pinocchio forward dynamics under the joint effects, integrated by RK4.

Between samples the controller's torque ``τ_k`` is held (zero-order hold) and the state advances
by ``substeps`` classic Runge–Kutta steps of ``h = 1 / (rate · substeps)`` of

    (M(q) + diag(Ia)) ddq + h(q, dq) + Σ_e τ_e(q, dq) = τ                   (pinocchio.aba)

(:class:`dynamics.simulation.simulator.Simulator` adds the reference, the base wrench and the sensors).
"""

from __future__ import annotations

import functools
from collections.abc import Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray

from dynamics.pinocchio_bridge import to_pinocchio
from dynamics.robot import RobotModel
from dynamics.simulation.controllers import Controller
from dynamics.simulation.effects import SimulatedArmature

__all__ = ["Plant"]


class Plant:
    """The robot in Pinocchio with its true parameters and joint effects, integrated by RK4 with the
    torque held over each sample.

    Parameters
    ----------
    robot, theta
        The chain and its true standard parameters (``10 n``).
    joint_effects
        The simulated joint effects (:mod:`dynamics.simulation.effects`): their torques are subtracted
        from the applied one, their armature is added to the mass matrix.
    rate_hz
        Sampling (and control) rate.
    """

    def __init__(self, robot: RobotModel, theta: Sequence[float], joint_effects: Sequence[Any], rate_hz: float) -> None:
        import pinocchio as pin

        self.robot, self.rate_hz = robot, rate_hz
        model = to_pinocchio(robot, theta=theta)
        model.armature = sum((effect.armature(robot) for effect in joint_effects), np.zeros(robot.n_joints))
        data = model.createData()
        self.forward_dynamics = functools.partial(pin.aba, model, data)
        self.mass_matrix = functools.partial(pin.crba, model, data)
        self.joint_effects = [effect for effect in joint_effects if not isinstance(effect, SimulatedArmature)]  # armature: in M

    def acceleration(self, q: NDArray, dq: NDArray, tau: NDArray) -> NDArray:
        """``ddq = aba(q, dq, τ − Σ_e τ_e(q, dq))``."""
        for effect in self.joint_effects:
            tau = tau - effect.joint_torque(self.robot, q, dq)
        return self.forward_dynamics(q, dq, tau).copy()

    def check_mass_matrix(self, q: NDArray) -> None:
        """Refuse a mass matrix singular at ``q`` (a joint that moves no mass or inertia)."""
        upper = np.triu(self.mass_matrix(q))  # CRBA fills the upper triangle
        inertia = np.linalg.eigvalsh(upper + np.triu(upper, 1).T)
        if not inertia[0] > 1e-12 * max(inertia[-1], 1e-300):
            raise ValueError(f"the mass matrix is singular at the start (eigenvalues {inertia[0]:.3g} … {inertia[-1]:.3g}): "
                             "a joint moves no mass or inertia (a massless link in the description?); "
                             "the robot cannot be simulated")

    def track(self, controller: Controller, t: NDArray, reference: tuple[NDArray, NDArray, NDArray],
              state: tuple[NDArray, NDArray], substeps: int) -> tuple[NDArray, NDArray, NDArray, NDArray]:
        """The true ``q, dq, ddq`` and the applied ``τ`` at every sample of ``t``, the controller
        tracking ``reference = (q_d, dq_d, ddq_d)`` from ``state = (q, dq)``."""
        q_d, dq_d, ddq_d = reference
        q, dq = state
        n = self.robot.n_joints
        Q, DQ, DDQ, TAU = (np.empty((t.shape[0], n)) for _ in range(4))
        h = 1.0 / (self.rate_hz * substeps)
        for k in range(t.shape[0]):
            tau = np.asarray(controller.torque(t[k], q, dq, q_d[k], dq_d[k], ddq_d[k]), dtype=float).reshape(n)
            a1 = self.acceleration(q, dq, tau)
            Q[k], DQ[k], DDQ[k], TAU[k] = q, dq, a1, tau
            q, dq = self.held_step(q, dq, tau, a1, h, substeps)
            if not (np.isfinite(q).all() and np.isfinite(dq).all() and (np.abs(dq) < 1e4).all()):  # methods: a step's cost
                with np.errstate(all="ignore"):
                    peak = np.max(np.abs(np.nan_to_num(dq_d, nan=np.inf)), axis=0)
                raise RuntimeError(
                    f"simulation diverged at t = {t[k]:.3f} s (joint velocities {np.array2string(dq, precision=3)}); "
                    f"lower the controller gains or raise rate_hz/substeps, or check the reference (its peak "
                    f"velocities {np.array2string(peak, precision=3)} rad/s)"
                )
        return Q, DQ, DDQ, TAU

    def held_step(self, q: NDArray, dq: NDArray, tau: NDArray, a1: NDArray, h: float, substeps: int
                  ) -> tuple[NDArray, NDArray]:
        """``substeps`` classic RK4 steps of ``h`` under the held torque ``tau`` (``a1``: the
        acceleration at ``q, dq``); the state at the next sample."""
        for step in range(substeps):
            if step:
                a1 = self.acceleration(q, dq, tau)
            v2 = dq + 0.5 * h * a1
            a2 = self.acceleration(q + 0.5 * h * dq, v2, tau)
            v3 = dq + 0.5 * h * a2
            a3 = self.acceleration(q + 0.5 * h * v2, v3, tau)
            v4 = dq + h * a3
            a4 = self.acceleration(q + h * v3, v4, tau)
            q = q + h / 6 * (dq + 2 * v2 + 2 * v3 + v4)
            dq = dq + h / 6 * (a1 + 2 * a2 + 2 * a3 + a4)
        return q, dq
