"""The noise floor against known noise: periodic (whole and fractional periods), non-periodic, the stopping rule."""

from __future__ import annotations

import numpy as np
import pytest

from dynamics.measurements import Measurements
from estimation.uncertainty.noise_floor import (NoiseFloorError, difference_variance, fourier_residual_variance, noise_floor,
                                                prepared_floor)
from estimation.uncertainty.floor_comparison import above_floor, compare_with_floor
from estimation.preprocessing.differentiation import ButterworthDifferentiation, average_periods

RATE = 1000.0


def _periodic_signal(t, frequency_hz, harmonics=20, seed=0):
    generator = np.random.default_rng(seed)
    signal = np.zeros((t.shape[0], 2))
    for k in range(1, harmonics + 1):
        amplitude = generator.normal(size=(2, 2)) * 20.0 / k
        signal += np.outer(np.sin(2 * np.pi * k * frequency_hz * t), amplitude[0])
        signal += np.outer(np.cos(2 * np.pi * k * frequency_hz * t), amplitude[1])
    return signal


def _record(tau, t, **metadata):
    q = np.zeros_like(tau)
    return Measurements(t, q, tau=tau, metadata=metadata)


def test_period_to_period_variance_recovers_known_noise():
    frequency = 1.0
    t = np.arange(5000) / RATE  # five periods of 1000 samples
    sigma = np.array([0.3, 0.05])
    noise = np.random.default_rng(1).normal(size=(t.shape[0], 2)) * sigma
    floor = noise_floor(_record(_periodic_signal(t, frequency) + noise, t), ("tau1", "tau2"), frequency_hz=frequency)
    assert floor.method == "periods" and floor.dof == 4000
    np.testing.assert_allclose(floor.variance, sigma**2, rtol=0.1)  # 4000 dof: 2.2 % standard deviation


def test_fractional_period_uses_a_fourier_fit_with_the_right_dof():
    frequency = 3.0  # 333.3 samples a period at 1 kHz
    t = np.arange(3000) / RATE
    signal = _periodic_signal(t, frequency, harmonics=40)
    estimates = []
    for seed in range(40):
        noise = np.random.default_rng(seed).normal(size=(t.shape[0], 2)) * 0.2
        floor = noise_floor(_record(signal + noise, t), ("tau1", "tau2"), frequency_hz=frequency)
        estimates.append(floor.variance / 0.04)
    assert floor.method == "fourier" and floor.details["harmonics"] == 166
    assert floor.dof == 3000 - 2 * 166 - 1
    estimates = np.concatenate(estimates)
    assert abs(np.mean(estimates) - 1.0) < 4 * np.sqrt(2 / floor.dof / estimates.size)  # unbiased
    # the spread is that of chi2_dof / dof: the dof are right (80 draws: ±25 %)
    assert 0.75 < np.std(estimates) / np.sqrt(2 / floor.dof) < 1.25


def _explicit_fourier_variance(t, values, frequency_hz, harmonics):
    """The Fourier floor from its whole design and the SVD: what the sums must reproduce."""
    phase = np.outer(t - t.mean(), 2 * np.pi * frequency_hz * np.arange(1, harmonics + 1))
    design = np.hstack([np.ones((t.shape[0], 1)), np.sin(phase), np.cos(phase)])
    residual = values - design @ np.linalg.lstsq(design, values, rcond=None)[0]
    return np.sum(residual**2, axis=0) / (t.shape[0] - 2 * harmonics - 1)


@pytest.mark.parametrize("jitter", [0.0, 1e-6], ids=["regular grid (chirp z)", "jittered stamps (blocks)"])
@pytest.mark.parametrize("harmonics", [40, 450])
def test_fourier_floor_sums_give_the_explicit_least_squares_fit(jitter, harmonics):
    frequency = 1 / 0.9993  # 999.3 samples a period: not a whole number
    t = np.arange(4100) / RATE + np.random.default_rng(7).normal(size=4100) * jitter
    values = _periodic_signal(t, frequency, harmonics=30) + np.random.default_rng(8).normal(size=(4100, 2)) * 0.2
    variance, dof, used = fourier_residual_variance(t, values, frequency, harmonics=harmonics)
    assert used == harmonics and dof == 4100 - 2 * harmonics - 1
    np.testing.assert_allclose(variance, _explicit_fourier_variance(t, values, frequency, harmonics), rtol=1e-9)


def test_difference_estimator_is_unbiased_on_a_smooth_signal_with_friction_jumps():
    t = np.arange(20000) / RATE
    velocity = np.sin(2 * np.pi * 0.37 * t) + 0.5 * np.sin(2 * np.pi * 1.3 * t + 1)
    signal = 80 * np.sin(2 * np.pi * 0.21 * t * (1 + t / 40)) + 26 * np.tanh(velocity / 0.002)  # chirp + a sharp Coulomb law
    ratios = []
    for seed in range(20):
        noise = np.random.default_rng(seed).normal(size=t.shape[0]) * 0.2
        variance, dof = difference_variance((signal + noise)[:, None])
        ratios.append(variance[0] / 0.04)
    assert abs(np.mean(ratios) - 1) < 0.02
    assert 0.6 < np.std(ratios) / np.sqrt(2 / dof) < 1.5
    # a plain (non-robust) mean square of the differences would be far off: the check can fail
    plain = np.mean(np.diff(signal + noise, n=4) ** 2) / 70 / 0.04
    assert plain > 1.2


def test_non_periodic_record_falls_back_to_differences():
    t = np.arange(4000) / RATE
    tau = np.column_stack([10 * np.sin(2 * np.pi * 0.5 * t), np.cos(t)]) + np.random.default_rng(3).normal(size=(4000, 2)) * 0.1
    floor = noise_floor(_record(tau, t, frequency_hz=0.2), ("tau1", "tau2"))  # 0.8 period
    assert floor.method == "differences"
    np.testing.assert_allclose(floor.variance, 0.01, rtol=0.1)
    with pytest.raises(NoiseFloorError, match="at least two"):
        noise_floor(_record(tau, t, frequency_hz=0.2), ("tau1",), method="periods")


def test_processed_records_are_refused_and_prepared_floor_scales_them():
    frequency = 1.0
    t = np.arange(4000) / RATE
    noise = np.random.default_rng(5).normal(size=(4000, 2)) * 0.5
    record = _record(_periodic_signal(t, frequency) + noise, t, frequency_hz=frequency)
    floor = noise_floor(record, ("tau1", "tau2"))
    averaged = average_periods(record, frequency)
    with pytest.raises(NoiseFloorError, match="processed"):
        noise_floor(averaged, ("tau1", "tau2"))
    scaled = prepared_floor(floor, averaged)
    np.testing.assert_allclose(scaled.variance, floor.variance / 4)
    # filtered white noise (torques filtered alike, the option): its variance is the recording's times the filter's gain
    white = _record(np.random.default_rng(6).normal(size=(20000, 2)), np.arange(20000) / RATE)
    recorded = ButterworthDifferentiation(cutoff_hz=50.0).apply(white)  # the default: the torques as recorded
    np.testing.assert_array_equal(recorded.tau, white.tau)
    np.testing.assert_allclose(prepared_floor(noise_floor(white, ("tau1", "tau2")), recorded).variance,
                               noise_floor(white, ("tau1", "tau2")).variance)
    filtered = ButterworthDifferentiation(cutoff_hz=50.0, torques="filtered").apply(white)
    gain = prepared_floor(noise_floor(white, ("tau1", "tau2")), filtered).variance / noise_floor(white, ("tau1", "tau2")).variance
    np.testing.assert_allclose(np.var(filtered.tau, axis=0), gain, rtol=0.1)
    assert 0.05 < gain[0] < 0.15  # about 2 x 50 Hz / 1000 Hz


def test_stopping_rule_keeps_an_exact_model_at_its_floor_and_flags_a_missing_effect():
    frequency = 1.0
    t = np.arange(4000) / RATE
    calls = []
    for seed in range(30):
        generator = np.random.default_rng(100 + seed)
        noise = generator.normal(size=(4000, 2)) * 0.2
        floor = noise_floor(_record(_periodic_signal(t, frequency) + noise, t), ("tau1", "tau2"), frequency_hz=frequency)
        exact = {"tau1": float(np.mean(noise[:, 0] ** 2)), "tau2": float(np.mean(noise[:, 1] ** 2))}
        calls.append(sum(above_floor(exact, floor, 4000, alpha=0.01).values()))
        missing = {"tau1": exact["tau1"] + 0.2 * 0.04, "tau2": exact["tau2"]}  # 20 % more: a missed effect
        comparison = compare_with_floor(missing, floor, 4000, alpha=0.01)
        assert comparison["tau1"].above and "above its floor" in comparison["tau1"].statement()
    assert sum(calls) <= 2  # alpha = 1 % over 60 channels
    assert "at its floor" in comparison["tau2"].statement()


def test_a_filtered_channel_gives_no_difference_floor():
    import scipy.signal

    t = np.arange(10000) / RATE
    noisy = np.sin(2 * np.pi * 0.3 * t) + np.random.default_rng(8).normal(size=10000) * 0.1
    smooth = scipy.signal.sosfiltfilt(scipy.signal.butter(4, 30.0, fs=RATE, output="sos"), noisy)
    with pytest.raises(NoiseFloorError, match="tau2: its 4th differences are not those of white noise"):
        noise_floor(_record(np.column_stack([noisy, smooth]), t), ("tau1", "tau2"))
    assert noise_floor(_record(noisy[:, None], t), ("tau1",)).method == "differences"
