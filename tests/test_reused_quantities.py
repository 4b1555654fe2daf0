"""Quantities the default `oed diagnose` forms once and reuses (issue 34's cost) equal those formed again, bit for
bit: the flexible friction columns of the derivative choice written into one array, the Gram matrices of the
consistent fit's problem formed once for every prior weight of its search, and a shaped fit's prediction along its
training record taken from the fit for the comparison there."""

from __future__ import annotations

from dataclasses import replace as dc_replace

import numpy as np
import pytest

from dynamics.effects.linear import CoulombFriction
from dynamics.measurements import Measurements
from dynamics.models import build_model
from dynamics.robots import load_robot
from dynamics.simulation.synthetic import simulate, true_parameters
from estimation.consistent.least_squares import ConsistentLeastSquares
from estimation.estimators.least_squares import WeightedLeastSquares, channel_gram
from estimation.identification.preprocessing_choice import FRICTION_SPEEDS, HeldOutScore, joint_speeds, \
    with_friction_columns
from estimation.identification.fit import identify
from estimation.identification.validation import compare
from estimation.identification.shaped import fit_shaped_model, fit_shaped_model_predicting, shaped_comparison
from estimation.preprocessing.plan import Preprocessing, prepare
from oed.fourier import random_fourier
from tests.test_consistent import consistent_truth, simulated_problem


def friction_by_blocks(measurements: Measurements, channels, speeds=None) -> np.ndarray:
    """The flexible friction as it was built before: a zero block a joint, concatenated."""
    speeds = joint_speeds(measurements) if speeds is None else speeds
    blocks = []
    for joint in range(measurements.n_joints):
        name = f"tau{joint + 1}"
        if name not in channels:
            continue
        dq = measurements.dq[:, joint]
        speed = float(speeds[joint])
        columns = np.zeros((measurements.n_samples, len(channels), 2 + len(FRICTION_SPEEDS)))
        channel = list(channels).index(name)
        columns[:, channel, 0] = 1.0
        columns[:, channel, 1] = dq / speed
        for k, fraction in enumerate(FRICTION_SPEEDS):
            columns[:, channel, 2 + k] = np.tanh(dq / (fraction * speed))
        blocks.append(columns)
    return np.concatenate(blocks, axis=2) if blocks else np.zeros((measurements.n_samples, len(channels), 0))


@pytest.mark.parametrize("channels", [("tau1", "tau2", "tau3"), ("tau3", "fz", "tau1"), ("fx", "fy")])
def test_the_friction_columns_written_into_one_array_are_those_concatenated_bit_for_bit(channels):
    rng = np.random.default_rng(3)
    n = 500
    dq = rng.normal(size=(n, 3)) * np.array([0.1, 2.0, 30.0])
    dq[:, 2] = 0.0  # a joint at rest: its speed is 1
    measurements = Measurements(t=np.arange(n) * 1e-3, q=rng.normal(size=(n, 3)), dq=dq, ddq=rng.normal(size=(n, 3)),
                                tau=rng.normal(size=(n, 3)))
    Y = rng.normal(size=(n, len(channels), 5))
    expected = friction_by_blocks(measurements, channels)
    np.testing.assert_array_equal(HeldOutScore.friction_columns(measurements, channels), expected)
    found = with_friction_columns(Y, measurements, channels)
    assert found.shape == (n, len(channels), 5 + expected.shape[2]) and found.flags.c_contiguous
    np.testing.assert_array_equal(found, np.concatenate([Y, expected], axis=2))
    speeds = np.array([0.5, 3.0, 7.0])  # another record's speeds (the score on a repeat)
    np.testing.assert_array_equal(with_friction_columns(Y, measurements, channels, speeds),
                                  np.concatenate([Y, friction_by_blocks(measurements, channels, speeds)], axis=2))


def test_the_consistent_fit_from_gram_matrices_formed_once_is_the_fit_that_forms_them_bit_for_bit():
    model = build_model(load_robot("puma560", joints=3), "internal", "viscous")
    problem, _ = simulated_problem(model, consistent_truth(model), 60, 1.0, seed=5)
    unconstrained = WeightedLeastSquares().fit(problem).estimate_
    gram, _ = channel_gram(problem)
    for weight in (10.0, 0.1):
        again = ConsistentLeastSquares(prior_weight=weight).fit(model, problem, unconstrained=unconstrained).estimate_
        reused = ConsistentLeastSquares(prior_weight=weight).fit(model, problem, unconstrained=unconstrained,
                                                                 gram=gram).estimate_
        for name in ("values", "phi", "cov", "std"):
            np.testing.assert_array_equal(getattr(reused, name), getattr(again, name))
        assert reused.excess_chi2 == again.excess_chi2
    with pytest.raises(ValueError, match="gram has shape"):
        ConsistentLeastSquares(prior_weight=1.0).fit(model, problem, unconstrained=unconstrained, gram=gram[:, :-1])


@pytest.fixture(scope="module")
def shaped_records():
    robot = load_robot("puma560", joints=3)
    truth = build_model(robot, "internal", ("viscous", CoulombFriction(smoothing=0.04)))
    theta = true_parameters(truth, seed=1, coulomb=[6.0, 4.0, 2.0])
    records = []
    for seed in (5, 6):
        clean = simulate(truth, theta, random_fourier(robot, seed=seed), rate_hz=250, periods=2)
        noisy = dc_replace(clean, tau=clean.tau + 0.05 * np.random.default_rng(seed).normal(size=clean.tau.shape))
        records.append(noisy)
    return build_model(robot, "internal", ("viscous", "coulomb:tanh")), records  # a shaped law fitted


def test_the_shaped_fit_compared_on_its_training_record_with_its_own_prediction_is_the_comparison_formed_again(
        shaped_records):
    model, (train, validate) = shaped_records
    positions_only = [dc_replace(record, dq=None, ddq=None) for record in (train, validate)]
    plan = Preprocessing("butterworth", cutoff_hz=10.0)  # the torques kept as recorded: a comparison with `filtered`
    for pair in ((train, validate), tuple(prepare(record, plan) for record in positions_only)):
        result = identify(model, *pair)
        again = shaped_comparison(result.shaped_fit, pair[0], "identification")
        found = result.train
        for one, other in ((found, again), (found.filtered, again.filtered)):
            if other is None:
                assert one is None
                continue
            np.testing.assert_array_equal(one.predicted, other.predicted)
            np.testing.assert_array_equal(one.measured, other.measured)
            assert one.mse == other.mse
        assert (found.filtered is None) == (pair[0].recorded is None)
    _, _, fitted = fit_shaped_model_predicting(model, train)
    np.testing.assert_array_equal(fitted, fit_shaped_model(model, train)[0].predict(train))
    with pytest.raises(ValueError, match="predicted has shape"):
        shaped_comparison(result.shaped_fit, pair[0], "identification", predicted=fitted[:-1])


def test_a_linear_fit_compared_on_its_training_record_with_its_regressor_is_the_comparison_formed_again(
        shaped_records):
    _, (train, validate) = shaped_records
    plan = Preprocessing("butterworth", cutoff_hz=10.0)
    prepared = prepare(dc_replace(train, dq=None, ddq=None), plan)
    for model in (build_model(load_robot("puma560", joints=3), "internal", ("viscous", "coulomb", "offset")),
                  build_model(load_robot("emps"), "internal", ("viscous", "coulomb", "offset"))):
        for record in (train, prepared) if model.robot.n_joints == 3 else (dc_replace(train, q=train.q[:, :1],
                                                                           dq=train.dq[:, :1], ddq=train.ddq[:, :1],
                                                                           tau=train.tau[:, :1]),):
            result = identify(model, record)
            again = compare(model, result.estimate.values, record, label="identification")
            for one, other in ((result.train, again), (result.train.filtered, again.filtered)):
                if other is None:
                    assert one is None
                    continue
                np.testing.assert_array_equal(one.predicted, other.predicted)
                assert one.mse == other.mse
    with pytest.raises(ValueError, match="predicted has shape"):
        compare(model, result.estimate.values, record, predicted=np.zeros((3, 1)))
