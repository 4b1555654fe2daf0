"""The delay search's profile (estimation.identification.delayed.fit_delay) forms what it needs once: the moved
record's recorded samples are not moved (a fixed part reads the columns and the channels alone), the fixed part
at the search's lowest point and the value at zero delay are not formed again. Checked bit for bit against the
search as it was, written out here."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import scipy.optimize

from dynamics.models import build_model
from dynamics.robots import load_robot
from dynamics.simulation.synthetic import simulate, true_parameters
from estimation.estimators.separable_least_squares import FixedPart, residuals, solve_linear
from estimation.identification import delayed as delayed_module
from estimation.identification.delayed import DelayFit, fit_delay
from estimation.preprocessing.delay import DelayBounds, delayed, longest_piece
from estimation.preprocessing.plan import Preprocessing, prepare
from estimation.uncertainty.batch_means import batch_length, batch_means
from oed.fourier import random_fourier

DELAY = 0.006  # s, the torques lag the motion


@pytest.fixture(scope="module")
def problem():
    """A 3-joint PUMA record whose torques answer the motion 6 ms earlier, prepared by a filter (so that it carries
    its samples as recorded, as the diagnosis's records do), with the declared model's columns and OLS weights."""
    robot = load_robot("puma560", joints=3)
    model = build_model(robot, "internal", "viscous")
    theta = true_parameters(model, seed=1)
    trajectory = random_fourier(robot, seed=5)
    data = simulate(model, theta, trajectory, rate_hz=250.0, periods=2, noise={"tau1": 0.1, "tau2": 0.1, "tau3": 0.05},
                    seed=5)
    q, dq, ddq = trajectory.evaluate(data.t + DELAY)
    record = prepare(dataclasses.replace(data, q=q, dq=None, ddq=None), Preprocessing("butterworth", cutoff_hz=20.0))
    assert record.recorded is not None

    def columns(measurements):
        return model.evaluate_base(measurements.q, measurements.dq, measurements.ddq)

    return columns, record, tuple(model.channels), np.array([1.0, 2.0, 4.0])


def reference_fit(columns, train, channels, weights, bounds=DelayBounds()) -> tuple[DelayFit, int]:
    """``fit_delay`` as it was (every fixed part formed from the record moved with its recorded samples), and how
    many fixed parts it formed."""
    formed = [0]

    def fixed_at(delay):
        formed[0] += 1
        moved = delayed(train, delay)
        return FixedPart.from_arrays(np.asarray(columns(moved)), moved.channels(list(channels)))

    def rss(delay):
        try:
            return solve_linear(fixed_at(delay), [], None, [], weights).rss
        except (np.linalg.LinAlgError, FloatingPointError):
            return np.inf

    bounds = bounds.within(longest_piece(train))
    grid = bounds.grid()
    profile = np.array([rss(value) for value in grid])
    best = int(np.nanargmin(np.where(np.isfinite(profile), profile, np.nan)))
    step = grid[1] - grid[0]
    low, high = max(grid[best] - step, bounds.lower), min(grid[best] + step, bounds.upper)
    resolution = 1e-3 * float(np.median(np.diff(train.t)))
    search = scipy.optimize.minimize_scalar(rss, bounds=(low, high), method="bounded", options={"xatol": resolution})
    delay = float(search.x) if search.fun <= profile[best] else float(grid[best])
    fixed = fixed_at(delay)
    solution = solve_linear(fixed, [], None, [], weights)
    residual = residuals(fixed, [], solution)
    h = max(0.5 * float(np.median(np.diff(train.t))), 1e-6)
    plus, minus = fixed_at(delay + h), fixed_at(delay - h)
    D = (plus.predict(solution.theta) - minus.predict(solution.theta)) / (2 * h)
    projected_solution = solve_linear(dataclasses.replace(fixed, y=D, moment=fixed.moments(D),
                                                          power=np.sum(D**2, axis=1)), [], None, [], weights)
    D_tilde = D - fixed.predict(projected_solution.theta)
    information = float(np.sum(weights[:, None] * D_tilde**2))
    sigma2 = solution.rss / max(fixed.n_rows - fixed.n_fixed - 1, 1)
    white = sigma2 / information if information > 0 else np.inf
    scores = np.sum(weights[:, None] * residual * D_tilde, axis=0)[:, None]
    hac = float(batch_means(scores, batch_length(residual, weights))[0, 0]) / information**2 if information > 0 else np.inf
    theta_slope = (solve_linear(plus, [], None, [], weights).theta - solve_linear(minus, [], None, [], weights).theta) / (2 * h)
    fit = DelayFit(delay, float(np.sqrt(max(white, hac))), float(solution.rss), rss(0.0), theta_slope, grid, profile)
    return fit, formed[0]


def test_the_delay_fit_is_the_search_as_it_was_bit_for_bit_with_two_fixed_parts_fewer(problem, monkeypatch):
    columns, record, channels, weights = problem
    expected, formed_before = reference_fit(columns, record, channels, weights)
    formed, moved_recorded = [0], []
    original_fixed, original_delayed = delayed_module._fixed, delayed_module.delayed

    def counted_fixed(*args, **kwargs):
        formed[0] += 1
        return original_fixed(*args, **kwargs)

    def watched_delayed(measurements, delay):
        moved_recorded.append(measurements.recorded is not None)
        return original_delayed(measurements, delay)

    monkeypatch.setattr(delayed_module, "_fixed", counted_fixed)
    monkeypatch.setattr(delayed_module, "delayed", watched_delayed)
    fit = fit_delay(columns, record, channels, weights)
    assert abs(fit.delay - DELAY) < 3 * fit.std  # the search finds the delay
    for field in dataclasses.fields(DelayFit):
        value, reference = getattr(fit, field.name), getattr(expected, field.name)
        assert np.array_equal(value, reference), field.name
        assert np.asarray(value).tobytes() == np.asarray(reference).tobytes(), field.name  # signs of zeros too
    assert 0.0 in expected.grid  # the grid holds zero: its value is the one the grid met
    assert formed[0] == formed_before - 2  # the lowest point's part and the one at zero not formed again
    assert moved_recorded and not any(moved_recorded)  # the recorded samples never moved


def test_bounds_whose_grid_leaves_zero_out_give_the_search_as_it_was(problem):
    """Bounds whose grid leaves zero out: the value at zero is formed on its own, as before."""
    columns, record, channels, weights = problem
    bounds = DelayBounds(0.001, 0.02, 9)
    expected, _ = reference_fit(columns, record, channels, weights, bounds)
    fit = fit_delay(columns, record, channels, weights, bounds)
    assert 0.0 not in expected.grid
    for field in dataclasses.fields(DelayFit):
        assert np.asarray(getattr(fit, field.name)).tobytes() == np.asarray(getattr(expected, field.name)).tobytes()
