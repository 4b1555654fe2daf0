"""The shape search evaluates each block's columns once where it used to evaluate them again, bit for bit.

``estimation.estimators.variable_projection._ShapeSearch``: a step's trial point is solved with the shape derivatives
(the next iteration's point when accepted), and each block's latest evaluations are kept (a plain block's columns, or
a shape held at its bound while the others move). Both must leave every fit exactly as the search that evaluated the
columns anew at every solve and the derivatives after them.
"""

from __future__ import annotations

import numpy as np
import pytest

import estimation.estimators.variable_projection as variable_projection
from dynamics.effects.linear import parse_effects
from dynamics.effects.shaped import TanhCoulombFriction, shape_parameters, start_grid
from dynamics.models import ModelKind
from dynamics.robots import load_robot
from estimation.estimators.effect_blocks import Block
from estimation.estimators.variable_projection import fit_shapes
from tests.shaped_problem import shaped_problem


@pytest.fixture(scope="module")
def robot():
    return load_robot("puma560", joints=3)


@pytest.fixture(scope="module")
def problem(robot):
    shaped = shaped_problem()
    return shaped.fixed, shaped.states, np.array([1.0, 0.7, 1.3])


def _anew(monkeypatch, counter=None):
    """The search as it was: every block evaluated at every solve, a trial solved without the derivatives."""
    cost = variable_projection._ShapeSearch.cost

    def evaluate(self, index, shape, jacobian):
        if counter is not None:
            counter.append(index)
        block = self.blocks[index]
        return block.evaluate(self.states, shape, jacobian=True) if jacobian else (block.evaluate(self.states, shape), None)

    monkeypatch.setattr(variable_projection._ShapeSearch, "evaluate", evaluate)
    monkeypatch.setattr(variable_projection._ShapeSearch, "cost", lambda self, s, jacobian=False: cost(self, s))


@pytest.mark.parametrize("spec", ["coulomb:tanh", "stribeck:velocity", "sigmoid", "ripple"])
def test_the_columns_with_the_derivatives_are_the_columns_alone_bit_for_bit(robot, problem, spec):
    _, states, _ = problem
    for effect in parse_effects(spec):
        block = Block(ModelKind.INTERNAL, robot, effect, 3)
        for point in start_grid(shape_parameters(effect, robot))[:4]:
            columns, _ = block.evaluate(states, point, jacobian=True)
            assert np.array_equal(columns, block.evaluate(states, point))


def _fits(robot, problem):
    fixed, states, weights = problem
    plain_and_shaped = [Block(ModelKind.INTERNAL, robot, parse_effects("offset")[0], 3),
                        Block(ModelKind.INTERNAL, robot, parse_effects("sigmoid")[0], 3)]
    held = [Block(ModelKind.INTERNAL, robot, TanhCoulombFriction(joints=(joint,), bounds=bounds), 3)
            for joint, bounds in enumerate((((0.1, 2.0),), None, None))]
    return [fit_shapes(fixed, plain_and_shaped, states, weights),
            fit_shapes(fixed, held, states, weights, starts=np.array([[0.5, 0.5, 0.5]]), covariance="white"),
            fit_shapes(fixed, [Block(ModelKind.INTERNAL, robot, parse_effects("ripple")[0], 3)], states, weights,
                       covariance="none")]


def test_the_search_with_its_evaluations_kept_fits_as_the_search_that_evaluates_anew(robot, problem, monkeypatch):
    kept = _fits(robot, problem)
    counted: list[int] = []
    with monkeypatch.context() as patch:
        _anew(patch, counted)
        anew = _fits(robot, problem)
    for new, old in zip(kept, anew):
        assert np.array_equal(new.shape, old.shape) and np.array_equal(new.theta, old.theta)
        assert np.array_equal(new.cov, old.cov, equal_nan=True)
        assert new.rss == old.rss and new.iterations == old.iterations
    again: list[int] = []
    original = variable_projection._ShapeSearch.evaluate

    def counting(self, index, shape, jacobian):
        known = self.evaluated[index].get(shape.tobytes())
        if known is None or (jacobian and known[1] is None):
            again.append(index)
        return original(self, index, shape, jacobian)

    monkeypatch.setattr(variable_projection._ShapeSearch, "evaluate", counting)
    _fits(robot, problem)
    assert len(again) < 0.7 * len(counted)  # the plain block once a fit, a held shape once, no trial twice


@pytest.mark.parametrize(("m", "k", "n_shape", "rows"), [(7, 1, 2, (2,)), (7, 2, 1, (0, 3)), (6, 1, 3, (1, 2, 5)),
                                                         (13, 2, 2, (6, 12)), (3, 3, 1, (0, 1, 2))])
def test_a_blocks_rows_are_taken_as_advanced_indexing_takes_them_strides_included(m, k, n_shape, rows):
    """``Block.evaluate`` copies its rows a row at a time: the arrays advanced indexing gave, values and layout (the
    products formed from them then read the same memory in the same order)."""
    from estimation.estimators.effect_blocks import rows_taken

    n = 40
    values = np.random.default_rng(0).random((n, m * k * (1 + n_shape)))
    columns = rows_taken(values[:, :m * k].reshape(n, m, k), rows)
    derivative = rows_taken(values[:, m * k:].reshape(n, n_shape, m, k), rows).transpose(1, 0, 2, 3)
    indexed_columns = values[:, :m * k].reshape(n, m, k)[:, list(rows), :]
    indexed_derivative = values[:, m * k:].reshape(n, n_shape, m, k)[:, :, list(rows), :].transpose(1, 0, 2, 3)
    for new, old in ((columns, indexed_columns), (derivative, indexed_derivative)):
        assert np.array_equal(new, old) and new.strides == old.strides and new.flags.c_contiguous == old.flags.c_contiguous
