"""The diagnosis's F tests and weighted validation errors from sums, against its in-memory fits."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.stats

from dynamics.effects.linear import CoulombFriction
from dynamics.models import build_model
from dynamics.robots import load_robot
from estimation.streaming.candidate_screening import accumulate_candidates, f_tests, weighted_fit, weighted_mse
from estimation.diagnosis.search import candidate_columns, default_candidates
from estimation.estimators.least_squares import stack
from dynamics.simulation.synthetic import simulate, true_parameters


from oed.fourier import random_fourier


def _weighted_fit(Y, y, weights):
    """The in-memory reference: least squares with fixed channel weights, ``(theta, weighted RSS)``."""
    root = np.sqrt(weights)
    A = (Y * root[None, :, None]).reshape(-1, Y.shape[2])
    b = (y * root[None, :]).reshape(-1)
    theta, *_ = np.linalg.lstsq(A, b, rcond=None)
    return theta, float(np.sum((A @ theta - b) ** 2))


def _weighted_mse(Y, y, theta, weights):
    return float(np.sum(np.mean((y - Y @ theta) ** 2, axis=0) * weights))


def test_f_tests_from_sums_equal_the_in_memory_fits():
    robot = load_robot("puma560", joints=3)
    truth = build_model(robot, "internal", ("viscous", CoulombFriction(joints=(1,))))
    theta = true_parameters(truth, seed=0, coulomb=[8.0])
    noise = {"tau1": 0.3, "tau2": 0.3, "tau3": 0.1}
    train = simulate(truth, theta, random_fourier(robot, seed=3), noise=noise, seed=1)
    validate = simulate(truth, theta, random_fourier(robot, seed=4), noise=noise, seed=2)
    model = build_model(robot, "internal", "viscous")
    candidates = [c for c in default_candidates(model) if c.name in ("coulomb", "offset")]
    weights = 1.0 / np.array([noise[c] ** 2 for c in model.channels])
    screen = accumulate_candidates(model, train, candidates, chunk_size=350)
    held_out = accumulate_candidates(model, validate, candidates, chunk_size=400)
    tests = f_tests(screen, weights)
    Y, y = stack(model, train).Y, stack(model, train).y
    _, rss = _weighted_fit(Y, y, weights)
    for test in tests:
        columns = candidate_columns(model, candidates[test.index], train)
        theta_aug, rss_aug = _weighted_fit(np.concatenate([Y, columns], axis=2), y, weights)
        count = columns.shape[2]
        dof = y.size - Y.shape[2] - count
        statistic = ((rss - rss_aug) / count) / (rss_aug / dof)
        assert test.f_statistic == pytest.approx(statistic, rel=1e-8, abs=1e-8)
        assert test.p_value == pytest.approx(scipy.stats.f.sf(statistic, count, dof), rel=1e-6, abs=1e-300)
        np.testing.assert_allclose(test.theta, theta_aug, rtol=1e-9, atol=1e-9 * np.abs(theta_aug).max())
        Y_validate = np.concatenate([stack(model, validate).Y, candidate_columns(model, candidates[test.index], validate)], axis=2)
        expected = _weighted_mse(Y_validate, stack(model, validate).y, theta_aug, weights)
        assert weighted_mse(held_out.sums, list(range(model.n_base)) + list(screen.blocks[test.index]), test.theta,
                            weights) == pytest.approx(expected, rel=1e-10)
    best = min(tests, key=lambda t: t.p_value)
    assert (best.name, candidates[best.index].joints) == ("coulomb", (1,))
    # after adding it, the next round's tests exclude it
    columns = list(range(model.n_base)) + list(screen.blocks[best.index])
    assert best.index not in [t.index for t in f_tests(screen, weights, columns=columns)]
    assert weighted_fit(screen.sums, columns, weights)[1] == pytest.approx(best.rss_augmented, rel=1e-12)
