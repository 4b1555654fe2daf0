"""Records of robots with a passive (unactuated) joint, simulated for ``tests/test_passive_joints.py``.

The actuated joints follow a prescribed motion (a random Fourier series, :func:`oed.fourier.random_fourier`, as a
position-controlled arm would); the passive joint moves as the dynamics make it move: its torque is zero, so
``M_pp(q) q̈_p = -(h_p(q, q̇, q̈_a) + f_v q̇_p + f_c sign q̇_p)`` (the rigid-body terms by Pinocchio's ``rnea`` and
``crba`` on the true bodies), integrated by the classical Runge-Kutta scheme at a quarter of the log's step from
rest at the middle of its range. The logged torques of the actuated joints are the truth's inverse dynamics (rigid
body, viscous, Coulomb, offset) along that motion, with white noise of 2 % of each channel's spread; the passive
joint's torque is zero by physics (no sensor, no offset, no noise).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pandas as pd

from dynamics.models import build_model
from dynamics.pinocchio_bridge import to_pinocchio
from dynamics.robots import load_robot
from dynamics.urdf_export import robot_urdf
from oed.fourier import random_fourier
from tests.test_unseen_robots import FRICTION, NOISE, truth


@dataclass(frozen=True)
class Passive:
    """One case: the robot (a callable), its passive joint (0-based), the seconds of each record and its rate, and
    whether the passive joint's column is written (``tau`` of zeros) or left out of the file."""

    name: str
    robot: object
    passive: int
    seconds: tuple[float, float, float] = (12.0, 5.0, 8.0)
    rate_hz: float = 250.0
    passive_coulomb: float = 0.05  # the passive joint's Coulomb friction (N m): a free joint's bearing
    passive_viscous: float | None = None  # its viscous friction (N m s); ``None``: the truth's draw


def true_parameters(case: Passive, folder: Path) -> tuple[object, np.ndarray]:
    """The truth's robot (bodies ±20 % in the frames of the description written as URDF) and its parameters:
    :func:`tests.test_unseen_robots.truth`, the passive joint's offset zero, its Coulomb friction
    ``case.passive_coulomb`` and its viscous friction ``case.passive_viscous`` (when given)."""
    urdf = folder / "true_bodies.urdf"
    urdf.write_text(robot_urdf(case.robot()))
    robot = load_robot(urdf=urdf)
    model = build_model(robot, "internal", FRICTION)
    theta = truth(model)
    names = list(model.parameter_names)
    p = case.passive + 1
    theta[names.index(f"off{p}")] = 0.0
    theta[names.index(f"fc{p}")] = case.passive_coulomb
    if case.passive_viscous is not None:
        theta[names.index(f"fv{p}")] = case.passive_viscous
    return robot, theta


def friction(theta: np.ndarray, names: list[str], dq: np.ndarray) -> np.ndarray:
    """``(N, n)`` viscous + Coulomb + offset of every joint along ``dq``."""
    n = dq.shape[1]
    value = np.zeros_like(dq)
    for j in range(n):
        value[:, j] = (theta[names.index(f"fv{j + 1}")] * dq[:, j] + theta[names.index(f"fc{j + 1}")]
                       * np.sign(dq[:, j]) + theta[names.index(f"off{j + 1}")])
    return value


def simulated(case: Passive, robot, theta: np.ndarray, seed: int, seconds: float
              ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """``(t, q, dq, ddq, tau)`` of one record: the actuated joints' Fourier motion, the passive joint integrated."""
    import pinocchio as pin

    n, p = robot.n_joints, case.passive
    names = list(build_model(robot, "internal", FRICTION).parameter_names)
    bodies = robot.with_parameters(theta[: 10 * n])
    pinocchio_model = to_pinocchio(bodies)
    data = pinocchio_model.createData()
    limits = SimpleNamespace(n_joints=n, lower=np.asarray(robot.lower, float), upper=np.asarray(robot.upper, float),
                             velocity_limit=np.asarray(robot.velocity_limit, float))
    trajectory = random_fourier(limits, seed=seed, frequency_hz=0.2)
    step = 1.0 / case.rate_hz
    substeps = 4
    h = step / substeps
    t_fine = np.arange(0.0, seconds + step, h / 2)
    q_a, dq_a, ddq_a = trajectory.evaluate(t_fine)
    fv, fc = theta[names.index(f"fv{p + 1}")], theta[names.index(f"fc{p + 1}")]

    def acceleration(k: int, position: float, speed: float) -> float:
        q, dq, ddq = q_a[k].copy(), dq_a[k].copy(), ddq_a[k].copy()
        q[p], dq[p], ddq[p] = position, speed, 0.0
        bias = pin.rnea(pinocchio_model, data, q, dq, ddq)[p]
        inertia = pin.crba(pinocchio_model, data, q)[p, p]
        return -(bias + fv * speed + fc * np.sign(speed)) / inertia

    count = int(round(seconds / step))
    position, speed = 0.5 * (limits.lower[p] + limits.upper[p]), 0.0
    states = np.zeros((count, 2))
    for i in range(count * substeps):
        if i % substeps == 0:
            states[i // substeps] = position, speed
        k = 2 * i
        k1 = speed, acceleration(k, position, speed)
        k2 = speed + h / 2 * k1[1], acceleration(k + 1, position + h / 2 * k1[0], speed + h / 2 * k1[1])
        k3 = speed + h / 2 * k2[1], acceleration(k + 1, position + h / 2 * k2[0], speed + h / 2 * k2[1])
        k4 = speed + h * k3[1], acceleration(k + 2, position + h * k3[0], speed + h * k3[1])
        position += h / 6 * (k1[0] + 2 * k2[0] + 2 * k3[0] + k4[0])
        speed += h / 6 * (k1[1] + 2 * k2[1] + 2 * k3[1] + k4[1])
    rows = np.arange(count) * 2 * substeps
    t = t_fine[rows]
    q, dq, ddq = q_a[rows].copy(), dq_a[rows].copy(), ddq_a[rows].copy()
    q[:, p], dq[:, p] = states[:, 0], states[:, 1]
    ddq[:, p] = [acceleration(k, *state) for k, state in zip(rows, states)]
    tau = np.array([pin.rnea(pinocchio_model, data, q[i], dq[i], ddq[i]) for i in range(count)])
    tau = tau + friction(theta, names, dq)
    return t, q, dq, ddq, tau


def write_passive_records(case: Passive, folder: Path, *, written_zero: bool = False, urdf_text: str | None = None
                          ) -> tuple[Path, dict, dict, np.ndarray]:
    """The description and the three records (train, validate, test of different motions) as a logger writes them:
    ``t, q1.., tau..`` without the passive joint's torque column (or with a column of zeros, ``written_zero``);
    ``(urdf, records, files, spread)``, the records the plain fit reads holding the passive joint's torque as 0."""
    from benchmarks.bench_real_robots import Record

    robot = case.robot()
    urdf = folder / "robot.urdf"
    urdf.write_text(urdf_text if urdf_text is not None else robot_urdf(robot))
    true_robot, theta = true_parameters(case, folder)
    spread, records, files = None, {}, {}
    for role, seconds, seed in zip(("train", "validate", "test"), case.seconds, (11, 12, 13)):
        generator = np.random.default_rng(1000 + seed)
        t, q, dq, _, tau = simulated(case, true_robot, theta, seed, seconds)
        if spread is None:
            spread = tau.std(axis=0)
        noise = generator.normal(0.0, 1.0, tau.shape) * NOISE * spread
        noise[:, case.passive] = 0.0
        tau = tau + noise
        tau[:, case.passive] = 0.0  # by physics: no torque acts on a free joint (its friction is in the model)
        frame = {"t": t, **{f"q{j + 1}": q[:, j] for j in range(robot.n_joints)}}
        frame.update({f"tau{j + 1}": tau[:, j] for j in range(robot.n_joints) if written_zero or j != case.passive})
        files[role] = folder / f"{role}.csv"
        pd.DataFrame(frame).to_csv(files[role], index=False, float_format="%.10g")
        records[role] = Record(t, q, tau, None)
    return urdf, records, files, spread
