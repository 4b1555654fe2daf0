"""Thread budgets: how many threads the sample loops and the BLAS library may use here.

A unit of work that runs beside others in separate processes (a design start in a process pool or
on a ``dask`` worker, a pytest-xdist worker) must stay on one thread. Otherwise every process adds
OpenBLAS's threads, which spin while idle, and the two slices of :class:`dynamics.codegen.compiled.
SampleEvaluator`'s loop, and the machine runs several runnable threads a core: on this 2-core
machine ``design_excitation(starts=8)`` through a 2-process pool took 4.5 s against 0.62 s with one
thread a process (``OPENBLAS_NUM_THREADS=1``), 1.7 s in turn. Within one process the spinning BLAS
threads also slow the tall, thin least-squares problems of identification: the KUKA diagnosis took
81 s against 17 s.

- :func:`single_threaded`: one BLAS thread and one sample-loop thread (design starts).
- :func:`single_threaded_blas`: one BLAS thread only (identification, diagnosis, least squares: the
  sample loop's own threads wait without spinning and still help on large inputs).

The sample-loop budget is a context variable (per thread and task). The BLAS budget is a property of
the process: the first context to enter limits it, the last one to leave restores it, whichever
threads they run on.
"""

from __future__ import annotations

import contextlib
import contextvars
import os
import threading
from collections.abc import Iterator

from threadpoolctl import threadpool_limits

_SAMPLE_THREADS: contextvars.ContextVar[int | None] = contextvars.ContextVar("robot_oed_sample_threads", default=None)


class _ProcessBlasLimit:
    """One BLAS thread while at least one context holds the limit (reference-counted, thread-safe)."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._depth = 0
        self._limiter: threadpool_limits | None = None
        # a child forked while another thread held the lock would wait for it forever
        os.register_at_fork(after_in_child=self._reset_lock)

    def _reset_lock(self) -> None:
        self._lock = threading.Lock()

    def acquire(self) -> None:
        with self._lock:
            if self._depth == 0:
                self._limiter = threadpool_limits(limits=1, user_api="blas")
            self._depth += 1

    def release(self) -> None:
        with self._lock:
            self._depth -= 1
            if self._depth == 0 and self._limiter is not None:
                limiter, self._limiter = self._limiter, None
                limiter.restore_original_limits()


_BLAS_LIMIT = _ProcessBlasLimit()


def available_cores() -> int:
    """Cores this process may run on (its CPU affinity where the system reports it)."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except (AttributeError, OSError):  # not Linux
        return max(1, os.cpu_count() or 1)


def sample_thread_limit() -> int | None:
    """The most threads a sample loop may use in the current context (``None``: its own setting)."""
    return _SAMPLE_THREADS.get()


@contextlib.contextmanager
def single_threaded_blas() -> Iterator[None]:
    """Run the wrapped code with one BLAS thread (process-wide while any context holds it)."""
    _BLAS_LIMIT.acquire()
    try:
        yield
    finally:
        _BLAS_LIMIT.release()


@contextlib.contextmanager
def single_threaded() -> Iterator[None]:
    """Run the wrapped code with one sample-loop thread (this context) and one BLAS thread (the process)."""
    token = _SAMPLE_THREADS.set(1)
    try:
        with single_threaded_blas():
            yield
    finally:
        _SAMPLE_THREADS.reset(token)
