"""One preprocessing chosen on the training data and reused; segments apart; the recording kept."""

from __future__ import annotations

import warnings
from dataclasses import replace

import numpy as np
import pytest
import scipy.signal

from dynamics.robots import load_robot
from estimation.preprocessing.fourier_series import evaluate_series, fit_series
from dynamics.measurements import Measurements
from estimation.preprocessing.periodicity import detect_fundamental, frequency_mismatch
from estimation.preprocessing.differentiation import ButterworthDifferentiation, FourierDifferentiation
from estimation.preprocessing.plan import (
    FrequencyMismatchWarning,
    PreprocessingWarning,
    SegmentTooShortForFilterError,
    choose_preprocessing,
    prepare,
)
from estimation.data.segments import SegmentColumnsError, concatenate, segment_slices
from oed.fourier import FourierTrajectory
from oed.fourier import random_fourier


@pytest.fixture(scope="module")
def trajectory():
    return random_fourier(load_robot("puma560", joints=3), seed=5)


def record(trajectory, start: float, duration: float, rate: float = 500.0, seed: int = 0, frequency=None):
    if frequency is not None:
        trajectory = FourierTrajectory(frequency, trajectory.q0, trajectory.a, trajectory.b)
    t = start + np.arange(int(round(duration * rate))) / rate
    q = trajectory.evaluate(t)[0]
    generator = np.random.default_rng(seed)
    tau = np.sin(3 * t)[:, None] * [1.0, 2.0, 3.0] + generator.normal(0, 0.1, q.shape)
    return Measurements(t, q + generator.normal(0, 1e-5, q.shape), tau=tau, metadata={"source": f"s{seed}"})


def test_the_fourier_series_fit_works_on_any_time_stamps(trajectory):
    t = np.sort(np.random.default_rng(1).uniform(3.0, 10.5, 3000)).astype(np.float32).astype(float)
    q = trajectory.evaluate(t)[0]
    fit, residual = fit_series(t, q, trajectory.frequency_hz, trajectory.harmonics)
    np.testing.assert_allclose(fit.a, trajectory.a, atol=1e-5)
    np.testing.assert_allclose(fit.b, trajectory.b, atol=1e-5)
    assert residual < 1e-8


def test_period_averaging_auto_yes_no(trajectory):
    whole = record(trajectory, 0.0, 10.0)  # two periods of 2500 samples
    assert FourierDifferentiation(0.2, 5).apply(whole).metadata["periods_averaged"] == 2
    assert FourierDifferentiation(0.2, 5, "no").apply(whole).n_samples == 5000
    one_and_a_half = record(trajectory, 0.0, 7.5)
    assert FourierDifferentiation(0.2, 5).apply(one_and_a_half).metadata["periods_averaged"] == 0
    odd = record(trajectory, 0.0, 10.0, rate=333.3)  # two periods, but of 1666.5 samples: fit every sample
    fitted = FourierDifferentiation(0.2, 5).apply(odd)
    assert fitted.metadata["periods_averaged"] == 0 and fitted.n_samples == odd.n_samples
    np.testing.assert_allclose(fitted.dq, trajectory.evaluate(odd.t)[1], atol=2e-3)
    with pytest.raises(ValueError, match="not a multiple"):
        FourierDifferentiation(0.3, 5, "yes").apply(whole)
    with pytest.raises(ValueError, match="less than one period"):
        FourierDifferentiation(0.2, 5).apply(record(trajectory, 0.0, 4.0))


def test_averaged_channels_keep_the_recording_with_the_fit_motion(trajectory):
    data = record(trajectory, 0.0, 15.0)
    prepared = FourierDifferentiation(0.2, 5).apply(data)
    assert prepared.n_samples == 2500 and prepared.recorded.n_samples == 7500
    np.testing.assert_array_equal(prepared.recorded.tau, data.tau)
    q, _, _ = trajectory.evaluate(data.t)
    np.testing.assert_allclose(prepared.recorded.q, q, atol=1e-5)


def test_the_cutoff_is_chosen_on_training_and_reused_and_every_sample_kept(trajectory):
    train = [record(trajectory, 0.0, 3.0, seed=1), record(trajectory, 5.0, 3.5, seed=2)]  # not periodic within
    validate = record(trajectory, 20.0, 4.0, seed=3)
    plan = choose_preprocessing(train)
    assert plan.method == "butterworth" and plan.trimmed_s == 0
    prepared = prepare(train, plan)
    checked = prepare(validate, plan)
    for measurements in (prepared, checked):
        assert measurements.metadata["preprocessing"]["cutoff_hz"] == plan.cutoff_hz
    assert [part.stop - part.start for part in segment_slices(prepared)] == [1500, 1750]
    np.testing.assert_array_equal(checked.recorded.tau, validate.tau)  # as recorded, every sample
    np.testing.assert_array_equal(checked.tau, checked.recorded.tau)  # the estimation fits the recorded torque
    # the filter's ends extended by reflection: the edges' velocity close to the truth's
    _, dq, _ = trajectory.evaluate(validate.t)
    edge = slice(0, 50)
    assert np.max(np.abs(checked.dq[edge] - dq[edge])) < 0.05 * np.max(np.abs(dq))
    # a plan of an earlier version that trims the settling still does, and refuses what it cannot trim
    trimmed = replace(plan, trimmed_s=0.2)
    trim = ButterworthDifferentiation(plan.cutoff_hz).settling_samples(500.0, plan.cutoff_hz)
    np.testing.assert_array_equal(prepare(validate, trimmed).recorded.tau, validate.tau[trim:-trim])
    with pytest.raises(SegmentTooShortForFilterError, match="too few for"):
        prepare([record(trajectory, 0.0, 2 * trim / 500.0, seed=4)], trimmed)


def test_a_periodic_record_gets_its_fundamental_detected(trajectory):
    data = record(trajectory, 0.0, 20.0, frequency=0.075)  # 1.5 periods
    assert detect_fundamental(data.t, data.q).frequency_hz == 0.075
    with pytest.warns(PreprocessingWarning, match="periodic excitation of 0.075 Hz detected"):
        plan = choose_preprocessing([data])
    assert (plan.method, plan.frequency_hz, plan.harmonics, plan.frequency_source) == ("fourier", 0.075, 15, "detected")
    with pytest.warns(FrequencyMismatchWarning, match="sub-harmonic"):
        choose_preprocessing([data], frequency_hz=0.0375)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        choose_preprocessing([data], frequency_hz=0.075)
    assert "do not repeat" in frequency_mismatch(data.t, data.q, 0.15)


def test_segments_must_hold_the_same_columns(trajectory):
    first = record(trajectory, 0.0, 3.0)
    second = Measurements(first.t, first.q, dq=first.q, ddq=first.q, tau=first.tau)
    with pytest.raises(SegmentColumnsError, match="segments with different columns"):
        concatenate([first, second])
    with pytest.raises(SegmentColumnsError):
        choose_preprocessing([first, second])


def test_the_fourier_series_motion_is_eq_18_harmonic_by_harmonic():
    generator = np.random.default_rng(5)
    t = np.sort(generator.uniform(0.0, 7.0, 300))
    q0, a, b = generator.normal(size=2), generator.normal(size=(2, 6)), generator.normal(size=(2, 6))
    q, dq, ddq = evaluate_series(0.3, q0, a, b, t)
    expected = [np.tile(q0, (t.size, 1)), np.zeros((t.size, 2)), np.zeros((t.size, 2))]
    for harmonic in range(1, 7):
        omega = 2 * np.pi * 0.3 * harmonic
        sine, cosine = np.sin(omega * t)[:, None], np.cos(omega * t)[:, None]
        alpha, beta = a[:, harmonic - 1], b[:, harmonic - 1]
        expected[0] += (alpha * sine - beta * cosine) / omega
        expected[1] += alpha * cosine + beta * sine
        expected[2] += omega * (-alpha * sine + beta * cosine)
    for found, wanted in zip((q, dq, ddq), expected):
        np.testing.assert_allclose(found, wanted, rtol=1e-12, atol=1e-12)


@pytest.mark.parametrize(("rate", "cutoff", "order"), [(1000.0, 1.0, 4), (1000.0, 17.0, 4), (250.0, 3.5, 2), (200.0, 60.0, 6)])
def test_a_filter_settles_where_its_impulse_response_autocorrelation_falls_below_one_percent(rate, cutoff, order):
    sos = scipy.signal.butter(order, cutoff, btype="low", fs=rate, output="sos")
    length = int(np.ceil(40 * rate / cutoff)) + 1
    forward = scipy.signal.sosfilt(sos, np.eye(1, length)[0])
    response = np.abs(np.correlate(forward, forward, mode="full")[length - 1:])  # the direct sum
    expected = int(np.flatnonzero(response > 1e-2 * response.max())[-1]) + 1
    assert ButterworthDifferentiation(order=order).settling_samples(rate, cutoff) == expected


def test_the_summary_says_what_the_training_blocks_preferred_when_only_the_hold_differs():
    """On the TX40 the validation record chose an 85 Hz filter with held torques where the training record's blocks
    preferred the same filter without: the line said the blocks "preferred a 85 Hz Butterworth filter", the chosen
    one's own words."""
    from estimation.preprocessing.plan import Evidence, Preprocessing

    trained = Preprocessing("butterworth", cutoff_hz=85.0)
    chosen = replace(trained, held_torques=True, evidence=Evidence("validation", 5, (), (), trained))
    line = chosen.describe()
    assert ", held torques (chosen among" in line
    assert line.endswith("preferred a 85 Hz Butterworth filter without held torques)")
    other = replace(chosen, cutoff_hz=20.0)  # another filter: its own words suffice
    assert other.describe().endswith("preferred a 85 Hz Butterworth filter)")
