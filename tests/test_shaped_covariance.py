"""``identify(covariance=...)`` on the shaped path (variable projection): ``"classical"`` gives the
white-noise covariance of the full Jacobian and says so, ``"hac"`` the batch-means sandwich."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from dynamics.effects.linear import CoulombFriction
from dynamics.models import build_model
from dynamics.robots import load_robot
from estimation.identification.fit import identify
from dynamics.simulation.synthetic import simulate, true_parameters


from oed.fourier import random_fourier


@pytest.fixture(scope="module")
def setting():
    robot = load_robot("puma560", joints=3)
    truth = build_model(robot, "internal", ("viscous", CoulombFriction(smoothing=0.04)))
    theta = true_parameters(truth, seed=1, coulomb=[6.0, 4.0, 2.0])
    clean = simulate(truth, theta, random_fourier(robot, seed=5), rate_hz=250, periods=2)
    return robot, clean


def _coloured(generator, shape, rho):
    out = np.empty(shape)
    out[0] = generator.normal(size=shape[1])
    for k in range(1, shape[0]):
        out[k] = rho * out[k - 1] + np.sqrt(1 - rho**2) * generator.normal(size=shape[1])
    return out


def test_classical_is_the_white_noise_covariance_and_says_so(setting):
    robot, clean = setting
    record = replace(clean, tau=clean.tau + 0.1 * _coloured(np.random.default_rng(0), clean.tau.shape, 0.95))
    model = build_model(robot, "internal", "viscous,coulomb:tanh")
    hac = identify(model, record)
    classical = identify(model, record, covariance="classical")
    assert hac.estimate.cov_method == "batch_means" and hac.to_dict()["cov_method"] == "batch_means"
    assert classical.estimate.cov_method == "classical" and classical.to_dict()["cov_method"] == "classical"
    np.testing.assert_allclose(classical.estimate.values, hac.estimate.values, rtol=1e-9, atol=1e-12)
    assert np.all(np.isfinite(classical.estimate.std)) and np.all(classical.estimate.std > 0)
    shape_classical = np.array([value.std for value in classical.shapes])
    shape_hac = np.array([value.std for value in hac.shapes])
    # strongly coloured residuals: the sandwich is wider, for the linear and the shape parameters
    assert np.all(hac.estimate.std >= classical.estimate.std * (1 - 1e-9))
    assert np.median(hac.estimate.std / classical.estimate.std) > 2
    assert np.all(shape_hac > 1.5 * shape_classical)


def test_classical_matches_hac_on_white_residuals(setting):
    robot, clean = setting
    record = replace(clean, tau=clean.tau + np.random.default_rng(1).normal(0.0, 0.1, clean.tau.shape))
    model = build_model(robot, "internal", "viscous,coulomb:tanh")
    hac = identify(model, record).estimate.std
    classical = identify(model, record, covariance="classical").estimate.std
    assert np.median(hac / classical) == pytest.approx(1.0, abs=0.15)


def test_an_unknown_covariance_is_refused_on_the_shaped_path(setting):
    robot, clean = setting
    with pytest.raises(ValueError, match="covariance"):
        identify(build_model(robot, "internal", "viscous,coulomb:tanh"), clean, covariance="sandwich")
