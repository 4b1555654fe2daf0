"""Synthetic measurements straight from a model: known parameters, Fourier motion, channel noise."""

from __future__ import annotations

import numpy as np

from dynamics.models import IdentificationModel
from dynamics.robot import RobotModel
from dynamics.measurements import Measurements
from oed.fourier import FourierTrajectory


def random_fourier(robot: RobotModel, seed: int, *, frequency_hz: float = 0.2, harmonics: int = 5,
                   fill: float = 0.8) -> FourierTrajectory:
    """Random coefficients scaled so that positions and velocities stay within ``fill`` of the bounds."""
    generator = np.random.default_rng(seed)
    n = robot.n_joints
    centre = 0.5 * (robot.lower + robot.upper)
    half_range = 0.5 * (robot.upper - robot.lower)
    a = generator.normal(size=(n, harmonics))
    b = generator.normal(size=(n, harmonics))
    trajectory = FourierTrajectory(frequency_hz, centre, a, b)
    _, q, dq, _ = trajectory.sample(200.0 * frequency_hz * harmonics, 1)
    deviation = np.max(np.abs(q - q.mean(axis=0)), axis=0)
    speed = np.max(np.abs(dq), axis=0)
    scale = fill * np.minimum(half_range / deviation, robot.velocity_limit / speed)
    return FourierTrajectory(frequency_hz, centre, a * scale[:, None], b * scale[:, None])


def true_parameters(model: IdentificationModel, seed: int = 0, **effect_values) -> np.ndarray:
    """The robot's standard parameters perturbed by ±20 %, viscous friction 2–10, other effects as given."""
    generator = np.random.default_rng(seed)
    rigid = model.robot.standard_parameters * generator.uniform(0.8, 1.2, model.robot.standard_parameters.shape)
    n = model.robot.n_joints
    defaults = {"viscous": generator.uniform(2.0, 10.0, n)}
    defaults.update(effect_values)
    values = {effect.name: defaults.get(effect.name, 0.0) for effect in model.effects}
    theta = model.nominal_parameters(**values)
    theta[: rigid.shape[0]] = rigid
    return theta


def simulate(model: IdentificationModel, theta: np.ndarray, trajectory: FourierTrajectory, *,
             rate_hz: float = 200.0, periods: int = 1, noise: dict[str, float] | None = None,
             seed: int = 1, bias: dict[str, float] | None = None) -> Measurements:
    """``Y θ`` plus white noise of the given standard deviation per channel (and constant biases)."""
    t, q, dq, ddq = trajectory.sample(rate_hz, periods)
    values = model.predict(theta, q, dq, ddq)
    generator = np.random.default_rng(seed)
    for index, channel in enumerate(model.channels):
        values[:, index] += (bias or {}).get(channel, 0.0)
        values[:, index] += generator.normal(0.0, (noise or {}).get(channel, 0.0), t.shape[0])
    n = model.robot.n_joints
    tau = wrench = None
    if any(channel.startswith("tau") for channel in model.channels):
        tau = values[:, [model.channels.index(f"tau{j}") for j in range(1, n + 1)]]
    if "fx" in model.channels:
        wrench = values[:, [model.channels.index(c) for c in ("fx", "fy", "fz", "mx", "my", "mz")]]
    return Measurements(t, q, dq, ddq, tau, wrench, {"frequency_hz": trajectory.frequency_hz})
