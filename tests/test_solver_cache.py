"""The on-disk cache of built IPOPT solvers (dynamics.codegen.solver_cache) and its use by the consistent problem:
a solver loaded from the cache solves bit for bit as the one built."""

from __future__ import annotations

import casadi
import numpy as np
import pytest

from dynamics.codegen.solver_cache import cached_nlpsol, solver_directory
from dynamics.models import build_model
from dynamics.robots import load_robot
from estimation.consistent import solver
from estimation.consistent.least_squares import ConsistentLeastSquares
from estimation.estimators.least_squares import WeightedLeastSquares
from tests.test_consistent import consistent_truth, simulated_problem

OPTIONS = {"print_time": False, "ipopt.print_level": 0, "ipopt.sb": "yes"}


@pytest.fixture(autouse=True)
def private_cache(tmp_path, monkeypatch):
    """Never write to the user's cache: ``$ROBOT_OED_CACHE`` points into the test's directory."""
    monkeypatch.setenv("ROBOT_OED_CACHE", str(tmp_path / "cache"))


def toy(scale: float = 1.0) -> dict:
    x, p = casadi.SX.sym("x", 2), casadi.SX.sym("p")
    return {"x": x, "p": p, "f": (x[0] - p) ** 2 + scale * (x[1] - x[0] ** 2) ** 2, "g": x[0] + x[1]}


def test_a_solver_is_built_once_then_loaded_and_solves_as_built():
    built = cached_nlpsol("toy", "ipopt", toy(), OPTIONS)
    entries = list(solver_directory().glob("toy_*.casadi"))
    assert len(entries) == 1
    loaded = cached_nlpsol("toy", "ipopt", toy(), OPTIONS)
    assert list(solver_directory().glob("*.casadi")) == entries and not list(solver_directory().glob(".robot-oed-*"))
    arguments = {"x0": [0.3, -0.2], "p": 1.5, "lbg": -10.0, "ubg": 10.0}
    one, other = built(**arguments), loaded(**arguments)
    for name in ("x", "f", "g", "lam_g", "lam_x"):
        assert np.array_equal(np.asarray(one[name]), np.asarray(other[name])), name
    assert built.stats()["iter_count"] == loaded.stats()["iter_count"]
    cached_nlpsol("toy", "ipopt", toy(scale=2.0), OPTIONS)  # another problem, another entry
    cached_nlpsol("toy", "ipopt", toy(), {**OPTIONS, "ipopt.max_iter": 5})  # other options, another entry
    assert len(list(solver_directory().glob("toy_*.casadi"))) == 3


def test_only_the_latest_solvers_are_kept(monkeypatch):
    import dynamics.codegen.solver_cache as solver_cache

    monkeypatch.setattr(solver_cache, "KEPT_SOLVERS", 2)
    for scale in (1.0, 2.0, 3.0):
        cached_nlpsol("toy", "ipopt", toy(scale), OPTIONS)
    assert len(list(solver_directory().glob("toy_*.casadi"))) == 2


def test_an_unreadable_entry_or_directory_builds_the_solver(tmp_path, monkeypatch):
    cached_nlpsol("toy", "ipopt", toy(), OPTIONS)
    (entry,) = solver_directory().glob("toy_*.casadi")
    entry.write_text("not a serialized function")
    assert cached_nlpsol("toy", "ipopt", toy(), OPTIONS)(x0=[0.0, 0.0], p=1.0, lbg=-10.0, ubg=10.0)["f"] is not None
    assert casadi.Function.load(str(entry)).name() == "toy"  # the damaged entry written anew
    blocked = tmp_path / "file"
    blocked.write_text("")
    monkeypatch.setenv("ROBOT_OED_CACHE", str(blocked))  # not a directory: nothing kept, the solver built
    assert cached_nlpsol("toy", "ipopt", toy(), OPTIONS).name() == "toy"


def test_the_consistent_problem_from_the_cache_fits_bit_for_bit_as_built():
    model = build_model(load_robot("puma560", joints=3), "internal", "viscous")
    problem, _ = simulated_problem(model, consistent_truth(model), 60, 1.0, seed=5)
    unconstrained = WeightedLeastSquares().fit(problem).estimate_

    def fits():
        solver.compiled_problem.cache_clear()
        solver._symbolic.cache_clear()
        return [ConsistentLeastSquares(prior_weight=weight).fit(model, problem, unconstrained=unconstrained).estimate_
                for weight in (0.0, 10.0)]

    built = fits()
    assert len(list(solver_directory().glob("consistent_least_squares_*.casadi"))) == 1  # the full solver alone
    loaded = fits()
    solver.compiled_problem.cache_clear()
    solver._symbolic.cache_clear()
    for one, other in zip(built, loaded):
        np.testing.assert_array_equal(one.values, other.values)
        np.testing.assert_array_equal(one.phi, other.phi)
        np.testing.assert_array_equal(one.cov, other.cov)
        assert [(s["name"], s["iterations"], s["cost"]) for s in one.solver["starts"]] == \
            [(s["name"], s["iterations"], s["cost"]) for s in other.solver["starts"]]
