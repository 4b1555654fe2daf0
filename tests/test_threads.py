"""Thread budgets: inside ``single_threaded`` the sample loops and BLAS use one thread, and both
budgets come back on exit, also when several threads hold them at once."""

from __future__ import annotations

import threading

import casadi
import numpy as np
import pytest
from threadpoolctl import threadpool_info

import dynamics.codegen.compiled as compiled
import dynamics.runtime.threads as threads
from dynamics.codegen.compiled import SampleEvaluator
from dynamics.runtime.threads import available_cores, sample_thread_limit, single_threaded, single_threaded_blas


def _blas_threads() -> list[int]:
    return [library["num_threads"] for library in threadpool_info() if library["user_api"] == "blas"]


@pytest.fixture
def two_blas_threads(default_blas_threads):
    """The BLAS thread counts before the test, when a limit to one can be seen in them (the xdist worker's own
    limit to one lifted: ``default_blas_threads`` of ``tests/conftest.py``).

    (Not set with ``threadpool_limits(2)`` here: OpenBLAS keeps a count set from the main thread
    against later changes from other threads.)
    """
    np.ones((50, 50)) @ np.ones((50, 50))  # make sure numpy's BLAS is loaded
    counts = _blas_threads()
    if not counts:
        pytest.skip("threadpoolctl finds no BLAS library it can control in this numpy")
    if max(counts) < 2:
        pytest.skip(f"BLAS runs on one thread already ({counts}): a limit to one cannot be seen")
    return counts


def _counting(monkeypatch, name):
    calls = []
    original = getattr(compiled, name)

    def counting(*arguments):
        calls.append(arguments[-1] if name == "_mapped" else arguments[0])
        return original(*arguments)

    monkeypatch.setattr(compiled, name, counting)
    return calls


def test_single_threaded_limits_the_compiled_sample_loop_and_restores_it(tmp_path, monkeypatch):
    if compiled.find_compiler() is None:
        pytest.skip("no C compiler on this machine: the sample loop runs on the virtual machine")
    monkeypatch.setenv("ROBOT_OED_CACHE", str(tmp_path))
    x = casadi.SX.sym("x", 2)
    evaluator = SampleEvaluator(casadi.Function("budget_case", [x], [casadi.sin(x)]), backend="compiled",
                                threads=2, min_samples_per_thread=10)
    values = np.linspace(0, 1, 200).reshape(100, 2)
    calls = _counting(monkeypatch, "_pool")
    assert sample_thread_limit() is None
    with single_threaded():
        assert sample_thread_limit() == 1
        np.testing.assert_array_equal(evaluator(values), np.sin(values))
    assert calls == [], "inside single_threaded the loop must not hand samples to worker threads"
    assert sample_thread_limit() is None
    np.testing.assert_array_equal(evaluator(values), np.sin(values))
    assert calls == [1], "outside, the evaluator's own two threads are back"


def test_single_threaded_limits_the_virtual_machine_map_too(monkeypatch):
    x = casadi.SX.sym("x", 2)
    evaluator = SampleEvaluator(casadi.Function("budget_vm", [x], [2 * x]), backend="vm", threads=2)
    values = np.ones((30, 2))
    calls = _counting(monkeypatch, "_mapped")
    with single_threaded():
        evaluator(values)
    evaluator(values)
    assert calls == [1, 2]


def test_single_threaded_limits_blas_and_restores_it(two_blas_threads):
    with single_threaded():
        assert _blas_threads() == [1] * len(two_blas_threads)
    assert _blas_threads() == two_blas_threads
    with single_threaded_blas():
        assert _blas_threads() == [1] * len(two_blas_threads)
        assert sample_thread_limit() is None, "the BLAS-only budget leaves the sample loops alone"
    assert _blas_threads() == two_blas_threads


def test_blas_budget_held_by_two_threads_is_restored_once_both_leave(monkeypatch):
    """Thread A enters, B enters, A leaves (B still inside: still limited), B leaves (restored).

    The limit itself is process-wide, so a fake ``threadpool_limits`` records what the budget asks
    of it (OpenBLAS's own reading of its thread count differs between Python threads).
    """
    events = []

    class FakeLimiter:
        def __init__(self, limits, user_api):
            events.append(("limit", limits, user_api))

        def restore_original_limits(self):
            events.append(("restore",))

    monkeypatch.setattr(threads, "threadpool_limits", FakeLimiter)
    a_inside, b_inside, a_left, b_may_leave = (threading.Event() for _ in range(4))
    seen = {}

    def first():
        with single_threaded():
            a_inside.set()
            b_inside.wait(10)
        a_left.set()

    def second():
        a_inside.wait(10)
        with single_threaded_blas():
            b_inside.set()
            a_left.wait(10)
            seen["after A left"] = list(events)
            b_may_leave.wait(10)

    workers = [threading.Thread(target=first), threading.Thread(target=second)]
    for worker in workers:
        worker.start()
    a_left.wait(10)
    b_may_leave.set()
    for worker in workers:
        worker.join(10)
    assert seen["after A left"] == [("limit", 1, "blas")], "A leaving must not lift B's limit"
    assert events == [("limit", 1, "blas"), ("restore",)]


def test_available_cores_is_positive():
    assert available_cores() >= 1
