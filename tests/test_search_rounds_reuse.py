"""What the diagnosis's search rounds keep from one solve to the next equals what they computed anew, bit for bit.

- a block's latest evaluation along kept states (``States(..., kept=True)``: the diagnosis's records), returned again
  for the same states and shape (``Block.evaluate``), and the products of those columns with each record's stored
  columns kept beside it (``Block.products``, used by ``solve_linear`` across the parts of successive rounds);
- a fixed part's weighted Gram sums at the latest weights (``FixedPart.weighted``);
- the normal matrices symmetrised with ``np.triu``'s masks made once (``symmetric_upper``) and the Cholesky solves by
  LAPACK's ``dpotrs`` without scipy's wrappers (``cholesky_solve``, ``solve_normal``).
"""

from __future__ import annotations

import numpy as np
import pytest
import scipy.linalg

from dynamics.effects.linear import parse_effects
from dynamics.models import ModelKind
from estimation.estimators.bordered_normal import cholesky_solve, symmetric_upper
from estimation.estimators.effect_blocks import Block, States
from estimation.estimators.separable_least_squares import solve_linear, solve_normal
from estimation.estimators.variable_projection import fit_shapes
from tests.shaped_problem import shaped_problem


@pytest.fixture(scope="module")
def problem():
    return shaped_problem()


@pytest.fixture(scope="module")
def robot(problem):
    return problem.robot


@pytest.fixture(scope="module")
def record(problem):
    return problem.record


@pytest.fixture(scope="module")
def declared(problem):
    return problem.fixed


def _states(record, kept):
    return States(record.q, record.dq, record.ddq, kept=kept)


def _same_solution(new, old):
    assert np.array_equal(new.theta, old.theta) and new.rss == old.rss and np.array_equal(new.normal, old.normal)


@pytest.mark.parametrize("spec", ["coulomb:tanh", "sigmoid", "offset"])
def test_a_kept_evaluation_is_the_evaluation_bit_for_bit_and_read_only(robot, record, spec):
    effect = parse_effects(spec)[0]
    kept, fresh = Block(ModelKind.INTERNAL, robot, effect, 3), Block(ModelKind.INTERNAL, robot, effect, 3)
    states, plain = _states(record, True), _states(record, False)
    shape = np.array([parameter.starts[0] for parameter in kept.parameters], dtype=float)
    first = kept.evaluate(states, shape)
    assert kept.evaluate(states, shape.copy()) is first and not first.flags.writeable  # the same shape: kept
    reference = fresh.evaluate(plain, shape)
    assert np.array_equal(first, reference) and first.strides == reference.strides and reference.flags.writeable
    assert fresh.evaluate(plain, shape) is not reference  # states not kept: evaluated anew
    columns, derivative = kept.evaluate(states, shape, jacobian=True)  # the derivatives asked: evaluated with them
    reference_columns, reference_derivative = fresh.evaluate(plain, shape, jacobian=True)
    assert np.array_equal(columns, first) and columns.strides == first.strides
    assert np.array_equal(derivative, reference_derivative) and derivative.strides == reference_derivative.strides
    assert kept.evaluate(states, shape) is columns  # the columns of the evaluation with the derivatives
    assert kept.evaluate(_states(record, True), shape) is not columns  # other states (another object): anew
    if kept.n_shape:
        moved = kept.evaluate(states, shape * 1.5)
        assert moved is not columns and np.array_equal(moved, fresh.evaluate(plain, shape * 1.5))


def test_solves_across_rounds_with_kept_products_are_the_solves_anew(robot, record, declared):
    """A candidate screened round after round against parts that grow by adopted blocks (the channels an adopted
    block reaches get new stored columns, the others share theirs) and against a part with an adopted block left out:
    every solve with the kept evaluation and products equals the solve from a fresh evaluation."""
    states, plain = _states(record, True), _states(record, False)
    adopted = [Block(ModelKind.INTERNAL, robot, parse_effects(spec)[0], 3) for spec in ("offset@1", "coulomb@3")]
    candidates = [Block(ModelKind.INTERNAL, robot, parse_effects(spec)[0], 3)
                  for spec in ("coulomb:tanh@2", "sigmoid", "spring@3", "coulomb@1+2")]
    fresh = {id(block): Block(ModelKind.INTERNAL, robot, block.effect, 3) for block in candidates}
    weights = np.array([1.0, 0.7, 1.3])
    shapes = {id(block): np.array([parameter.starts[-1] for parameter in block.parameters], dtype=float)
              for block in candidates}
    parts = [declared]
    for block in adopted:
        parts.append(parts[-1].with_blocks([block], plain, [np.zeros(0)]))
    parts.append(parts[-1].kept(list(range(declared.n_fixed)) + [declared.n_fixed + 1]))  # the offset left out
    for part in parts + parts[::-1]:
        for scale in (1.0, 2.0):
            for block in candidates:
                shape = shapes[id(block)]
                kept_solution = solve_linear(part, [block], states, [shape], weights * scale)
                anew = solve_linear(part, [fresh[id(block)]], plain, [shape], weights * scale)
                _same_solution(kept_solution, anew)
                assert block.products(kept_solution.columns[0]) is not None
    # tau2's stored columns are shared by every part (no adopted block reaches it), tau3's change with coulomb@3
    for block, count in ((candidates[0], 1), (candidates[2], 2)):
        assert len(block.products(block.evaluate(states, shapes[id(block)]))) == count


def test_a_fit_along_kept_states_is_the_fit_anew(robot, record, declared):
    weights = np.array([1.0, 0.7, 1.3])
    fits = []
    for kept in (True, False):
        block = Block(ModelKind.INTERNAL, robot, parse_effects("coulomb:tanh")[0], 3)
        states = _states(record, kept)
        fits.append([fit_shapes(declared, [block], states, weights, covariance="white"),
                     fit_shapes(declared, [block], states, weights, starts=np.array([[0.2, 0.05, 0.1]]),
                                covariance="none")])
    for new, old in zip(*fits):
        assert np.array_equal(new.shape, old.shape) and np.array_equal(new.theta, old.theta)
        assert np.array_equal(new.cov, old.cov, equal_nan=True) and new.rss == old.rss
        assert new.iterations == old.iterations


def test_the_weighted_sums_kept_are_those_computed_anew(declared):
    for weights in (np.array([1.0, 0.7, 1.3]), np.array([2.0, 0.1, 1.0]), np.array([1.0, 0.7, 1.3])):
        normal, right, power = declared.weighted(weights)
        assert np.array_equal(normal, np.tensordot(weights, declared.gram, axes=1)) and not normal.flags.writeable
        assert np.array_equal(right, weights @ declared.moment) and power == weights @ declared.power
    assert declared.weighted(weights)[0] is declared.weighted(weights.copy())[0]


@pytest.mark.parametrize("size", [1, 2, 5, 17, 64])
def test_the_symmetrised_matrix_and_the_cholesky_solves_are_scipys_bit_for_bit(size):
    generator = np.random.default_rng(size)
    matrix = generator.normal(size=(size, size))
    matrix[0, -1] = -0.0
    assert np.array_equal(symmetric_upper(matrix), np.triu(matrix) + np.triu(matrix, 1).T)
    assert np.array_equal(np.signbit(symmetric_upper(matrix)), np.signbit(np.triu(matrix) + np.triu(matrix, 1).T))
    normal = matrix @ matrix.T + size * np.eye(size)
    factor = scipy.linalg.cho_factor(normal, check_finite=False)
    for right in (generator.normal(size=size), generator.normal(size=(size, 3)), np.zeros((size, 0))):
        assert np.array_equal(cholesky_solve(factor[0], right), scipy.linalg.cho_solve(factor, right,
                                                                                       check_finite=False))
    right = generator.normal(size=size)
    scale = np.sqrt(np.diag(normal))
    reference = scipy.linalg.cho_solve(scipy.linalg.cho_factor(normal / np.outer(scale, scale), check_finite=False),
                                       right / scale, check_finite=False) / scale
    assert np.array_equal(solve_normal(normal, right), reference)
