"""The bordered normal equations: the fixed block factored once, the border by its Schur complement, the same
solution (to rounding) and the same rank verdict as the whole matrix solved by ``solve_normal``."""

import numpy as np
import pytest

from estimation.estimators.bordered_normal import FixedFactor, solve_bordered
from estimation.estimators.separable_least_squares import solve_normal


def _normal(columns: np.ndarray, weights: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per-channel Gram matrices of ``columns (m, N, p)`` and the weighted normal matrix."""
    gram = np.matmul(columns.transpose(0, 2, 1), columns)
    normal = np.tensordot(weights, gram, axes=1)
    return gram, np.triu(normal) + np.triu(normal, 1).T


def test_the_bordered_solution_is_the_whole_one_and_solves_other_right_hand_sides():
    generator = np.random.default_rng(0)
    fixed = generator.normal(size=(3, 500, 6)) * np.array([1.0, 10.0, 0.1, 3.0, 1e3, 1e-2])  # badly scaled columns
    border = generator.normal(size=(3, 500, 2))
    weights = np.array([1.0, 4.0, 0.25])
    gram, _ = _normal(fixed, weights)
    _, normal = _normal(np.concatenate([fixed, border], axis=2), weights)
    right = generator.normal(size=8)
    theta, factor = solve_bordered(normal, right, FixedFactor.of(gram, weights))
    np.testing.assert_allclose(theta, solve_normal(normal, right), rtol=1e-10)
    several = generator.normal(size=(8, 3))
    np.testing.assert_allclose(normal @ factor.solve(several), several, rtol=1e-9, atol=1e-9)


def test_a_border_the_fixed_columns_absorb_is_refused_as_the_whole_matrix_refuses_it():
    generator = np.random.default_rng(1)
    fixed = generator.normal(size=(2, 400, 5))
    copied = fixed[:, :, :1] * 2.0 - fixed[:, :, 3:4]  # a combination of the fixed columns
    weights = np.ones(2)
    gram, _ = _normal(fixed, weights)
    _, normal = _normal(np.concatenate([fixed, copied], axis=2), weights)
    right = generator.normal(size=6)
    assert solve_bordered(normal, right, FixedFactor.of(gram, weights)) is None  # left to the eigenvalues
    with pytest.raises(np.linalg.LinAlgError):
        solve_normal(normal, right)


def test_without_a_border_the_fixed_factor_alone_solves():
    generator = np.random.default_rng(2)
    fixed = generator.normal(size=(2, 300, 4))
    weights = np.array([2.0, 0.5])
    gram, normal = _normal(fixed, weights)
    right = generator.normal(size=4)
    theta, _ = solve_bordered(normal, right, FixedFactor.of(gram, weights))
    np.testing.assert_allclose(theta, solve_normal(normal, right), rtol=1e-12)
