"""``FixedPart.predict`` on every channel writes each channel's product into its row of one array (no list of rows
stacked afterwards), and ``residuals`` subtracts in that array: the same products and differences, so the same
bits as the stacked form (``np.stack`` of ``own_c @ θ[where_c]``), which the search's fits read thousands of
times."""

from __future__ import annotations

import numpy as np

from estimation.estimators.separable_least_squares import FixedPart, LinearSolution, residuals


def _part() -> FixedPart:
    rng = np.random.default_rng(3)
    n_samples, n_channels, n_fixed = 500, 4, 9
    Y = rng.normal(size=(n_samples, n_channels, n_fixed))
    Y[:, 0, 5:] = 0.0  # a channel storing some columns only
    Y[:, 2, :] = 0.0  # a channel storing none
    Y[:, 3, 1] = -0.0
    return FixedPart.from_arrays(Y, rng.normal(size=(n_samples, n_channels)))


def _stacked(part: FixedPart, theta: np.ndarray) -> np.ndarray:
    padded = np.append(theta, 0.0)
    return np.stack([own @ padded[where] for own, where in zip(part.own, part.where)])


def test_the_prediction_on_every_channel_is_the_stacked_products_bit_for_bit():
    part = _part()
    theta = np.random.default_rng(4).normal(size=part.n_fixed)
    predicted = part.predict(theta)
    assert predicted.shape == part.y.shape and predicted.flags.c_contiguous
    assert predicted.tobytes() == _stacked(part, theta).tobytes()
    for channel in range(len(part.own)):
        assert predicted[channel].tobytes() == part.predict(theta, channel).tobytes()
    kept = part.kept([7, 0, 3, 2])  # columns left out and reordered: places of −1 read the appended zero
    assert kept.predict(theta[[7, 0, 3, 2]]).tobytes() == _stacked(kept, theta[[7, 0, 3, 2]]).tobytes()


def test_the_residuals_of_every_channel_are_the_measured_channels_less_the_stacked_products_bit_for_bit():
    part = _part()
    theta = np.random.default_rng(5).normal(size=part.n_fixed)
    solution = LinearSolution(theta, 0.0, np.eye(part.n_fixed), [], None, None)
    values = residuals(part, [], solution)
    assert values.tobytes() == (part.y - _stacked(part, theta)).tobytes()
    assert not np.shares_memory(values, part.y)
