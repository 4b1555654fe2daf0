"""The on-disk cache of compiled functions with derivatives (dynamics.codegen.jit_cache) and its use by the design."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import casadi
import numpy as np
import pytest

import oed.design_solver
from dynamics.codegen.compiled import find_compiler
from dynamics.codegen.jit_cache import cached_jit, jit_directory, library_path
from dynamics.robots import load_robot
from oed.excitation import DesignSettings, ExcitationDesign, design_excitation

needs_compiler = pytest.mark.skipif(find_compiler() is None, reason="no C compiler")


@pytest.fixture(autouse=True)
def private_cache(tmp_path, monkeypatch):
    """Never write to the user's cache: ``$ROBOT_OED_CACHE`` points into the test's directory."""
    monkeypatch.setenv("ROBOT_OED_CACHE", str(tmp_path / "cache"))
    return tmp_path / "cache"


def toy_function(name: str = "toy_information") -> casadi.Function:
    q, dq = casadi.SX.sym("q", 3), casadi.SX.sym("dq", 3)
    Y = casadi.horzcat(casadi.sin(q) * dq, casadi.cos(q[0] * dq), q * q * dq[2], casadi.exp(-q * q))
    return casadi.Function(name, [q, dq], [casadi.triu(casadi.mtimes(Y.T, Y))], ["q", "dq"], ["M_upper"])


def summed_cost(per_sample: casadi.Function, samples: int = 7) -> casadi.Function:
    """``x -> (J, ∇J, ∂J/∂x·v)`` of a mapped, summed per-sample function: uses forward and reverse mode."""
    x = casadi.MX.sym("x", 6 * samples)
    states = casadi.reshape(x, 6, samples)
    summed = per_sample.map("summed", "serial", samples, [], [0])(states[:3, :], states[3:, :])
    J = casadi.sumsqr(summed) + casadi.sum1(casadi.sum2(summed))
    v = casadi.DM(np.linspace(-1.0, 1.0, x.numel()))
    return casadi.Function("cost", [x], [J, casadi.gradient(J, x), casadi.jtimes(J, x, v)])


@needs_compiler
def test_cached_function_and_derivatives_match_the_sx_function(private_cache):
    function = toy_function()
    cached = cached_jit(function)
    assert cached is not None and not cached.hit
    assert cached.library.parent == jit_directory() == private_cache / "jit"
    assert cached.function.forward(1).name() == "fwd1_toy_information"
    assert cached.function.reverse(1).name() == "adj1_toy_information"
    reference, compiled = summed_cost(function), summed_cost(cached.function)
    rng = np.random.default_rng(0)
    for _ in range(5):
        point = rng.normal(size=42)
        for expected, actual in zip(reference(point), compiled(point)):
            np.testing.assert_allclose(np.asarray(actual), np.asarray(expected), rtol=1e-12, atol=1e-12)


@needs_compiler
def test_a_second_build_hits_the_cache_in_this_and_another_process(private_cache):
    first = cached_jit(toy_function())
    second = cached_jit(toy_function())
    assert first is not None and second is not None
    assert (first.hit, second.hit) == (False, True) and first.library == second.library
    script = ("from tests.test_jit_cache import toy_function; from dynamics.codegen.jit_cache import cached_jit;"
              "c = cached_jit(toy_function()); print(c.hit, c.library)")
    root = Path(__file__).resolve().parents[1]
    environment = {**os.environ, "ROBOT_OED_CACHE": str(private_cache),
                   "PYTHONPATH": os.pathsep.join([str(root), os.environ.get("PYTHONPATH", "")])}
    output = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, check=True,
                            env=environment, cwd=root).stdout.split()
    assert output == ["True", str(first.library)]
    assert sorted(path.name for path in (private_cache / "jit").iterdir()) == [first.library.name]


@needs_compiler
def test_a_different_function_gets_its_own_entry(private_cache):
    first = cached_jit(toy_function())
    q, dq = casadi.SX.sym("q", 3), casadi.SX.sym("dq", 3)
    other = cached_jit(casadi.Function("toy_information", [q, dq], [casadi.triu(q @ dq.T)], ["q", "dq"], ["M_upper"]))
    assert first is not None and other is not None and not other.hit and other.library != first.library


def test_failures_return_none(private_cache, tmp_path, monkeypatch):
    blocker = tmp_path / "a_file"
    blocker.write_text("not a directory")
    assert cached_jit(toy_function(), blocker / "jit") is None  # the cache cannot be created
    monkeypatch.setenv("CC", "false")  # a "compiler" that always fails
    assert cached_jit(toy_function()) is None
    monkeypatch.setattr("dynamics.codegen.jit_cache.find_compiler", lambda: None)
    assert cached_jit(toy_function()) is None


@needs_compiler
def test_a_damaged_library_is_not_loaded(private_cache):
    # (never overwrite a library this process has loaded: it is mapped into memory, hence os.replace)
    function = toy_function("damaged_information")
    library = library_path(function, find_compiler(), jit_directory())
    library.parent.mkdir(parents=True)
    library.write_bytes(b"not a shared library")
    assert cached_jit(function) is None


@needs_compiler
def test_design_with_the_cache_equals_the_casadi_jit(private_cache, monkeypatch):
    """The cached library gives the criterion, its gradient and the designed starts of CasADi's own JIT."""
    robot = load_robot("puma560", joints=3)
    settings = DesignSettings(jit=True)
    cached_problem = ExcitationDesign(robot, "combined", settings=settings)
    cached_cost = cached_problem.cost_function()
    assert list((private_cache / "jit").glob("sample_information_*.so"))
    cached_result = design_excitation(robot, starts=2, seed=1, problem=cached_problem)
    monkeypatch.setattr(oed.design_solver, "cached_jit", lambda function: None)  # CasADi's JIT, as before
    shell_problem = ExcitationDesign(robot, "combined", settings=settings)
    shell_cost = shell_problem.cost_function()
    x = casadi.MX.sym("x", cached_problem.n_variables)
    rng = np.random.default_rng(2)
    for _ in range(3):
        point = cached_problem.random_start(rng)
        values = [casadi.Function("g", [x], [cost(x), casadi.gradient(cost(x), x)])(point)
                  for cost in (cached_cost, shell_cost)]
        for expected, actual in zip(values[1], values[0]):
            np.testing.assert_allclose(np.asarray(actual), np.asarray(expected), rtol=1e-10, atol=1e-10)
    shell_result = design_excitation(robot, starts=2, seed=1, problem=shell_problem)
    np.testing.assert_allclose([start.cost for start in cached_result.starts],
                               [start.cost for start in shell_result.starts], rtol=1e-10, atol=1e-10)
