"""Compiled evaluation equals the CasADi virtual machine, and falls back without a compiler."""

from __future__ import annotations

import multiprocessing
from concurrent.futures import ProcessPoolExecutor

import casadi
import numpy as np
import pytest

import dynamics.codegen.compiled as compiled
from dynamics.codegen.compiled import SampleEvaluator
from dynamics.models import build_model
from dynamics.robots import load_robot
from tests.conftest import random_states


def test_compiled_regressor_equals_virtual_machine(tmp_path, monkeypatch):
    if compiled.find_compiler() is None:
        pytest.skip("no C compiler on this machine: only the virtual machine can run")
    monkeypatch.setenv("ROBOT_OED_CACHE", str(tmp_path))
    model = build_model(load_robot("puma560", joints=6), "combined", "viscous,coulomb")
    function = model.regressor
    q, dq, ddq = random_states(6, 50, seed=1)
    fast = SampleEvaluator(function, backend="compiled")(q, dq, ddq)
    slow = SampleEvaluator(function, backend="vm")(q, dq, ddq)
    assert fast.shape == (50, function.numel_out(0))
    np.testing.assert_allclose(fast, slow, rtol=1e-12, atol=1e-12)
    assert fast.shape[1] == model.n_channels * model.n_parameters
    assert list(tmp_path.glob("combined_regressor_*.so")), "the compiled library is cached on disk"


def test_sparse_output_is_scattered_into_place():
    x = casadi.SX.sym("x", 2)
    function = casadi.Function("sparse_out", [x], [casadi.diag(x * 3)], ["x"], ["y"])
    assert not function.sparsity_out(0).is_dense()
    values = np.array([[1.0, 2.0], [3.0, 4.0]])
    result = SampleEvaluator(function, backend="vm")(values)
    np.testing.assert_array_equal(result, [[3, 0, 0, 6], [9, 0, 0, 12]])


def test_falls_back_to_virtual_machine_without_compiler(monkeypatch):
    monkeypatch.setattr(compiled, "find_compiler", lambda: None)
    x = casadi.SX.sym("x", 2)
    function = casadi.Function("no_compiler_case", [x], [x * 2], ["x"], ["y"])
    assert compiled.compile_function.__wrapped__(function, "auto") is function
    with pytest.raises(RuntimeError, match="no C compiler"):
        compiled.compile_function.__wrapped__(function, "compiled")


def test_wrong_input_width_is_named():
    x = casadi.SX.sym("x", 3)
    evaluator = SampleEvaluator(casadi.Function("width", [x], [x], ["x"], ["y"]), backend="vm")
    with pytest.raises(ValueError, match=r"input x must be \(4, 3\)"):
        evaluator(np.zeros((4, 2)))


def test_compiled_sample_loop_threads_and_sparse_output(tmp_path, monkeypatch):
    if compiled.find_compiler() is None:
        pytest.skip("no C compiler on this machine: only the virtual machine can run")
    monkeypatch.setenv("ROBOT_OED_CACHE", str(tmp_path))
    x, y = casadi.SX.sym("x", 2), casadi.SX.sym("y")
    function = casadi.Function("loop_case", [x, y], [casadi.diag(casadi.sin(x) * y)], ["x", "y"], ["z"])
    values = np.random.default_rng(3).normal(size=(2 * SampleEvaluator.MIN_SAMPLES_PER_THREAD + 7, 3))
    slow = SampleEvaluator(function, backend="vm")(values[:, :2], values[:, 2:])
    single = SampleEvaluator(function, backend="compiled")
    assert single.sample_loop is not None, "the compiled library exports the C sample loop"
    np.testing.assert_array_equal(single(values[:, :2], values[:, 2:]), slow)
    threaded = SampleEvaluator(function, backend="compiled", threads=2, min_samples_per_thread=500)
    np.testing.assert_array_equal(threaded(values[:, :2], values[:, 2:]), slow)
    np.testing.assert_array_equal(threaded(values[:3, :2], values[:3, 2:]), slow[:3])  # too few to split
    assert threaded(values[:0, :2], values[:0, 2:]).shape == (0, 4)


def _threaded_sum(evaluator: SampleEvaluator) -> float:
    return float(evaluator(np.ones((40, 1))).sum())


def test_threaded_evaluation_works_in_a_forked_child(tmp_path, monkeypatch):
    if compiled.find_compiler() is None or "fork" not in multiprocessing.get_all_start_methods():
        pytest.skip("needs a C compiler and fork")
    monkeypatch.setenv("ROBOT_OED_CACHE", str(tmp_path))
    x = casadi.SX.sym("x")
    evaluator = SampleEvaluator(casadi.Function("fork_case", [x], [3 * x]), threads=2, min_samples_per_thread=10)
    assert _threaded_sum(evaluator) == 120.0  # the parent's worker threads exist now
    with ProcessPoolExecutor(1, mp_context=multiprocessing.get_context("fork")) as executor:
        assert executor.submit(_threaded_sum, evaluator).result(timeout=60) == 120.0


def test_evaluate_writes_into_a_given_array_and_checks_it():
    model = build_model(load_robot("puma560", joints=3), "combined", "viscous")
    q, dq, ddq = random_states(3, 40, seed=4)
    expected = model.evaluate(q, dq, ddq)
    out = np.full_like(expected, np.nan)
    result = model.evaluate(q, dq, ddq, out=out)
    assert np.shares_memory(result, out)
    np.testing.assert_array_equal(out, expected)
    base = np.full((40, model.n_channels, model.n_base), np.nan)
    np.testing.assert_array_equal(model.evaluate_base(q, dq, ddq, out=base), model.evaluate_base(q, dq, ddq))
    with pytest.raises(ValueError, match="out must have shape"):
        model.evaluate(q, dq, ddq, out=np.empty((40, model.n_channels, 1)))
    with pytest.raises(TypeError, match="float64"):
        model.evaluate(q, dq, ddq, out=out.astype(np.float32))
    with pytest.raises(ValueError, match="C-contiguous"):
        model.evaluate(q, dq, ddq, out=np.empty((model.n_parameters, model.n_channels, 40)).T)


def test_sparse_output_into_a_given_array_is_zeroed_first():
    x = casadi.SX.sym("x", 2)
    function = casadi.Function("sparse_into", [x], [casadi.diag(x * 3)], ["x"], ["y"])
    out = np.full((2, 4), 7.0)
    SampleEvaluator(function, backend="vm")(np.array([[1.0, 2.0], [3.0, 4.0]]), out=out)
    np.testing.assert_array_equal(out, [[3, 0, 0, 6], [9, 0, 0, 12]])


def test_the_source_made_in_memory_is_the_file_casadi_generates(tmp_path):
    """The cache key is computed from the source made in memory (no temporary directory per function): it is byte
    for byte the file ``CodeGenerator.generate`` writes, so the libraries compiled before keep their keys."""
    model = build_model(load_robot("puma560", joints=3), "internal", "viscous")
    x = casadi.MX.sym("x", 3)
    for function in (model.base_regressor, casadi.Function("product", [x], [casadi.mtimes(x.T, x) * casadi.sin(x)])):
        generator = casadi.CodeGenerator(f"{function.name()}.c")
        generator.add(function)
        generator.generate(str(tmp_path) + "/")
        assert compiled.generated_source(function) == (tmp_path / f"{function.name()}.c").read_bytes()
