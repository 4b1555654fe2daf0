"""The diagnosis in several processes is the diagnosis in one: the same report, number for number."""

from __future__ import annotations

import json
import os
import time
import warnings

import numpy as np
import pytest

from dynamics.runtime import processes
from dynamics.runtime.processes import TaskError, beside, run_tasks, spare_core, worker_count
from dynamics.runtime.threads import sample_thread_limit
from estimation.diagnosis import record_fits
from estimation.diagnosis.candidates import delay_search
from estimation.diagnosis.candidates.delay import search_delay
from estimation.diagnosis.candidates.delay_search import DelaySearch
from estimation.diagnosis.search import diagnose
from estimation.preprocessing.delay import DelayBounds
from tests.corpus.cases import CASES
from tests.corpus.records import declared_model, records


def report(diagnosis) -> str:
    return json.dumps(diagnosis.to_dict(), sort_keys=True, default=repr)


@pytest.mark.parametrize("name", ["coulomb + offset", "delay"])
def test_two_processes_give_the_report_of_one(name, monkeypatch):
    (case,) = [case for case in CASES if case.name == name]
    model = declared_model()
    train, validate = records(case)
    serial = diagnose(model, train, validate, jobs=1)
    pools, inside, searched_outside = [], [], []

    def counted(tasks, workers, **options):
        pools.append((workers, getattr(tasks[0], "func", None)))
        inside.append(True)
        try:
            return run_tasks(tasks, workers, **options)
        finally:
            inside.pop()

    def searched(*args, **kwargs):
        if not inside:
            searched_outside.append(args)
        return search_delay(*args, **kwargs)

    monkeypatch.setattr(record_fits, "run_tasks", counted)
    monkeypatch.setattr(delay_search, "search_delay", searched)
    pooled = diagnose(model, train, validate, jobs=2)
    assert serial.effects, "the case must find something for the comparison to mean anything"
    # the first round's delay search on its whole grid: the first task of the round's pool, beside the candidates,
    # and the round's delay trial takes its outcome (no search on the whole grid outside a pool)
    assert pools[0] == (2, searched), pools
    assert [first for _, first in pools].count(searched) == 1, pools
    assert not searched_outside
    assert report(pooled) == report(serial)
    if name == "delay":
        assert "delay" in [effect.name for effect in serial.effects], "the case must adopt the delay"


def test_a_delay_step_run_ahead_serves_only_the_model_weights_and_start_it_was_run_at():
    (case,) = [case for case in CASES if case.name == "delay"]
    model = declared_model()
    train, validate = records(case)
    weights = np.ones(model.n_channels)

    def search() -> DelaySearch:
        return DelaySearch(train, validate, lambda record: model.evaluate_base(record.q, record.dq, record.ddq),
                           DelayBounds())

    ahead = search()
    task = ahead.ahead_task([], [], model, weights, 1e3, 10)
    ahead.keep_ahead(task(), [], [], weights, 1e3, 10)
    (trial,) = ahead.trials([], [], model, weights, 1e3, 10, [])
    (again,) = search().trials([], [], model, weights, 1e3, 10, [])
    assert (trial.delay, trial.p_value, trial.bic) == (again.delay, again.p_value, again.bic)
    assert np.array_equal(trial.fit.profile, again.fit.profile)
    assert ahead.ahead is None  # taken
    # the next round's first step is the screen at the last optimum, run ahead the same way
    screen = ahead.ahead_task([], [], model, weights, 2e3, 10)
    assert screen.func is delay_search.screen_delay and screen.args[0].delay == trial.delay
    ahead.keep_ahead("screened ahead", [], [], weights, 2e3, 10)
    assert ahead.trials([], [], model, weights, 2e3, 10, []) == [] and ahead.reason == "screened ahead"
    stale = search()
    stale.keep_ahead("delay search failed: kept", [], [], weights, 1e3, 10)
    assert stale.trials([], [], model, weights.copy(), 1e3, 10, []) != []  # other weights: searched again
    moved = search()
    moved.keep_ahead("delay search failed: kept", [], [], weights, 1e3, 10)
    assert moved.trials([], [], model, weights, 1.5e3, 10, []) != []  # another current RSS: searched again
    kept = search()
    kept.keep_ahead("delay search failed: kept", [], [], weights, 1e3, 10)
    assert kept.trials([], [], model, weights, 1e3, 10, []) == [] and kept.reason == "delay search failed: kept"
    assert kept.tried and kept.previous is None and not kept.searching()


def _square(value: int) -> int:
    return value * value


def _fails(value: int) -> int:
    if value == 3:
        raise ValueError(f"task {value} fails")
    return value


def _warns(value: int) -> int:
    warnings.warn(f"warning from task {value}", UserWarning, stacklevel=1)
    return value


def test_results_come_back_in_task_order_and_shared_objects_by_reference():
    shared = object()
    tasks = [lambda value=value: (_square(value), shared) for value in range(20)]
    results = run_tasks(tasks, 2, shared=[shared])
    assert [value for value, _ in results] == [value * value for value in range(20)]
    assert all(item is shared for _, item in results)


def test_a_task_exception_is_raised_in_the_parent_and_no_child_is_left():
    with pytest.raises(ValueError, match="task 3 fails"):
        run_tasks([lambda value=value: _fails(value) for value in range(8)], 2)
    with pytest.raises(ChildProcessError):
        os.waitpid(-1, os.WNOHANG)  # no child of this process remains


def test_a_child_warning_is_issued_in_the_parent():
    with pytest.warns(UserWarning) as caught:
        run_tasks([lambda value=value: _warns(value) for value in range(6)], 2)
    assert sorted(str(item.message) for item in caught) == [f"warning from task {value}" for value in range(6)]


@pytest.fixture
def idle_machine(monkeypatch):
    """A machine whose cores are idle (the load average 0), whatever this one's load: :func:`beside` forks."""
    monkeypatch.setattr(processes.os, "getloadavg", lambda: (0.0, 0.0, 0.0))


@pytest.mark.parametrize("workers", [1, 2])
def test_a_task_beside_gives_its_result_warnings_and_exception_where_asked_for(workers, idle_machine):
    with beside(lambda: _warns(7), workers) as result:
        before = _square(3)  # the block runs on meanwhile
        with pytest.warns(UserWarning, match="warning from task 7"):
            value = result()
    assert (before, value) == (9, 7)
    with pytest.raises(ValueError, match="task 3 fails"), beside(lambda: _fails(3), workers) as result:
        result()
    with pytest.raises(KeyError), beside(lambda: _square(2), workers):  # the block fails: the child is killed
        raise KeyError("the block's own error")
    with pytest.raises(ChildProcessError):
        os.waitpid(-1, os.WNOHANG)  # no child of this process remains


def test_a_task_beside_not_done_when_asked_for_runs_in_turn_there(idle_machine):
    parent = os.getpid()

    def task():
        if os.getpid() != parent:
            time.sleep(600)  # a child the machine never lets finish
        return os.getpid()

    started = time.perf_counter()
    with beside(task, 2) as result:
        assert result() == parent
    assert time.perf_counter() - started < 60
    with pytest.raises(ChildProcessError):
        os.waitpid(-1, os.WNOHANG)


@pytest.mark.parametrize("load", [0.0, 1.0e6])
def test_a_task_beside_runs_in_a_child_only_when_the_machine_has_a_core_to_spare(load, monkeypatch):
    monkeypatch.setattr(processes.os, "getloadavg", lambda: (load, load, load))
    assert spare_core() == (load == 0.0)
    forks, fork = [], os.fork

    def counted_fork():
        forks.append(os.getpid())
        return fork()

    monkeypatch.setattr(processes.os, "fork", counted_fork)
    with beside(lambda: _square(4), 2) as result:
        assert result() == 16  # the same result, from a child or in turn here
    assert len(forks) == (load == 0.0)
    with beside(lambda: _warns(5), 2) as result, pytest.warns(UserWarning, match="warning from task 5"):
        assert result() == 5
    with pytest.raises(ValueError, match="task 3 fails"), beside(lambda: _fails(3), 2) as result:
        result()
    with beside(sample_thread_limit, 2) as result:
        assert result() == 1  # one thread, as in a child
    with pytest.raises(ChildProcessError):
        os.waitpid(-1, os.WNOHANG)


def test_a_machine_without_a_load_average_has_a_core_to_spare(monkeypatch):
    def absent():
        raise OSError("no load average")

    monkeypatch.setattr(processes.os, "getloadavg", absent)
    assert spare_core()


def test_worker_count_is_serial_for_few_tasks_and_refuses_a_bad_number():
    assert worker_count(4, 3, min_tasks=8) == 1
    assert worker_count(2, 10) == 2
    assert worker_count(1, 10) == 1
    with pytest.raises(ValueError, match="jobs"):
        worker_count(0, 10)
    assert TaskError.__mro__[1] is RuntimeError


def test_the_confirmations_worked_out_ahead_are_those_made_one_after_another(monkeypatch):
    """A round's confirmations on the validation record, worked out in batches side by side once one trial was
    refused on its comparison (forward_selection.DiagnosisSearch.confirmed_ahead), give the report of the same
    confirmations made one after another, in rank order: the same verdicts, the same effects, number for number."""
    from estimation.diagnosis import forward_selection

    (case,) = [case for case in CASES if case.name == "coulomb on every joint"]
    model = declared_model()
    train, validate = records(case)
    original = forward_selection.DiagnosisSearch.confirmed_ahead
    batches = []

    def counted(self, ranked, start, springs_beaten, count):
        ahead = original(self, ranked, start, springs_beaten, count)
        batches.append((count, len(ahead)))
        return ahead

    monkeypatch.setattr(forward_selection.DiagnosisSearch, "confirmed_ahead", counted)
    pooled = diagnose(model, train, validate, jobs=2)
    monkeypatch.setattr(forward_selection.DiagnosisSearch, "confirmed_ahead", lambda *args: {})
    one_after_another = diagnose(model, train, validate, jobs=2)
    # the last round refuses every trial: a batch of 8, then one of 16 (the 10 left)
    assert pooled.effects and batches[:2] == [(8, 8), (16, 2)], batches
    assert report(pooled) == report(one_after_another)
