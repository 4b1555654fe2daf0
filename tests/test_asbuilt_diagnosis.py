"""The robot as built, in the library: coupled friction found by the diagnosis, rest segments,
trivial predictors, the wording of a rejection that raises the validation error."""

from __future__ import annotations

import numpy as np
import pytest

from dynamics.models import build_model
from dynamics.effects.motor import CombinationEffect
from dynamics.robots import load_robot
from estimation.diagnosis.search import diagnose, provisional_stopping_rule
from estimation.identification.fit import identify
from dynamics.measurements import Measurements
from estimation.data.rest import coulomb_combinations, drop_rest, smooth_coulomb
from estimation.identification.trivial_predictors import trivial_mse, trivial_warnings
from dynamics.simulation.synthetic import simulate, true_parameters

from oed.fourier import random_fourier

NOISE = 0.2


@pytest.fixture(scope="module")
def robot():
    return load_robot("puma560", joints=3)


def _pair(label="q2+q3", row=(0.0, 1.0, 1.0)):
    return CombinationEffect("coulomb", (row,), (label,))


def _experiments(truth, theta, *, bias=None):
    noise = {channel: NOISE for channel in truth.channels}
    train = simulate(truth, theta, random_fourier(truth.robot, seed=3), noise=noise, seed=1, bias=bias)
    validate = simulate(truth, theta, random_fourier(truth.robot, seed=4), noise=noise, seed=2)
    return train, validate


def test_diagnosis_finds_friction_on_a_joint_combination(robot):
    truth = build_model(robot, "internal", ("viscous", _pair()))
    theta = true_parameters(truth, seed=0)
    theta[-1] = 3.0
    train, validate = _experiments(truth, theta)
    diagnosis = diagnose(build_model(robot, "internal", "viscous"), train, validate)
    names = [effect.name for effect in diagnosis.effects]
    assert names[0] == "coulomb[q2+q3]", names
    found = diagnosis.effects[0]
    assert found.channels == ("tau2", "tau3") and found.parameters == ("fc[q2+q3]",)
    assert abs(found.values[0] - 3.0) < 3 * found.std[0]
    for channel, value in diagnosis.after.validation.mse.items():
        assert value < 1.3 * NOISE**2, (channel, value)


def test_a_rejection_that_raises_the_validation_error_says_so(robot):
    truth = build_model(robot, "internal", "viscous")
    theta = true_parameters(truth, seed=0)
    train, validate = _experiments(truth, theta, bias={"tau1": 0.3})  # a bias in training only
    # the validation record sits at its noise floor: without the floor rule the search tries the offset
    diagnosis = diagnose(truth, train, validate, stopping_rule=provisional_stopping_rule)
    (offset,) = [r for r in diagnosis.rejected if r.name == "offset" and r.channels == ("tau1",)]
    assert "raises the validation error" in offset.reason and "lowers" not in offset.reason
    before, after = (float(x) for x in offset.reason.rsplit("(", 1)[1].rstrip(")").split(" -> "))
    assert after > before


def test_rest_rows_are_dropped_with_their_count(robot):
    truth = build_model(robot, "internal", "viscous")
    data = simulate(truth, true_parameters(truth), random_fourier(robot, seed=3), noise={"tau1": NOISE}, seed=1)
    selection = drop_rest(data, 0.05)
    slow = np.any(np.abs(data.dq) < 0.05, axis=1)
    assert selection.dropped == int(slow.sum()) > 0 and selection.measurements.n_samples == data.n_samples - selection.dropped
    assert selection.to_dict() == {"min_speed": 0.05, "dropped": selection.dropped, "total": data.n_samples,
                                   "kept": data.n_samples - selection.dropped}
    combined = drop_rest(data, 0.05, combinations=coulomb_combinations((_pair(),)))
    assert combined.dropped >= selection.dropped  # q2 + q3 slow counts too
    with pytest.raises(ValueError, match="lower it"):
        drop_rest(data, 100.0)
    smoothed = smooth_coulomb(("viscous", _pair()), 0.05)
    assert smoothed[1].smoothing == 0.05 and smoothed[0] == "viscous"


def test_rest_at_standstill_biases_sign_coulomb_and_dropping_cures_it(robot):
    """1.5 s at rest with filtered encoder noise on dq: sign(dq) flips the Coulomb column at random
    while the measured torque is the holding torque (here: gravity, friction 0)."""
    truth = build_model(robot, "internal", ("viscous", "coulomb"))
    theta = true_parameters(truth, seed=0, coulomb=[5.0, 4.0, 3.0])
    moving = simulate(truth, theta, random_fourier(robot, seed=3), noise={f"tau{j}": NOISE for j in (1, 2, 3)}, seed=1)
    rng = np.random.default_rng(5)
    count = 300  # 1.5 s at 200 Hz
    q_rest = np.repeat(moving.q[-1:], count, axis=0)
    dq_rest = 1e-3 * rng.normal(size=(count, 3))  # differentiated encoder noise
    ddq_rest = np.zeros((count, 3))
    rigid = build_model(robot, "internal", "none")
    tau_rest = rigid.predict(theta[:30], q_rest, np.zeros((count, 3)), ddq_rest) + NOISE * rng.normal(size=(count, 3))
    t_rest = moving.t[-1] + (1 + np.arange(count)) * (moving.t[1] - moving.t[0])
    record = Measurements(np.concatenate([moving.t, t_rest]), np.vstack([moving.q, q_rest]),
                          np.vstack([moving.dq, dq_rest]), np.vstack([moving.ddq, ddq_rest]),
                          np.vstack([moving.tau, tau_rest]))
    biased = identify(truth, record).estimate
    cured = identify(truth, drop_rest(record, 0.01).measurements).estimate
    index = list(cured.names).index("fc1")
    assert abs(cured.values[index] - 5.0) < 3 * cured.std[index]
    assert abs(biased.values[index] - 5.0) > 3 * biased.std[index]


def test_trivial_predictors_and_their_warning(robot):
    truth = build_model(robot, "internal", "viscous")
    theta = true_parameters(truth, seed=0)
    train, validate = _experiments(truth, theta)
    flipped = Measurements(validate.t, validate.q, validate.dq, validate.ddq, validate.tau * [1, 1, -1])
    result = identify(truth, train, flipped)
    trivial = trivial_mse(truth, flipped)
    assert set(trivial) == {"zero_mse", "nominal_mse"}
    np.testing.assert_allclose(trivial["zero_mse"]["tau1"], np.mean(flipped.tau[:, 0] ** 2))
    messages = trivial_warnings(result.validation.mse, trivial)
    assert len(messages) == 1 and messages[0].startswith("tau3:") and "a zero prediction" in messages[0]
    assert trivial_warnings(identify(truth, train, validate).validation.mse, trivial_mse(truth, validate)) == ()
