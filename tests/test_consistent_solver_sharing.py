"""The consistent problem's solvers of one model share IPOPT's derivative functions
(:func:`estimation.consistent.solver.compiled_problem`): the escape's shorter solver is given those the full one
generated, and gives the same iterates bit for bit as a solver that generates its own."""

from __future__ import annotations

import numpy as np
import pytest

from dynamics.models import build_model
from dynamics.robots import load_robot
from estimation.consistent import solver
from estimation.consistent.least_squares import ESCAPE_ITERATIONS, ConsistentLeastSquares
from estimation.estimators.least_squares import WeightedLeastSquares
from tests.test_consistent import consistent_truth, simulated_problem


@pytest.fixture(scope="module")
def short_record():
    model = build_model(load_robot("puma560", joints=3), "internal", "viscous")
    problem, _ = simulated_problem(model, consistent_truth(model), 60, 1.0, seed=5)
    return model, problem, WeightedLeastSquares().fit(problem).estimate_


def fits(model, problem, unconstrained):
    """The fits that run both solvers: the weight-0 path (its steps on the escape's solver) and a prior's weight."""
    return [ConsistentLeastSquares(prior_weight=weight).fit(model, problem, unconstrained=unconstrained).estimate_
            for weight in (0.0, 10.0)]


def fresh():
    solver.compiled_problem.cache_clear()
    solver._symbolic.cache_clear()


def test_the_escape_solver_given_the_full_ones_derivatives_solves_bit_for_bit_as_one_built_alone(short_record,
                                                                                                  monkeypatch):
    model, problem, unconstrained = short_record
    fresh()
    shared = fits(model, problem, unconstrained)
    full, short = solver.compiled_problem(model, 3000), solver.compiled_problem(model, ESCAPE_ITERATIONS)
    for name in ("nlp_grad_f", "nlp_jac_g", "nlp_hess_l"):  # the very functions, not copies
        assert short.solver.get_function(name).__hash__() == full.solver.get_function(name).__hash__()
    assert any(start["name"].startswith("path") for start in shared[0].solver["starts"])  # the short solver ran
    fresh()
    monkeypatch.setattr(solver, "_DERIVATIVES", {})  # every solver generates its own (the code before)
    alone = fits(model, problem, unconstrained)
    assert solver.compiled_problem(model, ESCAPE_ITERATIONS).solver.get_function("nlp_hess_l").__hash__() != \
        solver.compiled_problem(model, 3000).solver.get_function("nlp_hess_l").__hash__()
    fresh()
    for one, other in zip(shared, alone):
        np.testing.assert_array_equal(one.values, other.values)
        np.testing.assert_array_equal(one.phi, other.phi)
        np.testing.assert_array_equal(one.cov, other.cov)
        assert [(s["name"], s["iterations"], s["cost"]) for s in one.solver["starts"]] == \
            [(s["name"], s["iterations"], s["cost"]) for s in other.solver["starts"]]
