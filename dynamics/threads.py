"""Thread budgets: how many threads the sample loops and the BLAS library may use here.

A unit of work that runs beside others in separate processes (a design start in a process pool or
on a ``dask`` worker, a pytest-xdist worker) must stay on one thread. Otherwise every process adds
OpenBLAS's threads, which spin while idle, and the two slices of :class:`dynamics.compiled.
SampleEvaluator`'s loop, and the machine runs several runnable threads a core: on this 2-core
machine ``design_excitation(starts=8)`` through a 2-process pool took 4.5 s against 0.62 s with one
thread a process (``OPENBLAS_NUM_THREADS=1``), 1.7 s in turn.

:func:`single_threaded` sets both budgets for the code it wraps (a context variable for the sample
loops, :mod:`threadpoolctl` for BLAS) and restores them on exit.
"""

from __future__ import annotations

import contextlib
import contextvars
import os
from collections.abc import Iterator

from threadpoolctl import threadpool_limits

_SAMPLE_THREADS: contextvars.ContextVar[int | None] = contextvars.ContextVar("robot_oed_sample_threads", default=None)


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
def single_threaded() -> Iterator[None]:
    """Run the wrapped code with one sample-loop thread and one BLAS thread, then restore both."""
    token = _SAMPLE_THREADS.set(1)
    try:
        with threadpool_limits(limits=1, user_api="blas"):
            yield
    finally:
        _SAMPLE_THREADS.reset(token)
