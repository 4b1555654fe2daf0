"""Thread budgets: inside ``single_threaded`` the sample loops and BLAS use one thread, and both
budgets come back on exit."""

from __future__ import annotations

import casadi
import numpy as np
import pytest
from threadpoolctl import threadpool_info

import dynamics.compiled as compiled
from dynamics.compiled import SampleEvaluator
from dynamics.threads import available_cores, sample_thread_limit, single_threaded


def _blas_threads() -> list[int]:
    return [library["num_threads"] for library in threadpool_info() if library["user_api"] == "blas"]


def test_single_threaded_limits_the_sample_loop_and_restores_it(tmp_path, monkeypatch):
    if compiled.find_compiler() is None:
        pytest.skip("no C compiler on this machine: the sample loop runs on the virtual machine")
    monkeypatch.setenv("ROBOT_OED_CACHE", str(tmp_path))
    x = casadi.SX.sym("x", 2)
    evaluator = SampleEvaluator(casadi.Function("budget_case", [x], [casadi.sin(x)]), backend="compiled",
                                threads=2, min_samples_per_thread=10)
    values = np.linspace(0, 1, 200).reshape(100, 2)
    expected = np.sin(values)
    calls = []
    original = compiled._pool

    def counting_pool(workers, process):
        calls.append(workers)
        return original(workers, process)

    monkeypatch.setattr(compiled, "_pool", counting_pool)
    assert sample_thread_limit() is None
    with single_threaded():
        assert sample_thread_limit() == 1
        np.testing.assert_array_equal(evaluator(values), expected)
    assert calls == [], "inside single_threaded the loop must not hand samples to worker threads"
    assert sample_thread_limit() is None
    np.testing.assert_array_equal(evaluator(values), expected)
    assert calls == [1], "outside, the evaluator's own two threads are back"


def test_single_threaded_limits_blas_and_restores_it():
    np.ones((50, 50)) @ np.ones((50, 50))  # make sure numpy's BLAS is loaded
    before = _blas_threads()
    if not before:
        pytest.skip("threadpoolctl finds no BLAS library it can control in this numpy")
    with single_threaded():
        assert _blas_threads() == [1] * len(before)
    assert _blas_threads() == before


def test_available_cores_is_positive():
    assert available_cores() >= 1
