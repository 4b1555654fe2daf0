"""The Wald test of the diagnosis (estimation.diagnosis.rules.robust_test): its statistic against the definition, its
covariance against the classical one on white residuals, and its verdict on residuals correlated in time, where
the F test of white residuals finds an effect in the noise."""

from __future__ import annotations

import numpy as np
import scipy.stats

from estimation.diagnosis.candidates.trials import nested_test
from estimation.diagnosis.rules.robust_test import fit_covariance, wald_test
from estimation.estimators.separable_least_squares import FixedPart, solve_linear

N = 4000


def test_the_wald_statistic_is_the_quadratic_form_of_the_covariance():
    theta = np.array([1.0, -2.0])
    cov = np.array([[0.25, 0.1], [0.1, 1.0]])
    test = wald_test(theta, cov)
    expected = theta @ np.linalg.inv(cov) @ theta
    assert abs(test.statistic - expected) < 1e-10
    assert abs(test.p_value - scipy.stats.chi2.sf(expected, 2)) < 1e-12 and test.f_statistic == test.statistic / 2


def _problem(noise: np.ndarray) -> FixedPart:
    t = np.arange(N) / 250.0
    Y = np.stack([np.ones(N), np.sin(2 * np.pi * 0.2 * t), np.sin(2 * np.pi * 0.05 * t + 1.0)], axis=1)[:, None, :]
    y = (Y[:, 0, :2] @ np.array([1.0, 2.0]) + noise)[:, None]
    return FixedPart.from_arrays(Y, y)


def test_on_white_residuals_the_covariance_is_the_classical_one():
    fixed = _problem(np.random.default_rng(1).normal(0.0, 0.1, N))
    weights = np.array([100.0])
    theta, cov = fit_covariance(fixed, [], None, [], weights, shaped=False)
    solution = solve_linear(fixed, [], None, [], weights)
    classical = solution.rss / (N - 3) * np.linalg.inv(solution.normal)
    np.testing.assert_allclose(theta, solution.theta)
    np.testing.assert_allclose(np.sqrt(np.diag(cov)), np.sqrt(np.diag(classical)), rtol=0.1)


def test_a_slow_regressor_in_correlated_noise_is_not_significant_though_the_f_test_says_it_is():
    # AR(1) 0.98 noise: the third column (a 0.05 Hz sine, absent from the truth) follows the noise's slow drift;
    # at level 1e-3 the F test of white residuals calls it significant in most records, the Wald test in none
    f_significant = wald_significant = 0
    for seed in range(10):
        generator = np.random.default_rng(seed)
        innovations, noise = generator.normal(0.0, 0.02, N), np.zeros(N)
        for index in range(1, N):
            noise[index] = 0.98 * noise[index - 1] + innovations[index]
        fixed = _problem(noise)
        reduced = FixedPart.from_arrays(fixed.A.transpose(1, 0, 2)[:, :, :2], fixed.y.T)
        weights = np.array([1.0])
        _, p_value, _ = nested_test(solve_linear(reduced, [], None, [], weights).rss,
                                    solve_linear(fixed, [], None, [], weights).rss, 1, N, 2)
        theta, cov = fit_covariance(fixed, [], None, [], weights, shaped=False)
        f_significant += p_value < 1e-3
        wald_significant += wald_test(theta[2:], cov[2:, 2:]).p_value < 1e-3
    assert f_significant >= 6 and wald_significant <= 1, (f_significant, wald_significant)


def test_the_nested_f_test_is_the_f_distributions_survival_function():
    generator = np.random.default_rng(3)
    for _ in range(200):
        rss = float(generator.uniform(1.0, 2.0))
        augmented, count, n_rows = rss * float(generator.uniform(0.5, 1.0)), int(generator.integers(1, 6)), 98_000
        statistic, p_value, _ = nested_test(rss, augmented, count, n_rows, 60)
        assert statistic == ((rss - augmented) / count) / (augmented / (n_rows - 60 - count))
        assert p_value == scipy.stats.f.sf(statistic, count, n_rows - 60 - count)  # the same number, not close to it
