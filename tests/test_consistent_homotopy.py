"""The prior-weight search as a homotopy (estimation.consistent.identification.choose_prior_weight): each weight
warm-started from its neighbour's optimum and certified by the whole cost's optimality condition (the prior's
term included, estimation.consistent.solver.escape) gives the answer of the cold starts."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import minimize_scalar

from dynamics.models import build_model
from dynamics.robots import load_robot
from estimation.consistent.least_squares import ConsistentLeastSquares
from estimation.consistent.solver import prior_line_search
from estimation.estimators.least_squares import WeightedLeastSquares
from tests.test_consistent import consistent_truth, simulated_problem

@pytest.fixture(scope="module")
def short_record():
    """A short noisy PUMA record: least squares gives bodies that are not rigid, so the prior matters."""
    model = build_model(load_robot("puma560", joints=3), "internal", "viscous")
    theta = consistent_truth(model)
    problem, _ = simulated_problem(model, theta, 60, 1.0, seed=5)
    return model, problem, WeightedLeastSquares().fit(problem).estimate_

@pytest.mark.parametrize("weight", [0.1, 1.0, 10.0, 100.0])
def test_a_warm_start_from_a_neighbouring_weight_gives_the_cold_starts_answer_in_one_certified_solve(short_record,
                                                                                                     weight):
    model, problem, unconstrained = short_record
    cold = ConsistentLeastSquares(prior_weight=weight).fit(model, problem, unconstrained=unconstrained).estimate_
    assert cold.solver["certified"]  # with the prior's term, the cold starts are certified too (not 6 starts)
    assert len(cold.solver["starts"]) == 2
    # warm-started from far along the grid (a factor 1000 in the weight), and from the neighbour
    for other in (weight * 10, weight / 1000):
        start = ConsistentLeastSquares(prior_weight=other).fit(model, problem, unconstrained=unconstrained).estimate_
        warm = ConsistentLeastSquares(prior_weight=weight, warm_start=start.phi).fit(
            model, problem, unconstrained=unconstrained).estimate_
        assert [s["name"] for s in warm.solver["starts"]] == ["warm"] and warm.solver["certified"]
        scale = np.abs(cold.values).max()
        assert np.max(np.abs(warm.values - cold.values)) < 1e-6 * scale, (weight, other)
        assert np.allclose(warm.theta, cold.theta, rtol=1e-5, atol=1e-7 * np.abs(cold.theta).max())
        assert warm.excess_chi2 == pytest.approx(cold.excess_chi2, abs=1e-4)  # χ² units: IPOPT tol 1e-8, scaled
        assert np.allclose(warm.std, cold.std, rtol=1e-3)

def test_an_uncertified_warm_start_falls_back_on_the_cold_starts(short_record):
    """Without a prior the optimum is on the cone's boundary: a warm start from a prior's optimum is not
    trusted alone when it is not certified; the cold starts follow and the best wins."""
    model, problem, unconstrained = short_record
    cold = ConsistentLeastSquares().fit(model, problem, unconstrained=unconstrained).estimate_
    start = ConsistentLeastSquares(prior_weight=100.0).fit(model, problem, unconstrained=unconstrained).estimate_
    warm = ConsistentLeastSquares(warm_start=start.phi).fit(model, problem, unconstrained=unconstrained).estimate_
    names = [s["name"] for s in warm.solver["starts"]]
    assert names[0] == "warm"
    if not warm.solver["starts"][0]["certified"]:
        assert "projection" in names
    assert warm.excess_chi2 <= cold.excess_chi2 * (1 + 1e-6) + 1e-9

def test_a_warm_start_of_the_wrong_size_is_a_named_error(short_record):
    model, problem, unconstrained = short_record
    with pytest.raises(ValueError, match="warm_start"):
        ConsistentLeastSquares(prior_weight=1.0, warm_start=np.zeros(3)).fit(model, problem, unconstrained=unconstrained)

@pytest.mark.parametrize("slope, curvature, weight, a, b", [
    (-3.0, 2.0, 0.5, 1.0, 4.0), (0.0, 0.0, 1.0, 0.2, 3.0), (-10.0, 0.1, 1e-3, 0.0, 1e3), (-0.5, 5.0, 10.0, 0.1, 0.5)])
def test_theprior_line_search_minimises_the_whole_cost_along_the_direction(slope, curvature, weight, a, b):
    """Against a bounded scalar minimisation of ``s α + ½ c α² + w (a α − log(1 + b α))``."""
    f = lambda alpha: slope * alpha + 0.5 * curvature * alpha**2 + weight * (a * alpha - np.log1p(b * alpha))  # noqa: E731
    alpha, gain = prior_line_search(slope, curvature, weight, a, b)
    reference = minimize_scalar(f, bounds=(0.0, 1e4), method="bounded", options={"xatol": 1e-12})
    assert alpha == pytest.approx(reference.x, rel=1e-5, abs=1e-8)
    assert gain == pytest.approx(-reference.fun, rel=1e-8, abs=1e-12)
    assert gain >= 0


def test_weight_zero_is_one_certified_answer_whatever_the_start(short_record):
    """Weight 0 (no prior): the optimum of the data term plus the vanishing pull, reached along the path of the
    weight down from 0.1 and certified with the pull's term (ConsistentLeastSquares._regularised_path). The
    configured starts, their number and seed, and a warm start from far along the grid give the same answer; it
    fits the training data no worse than any cold start of the data term alone (the code before: the best of up to
    six starts, none certified)."""
    model, problem, unconstrained = short_record
    fits = [ConsistentLeastSquares(starts=starts, seed=seed).fit(model, problem, unconstrained=unconstrained).estimate_
            for starts, seed in ((1, 0), (2, 0), (4, 7))]
    far = ConsistentLeastSquares(prior_weight=100.0).fit(model, problem, unconstrained=unconstrained).estimate_
    fits.append(ConsistentLeastSquares(warm_start=far.phi).fit(model, problem, unconstrained=unconstrained).estimate_)
    reference = fits[0]
    assert reference.prior_weight == 0.0
    for fit in fits:
        assert fit.solver["certified"], fit.solver["starts"]
        assert fit.solver["regularisation"] <= 1e-5
        assert fit.excess_chi2 == pytest.approx(reference.excess_chi2, abs=1e-3)
        scale = np.abs(reference.values).max()
        assert np.max(np.abs(fit.values - reference.values)) < 1e-4 * scale
    # the data term's cold starts alone (what weight 0 ran before) reach no better point
    solves_before = ConsistentLeastSquares(starts=6, max_iter=3000)
    solves_before._regularised_path = lambda *args: None  # the cold starts, as the code before ran them
    before = solves_before.fit(model, problem, unconstrained=unconstrained).estimate_
    assert reference.excess_chi2 <= before.excess_chi2 + 1e-3
