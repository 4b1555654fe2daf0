"""Design criteria: CasADi expressions against numpy, exact gradients against finite differences."""

from __future__ import annotations

import casadi
import numpy as np
import pytest

from oed.criteria import ConditionNumber, LogDet, MinEigenvalue, criterion_from_name, information_matrix


def random_information(seed: int, r: int = 6) -> np.ndarray:
    Y = np.random.default_rng(seed).normal(size=(40, r))
    return information_matrix(Y)


@pytest.mark.parametrize("criterion", [LogDet(), LogDet(regularization=1e-3), ConditionNumber(), MinEigenvalue()])
def test_casadi_expression_matches_numpy_value(criterion):
    M = random_information(0)
    function = criterion.function(M.shape[0])
    assert float(function(M)) == pytest.approx(criterion.value(M), rel=1e-10)
    numpy_reference = {
        "logdet": -np.linalg.slogdet(M + getattr(criterion, "regularization", 0) * np.eye(6))[1],
        "cond": np.linalg.cond(np.linalg.cholesky(M)),
        "mineig": -np.linalg.eigvalsh(M)[0],
    }[criterion.name]
    assert criterion.value(M) == pytest.approx(numpy_reference, rel=1e-9)


@pytest.mark.parametrize("criterion", [LogDet(), ConditionNumber(), MinEigenvalue()])
def test_reverse_derivative_matches_central_differences(criterion):
    Y0 = np.random.default_rng(1).normal(size=(30, 5))
    Y = casadi.MX.sym("Y", *Y0.shape)
    J = criterion.from_regressor(Y)
    gradient = casadi.Function("g", [Y], [casadi.gradient(J, Y)])
    analytic = np.asarray(gradient(Y0))
    step, numeric = 1e-6, np.zeros_like(Y0)
    value = casadi.Function("J", [Y], [J])
    for index in np.ndindex(*Y0.shape):
        plus, minus = Y0.copy(), Y0.copy()
        plus[index] += step
        minus[index] -= step
        numeric[index] = (float(value(plus)) - float(value(minus))) / (2 * step)
    np.testing.assert_allclose(analytic, numeric, rtol=1e-5, atol=1e-7)


def test_numeric_regressor_and_information_agree():
    Y = np.random.default_rng(2).normal(size=(10, 3, 4))
    assert LogDet().from_regressor(Y) == pytest.approx(LogDet().value(information_matrix(Y)))


def test_rank_deficient_regressor_is_penalised_by_every_criterion():
    Y = np.random.default_rng(3).normal(size=(20, 4))
    regular = information_matrix(Y)
    Y[:, 3] = Y[:, 0]  # two identical columns: an unidentifiable combination
    singular = information_matrix(Y)
    assert LogDet().value(singular) > LogDet().value(regular) + 20
    assert ConditionNumber().value(singular) > 1e6
    assert MinEigenvalue().value(singular) == pytest.approx(0, abs=1e-9)


def test_unknown_criterion_name_is_rejected():
    with pytest.raises(ValueError, match="unknown criterion"):
        criterion_from_name("aopt")
    with pytest.raises(ValueError, match="regularization"):
        LogDet(regularization=-1)
