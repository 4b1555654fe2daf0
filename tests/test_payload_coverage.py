"""Monte Carlo: the payload's 95 % intervals (the record's noise and the robot model's own uncertainty together)
cover the body put in 90–99 % of the time, the robot's model identified anew on each draw."""

from __future__ import annotations

import numpy as np
import pytest

from dynamics.simulation.synthetic import simulate
from estimation.payload import PayloadBody, identify_payload
from oed.fourier import random_fourier
from tests.test_payload import PAYLOAD, puma_with_payload, robot_model_file

Z_95 = 1.959963984540054
TRIALS = 100
RATE_HZ = 200.0


def coverage(trials: int = TRIALS) -> np.ndarray:
    """``(trials, 10)``: whether each body value (mass, centre of mass, inertia about it) lay in its 95 % interval."""
    model, theta, loaded, noise = puma_with_payload()
    robot = model.robot
    truth = PayloadBody(PAYLOAD, np.zeros((10, 10))).values
    training, excitation = random_fourier(robot, seed=1, frequency_hz=0.1), random_fourier(robot, seed=7, frequency_hz=0.1)
    inside = []
    for trial in range(trials):
        train = simulate(model, theta, training, rate_hz=RATE_HZ, periods=2, noise=noise, seed=1000 + trial)
        record = simulate(model, loaded, excitation, rate_hz=RATE_HZ, noise=noise, seed=5000 + trial)
        body = identify_payload(robot_model_file(model, train), record).body
        inside.append(np.abs(body.values - truth) <= Z_95 * body.values_std)
    return np.array(inside)


@pytest.mark.slow
def test_payload_intervals_cover_about_95_percent():
    inside = coverage()
    assert 0.90 <= inside[:, :4].mean() <= 0.99  # mass and centre of mass
    assert 0.90 <= inside.mean() <= 0.99  # all ten
