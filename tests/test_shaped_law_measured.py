"""A shaped friction law stands over the plain law of its joint only when the validation record measures its gain
(``estimation.diagnosis.plain_laws.measured_gain``: more than ``TIED_SE`` standard errors of the difference, from
``BLOCKS`` contiguous blocks); the servo arm of ``tests/test_unseen_robots.py`` (slow) is the end-to-end case."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from estimation.diagnosis.plain_laws import measured_gain
from estimation.identification.validation import Comparison


def _result(residuals: np.ndarray) -> SimpleNamespace:
    n = residuals.shape[0]
    return SimpleNamespace(validation=Comparison(np.arange(n) * 0.01, residuals, np.zeros_like(residuals),
                                                 ("tau1", "tau2")))


def test_a_gain_within_the_noise_of_the_validation_record_is_not_measured():
    rng = np.random.default_rng(0)
    noise = rng.normal(size=(400, 2))
    plain = _result(noise)
    tied = _result(noise * np.array([0.995, 1.0]) + 0.05 * rng.normal(size=(400, 2)))  # 0.5 % lower on tau1: noise
    clear = _result(noise * np.array([0.5, 1.0]))  # a quarter of the squared error on tau1
    assert not measured_gain(tied, plain, 0)
    assert measured_gain(clear, plain, 0)
    assert not measured_gain(plain, clear, 0)
    assert measured_gain(clear, plain)  # the score (geometric mean over the channels)
    assert not measured_gain(tied, plain)
    # errors without their samples (sums): the lower one is taken as measured
    summed = SimpleNamespace(validation=SimpleNamespace(mse={"tau1": 0.9, "tau2": 1.0}, channels=("tau1", "tau2")))
    assert measured_gain(summed, plain, 0) == (0.9 < plain.validation.mse["tau1"])
