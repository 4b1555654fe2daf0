"""Least squares from accumulated sums against the in-memory estimators (simulated PUMA data)."""

from __future__ import annotations

import numpy as np
import pytest

from dynamics.models import build_model
from dynamics.robots import load_robot
from estimation.estimators.least_squares import IdentifiabilityError, LeastSquares, WeightedLeastSquares, solve, stack
from estimation.estimators.normal_equations import NormalEquations, accumulate, reduce_sums
from estimation.estimators.summed_least_squares import SummedLeastSquares, solve_sums
from dynamics.simulation.synthetic import simulate, true_parameters

from oed.fourier import random_fourier

NOISE = {"tau1": 0.5, "tau2": 0.5, "tau3": 0.2, "fx": 5.0, "fy": 5.0, "fz": 8.0, "mx": 3.0, "my": 3.0, "mz": 1.0}


def relative(a, b) -> float:
    return float(np.linalg.norm(np.asarray(a) - b) / np.linalg.norm(b))


@pytest.fixture(scope="module", params=["internal", "combined"])
def case(request):
    puma = load_robot("puma560", joints=3)
    model = build_model(puma, request.param, "viscous")
    train = simulate(model, true_parameters(model, seed=2), random_fourier(puma, 3), noise=NOISE, seed=11)
    return model, train


def test_summed_wls_equals_in_memory_wls(case):
    model, train = case
    reference = WeightedLeastSquares().fit(stack(model, train)).estimate_
    estimate = SummedLeastSquares().fit(accumulate(model, train, chunk_size=777)).estimate_
    assert relative(estimate.values, reference.values) < 1e-10
    assert np.max(np.abs(estimate.values - reference.values) / reference.std) < 1e-6
    assert relative(estimate.cov, reference.cov) < 1e-10
    assert relative(estimate.channel_variance, reference.channel_variance) < 1e-10
    assert estimate.cond == pytest.approx(reference.cond, rel=1e-8)
    assert estimate.n_iterations == reference.n_iterations
    assert [r["name"] for r in estimate.records()] == [r["name"] for r in reference.records()]
    rms = reference.channel_rms()
    for channel, value in estimate.channel_rms().items():
        assert value == pytest.approx(rms[channel], rel=1e-10)


def test_summed_ols_equals_in_memory_ols(case):
    model, train = case
    reference = LeastSquares().fit(stack(model, train)).estimate_
    estimate = SummedLeastSquares(method="ols").fit(accumulate(model, train, chunk_size=100)).estimate_
    assert relative(estimate.values, reference.values) < 1e-10
    assert relative(estimate.cov, reference.cov) < 1e-10


def test_tsqr_solve_matches_a_direct_qr_and_the_semi_normal_solve(case):
    """Fixed weights: the factor route against numpy's QR of the whole weighted regressor."""
    model, train = case
    problem = stack(model, train)
    weights = 1.0 / np.array([NOISE[c] ** 2 for c in model.channels])
    theta = solve_sums(accumulate(model, train, chunk_size=333), weights)[0]
    Y = (problem.Y * np.sqrt(weights)[None, :, None]).reshape(-1, problem.n_parameters)
    y = (problem.y * np.sqrt(weights)).reshape(-1)
    Q, R = np.linalg.qr(Y)
    direct = np.linalg.solve(R, Q.T @ y)
    assert relative(theta, direct) < 1e-12
    assert relative(theta, solve(problem, weights)[0]) < 1e-12


def test_sums_add_in_any_grouping_and_gram_is_exact(case):
    model, train = case
    whole = accumulate(model, train, chunk_size=train.n_samples)
    parts = [accumulate(model, train.select(slice(a, a + 250)), chunk_size=64, source=f"part{a}")
             for a in range(0, train.n_samples, 250)]
    total = reduce_sums(parts)
    assert total.n_samples == train.n_samples
    assert total.sources == tuple(f"part{a}" for a in range(0, train.n_samples, 250))
    problem = stack(model, train)
    gram = np.matmul(problem.Y.transpose(1, 2, 0), problem.Y.transpose(1, 0, 2))
    assert relative(total.gram, gram) < 1e-13
    # R_cᵀR_c is the augmented Gram matrix, however the rows were grouped
    for sums in (whole, total):
        product = np.matmul(sums.factor.transpose(0, 2, 1), sums.factor)
        assert relative(product[:, :-1, :-1], gram) < 1e-13
        assert relative(product[:, :-1, -1], total.moment) < 1e-13
    rss = total.channel_rss(np.zeros(model.n_base))
    np.testing.assert_allclose(rss, np.sum(problem.y**2, axis=0), rtol=1e-12)
    with pytest.raises(ValueError, match="different problems"):
        total + NormalEquations.empty(model.channels[:1], model.base.names)


def test_validation_mse_from_sums_equals_compare(case):
    from estimation.identification.validation import compare

    model, train = case
    theta = WeightedLeastSquares().fit(stack(model, train)).theta_
    mse = accumulate(model, train, chunk_size=300).channel_mse(theta)
    expected = compare(model, theta, train).mse
    for channel in model.channels:
        assert mse[channel] == pytest.approx(expected[channel], rel=1e-10)


def test_select_columns_keeps_the_sub_problem(case):
    model, train = case
    sums = accumulate(model, train, chunk_size=500)
    keep = list(range(model.n_base - 3))
    problem = stack(model, train)
    from estimation.estimators.identification_problem import IdentificationProblem

    sub = IdentificationProblem(problem.Y[:, :, keep], problem.y, problem.channels,
                                tuple(problem.names[i] for i in keep))
    reference = WeightedLeastSquares().fit(sub).estimate_
    estimate = SummedLeastSquares().fit(sums.select(keep)).estimate_
    assert relative(estimate.values, reference.values) < 1e-10


def test_rank_deficient_sums_are_refused(case):
    model, train = case
    sums = accumulate(model, train.select(slice(0, 200)))
    duplicated = np.concatenate([stack(model, train).Y, stack(model, train).Y[:, :, :1]], axis=2)
    doubled = NormalEquations.from_arrays(duplicated, train.channels(model.channels), model.channels,
                                          model.base.names + ("copy",))
    with pytest.raises(IdentifiabilityError, match="do not determine"):
        SummedLeastSquares().fit(doubled)
    assert sums.n_samples == 200


@pytest.mark.parametrize("method", ["ols", "wls"])
def test_sums_without_the_gram_fit_the_same_bit_for_bit(case, method):
    """``accumulate(gram=False)`` (the derivative choice on a validation record): the same factors and powers,
    the Gram sums and moments left NaN, and the same fit to the last bit (the estimators use the factors only)."""
    model, train = case
    full = accumulate(model, train, chunk_size=333)
    lean = accumulate(model, train, chunk_size=333, gram=False)
    np.testing.assert_array_equal(lean.factor, full.factor)
    np.testing.assert_array_equal(lean.power, full.power)
    assert np.all(np.isnan(lean.gram)) and np.all(np.isnan(lean.moment))
    reference = SummedLeastSquares(method=method).fit(full).estimate_
    estimate = SummedLeastSquares(method=method).fit(lean).estimate_
    for name in ("values", "cov", "channel_rss", "weights"):
        np.testing.assert_array_equal(getattr(estimate, name), getattr(reference, name))
    assert (estimate.cond, estimate.n_iterations) == (reference.cond, reference.n_iterations)


@pytest.mark.parametrize("rows", [1, 511, 512, 1300])
def test_a_block_copied_in_pieces_is_factored_as_the_whole_channel(rows):
    """Each channel's rows are copied into the work array a few hundred at a time: its factor is that of the whole
    channel's rows ``[R; Y_c y_c]`` copied at once, bit for bit."""
    from estimation.estimators.normal_equations import stacked_factor

    generator = np.random.default_rng(rows)
    names = tuple(f"p{i}" for i in range(9))
    first = NormalEquations.empty(("a", "b", "c"), names).add_block(
        generator.standard_normal((40, 3, 9)), generator.standard_normal((40, 3)))
    Y, y = generator.standard_normal((rows, 3, 9)), generator.standard_normal((rows, 3))
    summed = first.add_block(Y, y, gram=False)
    for c in range(3):  # the same work array, [R_c; Y_c y_c], filled at once
        whole = stacked_factor([first.factor[c], np.column_stack([Y[:, c, :], y[:, c]])], 10)
        np.testing.assert_array_equal(summed.factor[c], whole)


def test_a_channel_is_factored_on_its_own_columns():
    """``add_block`` factors each channel on the columns that are not zero on it (a distal joint's torque reaches
    few base parameters): its factor is the QR of those columns alone, put back in place, bit for bit; its
    ``RᵀR`` is the dense factor's, and the fits are those of the dense factors to rounding (issue 34's cost)."""
    from estimation.estimators.normal_equations import channel_columns, stacked_factor

    generator = np.random.default_rng(5)
    names = tuple(f"p{i}" for i in range(8))
    support = np.array([[1, 1, 1, 1, 1, 1, 1, 1], [0, 1, 1, 0, 1, 1, 0, 1], [0, 0, 0, 1, 0, 1, 1, 0]], dtype=bool)
    blocks = []
    for rows in (300, 40, 1):
        Y = generator.standard_normal((rows, 3, 8)) * support[None]
        blocks.append((Y, generator.standard_normal((rows, 3)) + Y @ generator.standard_normal(8)))
    sums, dense = NormalEquations.empty(("a", "b", "c"), names), None
    for Y, y in blocks:
        before = sums
        sums = sums.add_block(Y, y)
        part = NormalEquations.from_arrays(Y, y, ("a", "b", "c"), names)
        dense = part if dense is None else dense + part
        for c in range(3):
            columns = np.append(np.flatnonzero(support[c]), 8)
            np.testing.assert_array_equal(channel_columns(before.factor[c], support[c]), columns)
            narrow = stacked_factor([before.factor[c][np.ix_(columns, columns)],
                                     np.column_stack([Y[:, c, columns[:-1]], y[:, c]])], len(columns))
            expected = np.zeros((9, 9))
            expected[np.ix_(columns, columns)] = narrow
            np.testing.assert_array_equal(sums.factor[c], expected)
            assert np.all(sums.factor[c] == np.triu(sums.factor[c]))
    for c in range(3):
        gram, reference = sums.factor[c].T @ sums.factor[c], dense.factor[c].T @ dense.factor[c]
        assert np.max(np.abs(gram - reference)) < 1e-12 * np.max(np.abs(reference))
    for method in ("ols", "wls"):
        estimate = SummedLeastSquares(method=method).fit(sums).estimate_
        reference = SummedLeastSquares(method=method).fit(dense).estimate_
        assert relative(estimate.values, reference.values) < 1e-12
        assert relative(estimate.channel_rss, reference.channel_rss) < 1e-12
    # a dense factor (summed by ``+``) keeps every column it has a row or a column on
    combined = sums + dense
    np.testing.assert_array_equal(channel_columns(combined.factor[2], np.zeros(8, dtype=bool)),
                                  np.flatnonzero(np.any(combined.factor[2] != 0, axis=0)
                                                 | np.any(combined.factor[2] != 0, axis=1)))
