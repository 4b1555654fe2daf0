"""Shaped effects found by the diagnosis: the right law on the right joint, nothing of another shape,
the validation error of a fit that knows the true shape; from derivatives and from positions only."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from dynamics.models import ModelKind, build_model
from dynamics.robots import load_robot
from dynamics.effects.shaped import PositionRipple, ShapedStribeckFriction, SigmoidFriction, TanhCoulombFriction
from estimation.diagnosis.search import diagnose
from estimation.identification.fit import identify
from estimation.preprocessing.differentiation import FourierDifferentiation, fill_derivatives
from estimation.estimators.effect_blocks import Block, States
from dynamics.simulation.synthetic import simulate, true_parameters
from oed.fourier import random_fourier

NOISE = 0.1
RATE_HZ = 250.0  # two periods of 5 s: 2500 samples a record

# law, joint (0-based), linear coefficients, shape values: none of them the defaults
CASES = {
    "coulomb:tanh": (TanhCoulombFriction, 1, [6.0], [0.03]),
    "stribeck:velocity": (ShapedStribeckFriction, 2, [2.0, 3.0], [0.2]),
    "sigmoid": (SigmoidFriction, 1, [8.0], [40.0, 0.15]),
    "ripple": (PositionRipple, 2, [1.2, -0.8], [7.3]),
}


@pytest.fixture(scope="module")
def robot():
    return load_robot("puma560", joints=3)


def _records(robot, spec):
    effect_type, joint, coefficients, shape = CASES[spec]
    declared = build_model(robot, "internal", "viscous")
    theta = true_parameters(declared, seed=0)
    effect = effect_type(joints=(joint,))
    block = Block(ModelKind.INTERNAL, robot, effect, 3)
    records = []
    for seed in (3, 4):
        data = simulate(declared, theta, random_fourier(robot, seed=seed), rate_hz=RATE_HZ, periods=2,
                        noise={f"tau{j}": NOISE for j in (1, 2, 3)}, seed=seed)
        extra = block.evaluate(States(data.q, data.dq, data.ddq), np.array(shape)) @ np.array(coefficients)  # (N, rows)
        tau = data.tau.copy()
        tau[:, list(block.rows)] += extra
        records.append(dataclasses.replace(data, tau=tau))
    return declared, effect, records


def _positions_only(data):
    stripped = dataclasses.replace(data, dq=None, ddq=None)
    return fill_derivatives(stripped, FourierDifferentiation(0.2, harmonics=5, average=False))


@pytest.mark.parametrize("derivatives", ["given", "positions"])
@pytest.mark.parametrize("spec", list(CASES))
def test_the_undeclared_law_is_named_with_its_shape(robot, spec, derivatives):
    declared, effect, (train, validate) = _records(robot, spec)
    if derivatives == "positions":
        train, validate = _positions_only(train), _positions_only(validate)
    diagnosis = diagnose(declared, train, validate)
    joint = CASES[spec][1]
    found = [(found.spec, found.channels) for found in diagnosis.effects]
    assert found == [(spec, (f"tau{joint + 1}",))], found  # the right law, nothing of another shape
    # against a fit that knows the true law (its shape estimated too)
    reference = identify(build_model(robot, "internal", ("viscous", effect)), train, validate)
    tolerance = 1.2 if derivatives == "given" else 1.5
    for channel, value in diagnosis.after.validation.mse.items():
        assert value <= tolerance * reference.validation.mse[channel] + 1e-12, (channel, value)
    shape = diagnosis.effects[0].shape
    truth = dict(zip((parameter.name for parameter in effect.shape_parameters(robot)), CASES[spec][3]))
    for name, value in shape.items():
        assert abs(value - truth[name]) < max(4 * diagnosis.effects[0].shape_std[name], 0.02 * abs(truth[name])), name
    document = diagnosis.to_dict()["effects"][0]
    assert set(document) >= {"name", "channels", "values", "std", "p_value", "shape", "shape_std"}
