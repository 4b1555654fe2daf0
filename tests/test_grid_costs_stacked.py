"""The grid's per-point costs formed with every point's steps stacked (estimation.estimators.shape_starts._points_costs)
equal the costs formed a point at a time (``_point_cost``) bit for bit: on the batches of real grids, and on a batch
with a point whose Schur complement is not positive definite."""

from __future__ import annotations

import numpy as np
import pytest

from dynamics.effects.linear import parse_effects
from dynamics.models import ModelKind
from dynamics.effects.shaped import start_grid
from estimation.estimators import shape_starts
from estimation.estimators.bordered_normal import FixedFactor
from estimation.estimators.effect_blocks import Block
from tests.shaped_problem import shaped_problem


def one_at_a_time(complement, eliminated, border, corner, v, factored, rest, usable):
    """The costs as formed before the stacking: ``_point_cost`` a point at a time."""
    costs = np.full(usable.shape[0], np.nan)
    for point in np.flatnonzero(usable):
        costs[point] = shape_starts._point_cost(complement[point], eliminated[:, point], border[:, point],
                                                corner[point], v[point], factored, rest)
    return costs


@pytest.fixture(scope="module")
def problem():
    shaped = shaped_problem()
    return shaped.robot, shaped.model, shaped.fixed, shaped.states, np.array([1.0, 2.0, 4.0])


@pytest.mark.parametrize("spec", ["coulomb:tanh", "ripple", "stribeck:velocity", "sigmoid"])
def test_the_stacked_costs_are_the_point_costs_bit_for_bit(problem, spec, monkeypatch):
    robot, model, fixed, states, weights = problem
    factored = FixedFactor.of(fixed.gram, weights)
    stacked = shape_starts._points_costs
    compared = []

    def both(*arguments):
        result = stacked(*arguments)
        expected = one_at_a_time(*arguments)
        assert np.array_equal(result, expected, equal_nan=True)
        assert np.array_equal(np.signbit(result), np.signbit(expected))
        compared.append(int(np.sum(np.isfinite(result))))
        return result

    monkeypatch.setattr(shape_starts, "_points_costs", both)
    for effect in parse_effects(spec):
        for joint in range(robot.n_joints):
            block = Block(ModelKind.INTERNAL, robot, type(effect)(joints=(joint,)), len(model.channels))
            shape_starts.grid_costs(fixed, block, states, start_grid(block.parameters), weights, factored)
    assert compared and sum(compared) > 0


def test_a_point_not_positive_definite_is_nan_and_the_others_as_alone(problem):
    robot, model, fixed, states, weights = problem
    factored = FixedFactor.of(fixed.gram, weights)
    generator = np.random.default_rng(1)
    n_points, k, p0 = 5, 2, fixed.n_fixed
    raw = generator.normal(size=(n_points, k, k))
    complement = np.matmul(raw, np.swapaxes(raw, 1, 2)) + 0.5 * np.eye(k)
    complement[2] = np.array([[1.0, 0.0], [0.0, -1.0]])  # indefinite: its factor fails
    eliminated = generator.normal(size=(p0, n_points, k)) * 1e-3
    border = generator.normal(size=(p0, n_points, k)) * 1e-3
    corner = complement.copy()
    v = generator.normal(size=(n_points, k))
    usable = np.array([True, True, True, False, True])
    arguments = (complement, eliminated, border, corner, v, factored, 1e3, usable)
    result = shape_starts._points_costs(*arguments)
    assert np.array_equal(result, one_at_a_time(*arguments), equal_nan=True)
    assert np.isnan(result[2]) and np.isnan(result[3]) and np.isfinite(result[[0, 1, 4]]).all()
    none = np.zeros(n_points, dtype=bool)
    assert np.all(np.isnan(shape_starts._points_costs(*arguments[:-1], none)))
