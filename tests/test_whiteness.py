"""resid-style checks: a white residual passes, a coloured one and one that follows an input fail."""

from __future__ import annotations

import numpy as np
import pytest

from estimation.uncertainty.whiteness import autocorrelation, cross_correlation, residual_checks


def _inputs(n, seed=0):
    t = np.arange(n) / 1000.0
    generator = np.random.default_rng(seed)
    return {"dq1": np.sin(2 * np.pi * 0.3 * t) + 0.3 * np.sin(2 * np.pi * 2.1 * t + generator.uniform()),
            "noise_input": generator.normal(size=n)}


def test_white_residual_passes_both_checks():
    n = 5000
    failures = 0
    for seed in range(20):
        residual = np.random.default_rng(seed).normal(size=(n, 2))
        checks = residual_checks(residual, ("tau1", "tau2"), _inputs(n, seed))
        for check in checks.checks.values():
            failures += (not check.whiteness.passed) + sum(not c.passed for c in check.inputs.values())
            assert abs(check.whiteness.band - 2.5758 / np.sqrt(n)) < 1e-3
    assert failures <= 3  # 120 checks, each failing by chance about 1 % of the time


def test_coloured_residual_is_not_white_and_an_input_dependence_is_found():
    n = 5000
    generator = np.random.default_rng(1)
    white = generator.normal(size=n)
    coloured = np.zeros(n)
    for k in range(1, n):
        coloured[k] = 0.6 * coloured[k - 1] + white[k]
    inputs = _inputs(n)
    follows = generator.normal(size=n) + 0.2 * np.roll(inputs["noise_input"], -3)  # u three samples later
    checks = residual_checks(np.column_stack([coloured, follows]), ("tau1", "tau2"), inputs)
    assert not checks.checks["tau1"].whiteness.passed
    assert abs(checks.checks["tau1"].whiteness.values[0] - 0.6) < 0.05
    cross = checks.checks["tau2"].inputs["noise_input"]
    assert not cross.passed and cross.lags[int(np.argmax(np.abs(cross.values)))] == 3
    assert checks.checks["tau2"].whiteness.passed
    assert "correlated with noise_input" in checks.checks["tau2"].statement()


def test_smooth_residual_is_not_called_correlated_with_an_independent_smooth_input():
    n = 10000
    t = np.arange(n) / 1000.0
    calls = 0
    for seed in range(10):
        generator = np.random.default_rng(seed)
        smooth = np.convolve(generator.normal(size=n + 400), np.hanning(400), mode="valid")[:n]
        inputs = {"dq1": np.sin(2 * np.pi * 0.37 * t + generator.uniform(0, 6))}
        calls += not residual_checks(smooth[:, None], ("tau1",), inputs).checks["tau1"].inputs["dq1"].passed
    assert calls <= 2  # a band of z/sqrt(N) would call almost every one correlated


def test_correlations_stay_within_one():
    values = 1.0 + 1e-9 * np.arange(100.0) ** 2  # smooth, tiny variance: the old estimator read > 1
    assert np.all(np.abs(autocorrelation(values, 50)) <= 1.0)
    assert np.all(np.abs(cross_correlation(values, values, 50)) <= 1.0 + 1e-12)
    with pytest.raises(ValueError, match="do not match"):
        residual_checks(np.zeros((10, 2)), ("tau1",), {})


def test_residual_statistics_of_diagnose_stay_within_one():
    from types import SimpleNamespace

    from estimation.diagnosis.search import residual_statistics

    t = np.arange(2000.0)
    residuals = np.column_stack([np.sin(t / 300.0), np.random.default_rng(0).normal(size=2000)])
    result = SimpleNamespace(estimate=SimpleNamespace(residuals=residuals, channels=("tau1", "tau2")))
    statistics = residual_statistics(result)
    assert 0.99 < statistics["tau1"]["autocorrelation_lag1"] <= 1.0
    assert abs(statistics["tau2"]["autocorrelation_lag1"]) < 0.1
