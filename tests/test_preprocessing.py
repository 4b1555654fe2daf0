"""Derivative estimation against the analytic derivatives of known motions."""

from __future__ import annotations

import numpy as np
import pytest

from dynamics.robots import load_robot
from dynamics.measurements import Measurements
from estimation.preprocessing.differentiation import (
    ButterworthDifferentiation,
    FourierDifferentiation,
    average_periods,
    compensate_hold,
    decimate,
    fill_derivatives,
    repeats_exactly,
)
from estimation.preprocessing.fourier_series import FourierSeries
from oed.fourier import random_fourier


@pytest.fixture(scope="module")
def trajectory():
    return random_fourier(load_robot("puma560", joints=3), seed=5)


def noisy(trajectory, periods: int, rate_hz: float, sigma_q: float, sigma_tau: float, seed: int = 0) -> tuple:
    t, q, dq, ddq = trajectory.sample(rate_hz, periods)
    generator = np.random.default_rng(seed)
    tau = np.column_stack([np.sin(2 * np.pi * 0.2 * t), np.cos(2 * np.pi * 0.4 * t), 0 * t])
    measured = Measurements(t, q + generator.normal(0, sigma_q, q.shape), tau=tau + generator.normal(0, sigma_tau, tau.shape),
                            metadata={"frequency_hz": trajectory.frequency_hz})
    return measured, (q, dq, ddq, tau)


def test_fourier_differentiation_recovers_analytic_derivatives_of_noisy_periodic_data(trajectory):
    measured, (q, dq, ddq, tau) = noisy(trajectory, periods=4, rate_hz=200.0, sigma_q=1e-3, sigma_tau=0.1)
    result = FourierDifferentiation(trajectory.frequency_hz, harmonics=5).apply(measured)
    samples = result.n_samples
    assert samples == q.shape[0] // 4 and result.metadata["periods_averaged"] == 4
    np.testing.assert_allclose(result.q, q[:samples], atol=3e-4)
    np.testing.assert_allclose(result.dq, dq[:samples], atol=3e-3)
    np.testing.assert_allclose(result.ddq, ddq[:samples], atol=2e-2)
    # averaging four periods halves the torque noise
    residual = np.std(result.tau - tau[:samples])
    assert 0.04 < residual < 0.06


def test_averaging_needs_a_rate_that_is_a_multiple_of_the_frequency(trajectory):
    measured, _ = noisy(trajectory, periods=2, rate_hz=200.0, sigma_q=0.0, sigma_tau=0.0)
    with pytest.raises(ValueError, match="not a multiple"):
        average_periods(measured, 0.3)


def test_butterworth_differentiation_is_zero_phase_and_matches_the_analytic_derivatives(trajectory):
    # 1.5 periods: not periodic in the record, so the Fourier route does not apply
    t = np.arange(1500) / 200.0
    q, dq, ddq = trajectory.evaluate(t)
    generator = np.random.default_rng(3)
    tau = np.sin(2 * np.pi * 0.5 * t)[:, None] * [1.0, 2.0, 3.0]
    measured = Measurements(t, q + generator.normal(0, 2e-4, q.shape), tau=tau + generator.normal(0, 0.05, tau.shape))
    result = ButterworthDifferentiation(cutoff_hz=5.0).apply(measured)
    inner = slice(100, -100)  # edges of filtfilt and of the differences
    np.testing.assert_allclose(result.dq[inner], dq[inner], atol=0.02)
    np.testing.assert_allclose(result.ddq[inner], ddq[inner], atol=0.25)
    # the torques stay as recorded (the default): the fit's target (a filtered Coulomb step would not match the
    # sharp sign column)
    np.testing.assert_array_equal(result.tau, measured.tau)
    np.testing.assert_array_equal(result.recorded.tau, measured.tau)
    # filtered alike (the option): zero phase, the filtered torque is not delayed (a causal filter lags ~0.1 s here)
    filtered = ButterworthDifferentiation(cutoff_hz=5.0, torques="filtered").apply(measured)
    assert np.sqrt(np.mean((filtered.tau[inner] - tau[inner]) ** 2)) < 0.02
    automatic = ButterworthDifferentiation().cutoff(measured)
    assert 1.0 < automatic < 0.8 * 100.0


def test_decimation_keeps_the_signal_and_one_sample_in_factor(trajectory):
    t, q, dq, ddq = trajectory.sample(1000.0, 1)
    data = Measurements(t, q, dq, ddq)
    reduced = decimate(data, 5)
    assert reduced.n_samples == int(np.ceil(t.shape[0] / 5))
    np.testing.assert_allclose(reduced.q[50:-50], q[::5][50:-50], atol=1e-4)
    with pytest.raises(ValueError, match="positive integer"):
        decimate(data, 0)


def test_fill_derivatives_chooses_the_fourier_route_for_periodic_data(trajectory):
    measured, (q, dq, ddq, _) = noisy(trajectory, periods=2, rate_hz=100.0, sigma_q=0.0, sigma_tau=0.0)
    filled = fill_derivatives(measured)
    assert filled.metadata["differentiation"] == "fourier"
    np.testing.assert_allclose(filled.ddq, ddq[: filled.n_samples], atol=1e-8)
    untouched = Measurements(measured.t, q, dq, ddq)
    assert fill_derivatives(untouched) is untouched


def test_compensate_hold_moves_the_derived_motion_half_a_sample_later(trajectory):
    t, q, dq, ddq = trajectory.sample(200.0)
    held = compensate_hold(Measurements(t, q, dq, ddq, tau=np.ones_like(q)))
    later = trajectory.evaluate(t + 0.5 / 200.0)
    for moved, expected in zip((held.q, held.dq, held.ddq), later):
        np.testing.assert_allclose(moved, expected, atol=1e-3 * np.abs(expected).max())
    np.testing.assert_array_equal(held.tau, np.ones_like(q))  # the torques stay as measured
    assert held.metadata["hold_compensated"] is True
    with pytest.raises(ValueError, match="derive them first"):
        compensate_hold(Measurements(t, q, tau=np.ones_like(q)))
    with pytest.warns(UserWarning, match="nothing to align"):
        fill_derivatives(Measurements(t, q, dq, ddq, tau=np.ones_like(q)), held_torques=True)


def test_the_motion_of_averaged_periods_is_repeated_only_where_the_time_stamps_repeat():
    frequency, rate = 0.25, 200.0
    t = np.arange(3 * 800) / rate
    q = np.column_stack([np.sin(2 * np.pi * frequency * t), np.cos(4 * np.pi * frequency * t)])
    q += np.random.default_rng(0).normal(0.0, 1e-4, q.shape)
    data = Measurements(t=t, q=q, tau=np.zeros_like(q))
    assert repeats_exactly(t, 3, frequency) and not repeats_exactly(t + 1e-7 * t**2, 3, frequency)
    derived = FourierDifferentiation(frequency, 10, average="yes").apply(data)
    fit = derived.metadata["fourier_fit"]
    direct = FourierSeries(fit["frequency_hz"], np.array(fit["q0"]), np.array(fit["a"]), np.array(fit["b"])).evaluate(t)
    for repeated, evaluated in zip((derived.recorded.q, derived.recorded.dq, derived.recorded.ddq), direct):
        np.testing.assert_allclose(repeated, evaluated, rtol=0, atol=1e-12 * np.max(np.abs(evaluated)))


def test_a_joint_whose_positions_do_not_change_has_zero_derived_velocity():
    """A joint held still while another moves (a teach pendant's jog): filtered and spline-differentiated, its
    velocity was rounding noise (±6e-14 rad/s at 0.52 rad), whose sign switched its Coulomb column between +fc and
    -fc on every row (h-extrap: the jog test's joint 4 56x the plain fit); now exactly zero, as is its
    acceleration. A slow motion (1e-6 rad/s, far below any friction's interest but resolved) keeps its sign, and
    the moving joint's derivatives are unchanged."""
    t = np.arange(0.0, 4.0, 0.004)
    q = np.column_stack([np.full_like(t, np.pi / 6), np.sin(2 * np.pi * 0.5 * t), 1.0 + 1e-6 * t])
    derived = ButterworthDifferentiation(cutoff_hz=21.25, logged_velocity=False).apply(
        Measurements(t, q, None, None, np.zeros_like(q), None, {}))
    assert np.all(derived.dq[:, 0] == 0.0) and np.all(derived.ddq[:, 0] == 0.0)
    assert np.all(derived.dq[:, 2] > 0.0)
    assert np.abs(derived.dq[:, 2] - 1e-6).max() < 1e-8
    inside = slice(50, -50)
    assert np.abs(derived.dq[inside, 1] - np.pi * np.cos(np.pi * t[inside])).max() < 1e-3
