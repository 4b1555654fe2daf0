"""HAC standard deviations hold with coloured residuals where the classical ones do not."""

from __future__ import annotations

import numpy as np
import pytest

from estimation.uncertainty.covariance import bandwidth, hac_covariance, prewhitened_long_run_covariance
from estimation.estimators.least_squares import IdentificationProblem, LeastSquares, WeightedLeastSquares


def _problem(noise, t):
    Y = np.stack([np.ones_like(t), np.sin(2 * np.pi * 0.5 * t), np.cos(2 * np.pi * 1.3 * t)], axis=-1)  # (N, r)
    Y = np.stack([Y, 0.5 * Y[:, ::-1]], axis=1)  # two channels (N, 2, 3)
    theta = np.array([1.0, -2.0, 0.5])
    return IdentificationProblem(Y, Y @ theta + noise, ("tau1", "tau2"), ("a", "b", "c")), theta


def _ar1(generator, n, rho, scale):
    white = generator.normal(size=(n, 2)) * scale
    out = np.zeros_like(white)
    for k in range(1, n):
        out[k] = rho * out[k - 1] + white[k]
    return out


@pytest.mark.parametrize("estimator_type", [LeastSquares, WeightedLeastSquares])
def test_hac_intervals_cover_with_coloured_noise(estimator_type):
    n, realisations = 2000, 150
    t = np.arange(n) / 100.0
    generator = np.random.default_rng(0)
    covered = {"classical": 0, "hac": 0}
    for _ in range(realisations):
        problem, theta = _problem(_ar1(generator, n, 0.95, np.array([0.3, 0.1])), t)
        for method in covered:
            estimate = estimator_type(covariance=method).fit(problem).estimate_
            covered[method] += np.sum(np.abs(estimate.values - theta) < 1.96 * estimate.std)
    coverage = {method: count / (3 * realisations) for method, count in covered.items()}
    assert 0.88 <= coverage["hac"] <= 0.99, coverage
    assert coverage["classical"] < 0.6, coverage  # the check can fail: white-noise intervals are far too narrow
    assert estimate.cov_method == "hac" and estimate.hac_lags >= 0


def test_white_residuals_give_back_the_classical_covariance():
    n = 5000
    t = np.arange(n) / 100.0
    problem, _ = _problem(np.random.default_rng(1).normal(size=(n, 2)), t)
    classical = LeastSquares().fit(problem).estimate_
    hac = LeastSquares(covariance="hac").fit(problem).estimate_
    assert hac.hac_lags <= 3
    np.testing.assert_allclose(hac.std, classical.std, rtol=0.1)
    assert classical.cov_method == "classical" and classical.hac_lags is None


def test_bandwidth_and_bad_settings():
    generator = np.random.default_rng(2)
    assert bandwidth(generator.normal(size=(4000, 3))) <= 3
    smooth = _ar1(generator, 4000, 0.99, 1.0)
    assert bandwidth(smooth) > 50
    # prewhitening takes the AR(1) out: the innovations need a short window, and the long-run
    # variance of an AR(1) with unit innovations is 1 / (1 - rho)^2
    _, lags = prewhitened_long_run_covariance(_ar1(generator, 20000, 0.9, 1.0)[:, :1])
    assert lags <= 5
    meat, _ = prewhitened_long_run_covariance(_ar1(generator, 20000, 0.9, 1.0)[:, :1])
    assert abs(meat[0, 0] / 20000 / 100 - 1) < 0.3
    with pytest.raises(ValueError, match="covariance must be one of"):
        LeastSquares(covariance="newey").fit(_problem(np.zeros((100, 2)), np.arange(100.0))[0])
    with pytest.raises(TypeError, match="covariance must be one of"):
        WeightedLeastSquares(covariance=None).fit(_problem(np.zeros((100, 2)), np.arange(100.0))[0])
    Y = generator.normal(size=(50, 1, 2))
    cov, lags = hac_covariance(Y, generator.normal(size=(50, 1)), np.ones(1), np.eye(2), lags=0)
    assert lags == 0 and np.allclose(cov, cov.T)
