"""Many records, one set of sums: per-file sums through any ``concurrent.futures.Executor``.

::

    total, parts = sum_files(model, paths, executor=ProcessPoolExecutor(2), chunk_size=10_000)
    with connect("tcp://scheduler:8786") as executor:        # a dask.distributed cluster
        total, parts = sum_files(model, paths, executor=executor)

Each file is one task (:func:`file_task`): the worker rebuilds the model once from its
definition (robot, kind, effects; :func:`model_payload`), reads and preprocesses the file chunk by
chunk (:func:`estimation.streaming.chunks.file_sums`) and returns its sums, a few kilobytes. The driver
adds them. Nothing is added silently: every file submitted must come back once, with as many
samples summed as its rows call for (:class:`IncompleteSumError`), and a worker lost mid-run is a
:class:`WorkerLostError` naming the file (dask retries a task on another worker first, up to its
``distributed.scheduler.allowed-failures``).
"""

from __future__ import annotations

import contextlib
import functools
import os
import pickle
import warnings
from collections.abc import Iterator, Sequence
from concurrent.futures import CancelledError
from concurrent.futures.process import BrokenProcessPool
from pathlib import Path
from typing import Any

from dynamics.models import IdentificationModel, build_model
from estimation.data.loading import MeasurementError
from estimation.estimators.normal_equations import DEFAULT_CHUNK_SIZE, NormalEquations, reduce_sums
from estimation.streaming.chunks import FileScans, FileSums, file_sums, read_chunks
from estimation.streaming.periods import periodic_file_sums
from estimation.streaming.settings import SCHEDULER_VARIABLE, scheduler_address

__all__ = [
    "SCHEDULER_VARIABLE", "ClusterUnavailableError", "IncompleteSumError", "WorkerLostError", "caught_warnings",
    "connect", "file_stamp", "file_task", "model_from_payload", "model_payload", "scheduler_address", "sum_files",
    "task_result",
]

#: seconds to wait for a scheduler before giving up
CONNECT_TIMEOUT = 20.0


class ClusterUnavailableError(ValueError):
    """dask is not installed, or the scheduler cannot be reached."""


class WorkerLostError(RuntimeError):
    """A worker died (or was cancelled) before returning a file's sums."""


class IncompleteSumError(RuntimeError):
    """The sums returned do not cover every sample of every file."""


def model_payload(model: IdentificationModel) -> bytes:
    """The model's definition as bytes a worker rebuilds it from (the compiled functions stay behind)."""
    return pickle.dumps((model.robot, model.kind.value, model.effects))


@functools.lru_cache(maxsize=8)
def model_from_payload(payload: bytes) -> IdentificationModel:
    """The model :func:`model_payload` describes, built once per process for each payload (cached)."""
    robot, kind, effects = pickle.loads(payload)
    return build_model(robot, kind, effects)


def file_task(payload: bytes, path: str, options: dict[str, Any], stamp: tuple[int, int] | None = None
              ) -> tuple[FileSums, tuple[tuple[type, str], ...]]:
    """Picklable unit of work: the sums of one file (model rebuilt once per worker process) and the
    warnings reading it gave (category, message), for the driver to issue again. ``stamp`` (the
    file's modification time and size) is not used here: it changes the task's identity when the
    file changes, so that an executor caching results by their arguments (dask's ``pure=True``)
    never returns the sums of an older version."""
    return caught_warnings(sums_of_file, path, model_from_payload(payload), **options)


def caught_warnings(call: Any, *args: Any, **kwargs: Any) -> tuple[Any, tuple[tuple[type, str], ...]]:
    """``call(*args, **kwargs)`` in a worker, and the warnings it gave as ``(category, message)`` pairs
    (picklable), for :func:`task_result` to issue again in the driver."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        value = call(*args, **kwargs)
    return value, tuple((warning.category, str(warning.message)) for warning in caught)


def sums_of_file(path: str | Path, model: IdentificationModel, *, frequency_hz: float | None = None,
                 harmonics: int = 5, scans: FileScans | None = None, **options: Any) -> FileSums:
    """One file's sums: the Fourier path (:func:`estimation.streaming.periods.periodic_file_sums`) when a
    ``frequency_hz`` is given and the file lacks ``dq``/``ddq``, else :func:`estimation.streaming.chunks.file_sums`
    (the frequency is then unused, as in memory). ``scans``: the run's
    :class:`~estimation.streaming.chunks.FileScans`."""
    if frequency_hz is not None:
        first = next(read_chunks(path, model, chunk_size=options.get("chunk_size", DEFAULT_CHUNK_SIZE), scans=scans))
        if first.dq is None or first.ddq is None:
            return periodic_file_sums(path, model, frequency_hz=frequency_hz, harmonics=harmonics, **options)
    return file_sums(path, model, scans=scans, **options)


def sum_files(
    model: IdentificationModel,
    paths: Sequence[str | Path],
    *,
    executor: Any = None,
    scans: FileScans | None = None,
    **options: Any,
) -> tuple[NormalEquations, tuple[FileSums, ...]]:
    """Sums of ``model``'s problem over every file, and each file's own.

    Parameters
    ----------
    model
        The identification model.
    paths
        CSV/Parquet files (records or segments of one experiment).
    executor
        Any ``concurrent.futures.Executor`` (a process pool, ``dask.distributed.Client.get_executor()``);
        ``None``: the files in turn, in this process.
    scans
        The run's :class:`~estimation.streaming.chunks.FileScans` (in this process only: a worker scans its file):
        each file's scan taken from it, or made and held there.
    options
        For :func:`sums_of_file` (``chunk_size``, ``cutoff_hz``, ``decimation``, ``frequency_hz``…).

    Raises
    ------
    MeasurementError
        A file unreadable, with missing columns, or with other column groups than the first file
        (naming it).
    WorkerLostError, IncompleteSumError
        A file's sums did not come back whole.
    """
    paths = [str(path) for path in paths]
    if not paths:
        raise ValueError("no data files")
    if len(set(paths)) != len(paths):
        raise ValueError(f"a data file is given twice: {sorted({p for p in paths if paths.count(p) > 1})}")
    if executor is None:
        parts = [sums_of_file(path, model, scans=scans, **options) for path in paths]
    else:
        if not callable(getattr(executor, "submit", None)):
            raise TypeError(f"executor must be a concurrent.futures.Executor (with submit), got {type(executor).__name__}")
        payload = model_payload(model)
        futures = [executor.submit(file_task, payload, path, dict(options), file_stamp(path)) for path in paths]
        parts = []
        try:
            for path, future in zip(paths, futures):
                parts.append(task_result(future, path))
        finally:
            for future in futures:
                future.cancel()
    return check_parts(model, paths, parts), tuple(parts)


def file_stamp(path: str) -> tuple[int, int] | None:
    """The file's modification time (ns) and size, the ``stamp`` of a task (:func:`file_task`), or ``None``
    when it cannot be read (the reader then names the file)."""
    try:
        status = os.stat(path)
    except OSError:
        return None  # the reader names the file
    return (status.st_mtime_ns, status.st_size)


def task_result(future: Any, path: str) -> Any:
    """The value of a task's ``future`` (a :func:`caught_warnings` pair), its worker's warnings issued again
    here; a lost worker is a :class:`WorkerLostError` naming ``path``, other errors pass through."""
    try:
        part, caught = future.result()
        for category, message in caught:  # a worker's warnings, issued here
            warnings.warn(message, category, stacklevel=3)
        return part
    except Exception as error:
        lost = isinstance(error, (BrokenProcessPool, CancelledError)) or type(error).__name__ in LOST_WORKER_ERRORS
        if lost:
            raise WorkerLostError(f"the worker summing {path} was lost ({type(error).__name__}: {error}): "
                                  "no estimate is made from a partial sum") from None
        raise  # bad input named by the reader (MeasurementError…), or a bug


#: dask's exceptions for a task whose worker died (after its retries) or whose connection closed
LOST_WORKER_ERRORS = ("KilledWorker", "CommClosedError", "FutureCancelledError", "CancelledError")


def check_parts(model: IdentificationModel, paths: Sequence[str], parts: Sequence[FileSums]) -> NormalEquations:
    """The total of the per-file sums after checking that each file came back once and whole."""
    if len(parts) != len(paths) or [part.path for part in parts] != list(paths):
        returned = [part.path for part in parts]
        missing = [path for path in paths if path not in returned]
        raise IncompleteSumError(f"sums of {len(parts)} of {len(paths)} files came back (missing: {missing})")
    for part in parts:
        if part.sums.n_samples != part.expected_samples:
            raise IncompleteSumError(f"{part.path}: {part.sums.n_samples} samples summed of the "
                                     f"{part.expected_samples} its {part.rows} rows give: a partial sum")
        if part.sums.names != model.base.names or part.sums.channels != model.channels:
            raise IncompleteSumError(f"{part.path}: summed for another model (columns {part.sums.names[:3]}…)")
        if part.columns != parts[0].columns:
            raise MeasurementError(f"{part.path} holds the column groups {part.columns}, {parts[0].path} "
                                   f"{parts[0].columns}: the files of one set must have the same columns")
    total = reduce_sums([part.sums for part in parts])
    expected = sum(part.expected_samples for part in parts)
    if total.n_samples != expected:
        raise IncompleteSumError(f"{total.n_samples} samples summed of {expected} expected")
    return total


@contextlib.contextmanager
def connect(address: str, *, timeout: float | None = None) -> Iterator[Any]:
    """A ``concurrent.futures.Executor`` on the dask scheduler at ``address`` (closed on exit)."""
    try:
        from dask.distributed import Client
    except ImportError:
        raise ClusterUnavailableError("a scheduler needs dask.distributed: pip install 'robot-oed[cluster]'") from None
    try:
        client = Client(address, timeout=CONNECT_TIMEOUT if timeout is None else timeout)
    except (OSError, TimeoutError) as error:
        raise ClusterUnavailableError(f"cannot reach the dask scheduler at {address}: {error}") from None
    try:
        yield client.get_executor(pure=False)  # every call computed, never a result cached from an earlier run
    finally:
        client.close()
