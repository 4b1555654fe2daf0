"""Synthetic measurements straight from a model: known parameters, the model's own prediction, channel noise.

Where :class:`dynamics.simulation.simulator.Simulator` integrates the robot under a controller and measures it
with a sensor model, :func:`simulate` takes the identification model at its word: the channels are ``Y(q, dq,
ddq) θ`` along a trajectory, plus white noise (and constant biases) per channel. With :func:`true_parameters`
(known ``θ``) and a trajectory such as :func:`oed.fourier.random_fourier`, it makes the experiments on which an
estimator must give back what was put in::

    model = build_model(load_robot("puma560", joints=3), "internal", "viscous")
    theta = true_parameters(model, seed=0)
    train = simulate(model, theta, random_fourier(model.robot, seed=1), noise={"tau1": 0.5})
"""

from __future__ import annotations

from typing import Any, Protocol

import numpy as np
from numpy.typing import NDArray

from dynamics.channels import is_joint_torque
from dynamics.measurements import Measurements
from dynamics.models import IdentificationModel

__all__ = ["SampledTrajectory", "simulate", "true_parameters"]


class SampledTrajectory(Protocol):
    """A periodic trajectory sampled on a uniform grid (as :class:`oed.fourier.FourierTrajectory`)."""

    frequency_hz: float

    def sample(self, rate_hz: float = ..., periods: int = ...) -> tuple[NDArray[np.float64], ...]:
        """``t, q, dq, ddq`` over whole periods."""
        ...


def true_parameters(model: IdentificationModel, seed: int = 0, **effect_values: Any) -> NDArray[np.float64]:
    """Parameters to recover: the robot's standard parameters perturbed by ±20 % (uniform, ``seed``), viscous
    friction drawn in 2–10, the other effects' parameters as given by name (``coulomb=…``), else zero.

    Returns the full parameter vector of ``model`` (:meth:`dynamics.models.IdentificationModel.nominal_parameters`
    order: rigid body, then the effects').
    """
    generator = np.random.default_rng(seed)
    rigid = model.robot.standard_parameters * generator.uniform(0.8, 1.2, model.robot.standard_parameters.shape)
    n = model.robot.n_joints
    defaults = {"viscous": generator.uniform(2.0, 10.0, n)}
    defaults.update(effect_values)
    values = {effect.name: defaults.get(effect.name, 0.0) for effect in model.effects}
    theta = model.nominal_parameters(**values)
    theta[: rigid.shape[0]] = rigid
    return theta


def simulate(model: IdentificationModel, theta: NDArray[np.float64], trajectory: SampledTrajectory, *,
             rate_hz: float = 200.0, periods: int = 1, noise: dict[str, float] | None = None,
             seed: int = 1, bias: dict[str, float] | None = None) -> Measurements:
    """``Y θ`` along ``trajectory`` plus white noise of the given standard deviation per channel (and constant
    biases), as measurements with ``q, dq, ddq`` exact.

    Parameters
    ----------
    model, theta
        The identification model and its full parameter vector.
    trajectory
        Sampled at ``rate_hz`` (Hz) over ``periods`` periods; its ``frequency_hz`` goes to the metadata.
    noise, bias
        Standard deviation and constant offset by channel name (``tau1``, ``fx``…); channels not named get none.
    seed
        Seed of the noise.
    """
    t, q, dq, ddq = trajectory.sample(rate_hz, periods)
    values = model.predict(theta, q, dq, ddq)
    generator = np.random.default_rng(seed)
    for index, channel in enumerate(model.channels):
        values[:, index] += (bias or {}).get(channel, 0.0)
        values[:, index] += generator.normal(0.0, (noise or {}).get(channel, 0.0), t.shape[0])
    n = model.robot.n_joints
    tau = wrench = None
    if any(map(is_joint_torque, model.channels)):
        tau = values[:, [model.channels.index(f"tau{j}") for j in range(1, n + 1)]]
    if "fx" in model.channels:
        wrench = values[:, [model.channels.index(c) for c in ("fx", "fy", "fz", "mx", "my", "mz")]]
    return Measurements(t, q, dq, ddq, tau, wrench, {"frequency_hz": trajectory.frequency_hz})
