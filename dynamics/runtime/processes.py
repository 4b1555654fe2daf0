"""Independent tasks in forked worker processes, their results in task order.

A round of a search fits many candidates, each independent of the others; in one process their Python
holds the GIL, so a second core helps only from a second process. :func:`run_tasks` forks
``workers - 1`` children (the parent is the last worker): each child starts with the parent's memory,
copy-on-write, so the records and the current model's columns are shared, not pickled. The workers take
tasks from a shared counter in task order, each on one thread (:func:`dynamics.runtime.threads.single_threaded`:
the workers already fill the cores); a child sends each result back pickled, and the parent
returns them in task order, so a result never depends on which worker computed it or when. Objects given
as ``shared`` (existing before the fork: column blocks, say) travel by reference: a result that holds
one gets the parent's object back, not a copy.

A task's exception is raised again in the parent (the first in task order); a child's warnings are
issued again in the parent. On any exception in the parent (Ctrl-C included) the children are killed and
reaped before it propagates: none is left behind.

:func:`worker_count` decides the pool's size: the cores this process may run on (its CPU affinity),
at most :data:`MAX_WORKERS`, one (in turn, no fork) where ``fork`` is unavailable or there are fewer
than ``min_tasks`` tasks. :func:`beside` forks only when the machine has a core to spare (:func:`spare_core`): its
low-priority child would otherwise be starved, killed and its task run in turn, the fork's cost (the copy-on-write
page faults of the pages the parent writes while the child lives: 80 000 of the 336 000 of a Panda diagnosis on a
loaded machine) paid for nothing.
"""

from __future__ import annotations

import contextlib
import io
import os
import pickle
import select
import signal
import threading
import traceback
import warnings
from collections.abc import Callable, Iterable, Iterator, Sequence
from dataclasses import dataclass
from multiprocessing import get_all_start_methods, get_context
from typing import Any, TypeVar

from dynamics.runtime.threads import available_cores, single_threaded

__all__ = ["MAX_WORKERS", "TaskError", "beside", "run_tasks", "spare_core", "worker_count"]

T = TypeVar("T")

#: the most workers :func:`worker_count` gives by default
MAX_WORKERS = 4
#: how much lower the priority of :func:`beside`'s child is (``os.nice``; 19, the lowest)
BESIDE_NICENESS = 19


def spare_core() -> bool:
    """Whether the machine has a core its programs leave idle: the load average of the last minute (the runnable
    processes, this one included) below the machine's cores. Where the system gives no load average, ``True``.
    Decides where a task runs, never its result."""
    try:
        load = os.getloadavg()[0]
    except (AttributeError, OSError):  # no load average on this system
        return True
    return load < (os.cpu_count() or 1)


class TaskError(RuntimeError):
    """A task failed in a child process with an exception that could not be sent back as it was."""


def worker_count(jobs: int | None, n_tasks: int, *, min_tasks: int = 2) -> int:
    """How many workers run ``n_tasks`` tasks: ``jobs`` (``None``: the available cores, at most
    :data:`MAX_WORKERS`), never more than the tasks, and 1 when ``fork`` is unavailable or there are
    fewer than ``min_tasks`` tasks."""
    if jobs is not None and (isinstance(jobs, bool) or not isinstance(jobs, int) or jobs < 1):
        raise ValueError(f"jobs must be a positive integer or None (the available cores), got {jobs!r}")
    if "fork" not in get_all_start_methods() or n_tasks < max(min_tasks, 2):
        return 1
    wanted = min(available_cores(), MAX_WORKERS) if jobs is None else jobs
    return max(1, min(wanted, n_tasks))


@dataclass(frozen=True)
class _Outcome:
    """One task's result, or its exception (or, when that cannot be pickled, its traceback)."""

    index: int
    value: Any = None
    error: BaseException | None = None
    error_text: str | None = None
    warnings: tuple[tuple[str, type[Warning], str, int], ...] = ()


class _Sharing:
    """Pickling with the ``shared`` objects replaced by their position (both sides hold them: a fork)."""

    def __init__(self, shared: Iterable[object]) -> None:
        self.objects = list(shared)
        self.positions = {id(item): position for position, item in enumerate(self.objects)}

    def dumps(self, value: object) -> bytes:
        buffer = io.BytesIO()
        pickler = pickle.Pickler(buffer, protocol=pickle.HIGHEST_PROTOCOL)
        pickler.persistent_id = lambda item: self.positions.get(id(item))  # type: ignore[method-assign]
        pickler.dump(value)
        return buffer.getvalue()

    def loads_all(self, data: bytes) -> list[_Outcome]:
        buffer, outcomes = io.BytesIO(data), []
        while buffer.tell() < len(data):
            unpickler = pickle.Unpickler(buffer)
            unpickler.persistent_load = self.objects.__getitem__  # type: ignore[assignment]
            outcomes.append(unpickler.load())
        return outcomes


def _run_one(index: int, task: Callable[[], Any]) -> _Outcome:
    with warnings.catch_warnings(record=True) as caught, single_threaded():  # one thread a worker: no oversubscription
        try:
            value = task()
        except Exception as error:  # sent back and raised again in the parent
            return _Outcome(index, error=error, error_text=traceback.format_exc())
    issued = tuple((str(item.message), item.category, item.filename, item.lineno) for item in caught)
    return _Outcome(index, value, warnings=issued)


def _next_index(counter: Any) -> int:
    with counter.get_lock():
        index = counter.value
        counter.value += 1
    return index


def _child(tasks: Sequence[Callable[[], Any]], counter: Any, sharing: _Sharing, write_end: int) -> None:
    """A child's loop: tasks from the counter until none is left, each outcome written to the pipe."""
    status = 1
    try:
        signal.signal(signal.SIGINT, signal.SIG_DFL)  # Ctrl-C ends a child at once; the parent reaps it
        with os.fdopen(write_end, "wb") as pipe:
            while (index := _next_index(counter)) < len(tasks):
                outcome = _run_one(index, tasks[index])
                try:
                    data = sharing.dumps(outcome)
                except Exception:  # an exception object that does not pickle: its traceback instead
                    data = sharing.dumps(_Outcome(index, error_text=outcome.error_text or traceback.format_exc()))
                pipe.write(data)
                pipe.flush()
        status = 0
    finally:
        os._exit(status)  # never the parent's cleanup (atexit, buffered output) in a child


def run_tasks(tasks: Sequence[Callable[[], T]], workers: int, *, shared: Iterable[object] = ()) -> list[T]:
    """``[task() for task in tasks]``, on ``workers`` processes (module docstring); in turn when
    ``workers`` is 1.

    Parameters
    ----------
    tasks
        Callables without arguments; their results must pickle (apart from ``shared`` objects).
    workers
        Processes, the parent included (:func:`worker_count`).
    shared
        Objects that exist before the call and may appear in results: returned as the parent's own.
    """
    if workers <= 1 or len(tasks) < 2:
        return [task() for task in tasks]
    sharing = _Sharing(shared)
    counter = get_context("fork").Value("q", 0)
    children: dict[int, int] = {}  # pid -> read end
    received: dict[int, bytearray] = {}
    ends: list[int] = []
    reader: threading.Thread | None = None
    try:
        for _ in range(min(workers, len(tasks)) - 1):
            read_end, write_end = os.pipe()
            pid = os.fork()
            if pid == 0:
                os.close(read_end)
                _child(tasks, counter, sharing, write_end)
            os.close(write_end)
            children[pid], received[pid] = read_end, bytearray()
            ends.append(read_end)
        # the children's results read as they come (a child waits on a full pipe), the GIL free while waiting
        reader = threading.Thread(target=_read_all, args=(dict(children), received), daemon=True)
        reader.start()
        own: list[_Outcome] = []
        while (index := _next_index(counter)) < len(tasks):
            own.append(_run_one(index, tasks[index]))
        reader.join()
        _reap(children, kill=False)  # a child ended by Ctrl-C or a failure: raised before its truncated results are read
        outcomes = own + [item for pid in received for item in sharing.loads_all(bytes(received[pid]))]
    finally:
        _reap(children, kill=True)  # their pipes reach their end: a reader still waiting returns
        if reader is not None:
            reader.join()
        for fd in ends:
            os.close(fd)
    return _in_order(outcomes, len(tasks))


@contextlib.contextmanager
def beside(task: Callable[[], T], workers: int, *, shared: Iterable[object] = ()) -> Iterator[Callable[[], T]]:
    """``task`` run in a forked child while the ``with`` block runs on in this process; the block calls the function
    it is given for ``task()``'s result (its warnings issued again there, its exception raised there). The child runs
    at the lowest priority (:data:`BESIDE_NICENESS`): a task that only reads what exists before the block (the
    records, the model) and returns a small result takes the cores the block leaves idle (its serial steps, a pool's
    slower worker) rather than sharing those its pools fill. A child not done when the result is asked for is
    killed and the task run in turn there (one thread, as in the child): the same result, never a wait on a child
    other programs starve. With ``workers`` 1 (or no ``fork``), ``task`` runs in turn at that call. The child is
    killed and reaped when the block ends, whatever happened; ask for the result once. ``shared``: objects that exist
    before the block and may appear in the result, returned as this process's own (:func:`run_tasks`). No child
    either when the machine has no core to spare (:func:`spare_core`): a child at the lowest priority would not get
    one, and the fork costs the parent a page fault for each page it writes while the child lives.
    """
    if workers <= 1 or "fork" not in get_all_start_methods():
        yield task
        return
    if not spare_core():  # run in turn when asked for, as a child would run it (one thread), as a starved one is
        yield lambda: _in_order([_run_one(0, task)], 1)[0]
        return
    sharing = _Sharing(shared)
    counter = get_context("fork").Value("q", 0)
    children: dict[int, int] = {}
    received: dict[int, bytearray] = {}
    read_end, write_end = os.pipe()
    reader: threading.Thread | None = None
    try:
        pid = os.fork()
        if pid == 0:
            os.close(read_end)
            os.nice(BESIDE_NICENESS)  # the cores the block leaves idle, not the ones its own work needs
            _child([task], counter, sharing, write_end)
        os.close(write_end)
        children[pid], received[pid] = read_end, bytearray()
        reader = threading.Thread(target=_read_all, args=(dict(children), received), daemon=True)
        reader.start()

        def result() -> T:
            if reader.is_alive():  # not done (the idle cores were too few, or other programs took them): in turn
                with contextlib.suppress(ProcessLookupError):
                    os.kill(pid, signal.SIGKILL)  # reaped when the block ends (a starved child dies slowly too)
                return _in_order([_run_one(0, task)], 1)[0]
            _reap(children, kill=False)
            return _in_order(sharing.loads_all(bytes(received[pid])), 1)[0]

        yield result
    finally:
        _reap(children, kill=True)
        if reader is not None:
            reader.join()
        os.close(read_end)


def _read_all(ends: dict[int, int], received: dict[int, bytearray]) -> None:
    """Read every child's pipe until each is closed."""
    open_ends = dict(ends)
    while open_ends:
        try:
            ready, _, _ = select.select(list(open_ends.values()), [], [])
        except (OSError, ValueError):  # a pipe closed by the parent after an error
            return
        for pid, fd in list(open_ends.items()):
            if fd in ready:
                try:
                    chunk = os.read(fd, 1 << 20)
                except OSError:
                    chunk = b""
                if chunk:
                    received[pid] += chunk
                else:
                    del open_ends[pid]


def _reap(children: dict[int, int], *, kill: bool) -> None:
    """Wait for every child (killed first when ``kill``) and forget it (its pipe stays open)."""
    for pid in list(children):
        if kill:
            try:
                os.kill(pid, signal.SIGKILL)
            except ProcessLookupError:
                pass
        _, status = os.waitpid(pid, 0)
        del children[pid]
        code = os.waitstatus_to_exitcode(status)
        if not kill and code == -signal.SIGINT:
            raise KeyboardInterrupt  # Ctrl-C reached the worker first
        if not kill and code != 0:
            raise TaskError(f"a worker process ended with status {code}")


def _in_order(outcomes: list[_Outcome], n_tasks: int) -> list[Any]:
    """The results in task order, each task's warnings issued again; the first failed task's exception raised."""
    by_index = {outcome.index: outcome for outcome in outcomes}
    if sorted(by_index) != list(range(n_tasks)):
        raise TaskError(f"the workers returned {len(by_index)} of {n_tasks} results")
    results = []
    for index in range(n_tasks):
        outcome = by_index[index]
        for message, category, filename, lineno in outcome.warnings:
            warnings.warn_explicit(message, category, filename, lineno)
        if outcome.error is not None:
            raise outcome.error
        if outcome.error_text is not None:
            raise TaskError(f"task {index} failed in a worker process:\n{outcome.error_text}")
        results.append(outcome.value)
    return results
