"""Estimators against known simulated parameters: recovery within 3σ, noise-floor validation,
channel weighting for the combined model, plate offsets."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pinocchio as pin
import pytest

from dynamics.models import build_model
from dynamics.pinocchio_bridge import to_pinocchio
from dynamics.robots import load_robot
from estimation.identification.fit import identify
from estimation.estimators.least_squares import (
    IdentifiabilityError,
    IdentificationProblem,
    LeastSquares,
    NotFittedError,
    WeightedLeastSquares,
    stack,
)
from dynamics.simulation.synthetic import simulate, true_parameters

from oed.fourier import random_fourier

NOISE = {"tau1": 0.5, "tau2": 0.5, "tau3": 0.2, "fx": 5.0, "fy": 5.0, "fz": 8.0, "mx": 3.0, "my": 3.0, "mz": 1.0}


@pytest.fixture(scope="module")
def puma():
    return load_robot("puma560", joints=3)


def test_synthetic_torques_match_pinocchio_rnea_plus_viscous_friction(puma):
    model = build_model(puma, "internal", "viscous")
    theta = true_parameters(model)
    data = simulate(model, theta, random_fourier(puma, 3), rate_hz=20.0)
    pin_model = to_pinocchio(puma, theta=theta[:30])
    pin_data = pin_model.createData()
    friction = theta[30:]
    for k in range(data.n_samples):
        expected = pin.rnea(pin_model, pin_data, data.q[k], data.dq[k], data.ddq[k]) + friction * data.dq[k]
        np.testing.assert_allclose(data.tau[k], expected, atol=1e-8)


@pytest.mark.parametrize("kind", ["internal", "external", "combined"])
def test_base_parameters_recovered_within_three_sigma_and_validation_at_noise_floor(puma, kind):
    model = build_model(puma, kind, "viscous")
    theta = true_parameters(model, seed=2)
    train = simulate(model, theta, random_fourier(puma, 3), noise=NOISE, seed=11)
    validate = simulate(model, theta, random_fourier(puma, 4), noise=NOISE, seed=12)
    result = identify(model, train, validate)
    estimate = result.estimate
    error = (estimate.values - model.base.to_base(theta)) / estimate.std
    assert np.all(np.abs(error) < 3.0), dict(zip(estimate.names, np.round(error, 2)))
    for channel, mse in result.validation.mse.items():
        assert 0.85 < mse / NOISE[channel] ** 2 < 1.2, (channel, mse, NOISE[channel] ** 2)
    np.testing.assert_allclose(np.sqrt(estimate.channel_variance), [NOISE[c] for c in model.channels], rtol=0.1)


def test_weighting_makes_the_combined_model_efficient_and_its_uncertainty_honest(puma):
    """Monte Carlo over noise draws: the per-channel weighting lowers the actual parameter error,
    and the weighted estimator's stated σ matches the spread it really has."""
    model = build_model(puma, "combined", "viscous")
    theta = true_parameters(model, seed=2)
    clean = stack(model, simulate(model, theta, random_fourier(puma, 3), rate_hz=100.0))
    sigma = np.array([NOISE[channel] for channel in model.channels])
    truth = model.base.to_base(theta)
    generator = np.random.default_rng(0)
    errors = {"ols": [], "wls": []}
    stated = {"ols": [], "wls": []}
    for _ in range(30):
        noisy = replace(clean, y=clean.y + generator.normal(size=clean.y.shape) * sigma)
        for label, estimator in (("ols", LeastSquares()), ("wls", WeightedLeastSquares())):
            estimator.fit(noisy)
            errors[label].append(estimator.theta_ - truth)
            stated[label].append(estimator.std_)
    spread = {label: np.sqrt(np.mean(np.square(errors[label]), axis=0)) for label in errors}
    assert np.sum(spread["wls"] ** 2) < 0.5 * np.sum(spread["ols"] ** 2)
    ratio = spread["wls"] / np.mean(stated["wls"], axis=0)
    assert np.all((ratio > 0.55) & (ratio < 1.6)), np.round(ratio, 2)


def test_plate_offsets_break_the_combined_model_unless_modelled(puma):
    """A constant moment on mx (cable) and mz (tightened screws), as the PUMA paper suspected:
    weighting alone does not save the combined estimate, offsets alone leave the small joint
    channels badly fitted; the wrench_offset effect with weighting recovers everything."""
    bias = {"mx": 15.0, "mz": 4.0}
    plain = build_model(puma, "combined", "viscous")
    with_offsets = build_model(puma, "combined", "viscous,wrench_offset")
    theta = true_parameters(with_offsets, seed=2, wrench_offset=[0, 0, 0, 15.0, 0, 4.0])
    theta_plain = theta[: plain.n_parameters]
    train = simulate(plain, theta_plain, random_fourier(puma, 3), noise=NOISE, seed=11, bias=bias)
    validate = simulate(plain, theta_plain, random_fourier(puma, 4), noise=NOISE, seed=12, bias=bias)
    truth_plain = plain.base.to_base(theta_plain)

    for weighted in (False, True):
        failed = identify(plain, train, validate, weighted=weighted)
        error = (failed.estimate.values - truth_plain) / failed.estimate.std
        assert np.max(np.abs(error)) > 10, weighted
        assert failed.validation.mse["mz"] > 5 * NOISE["mz"] ** 2, weighted

    unweighted = identify(with_offsets, train, validate, weighted=False)
    assert unweighted.validation.mse["tau3"] > 1.5 * NOISE["tau3"] ** 2  # the wrench rows swamp the joint rows
    fixed = identify(with_offsets, train, validate, weighted=True)
    error = (fixed.estimate.values - with_offsets.base.to_base(theta)) / fixed.estimate.std
    assert np.all(np.abs(error) < 3.0), dict(zip(fixed.estimate.names, np.round(error, 2)))
    offsets = dict(zip(fixed.estimate.names, fixed.estimate.values))
    assert abs(offsets["mx_off"] - 15.0) < 0.2 and abs(offsets["mz_off"] - 4.0) < 0.1
    for channel, mse in fixed.validation.mse.items():
        assert mse / NOISE[channel] ** 2 < 1.2, channel


def test_fit_accepts_a_model_and_measurements_like_a_stacked_problem(puma):
    model = build_model(puma, "internal", "viscous")
    data = simulate(model, true_parameters(model), random_fourier(puma, 3), rate_hz=50.0, noise=NOISE)
    estimator = WeightedLeastSquares()
    assert estimator.fit(model, data) is estimator
    np.testing.assert_allclose(estimator.theta_, WeightedLeastSquares().fit(stack(model, data)).theta_)
    assert estimator.residuals_.shape == (data.n_samples, 3)
    assert estimator.cov_.shape == (model.n_base, model.n_base)
    np.testing.assert_allclose(estimator.predict(stack(model, data)), data.tau - estimator.residuals_)
    np.testing.assert_allclose(estimator.predict(model, replace(data, tau=None)), estimator.predict(stack(model, data)))
    with pytest.raises(TypeError, match="predict.model, measurements.: give measurements"):
        estimator.predict(model)


def test_unfitted_estimator_and_bad_settings_raise_clear_errors():
    with pytest.raises(NotFittedError, match="not fitted"):
        _ = LeastSquares().theta_
    problem = IdentificationProblem(np.ones((5, 1, 1)), np.ones((5, 1)), ("tau1",), ("m",))
    with pytest.raises(ValueError, match="max_iter"):
        WeightedLeastSquares(max_iter=0).fit(problem)
    with pytest.raises(TypeError, match="measurements are missing"):
        LeastSquares().fit(build_model(load_robot("puma560", joints=3), "internal"))
    assert not hasattr(LeastSquares(), "theta_")  # NotFittedError is an AttributeError too
    with pytest.raises(ValueError, match="variance_floor must be a non-negative number, got nan"):
        WeightedLeastSquares(variance_floor=np.nan).fit(problem)
    with pytest.raises(TypeError, match="tol must be a number, got str"):
        WeightedLeastSquares(tol="a").fit(problem)
    Y = np.ones((5, 1, 1))
    Y[3] = np.nan
    with pytest.raises(ValueError, match="regressor column m holds NaN or inf .sample 3, channel tau1"):
        IdentificationProblem(Y, np.ones((5, 1)), ("tau1",), ("m",))


def test_a_dead_channel_or_overflowing_data_is_named_not_a_lapack_error():
    Y = np.random.default_rng(0).normal(size=(50, 2, 2))
    y = np.column_stack([Y[:, 0] @ [1.0, 2.0], np.zeros(50)])  # the second sensor reads nothing
    problem = IdentificationProblem(Y, y, ("tau1", "tau2"), ("a", "b"))
    with pytest.raises(ValueError, match="channel.s. tau2 read zero in every sample"):
        WeightedLeastSquares().fit(problem)
    assert LeastSquares().fit(problem).theta_.shape == (2,)  # ordinary least squares still works
    with pytest.raises(ValueError, match="tau1, tau2 overflow when squared .values up to 1e.200"):
        IdentificationProblem(Y, y + 1e200, ("tau1", "tau2"), ("a", "b"))


def test_fitted_values_are_read_only_and_predict_checks_the_parameter_axis():
    problem = IdentificationProblem(np.arange(10.0).reshape(5, 1, 2), np.arange(5.0).reshape(5, 1), ("tau1",), ("m", "c"))
    estimator = LeastSquares().fit(problem)
    with pytest.raises(ValueError, match="read-only"):
        estimator.theta_[0] = 0.0
    with pytest.raises(ValueError, match="last axis must hold the 2 fitted parameters"):
        estimator.predict(np.ones((5, 1, 3)))


def test_unexcited_parameters_are_named(puma):
    model = build_model(puma, "internal", "viscous")
    data = simulate(model, true_parameters(model), random_fourier(puma, 3), rate_hz=50.0)
    still = replace(data, q=data.q * [0, 1, 1] + [0.3, 0, 0], dq=data.dq * [0, 1, 1], ddq=data.ddq * [0, 1, 1])
    with pytest.raises(IdentifiabilityError, match="fv1"):
        LeastSquares().fit(model, still)


def test_extra_columns_and_channel_selection_keep_the_problem_consistent(puma):
    model = build_model(puma, "combined", "viscous")
    theta = true_parameters(model)
    data = simulate(model, theta, random_fourier(puma, 3), rate_hz=50.0)
    problem = stack(model, data)
    joints = problem.select_channels(["tau1", "tau2", "tau3"])
    np.testing.assert_allclose(joints.y, data.tau)
    augmented = problem.with_columns(np.ones(problem.y.shape), ["bias"])
    assert augmented.names[-1] == "bias" and augmented.Y.shape[2] == problem.n_parameters + 1
    estimate = LeastSquares().fit(augmented).estimate_
    assert abs(estimate.values[-1]) < 1e-6
    with pytest.raises(ValueError, match="already"):
        problem.with_columns(np.ones(problem.y.shape), ["fv1"])


def test_channel_weights_come_from_the_residual_in_the_motions_band():
    """Torques fitted as recorded after a Butterworth differentiation (``torques="recorded"``): the channel weights are those of the residual
    in the motion's band, not of the recording's high-frequency noise, which no column fits. Two channels with the
    same in-band noise, one with a large white noise on top: weighted alike in band, 10 times apart as recorded."""
    from estimation.estimators.identification_problem import ResidualBand, in_band_variance
    from estimation.preprocessing.differentiation import ButterworthDifferentiation
    from dynamics.measurements import Measurements

    rate, n = 200.0, 8000
    rng = np.random.default_rng(3)
    t = np.arange(n) / rate
    band = ResidualBand(2.0, 4, rate)
    slow = band.apply(rng.normal(size=(n, 2)))  # in-band noise, the same on both channels
    slow /= slow.std(axis=0)
    white = rng.normal(size=(n, 2)) * np.array([0.0, 3.0])  # 2 % of its variance in band
    columns = np.stack([np.sin(0.5 * t), np.cos(0.3 * t)], axis=1)
    Y = np.zeros((n, 2, 2))
    Y[:, 0, 0], Y[:, 1, 1] = columns[:, 0], columns[:, 1]
    y = Y @ np.array([2.0, -1.0]) + slow + white
    recorded = WeightedLeastSquares().fit(IdentificationProblem(Y, y, ("tau1", "tau2"), ("a", "b")))
    banded = WeightedLeastSquares().fit(IdentificationProblem(Y, y, ("tau1", "tau2"), ("a", "b"), band=band))
    assert recorded.estimate_.weights[0] / recorded.estimate_.weights[1] > 5
    assert banded.estimate_.weights[0] / banded.estimate_.weights[1] == pytest.approx(1.0, rel=0.3)
    # the weights are the inverse in-band variances; the reported variance stays that of the recorded residual
    np.testing.assert_allclose(banded.estimate_.weights,
                               1 / in_band_variance(banded.estimate_.residuals, 2, band), rtol=1e-4)
    np.testing.assert_allclose(banded.estimate_.channel_variance, recorded.estimate_.channel_variance, rtol=0.05)
    # a Butterworth-prepared record carries its band into the problem; its torques as recorded
    q = np.stack([np.sin(0.5 * t), np.cos(0.3 * t)], axis=1)
    measured = Measurements(t=t, q=q, tau=y)
    prepared = ButterworthDifferentiation(cutoff_hz=2.0, torques="recorded").apply(measured)
    np.testing.assert_array_equal(prepared.tau, y)
    assert ResidualBand.of(prepared) == band
    assert ResidualBand.of(measured) is None
    # torques filtered alike (the default): nothing out of band, no band
    assert ResidualBand.of(ButterworthDifferentiation(cutoff_hz=2.0, torques="filtered").apply(measured)) is None


def test_summed_weights_come_from_the_residual_in_the_motions_band_as_in_memory(tmp_path, monkeypatch):
    """The sums of the in-band problem (``NormalEquations.band``): summed in blocks of a record in memory
    (``accumulate``) and read in chunks from a file (``file_sums``, windows reaching the band filter's margin further),
    the weighted fit from the sums has the in-memory weights and estimate (relative 1e-6, the iteration's tolerance); without the band (the
    torques filtered alike) the sums have none."""
    from dynamics.models import build_model
    from dynamics.robots import load_robot
    from dynamics.measurements import Measurements
    from dynamics.simulation.synthetic import simulate, true_parameters
    from estimation.estimators.identification_problem import stack
    from estimation.estimators.normal_equations import accumulate
    from estimation.estimators.summed_least_squares import SummedLeastSquares
    from estimation.preprocessing.differentiation import ButterworthDifferentiation
    from estimation.streaming.chunks import file_sums
    from oed.fourier import random_fourier

    model = build_model(load_robot("puma560", joints=3), "internal", "viscous")
    theta = true_parameters(model, seed=0)
    data = simulate(model, theta, random_fourier(model.robot, seed=3), noise={c: 0.3 for c in model.channels},
                    seed=1, rate_hz=200.0, periods=1)
    rng = np.random.default_rng(0)
    tau = data.tau + rng.normal(size=data.tau.shape) * np.array([0.1, 2.0, 0.5])  # unequal out-of-band noise
    raw = Measurements(data.t, data.q, tau=tau)
    path = tmp_path / "raw.csv"
    raw.write(path)
    prepared = ButterworthDifferentiation(5.0, torques="recorded").apply(raw)
    memory = WeightedLeastSquares().fit(stack(model, prepared)).estimate_
    summed = accumulate(model, prepared, chunk_size=150)
    import functools

    import estimation.streaming.chunks as chunks

    # the streamed reader's filter keeping the torques as recorded, whatever the default
    monkeypatch.setattr(chunks, "ButterworthDifferentiation", functools.partial(ButterworthDifferentiation,
                                                                                torques="recorded"))
    streamed = file_sums(path, model, chunk_size=150, cutoff_hz=5.0).sums
    assert summed.band is not None and streamed.band is not None
    for sums in (summed, streamed):
        fit = SummedLeastSquares().fit(sums).estimate_
        np.testing.assert_allclose(fit.weights, memory.weights, rtol=1e-6)  # the iteration stops at tol 1e-6
        np.testing.assert_allclose(fit.values, memory.values, rtol=1e-6, atol=1e-8 * np.max(np.abs(memory.values)))
    # without the band, the weights are those of the recorded residual, its white noise whole (a tenth in band)
    from dataclasses import replace
    unbanded = SummedLeastSquares().fit(replace(summed, band=None)).estimate_
    assert np.all(unbanded.weights < 0.2 * memory.weights)
    assert accumulate(model, ButterworthDifferentiation(5.0, torques="filtered").apply(raw)).band is None


def test_the_band_filters_as_scipys_zero_phase_filter():
    """``ResidualBand.apply`` (the in-band variances, the in-band sums) equals ``scipy.signal.sosfiltfilt`` along the
    samples, each segment on its own, whatever the trailing axes; a segment too short for the padding is left."""
    import scipy.signal

    from estimation.estimators.identification_problem import ResidualBand

    rng = np.random.default_rng(5)
    band = ResidualBand(6.0, 4, 200.0, segments=((0, 300), (300, 310), (310, 700)))
    values = rng.normal(size=(700, 3, 4))
    sos = scipy.signal.butter(4, 6.0, btype="low", fs=200.0, output="sos")
    expected = values.copy()
    for start, stop in ((0, 300), (310, 700)):
        expected[start:stop] = scipy.signal.sosfiltfilt(sos, values[start:stop], axis=0)
    np.testing.assert_allclose(band.apply(values), expected, rtol=1e-12, atol=1e-12)
    assert not np.allclose(expected[:300], values[:300])
    np.testing.assert_array_equal(band.apply(values)[300:310], values[300:310])
