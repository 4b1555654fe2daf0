"""A validation record that repeats the training motion confirms on stretches of the motion the fit did not see
(:class:`estimation.diagnosis.confirmation.HeldOutBlocks`): each stretch is predicted by a least-squares fit on the
training record without that stretch, checked against numpy's least squares on the samples kept."""

from __future__ import annotations

import numpy as np

from estimation.diagnosis.confirmation import HeldOutBlocks
from estimation.estimators.separable_least_squares import FixedPart


def test_each_stretch_is_predicted_by_the_fit_that_left_it_out():
    rng = np.random.default_rng(0)
    n, m, p = 400, 2, 3
    t = np.arange(n) / 100.0
    Y = rng.normal(size=(n, m, p))
    Y[:, 1, 0] = 0.0  # a column absent from one channel (stored per channel)
    y = Y @ np.array([1.0, -2.0, 0.5]) + 0.3 * np.sin(7 * t)[:, None] + rng.normal(scale=0.1, size=(n, m))
    Yv = rng.normal(size=(n, m, p))
    yv = Yv @ np.array([1.0, -2.0, 0.5]) + rng.normal(scale=0.1, size=(n, m))
    weights = np.array([1.0, 4.0])
    blocks = HeldOutBlocks.of(t, t, frequency_hz=None, n_blocks=4)
    residual = blocks.residual(FixedPart.from_arrays(Y, y), FixedPart.from_arrays(Yv, yv), weights)
    for block in range(4):
        kept = blocks.train != block
        A = (Y[kept] * np.sqrt(weights)[None, :, None]).reshape(-1, p)
        b = (y[kept] * np.sqrt(weights)[None, :]).reshape(-1)
        theta = np.linalg.lstsq(A, b, rcond=None)[0]
        rows = blocks.validate == block
        expected = (yv[rows] - Yv[rows] @ theta).T
        np.testing.assert_allclose(residual[:, rows], expected, rtol=1e-9, atol=1e-10)


def test_a_periodic_record_leaves_out_the_same_stretch_of_every_period():
    t = np.arange(1000) / 100.0  # two periods of 5 s
    blocks = HeldOutBlocks.of(t, t, frequency_hz=0.2, n_blocks=5)
    assert np.array_equal(blocks.train[:500], blocks.train[500:])
    assert np.array_equal(np.bincount(blocks.train), np.full(5, 200))
