"""One statistic: every effect a diagnosis names carries the p-value of the Wald test of its coefficients from the
covariance its standard deviations come from, and that p-value is below the adoption threshold (nothing named within
its noise)."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.stats

from tests.corpus.cases import CASES
from tests.corpus.records import run

STATISTIC_CASES = ("coulomb + offset", "stribeck + offset", "ripple", "spring + offset")
ALPHA = 1e-3  # diagnose's default family-wise level


@pytest.mark.parametrize("name", STATISTIC_CASES)
def test_reported_p_values_are_the_wald_tests_of_the_reported_covariance(name):
    (case,) = [case for case in CASES if case.name == name]
    diagnosis, _ = run(case)
    estimate = diagnosis.after.estimate
    names = list(estimate.names)
    n_tests = len(diagnosis.effects) + len(diagnosis.rejected)  # every candidate (and the delay) is one or the other
    assert diagnosis.effects
    for effect in diagnosis.effects:
        indices = [names.index(parameter) for parameter in effect.parameters]
        theta, cov = estimate.values[indices], estimate.cov[np.ix_(indices, indices)]
        np.testing.assert_allclose(effect.std, np.sqrt(np.diag(cov)), rtol=1e-12)
        statistic = float(theta @ np.linalg.solve(cov, theta))
        assert effect.f_statistic == pytest.approx(statistic / len(indices), rel=1e-6), effect.spec
        assert effect.p_value == pytest.approx(scipy.stats.chi2.sf(statistic, len(indices)), rel=1e-6, abs=1e-300)
        assert effect.p_value < ALPHA / n_tests, (effect.spec, effect.p_value)
        assert np.max(np.abs(theta) / np.sqrt(np.diag(cov))) > 3.0, effect.spec  # not within its noise
