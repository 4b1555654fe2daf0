"""A shape grid's costs at once (estimation.estimators.shape_starts.grid_costs) against the linear solve at each point."""

from __future__ import annotations

import numpy as np
import pytest

from dynamics.effects.linear import parse_effects
from dynamics.models import ModelKind
from dynamics.effects.shaped import start_grid
from estimation.estimators.bordered_normal import FixedFactor
from estimation.estimators.effect_blocks import Block
from estimation.estimators.shape_starts import BATCH, grid_costs
from estimation.estimators.separable_least_squares import solve_linear
from tests.shaped_problem import shaped_problem


@pytest.fixture(scope="module")
def problem():
    shaped = shaped_problem()
    return shaped.robot, shaped.model, shaped.fixed, shaped.states, np.array([1.0, 2.0, 4.0])


@pytest.mark.parametrize("spec", ["coulomb:tanh", "ripple", "stribeck:velocity"])
def test_the_grid_costs_are_the_linear_solves_to_rounding(problem, spec):
    robot, model, fixed, states, weights = problem
    factored = FixedFactor.of(fixed.gram, weights)
    for effect in parse_effects(spec):
        for part in ([effect] if effect.joints is not None else
                     [type(effect)(joints=(joint,)) for joint in range(robot.n_joints)]):
            block = Block(ModelKind.INTERNAL, robot, part, len(model.channels))
            grid = start_grid(block.parameters)
            costs = grid_costs(fixed, block, states, grid, weights, factored)
            solved = np.array([solve_linear(fixed, [block], states, [point], weights).rss for point in grid])
            assert np.all(np.isfinite(costs)), "every point decided here"
            assert np.max(np.abs(costs - solved) / solved) < 1e-12
            assert np.array_equal(np.argsort(costs, kind="stable"), np.argsort(solved, kind="stable")) or \
                np.max(np.abs(np.diff(np.sort(solved))) / solved.max()) < 1e-12  # an order only ties could change
    assert len(start_grid(Block(ModelKind.INTERNAL, robot, parse_effects("ripple")[0].__class__(joints=(0,)),
                                len(model.channels)).parameters)) > BATCH  # the ripple's grid spans batches


def test_a_point_the_fixed_columns_absorb_is_left_to_the_linear_solve(problem):
    robot, model, fixed, states, weights = problem
    # joint 1's viscous friction is among the fixed columns: the same column appended is absorbed at every point
    viscous = parse_effects("viscous")[0]
    block = Block(ModelKind.INTERNAL, robot, type(viscous)(joints=(0,)), len(model.channels))
    costs = grid_costs(fixed, block, states, np.zeros((3, 0)), weights, FixedFactor.of(fixed.gram, weights))
    assert np.all(np.isnan(costs))  # not decided here: the linear solve says why (rank-deficient columns)
    with pytest.raises(np.linalg.LinAlgError):
        solve_linear(fixed, [block], states, [np.zeros(0)], weights)
