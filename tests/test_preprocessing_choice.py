"""The derivative method chosen by held-out evidence: the tie rule among candidates that predict equally well,
independent of the order of the candidates, and the flexible friction of the score on each joint's own channel."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from dynamics.measurements import Measurements
from estimation.identification.preprocessing_choice import EQUIVALENT, HeldOutScore, preferred
from estimation.preprocessing.plan import CandidateEvidence, Preprocessing


def fourier(harmonics: int) -> Preprocessing:
    return Preprocessing("fourier", 0.2, harmonics, "detected")


def butterworth(cutoff: float) -> Preprocessing:
    return Preprocessing("butterworth", cutoff_hz=cutoff)


def scored(*pairs: tuple[Preprocessing, float]) -> list[CandidateEvidence]:
    return [CandidateEvidence(plan, score, {}) for plan, score in pairs]


def test_a_fourier_fit_that_predicts_as_well_is_preferred_to_a_filter():
    evidence = scored((butterworth(2.5), 1.00), (fourier(5), 1.02), (fourier(40), 1.03), (butterworth(50), 1.2))
    assert preferred(evidence) == fourier(5)
    # beyond the tolerance the better filter wins
    evidence = scored((butterworth(2.5), 1.00), (fourier(5), (1 + 2 * EQUIVALENT) * 1.00))
    assert preferred(evidence) == butterworth(2.5)


def test_among_equivalent_filters_the_highest_cut_off_and_among_fourier_fits_the_best_score():
    assert preferred(scored((butterworth(2.5), 1.00), (butterworth(20), 1.04), (butterworth(80), 1.2))) == \
        butterworth(20)
    assert preferred(scored((fourier(250), 1.00), (fourier(5), 1.04))) == fourier(250)
    assert preferred(scored((fourier(250), 1.00), (fourier(5), 1.00))) == fourier(5)  # a tie: fewer harmonics


def test_the_choice_does_not_depend_on_the_order_of_the_candidates():
    evidence = scored((butterworth(2.5), 1.00), (butterworth(20), 1.03), (fourier(160), 1.04), (fourier(250), 1.02),
                      (fourier(5), 1.2), (butterworth(80), 1.01))
    choices = {preferred(list(order)) for order in itertools.permutations(evidence)}
    assert choices == {fourier(250)}


def test_the_flexible_friction_sits_on_each_joint_own_torque_channel():
    t = np.arange(200) * 0.01
    dq = np.column_stack([np.sin(t), 2 * np.cos(t)])
    measurements = Measurements(t=t, q=np.zeros((200, 2)), dq=dq, ddq=np.zeros((200, 2)), tau=np.zeros((200, 2)))
    columns = HeldOutScore.friction_columns(measurements, ("tau1", "tau2", "fz"))
    assert columns.shape == (200, 3, 12)
    assert np.all(columns[:, 2, :] == 0)  # nothing on the force plate
    assert np.all(columns[:, 1, :6] == 0) and np.all(columns[:, 0, 6:] == 0)
    assert np.all(columns[:, 0, 0] == 1) and np.allclose(np.sign(columns[:, 1, 7]), np.sign(dq[:, 1]))


def test_settings_are_checked():
    with pytest.raises(ValueError, match="folds"):
        HeldOutScore(model=None, folds=1)
    with pytest.raises(ValueError, match="max_rows"):
        HeldOutScore(model=None, max_rows=3)


def kept_rows_fit(Y: np.ndarray, y: np.ndarray, folds: int) -> np.ndarray:
    """The held-out MSE by a least-squares solve of all kept rows per fold (the score's definition)."""
    scale = np.std(y, axis=0)
    squared = np.zeros(y.shape[1])
    edges = np.linspace(0, y.shape[0], folds + 1).astype(int)
    for start, stop in zip(edges[:-1], edges[1:]):
        kept = np.r_[0:start, stop:y.shape[0]]
        A = (Y[kept] / scale[None, :, None]).reshape(-1, Y.shape[2])
        theta = np.linalg.lstsq(A, (y[kept] / scale).reshape(-1), rcond=None)[0]
        squared += np.sum((y[start:stop] - Y[start:stop] @ theta) ** 2, axis=0)
    return squared / y.shape[0]


def test_the_held_out_score_from_block_factors_is_the_least_squares_fit_of_the_kept_rows():
    generator = np.random.default_rng(3)
    n_samples, channels = 600, 3
    Y = generator.normal(size=(n_samples, channels, 9))
    Y[:, 2, :4] = 0.0  # a channel that reaches few columns
    Y[:, 0, 8] = 0.0
    Y[:, :, 7] = 2.5 * Y[:, :, 6]  # rank deficient, as a viscous column beside the flexible friction's dq
    y = Y @ generator.normal(size=9) + generator.normal(0.0, [0.1, 1.0, 10.0], (n_samples, channels))
    expected = kept_rows_fit(Y, y, folds=5)
    found = HeldOutScore(model=None, folds=5).held_out_mse(Y, y)
    np.testing.assert_allclose(found, expected, rtol=1e-10)
    assert np.all(found > 0)
