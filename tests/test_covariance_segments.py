"""The HAC covariance runs no lag across a boundary between stacked segments (issue 13 review).

Two pieces recorded apart are independent: the order in which they are stacked must not change the
standard deviations. A residual that jumps at the boundary (the first piece ends high, the second
starts low) is where a lag across the boundary would count the jump as serial correlation.
"""

from __future__ import annotations

import numpy as np
import pytest

from estimation.uncertainty.covariance import (
    bandwidth,
    hac_covariance,
    long_run_covariance,
    prewhitened_long_run_covariance,
    segment_bounds,
)
from estimation.estimators.least_squares import WeightedLeastSquares, stack
from dynamics.measurements import Measurements
from estimation.data.segments import concatenate


def _ramp_scores(generator, n, start, stop):
    """Scores drifting from ``start`` to ``stop`` with AR(1) wiggles: a residual that ends far from where it began."""
    wiggle = np.zeros((n, 2))
    for k in range(1, n):
        wiggle[k] = 0.8 * wiggle[k - 1] + 0.3 * generator.normal(size=2)
    return np.linspace(start, stop, n)[:, None] * np.array([1.0, -0.5]) + wiggle


def test_long_run_covariance_is_the_sum_over_segments():
    generator = np.random.default_rng(0)
    first, second = _ramp_scores(generator, 300, -1.0, 3.0), _ramp_scores(generator, 200, -3.0, 1.0)
    g = np.vstack([first, second])
    for lags in (0, 5, 40, 250):  # 250: longer than the second segment, which is then one batch
        joined = long_run_covariance(g, lags, [(0, 300), (300, 500)])
        separate = long_run_covariance(first, lags) + long_run_covariance(second, min(lags, 199))
        np.testing.assert_allclose(joined, separate, rtol=1e-12)
    np.testing.assert_allclose(long_run_covariance(g, 7, None), long_run_covariance(g, 7, [(0, 500)]))


@pytest.mark.parametrize("prewhiten", [True, False])
def test_the_order_of_the_segments_does_not_change_the_hac_covariance(prewhiten):
    generator = np.random.default_rng(1)
    n1, n2 = 400, 300
    t = np.concatenate([np.arange(n1), np.arange(n2)]) / 100.0
    Y = np.stack([np.ones_like(t), np.sin(2 * np.pi * 0.7 * t)], axis=-1)[:, None, :]  # (N, 1, 2)
    # the residual of the first piece ends at +3, the second starts at -3: a jump at the boundary
    residual = np.concatenate([np.linspace(-1.0, 3.0, n1), np.linspace(-3.0, 1.0, n2)]) + 0.2 * generator.normal(size=n1 + n2)
    residual = residual[:, None]
    bread = np.linalg.inv(np.einsum("tcr,tcs->rs", Y, Y))
    weights = np.ones(1)
    swapped = np.r_[n1:n1 + n2, 0:n1]
    kwargs = {"prewhiten": prewhiten}
    cov, lags = hac_covariance(Y, residual, weights, bread, segments=[(0, n1), (n1, n1 + n2)], **kwargs)
    cov_swapped, lags_swapped = hac_covariance(Y[swapped], residual[swapped], weights, bread,
                                               segments=[(0, n2), (n2, n1 + n2)], **kwargs)
    np.testing.assert_allclose(cov, cov_swapped, rtol=1e-9)
    assert lags == lags_swapped
    # stacked as one record the lags cross the jump: the order then matters (what the segments avoid)
    crossing, _ = hac_covariance(Y, residual, weights, bread, lags=lags, **kwargs)
    crossing_swapped, _ = hac_covariance(Y[swapped], residual[swapped], weights, bread, lags=lags, **kwargs)
    assert not np.allclose(crossing, crossing_swapped, rtol=1e-3)


def test_prewhitening_and_bandwidth_use_no_pair_across_the_boundary():
    generator = np.random.default_rng(2)
    first, second = _ramp_scores(generator, 500, -1.0, 3.0), _ramp_scores(generator, 500, -3.0, 1.0)
    bounds = [(0, 500), (500, 1000)]
    swapped_bounds = [(0, 500), (500, 1000)]
    g, g_swapped = np.vstack([first, second]), np.vstack([second, first])
    meat, lags = prewhitened_long_run_covariance(g, segments=bounds)
    meat_swapped, lags_swapped = prewhitened_long_run_covariance(g_swapped, segments=swapped_bounds)
    np.testing.assert_allclose(meat, meat_swapped, rtol=1e-9)
    assert lags == lags_swapped and bandwidth(g, bounds) == bandwidth(g_swapped, swapped_bounds)


def test_bad_segment_bounds_are_refused():
    with pytest.raises(ValueError, match="tile"):
        segment_bounds(10, [(0, 4), (5, 10)])
    with pytest.raises(ValueError, match="tile"):
        segment_bounds(10, [(0, 4), (4, 9)])
    assert segment_bounds(10, None) == [(0, 10)]


def test_stacked_segments_reach_the_estimator(tmp_path):
    """``stack`` of a concatenation carries its segments; the HAC std do not depend on their order."""
    from dynamics.models import build_model
    from dynamics.robots import load_robot
    from dynamics.simulation.synthetic import simulate, true_parameters

    from oed.fourier import random_fourier

    robot = load_robot("puma560", joints=2)
    model = build_model(robot, "internal", "viscous,offset")
    theta = true_parameters(model, seed=0, offset=[0.5, -0.3])
    pieces = []
    for seed, shift in ((3, 0.4), (4, -0.4)):  # a torque bias that differs between the pieces: a jump
        record = simulate(model, theta, random_fourier(robot, seed=seed), rate_hz=100.0, periods=1,
                          noise={"tau1": 0.1, "tau2": 0.1}, seed=seed, bias={"tau1": shift, "tau2": -shift})
        pieces.append(Measurements(record.t, record.q, record.dq, record.ddq, record.tau, None,
                                   {"source": f"piece{seed}"}))
    forward, backward = stack(model, pieces), stack(model, pieces[::-1])
    assert forward.segments == ((0, pieces[0].n_samples), (pieces[0].n_samples, forward.n_samples))
    assert concatenate(pieces).metadata["segments"][1]["start"] == pieces[0].n_samples
    std = WeightedLeastSquares(covariance="hac").fit(forward).estimate_.std
    std_backward = WeightedLeastSquares(covariance="hac").fit(backward).estimate_.std
    np.testing.assert_allclose(std, std_backward, rtol=1e-6)
    assert forward.with_columns(np.zeros((forward.n_samples, 2, 1)), ["z"]).segments == forward.segments


def test_batch_means_of_shaped_fits_restart_at_each_segment():
    from estimation.uncertainty.batch_means import batch_length, batch_means

    generator = np.random.default_rng(3)
    first, second = _ramp_scores(generator, 310, -1.0, 3.0), _ramp_scores(generator, 190, -3.0, 1.0)
    joined = batch_means(np.vstack([first, second]), 50, [(0, 310), (310, 500)])
    np.testing.assert_allclose(joined, batch_means(first, 50) + batch_means(second, 50), rtol=1e-12)
    residual = np.vstack([first, second]).T  # (m, N): the jump at 310 is no lag pair
    weights = np.ones(2)
    swapped = np.vstack([second, first]).T
    assert batch_length(residual, weights, [(0, 310), (310, 500)]) == batch_length(swapped, weights, [(0, 190), (190, 500)])
