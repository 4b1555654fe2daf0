"""The final model of a diagnosis respects the physical signs, and candidates are compared at the weights
their own residuals give (estimation.diagnosis.sign_constraints, estimation.diagnosis.confirmation)."""

from __future__ import annotations

import numpy as np
import pytest

from dynamics.effects.linear import CoulombFriction, JointOffset
from dynamics.models import build_model
from dynamics.robots import load_robot
from estimation.diagnosis.confirmation import settled_weights
from estimation.diagnosis.search import diagnose
from estimation.identification.fit import ImplausibleEstimateWarning, identify
from estimation.diagnosis.sign_constraints import negative_terms, pin_wrong_signs
from estimation.estimators.effect_blocks import Block, States
from estimation.estimators.separable_least_squares import FixedPart
from dynamics.simulation.synthetic import simulate, true_parameters
from oed.fourier import random_fourier


@pytest.fixture(scope="module")
def robot():
    return load_robot("puma560", joints=3)


def _records(robot, truth, theta, noise):
    return [simulate(truth, theta, random_fourier(robot, seed=seed), rate_hz=200.0, periods=2, noise=noise, seed=seed)
            for seed in (3, 4)]


def test_a_negative_viscous_term_is_held_at_zero_and_reported(robot):
    """A robot whose joint-2 'viscous friction' is negative (-3: no physical friction) gives a negative
    fv2; the step holds it at zero, keeps fv1 and fv3, and reports the estimate it had."""
    truth = build_model(robot, "internal", "viscous")
    theta = true_parameters(truth, seed=0, viscous=np.array([4.0, -3.0, 2.0]))
    train, validate = _records(robot, truth, theta, {"tau1": 0.1, "tau2": 0.1, "tau3": 0.05})
    with pytest.warns(ImplausibleEstimateWarning, match="fv2"):
        after = identify(truth, train, validate)
    assert set(negative_terms(after)) == {"fv2"}
    selected, pinned_after, pinned = pin_wrong_signs([], after, truth, train, validate, {})
    assert selected == []
    assert [term.parameter for term in pinned] == ["fv2"] and pinned[0].value < -2.5 and not pinned[0].found
    names = list(pinned_after.estimate.names)
    assert "fv2" not in names and {"fv1", "fv3"} <= set(names)
    assert not negative_terms(pinned_after)
    assert "standard deviations below zero" in pinned[0].reason


def test_nothing_is_pinned_when_every_sign_is_physical(robot):
    truth = build_model(robot, "internal", "viscous")
    theta = true_parameters(truth, seed=0)
    train, validate = _records(robot, truth, theta, {"tau1": 0.1, "tau2": 0.1, "tau3": 0.05})
    after = identify(truth, train, validate)
    selected, same, pinned = pin_wrong_signs([], after, truth, train, validate, {})
    assert pinned == () and same is after


def test_settled_weights_are_those_of_the_weighted_fit_of_the_augmented_model(robot):
    """The weights a candidate is confirmed at are the channel weights the final weighted least squares
    of the augmented model settles to (PUMA paper eq. 21), not the declared model's."""
    truth = build_model(robot, "internal", ("viscous", CoulombFriction(), JointOffset()))
    theta = true_parameters(truth, seed=0, coulomb=[20.0, 0.5, 0.3], offset=[0.5, -0.2, 0.1])
    train, _ = _records(robot, truth, theta, {"tau1": 0.05, "tau2": 0.2, "tau3": 0.1})
    declared = build_model(robot, "internal", "viscous")
    before = identify(declared, train)
    augmented = identify(build_model(robot, "internal", ("viscous", CoulombFriction(joints=(0,)))), train)
    fixed = FixedPart.from_arrays(declared.evaluate_base(train.q, train.dq, train.ddq), train.channels(declared.channels))
    block = Block(declared.kind, robot, CoulombFriction(joints=(0,)), declared.n_channels)
    weights = settled_weights(fixed, [block], States(train.q, train.dq, train.ddq), [np.zeros(0)],
                              before.estimate.weights, passes=6)
    # the declared model's residual on tau1 is the missing Coulomb friction: its weight is far too small
    assert before.estimate.weights[0] < 0.05 * augmented.estimate.weights[0]
    np.testing.assert_allclose(weights, augmented.estimate.weights, rtol=0.02)


def test_diagnosis_finds_the_effect_of_the_channel_the_declared_weights_discount(robot):
    """tau1 misses a large Coulomb friction and an offset; the others are nearly clean. The diagnosis adds
    them on tau1 and ends with tau1 near its noise (0.05² = 0.0025), whatever the declared weights were."""
    truth = build_model(robot, "internal", ("viscous", CoulombFriction(joints=(0,)), JointOffset(joints=(0,))))
    theta = true_parameters(truth, seed=0, coulomb=[20.0], offset=[1.5])
    train, validate = _records(robot, truth, theta, {"tau1": 0.05, "tau2": 0.05, "tau3": 0.05})
    diagnosis = diagnose(build_model(robot, "internal", "viscous"), train, validate)
    found = {(effect.name, effect.channels) for effect in diagnosis.effects}
    assert ("offset", ("tau1",)) in found and any(name == "coulomb" and channels == ("tau1",) for name, channels in found)
    assert diagnosis.after.validation.mse["tau1"] < 1.5 * 0.05**2
    assert diagnosis.pinned == ()
