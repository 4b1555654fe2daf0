"""A per-channel sample mask (:mod:`estimation.data.channel_mask`): a sample whose reading on one channel is no
measurement (a clipped torque sensor) leaves that channel's equation out of the fit and that channel's error only;
the other channels' equations of that sample stay. Checked against independent sums: a plain least-squares fit on
the valid equations alone (``numpy.linalg.lstsq``) and the errors summed by hand over each channel's valid samples.
"""

from __future__ import annotations

import numpy as np
import pytest

from estimation.data.channel_mask import channel_counts, channel_mean, masked_channels, masked_equations
from estimation.estimators.identification_problem import IdentificationProblem
from estimation.estimators.least_squares import LeastSquares, WeightedLeastSquares
from estimation.identification.validation import Comparison, channel_mse


def _problem(seed: int = 0, n: int = 400, m: int = 3, r: int = 5):
    generator = np.random.default_rng(seed)
    Y = generator.standard_normal((n, m, r))
    theta = generator.standard_normal(r)
    noise = generator.standard_normal((n, m)) * np.array([0.01, 0.1, 0.03])[:m]
    y = Y @ theta + noise
    masked = np.zeros((n, m), dtype=bool)
    masked[50:170, 1] = True  # one channel's stretch, the others' equations of those samples kept
    masked[300:305, 2] = True
    y[masked] = 1e3  # what a clipped sensor read: far off, so that keeping it would show
    return Y, y, masked, theta


def test_the_masked_equations_leave_the_fit_and_the_others_of_that_sample_stay():
    Y, y, masked, _ = _problem()
    problem = IdentificationProblem(*masked_equations(Y, np.where(masked, np.nan, y))[:2], ("tau1", "tau2", "tau3"),
                                    tuple(f"p{k}" for k in range(Y.shape[2])), mask=~masked)
    valid = ~masked.reshape(-1)
    expected = np.linalg.lstsq(Y.reshape(-1, Y.shape[2])[valid], y.reshape(-1)[valid], rcond=None)[0]
    ols = LeastSquares().fit(problem)
    assert np.allclose(ols.theta_, expected, rtol=1e-10, atol=1e-12)
    assert problem.n_equations == int(valid.sum())
    assert np.array_equal(problem.channel_samples, (~masked).sum(axis=0))
    # a row-wise drop (the whole sample out wherever one channel is masked) is another, poorer answer
    rows = ~masked.any(axis=1)
    by_row = np.linalg.lstsq(Y[rows].reshape(-1, Y.shape[2]), y[rows].reshape(-1), rcond=None)[0]
    assert not np.allclose(by_row, expected, rtol=1e-10, atol=1e-12)
    # the channel variances over each channel's own valid samples: ‖ρ_c‖² / (N_c − r/m)
    residual = y - Y @ ols.theta_
    counts = (~masked).sum(axis=0)
    by_hand = np.array([np.sum(residual[~masked[:, c], c] ** 2) for c in range(3)]) / (counts - Y.shape[2] / 3)
    assert np.allclose(ols.channel_variance_, by_hand, rtol=1e-10)


def test_a_weighted_fit_weights_each_channel_by_its_valid_samples_only():
    Y, y, masked, _ = _problem(1)
    y_masked = np.where(masked, np.nan, y)
    stacked = masked_equations(Y, y_masked)
    problem = IdentificationProblem(stacked[0], stacked[1], ("tau1", "tau2", "tau3"),
                                    tuple(f"p{k}" for k in range(Y.shape[2])), mask=stacked[2])
    wls = WeightedLeastSquares().fit(problem)
    # independent: iterate the weights by hand on the valid equations alone
    weights, counts = np.ones(3), (~masked).sum(axis=0)
    for _ in range(50):
        scale = np.sqrt(np.broadcast_to(weights, y.shape))[~masked]
        theta = np.linalg.lstsq(Y[~masked] * scale[:, None], y[~masked] * scale, rcond=None)[0]
        residual = np.where(masked, 0.0, y - Y @ theta)
        weights = 1.0 / (np.sum(residual**2, axis=0) / (counts - Y.shape[2] / 3))
    assert np.allclose(wls.theta_, theta, rtol=1e-6, atol=1e-9)
    # nothing masked: the problem is the one given, no copy, no mask
    same = masked_equations(Y, y)
    assert same[0] is Y and same[1] is y and same[2] is None


def test_each_channels_error_is_over_its_valid_samples_and_the_counts_are_said():
    generator = np.random.default_rng(2)
    measured = generator.standard_normal((200, 3))
    predicted = measured + generator.standard_normal((200, 3)) * 0.1
    masked = np.zeros_like(measured, dtype=bool)
    masked[20:80, 0] = True
    recorded = np.where(masked, np.nan, measured)
    mse = channel_mse(recorded, predicted, ("tau1", "tau2", "tau3"))
    by_hand = [np.mean((measured[~masked[:, c], c] - predicted[~masked[:, c], c]) ** 2) for c in range(3)]
    assert np.allclose(list(mse.values()), by_hand, rtol=1e-12)
    comparison = Comparison(np.arange(200.0), recorded, predicted, ("tau1", "tau2", "tau3"))
    assert comparison.channel_samples == {"tau1": 140, "tau2": 200, "tau3": 200}
    power = np.mean(measured[~masked[:, 0], 0] ** 2)
    assert np.isclose(comparison.relative_mse["tau1"], by_hand[0] / power, rtol=1e-12)
    clean = Comparison(np.arange(200.0), measured, predicted, ("tau1", "tau2", "tau3"))
    assert clean.channel_samples is None
    # a prediction that failed (NaN where the recording is valid) stays NaN: it is no mask
    failed = predicted.copy()
    failed[5, 1] = np.nan
    assert np.isnan(channel_mse(recorded, failed, ("tau1", "tau2", "tau3"))["tau2"])
    assert np.array_equal(channel_counts(recorded), [140, 200, 200])
    assert np.allclose(channel_mean(recorded), [np.mean(measured[~masked[:, 0], 0]), *measured[:, 1:].mean(axis=0)])


def test_the_readers_mask_puts_nan_in_the_masked_channel_only():
    tau, wrench = np.ones((5, 2)), np.ones((5, 6))
    found = np.zeros((5, 8), dtype=bool)
    found[1, 1] = found[3, 7] = True
    masked = masked_channels({"q": np.zeros((5, 2)), "tau": tau, "wrench": wrench}, found)
    assert np.isnan(masked["tau"][1, 1]) and np.isnan(masked["wrench"][3, 5])
    assert np.count_nonzero(np.isnan(masked["tau"])) == 1 and np.count_nonzero(np.isnan(masked["wrench"])) == 1
    assert np.all(tau == 1) and masked["q"] is not None
    with pytest.raises(ValueError, match="mask has shape"):
        IdentificationProblem(np.zeros((5, 2, 1)), np.zeros((5, 2)), ("a", "b"), ("p",), mask=np.ones((5, 3), bool))


def test_a_driven_joints_unlogged_torque_is_refused_naming_what_only_its_equations_hold(tmp_path):
    """A log without ``tau3`` for a robot whose joint 3 is driven: the refusal (h-passive's) now names the base
    parameters that no other joint's equation holds. Checked independently: each named parameter's column is zero on
    tau1 and tau2 at other random states, and the others' equations alone leave exactly those undetermined (the
    rank of the regressor stacked over tau1 and tau2 falls short by their count)."""
    import pandas as pd

    from dynamics.models import build_model
    from dynamics.robots import load_robot
    from estimation.data import read_record
    from estimation.data.channel_mask import channel_only_parameters
    from estimation.data.loading import MissingColumnError

    model = build_model(load_robot("puma560", joints=3), "internal", "viscous,coulomb,offset")
    alone = channel_only_parameters(model, ["tau3"])
    assert {"fv3", "fc3"} <= set(alone) and not {"fv1", "fv2"} & set(alone), alone
    generator = np.random.default_rng(7)
    states = [generator.uniform(-3, 3, (300, 3)), generator.standard_normal((300, 3)), generator.standard_normal((300, 3))]
    Y = model.evaluate_base(*states)
    others = Y[:, :2, :].reshape(-1, Y.shape[2])
    index = [model.base.names.index(name) for name in alone]
    assert np.all(others[:, index] == 0)
    assert np.linalg.matrix_rank(others) == np.linalg.matrix_rank(Y.reshape(-1, Y.shape[2])) - len(alone)
    t = np.arange(0.0, 2.0, 0.01)
    pd.DataFrame({"t": t, "q1": np.sin(t), "q2": np.cos(t), "q3": np.sin(2 * t), "tau1": np.cos(t),
                  "tau2": np.sin(t)}).to_csv(tmp_path / "log.csv", index=False)
    with pytest.raises(MissingColumnError, match=r"no torque column tau3 .*unknown, not zero.*without tau3 no other "
                       r"joint's equation holds .*fv3.*cannot be identified"):
        read_record(tmp_path / "log.csv", model=model)


def test_a_jittered_clipped_record_masks_the_recorded_samples_and_the_grid_beside_them(tmp_path):
    """A record resampled by its jittered stamps, its tau2 clipped: the samples as recorded hold tau2 masked exactly
    at its clipped samples (the errors' samples), the uniform grid (the fit's) at those and the few grid points
    interpolated from them; tau1 and tau3 masked nowhere."""
    import warnings

    import pandas as pd

    from dynamics.models import build_model
    from dynamics.robots import load_robot
    from estimation.data.records import read_measurements
    from tests.test_unseen_robots import FRICTION, Log, truth, urdf_of, write_record

    model = build_model(load_robot(urdf=urdf_of("puma560:3", tmp_path)), "internal", FRICTION)
    write_record(model, truth(model), Log(4.0, 250.0, velocity=False), 11, tmp_path / "clean.csv")
    table = pd.read_csv(tmp_path / "clean.csv")
    table.loc[1:, "t"] += np.random.default_rng(0).uniform(-1e-4, 1e-4, len(table) - 1)
    limit = 0.8 * float(np.abs(table["tau2"]).max())
    table["tau2"] = np.clip(table["tau2"], -limit, limit)
    table.to_csv(tmp_path / "jittered.csv", index=False, float_format="%.10g")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        read = read_measurements(tmp_path / "jittered.csv", model=model)
    written = pd.read_csv(tmp_path / "jittered.csv")["tau2"].to_numpy()
    at_limit = np.abs(written) >= limit * (1 - 1e-9)
    assert read.metadata["resampled_from"] == len(table) and read.metadata["saturated_samples"] == {
        "tau2": int(at_limit.sum())}
    assert np.array_equal(np.isnan(read.as_recorded.tau[:, 1]), at_limit)
    assert not np.isnan(read.as_recorded.tau[:, [0, 2]]).any() and not np.isnan(read.tau[:, [0, 2]]).any()
    grid_masked = np.isnan(read.tau[:, 1])
    assert at_limit.sum() <= grid_masked.sum() <= at_limit.sum() + 2 * np.count_nonzero(np.diff(at_limit.astype(int)))
