"""The sums of a Fourier fit without its design (chirp z-transforms on a regular grid) against the design itself."""

from __future__ import annotations

from fractions import Fraction

import numpy as np
import pytest

from estimation.preprocessing.fourier_series import evaluate_series, fit_series
from estimation.preprocessing.fourier_sums import (BlockFourierSums, UniformFourierSums, chirp_sums, fourier_sums,
                                                   fractional_turns)

RATE = 1000.0


def test_fractional_turns_are_exact_where_the_plain_product_is_not():
    rate = 1 / 6999.97  # turns a sample of a 6.99997 s period at 1 kHz
    counts = 0.5 * np.arange(0, 40_000, 37, dtype=float) ** 2  # up to 8e8: 1e5 turns
    exact = np.array([float((Fraction(rate) * Fraction(count)) % 1) for count in counts])
    error = np.abs(fractional_turns(rate, counts) - exact)
    assert np.max(np.minimum(error, 1 - error)) < 1e-15
    plain = np.abs((rate * counts) % 1 - exact)
    assert np.max(np.minimum(plain, 1 - plain)) > 1e-13  # what the reduction removes


@pytest.mark.parametrize("count", [40, 700], ids=["fewer outputs than values", "more outputs than values"])
def test_chirp_sums_are_the_direct_sums(count):
    rate = 0.01234567
    values = np.random.default_rng(0).normal(size=(500, 3)) + 1j * np.random.default_rng(1).normal(size=(500, 3))
    n, k = np.arange(500), np.arange(count)
    direct = np.exp(2j * np.pi * fractional_turns(rate, np.outer(k, n).astype(float))) @ values
    np.testing.assert_allclose(chirp_sums(values, count, rate), direct, rtol=0, atol=1e-11 * np.max(np.abs(direct)))


def test_uniform_fourier_sums_are_the_block_sums():
    frequency, harmonics = 1 / 0.9993, 300
    t = 2.5 + np.arange(3000) / RATE
    values = np.random.default_rng(9).normal(size=(3000, 3))
    uniform = UniformFourierSums.of(t, frequency, harmonics, origin=1.0)
    blocks = BlockFourierSums(t, frequency, harmonics, origin=1.0)
    for got, expected in zip(uniform.normal_equations(values), blocks.normal_equations(values)):
        np.testing.assert_allclose(got, expected, rtol=0, atol=1e-9 * np.max(np.abs(expected)))
    coefficients = np.random.default_rng(10).normal(size=(2 * harmonics + 1, 3))
    expected = blocks.fitted(coefficients)
    np.testing.assert_allclose(uniform.fitted(coefficients), expected, rtol=0, atol=1e-9 * np.max(np.abs(expected)))


def test_only_a_regular_grid_takes_the_chirp_sums():
    t = np.arange(2000) / RATE
    assert isinstance(fourier_sums(t, 1.3, 20, origin=0.0), UniformFourierSums)
    jittered = t + np.random.default_rng(2).normal(size=2000) * 1e-7
    assert isinstance(fourier_sums(jittered, 1.3, 20, origin=0.0), BlockFourierSums)
    assert UniformFourierSums.of(1e5 + t, 1.3, 20, origin=0.0) is None  # stamps rounded to 1.5e-11 s: off the grid


def _positions(t, frequency, harmonics=40, seed=3):
    generator = np.random.default_rng(seed)
    omega = 2 * np.pi * frequency * np.arange(1, harmonics + 1)
    amplitude = generator.normal(size=(2, harmonics, 2)) / np.arange(1, harmonics + 1)[None, :, None] ** 2
    return 0.3 + np.sin(np.outer(t, omega)) @ amplitude[0] + np.cos(np.outer(t, omega)) @ amplitude[1]


@pytest.mark.parametrize("harmonics", [60, 300])
def test_a_fit_on_a_regular_grid_is_the_design_fit(harmonics):
    frequency = 1 / 2.9997  # not a whole number of samples a period
    t = 0.7 + np.arange(4000) / RATE
    q = _positions(t, frequency) + np.random.default_rng(4).normal(size=(4000, 2)) * 1e-4
    chirp, _ = fit_series(t, q, frequency, harmonics, solver="normal")
    design, _ = fit_series(t, q, frequency, harmonics, solver="svd")
    for got, expected in zip(chirp.evaluate(t), design.evaluate(t)):
        np.testing.assert_allclose(got, expected, rtol=0, atol=1e-9 * np.max(np.abs(expected)))


def test_a_series_evaluated_on_a_regular_grid_is_the_series():
    frequency, harmonics = 0.37, 300
    t = 3.0 + np.arange(5000) / RATE
    generator = np.random.default_rng(5)
    q0, a, b = generator.normal(size=2), generator.normal(size=(2, harmonics)), generator.normal(size=(2, harmonics))
    omega = 2 * np.pi * frequency * np.arange(1, harmonics + 1)
    sin, cos = np.sin(np.outer(t, omega)), np.cos(np.outer(t, omega))
    expected = (q0 + sin @ (a / omega).T - cos @ (b / omega).T, cos @ a.T + sin @ b.T,
                -sin @ (a * omega).T + cos @ (b * omega).T)
    for got, value in zip(evaluate_series(frequency, q0, a, b, t), expected):
        np.testing.assert_allclose(got, value, rtol=0, atol=1e-10 * np.max(np.abs(value)))
