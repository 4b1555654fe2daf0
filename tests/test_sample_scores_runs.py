"""The per-sample scores of the sandwich covariance (separable_least_squares.sample_scores) summed on runs of
consecutive columns: the same sums as the indexed sum they replace, bit for bit (signs of zeros included), on parts
with every column, with columns left out and reordered (FixedPart.kept)."""

from __future__ import annotations

import numpy as np
import pytest

from estimation.estimators.separable_least_squares import FixedPart, LinearSolution, consecutive_runs, sample_scores


def indexed_scores(fixed: FixedPart, weights, residual):
    """The fixed columns' scores as they were summed: ``declared[:, places] += w_c r_c A_c``, channel after channel."""
    weighted = weights[:, None] * residual
    declared = np.zeros((fixed.n_samples, fixed.n_fixed))
    for channel, (own, where) in enumerate(zip(fixed.own, fixed.where)):
        kept = where >= 0
        declared[:, where[kept]] += weighted[channel][:, None] * own[:, kept]
    return declared


@pytest.fixture(scope="module")
def part():
    generator = np.random.default_rng(3)
    n, m, p0 = 500, 5, 23
    Y = generator.standard_normal((n, m, p0))
    for channel in range(m):  # each channel on its own columns, in runs and alone
        Y[:, channel, generator.choice(p0, size=3 * channel, replace=False)] = 0.0
    Y[7, 1, 4], Y[9, 0, 2] = -0.0, -0.0
    return FixedPart.from_arrays(Y, generator.standard_normal((n, m))), generator


@pytest.mark.parametrize("columns", [None, [3, 1, 0, 10, 11, 12, 20], list(range(22, -1, -1)), [5]])
def test_the_scores_are_the_indexed_sums_bit_for_bit(part, columns):
    fixed, generator = part
    fixed = fixed if columns is None else fixed.kept(columns)
    weights = generator.random(len(fixed.own))
    residual = generator.standard_normal((len(fixed.own), fixed.n_samples))
    residual[0, 3], residual[2, 8] = -0.0, 0.0
    solution = LinearSolution(np.zeros(fixed.n_fixed), 0.0, np.eye(fixed.n_fixed), [], None)
    scores = sample_scores(fixed, [], solution, weights, residual)
    expected = indexed_scores(fixed, weights, residual)
    assert scores.shape == expected.shape and scores.flags.c_contiguous
    assert scores.tobytes() == expected.tobytes()


@pytest.mark.parametrize(("places", "runs"), [([], []), ([4], [(4, 5, 0)]), ([0, 1, 2, 5, 6, 9], [(0, 3, 0), (5, 7, 3), (9, 10, 5)]),
                                              ([3, 2, 1], [(3, 4, 0), (2, 3, 1), (1, 2, 2)])])
def test_consecutive_runs(places, runs):
    assert consecutive_runs(np.asarray(places, dtype=np.intp)) == runs
