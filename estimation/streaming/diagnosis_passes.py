"""The passes of the streamed diagnosis over its files (:mod:`estimation.streaming.diagnosis`), one
task a file on any ``concurrent.futures.Executor`` (as :func:`estimation.streaming.cluster.sum_files`), and
the noise floor on a bounded window.

* :func:`subsample_pass`, :func:`sums_pass`, :func:`scores_pass`: the three passes over the files,
  with their checks (the files of one set hold the same columns, the second pass reads the samples
  the first did);
* :func:`subsample_task`: an evenly spread subsample of one file's prepared samples
  (:class:`~estimation.streaming.diagnosis_sums.EvenSubsample`), the samples seen and the reading record;
* :func:`sums_task`: one file's :class:`~estimation.streaming.diagnosis_sums.ChannelSums` of the base and
  candidate columns at fixed shapes;
* :func:`map_files`: the tasks over the files, each file back once (a lost worker is a
  :class:`~estimation.streaming.cluster.WorkerLostError` naming the file, never a partial sum), the workers'
  warnings issued again here;
* :func:`window_floor`: the model-free noise floor of the first rows of each file as recorded.
"""

from __future__ import annotations

import functools
import pickle
import warnings
from collections.abc import Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from dynamics.measurements import Measurements
from dynamics.models import IdentificationModel
from dynamics.runtime.threads import single_threaded_blas
from estimation.streaming.cluster import caught_warnings, file_stamp, model_from_payload, task_result
from estimation.streaming.diagnosis_sums import ChannelSums, ColumnLayout, EvenSubsample, chunk_sums, concatenate
from estimation.data.loading import MeasurementError
from estimation.uncertainty.noise_floor import NoiseFloor, NoiseFloorError, noise_floor, pooled_floor
from estimation.streaming.chunks import logged_chunks
from estimation.streaming.periods import plan_chunks
from estimation.streaming.covariance import BatchScores, chunk_scores
from estimation.estimators.effect_blocks import Block

__all__ = ["FLOOR_WINDOW", "SubsamplePass", "SumsPass", "map_files", "scores_pass", "scores_task", "subsample_pass",
           "subsample_task", "sums_pass", "sums_task", "window_floor"]

#: rows of each validation file (as recorded) the noise floor is estimated on
FLOOR_WINDOW = 100_000


def _subsample(path: str, model: IdentificationModel, options: dict[str, Any], cap: int):
    record: dict = {}
    subsample = EvenSubsample(cap)
    for chunk in plan_chunks(path, model, record=record, **options):
        subsample.add(chunk)
    return subsample.measurements(), subsample.seen, record


def subsample_task(payload: bytes, path: str, options: dict[str, Any], cap: int, stamp=None):
    """Picklable: the evenly spread subsample of one file, samples seen, and its reading record."""
    return caught_warnings(_subsample, path, model_from_payload(payload), options, cap)


@functools.lru_cache(maxsize=4)
def _plan(payload: bytes, plan: bytes) -> tuple[ColumnLayout, tuple[Block, ...], tuple[np.ndarray, ...]]:
    model = model_from_payload(payload)
    effects, shapes = pickle.loads(plan)
    blocks = tuple(Block(model.kind, model.robot, effect, model.n_channels) for effect in effects)
    return ColumnLayout.build(model, blocks), blocks, tuple(shapes)


@single_threaded_blas()
def _sums(path: str, model: IdentificationModel, payload: bytes, plan: bytes, options: dict[str, Any]):
    layout, blocks, shapes = _plan(payload, plan)
    record: dict = {}
    sums = ChannelSums.empty(layout)
    for chunk in plan_chunks(path, model, record=record, **options):
        try:
            sums = chunk_sums(model, layout, blocks, shapes, chunk, sums)
        except ValueError as error:
            raise MeasurementError(f"{path} (near sample {sums.n_samples}): {error}") from None
    return sums, record


def sums_task(payload: bytes, plan: bytes, path: str, options: dict[str, Any], stamp=None):
    """Picklable: one file's :class:`ChannelSums` (base and candidate columns at fixed shapes)."""
    return caught_warnings(_sums, path, model_from_payload(payload), payload, plan, options)


@single_threaded_blas()
def _scores(path: str, model: IdentificationModel, payload: bytes, plan: bytes, options: dict[str, Any],
            theta: np.ndarray, weights: np.ndarray) -> BatchScores:
    layout, blocks, shapes = _plan(payload, plan)
    scores = BatchScores.empty(len(layout.names), layout.n_channels)
    for chunk in plan_chunks(path, model, **options):
        scores.add(*chunk_scores(model, layout, blocks, shapes, chunk, theta, weights))
    return scores.closed()


def scores_task(payload: bytes, plan: bytes, path: str, options: dict[str, Any], theta, weights, stamp=None):
    """Picklable: one file's :class:`~estimation.streaming.covariance.BatchScores` at the final estimate
    (``plan``: the chosen effects and shapes; ``theta`` on the base then their columns)."""
    return caught_warnings(_scores, path, model_from_payload(payload), payload, plan, options, np.asarray(theta), np.asarray(weights))


def map_files(executor, task, paths: Sequence[str], *arguments) -> list:
    """``task(*arguments_before_path, path, ...)`` for each path, in this process or on ``executor``;
    every file must come back (a lost worker is :class:`~estimation.streaming.cluster.WorkerLostError`)."""
    if executor is None:
        results = []
        for path in paths:
            value, caught = task(*arguments[0](path))
            for category, message in caught:
                warnings.warn(message, category, stacklevel=3)
            results.append(value)
        return results
    if not callable(getattr(executor, "submit", None)):
        raise TypeError(f"executor must be a concurrent.futures.Executor (with submit), got {type(executor).__name__}")
    futures = [executor.submit(task, *arguments[0](path)) for path in paths]
    try:
        return [task_result(future, path) for path, future in zip(paths, futures)]
    finally:
        for future in futures:
            future.cancel()


@dataclass(frozen=True)
class SubsamplePass:
    """The first pass: the evenly spread training subsample, the samples read in each file and each
    file's reading record."""

    sample: Measurements
    counts: tuple[int, ...]
    records: tuple[dict, ...]

    @property
    def seen(self) -> int:
        return sum(self.counts)


@dataclass(frozen=True)
class SumsPass:
    """The second pass: the training and validation sums, and each file's ``(sums, reading record)``."""

    train: ChannelSums
    validation: ChannelSums
    train_parts: tuple[tuple[ChannelSums, dict], ...]
    validate_parts: tuple[tuple[ChannelSums, dict], ...]


def _same_columns(paths: Sequence[str], records: Sequence[dict], reference: str, expected: dict) -> None:
    for path, record in zip(paths, records):
        if record["columns"] != expected["columns"]:
            raise MeasurementError(f"{path} holds the column groups {record['columns']}, {reference} "
                                   f"{expected['columns']}: the files of one set must have the same columns")


def subsample_pass(executor, payload: bytes, paths: Sequence[str], options: dict[str, Any],
                   subsample: int) -> SubsamplePass:
    """About ``subsample`` training samples spread evenly over the files (:func:`subsample_task`)."""
    cap = -(-int(subsample) // len(paths))
    parts = map_files(executor, subsample_task, paths, lambda path: (payload, path, options, cap, file_stamp(path)))
    records = tuple(record for _, _, record in parts)
    _same_columns(paths, records, paths[0], records[0])
    return SubsamplePass(_whole_band(concatenate([part for part, _, _ in parts]), [part for part, _, _ in parts],
                                     [count for _, count, _ in parts]),
                         tuple(count for _, count, _ in parts), records)


def _whole_band(sample: Measurements, parts: Sequence[Measurements], counts: Sequence[int]) -> Measurements:
    """The subsample with the band of the in-band problem when it holds every sample of every file (each file a
    segment, low-passed on its own as in memory: :meth:`~estimation.estimators.identification_problem.ResidualBand.of`);
    a thinned subsample has none (its samples are not contiguous: the channel weights of its fits are from the
    residual)."""
    if "band_window" not in sample.metadata or any(part.n_samples != count for part, count in zip(parts, counts)):
        return sample
    metadata = {key: value for key, value in sample.metadata.items() if key != "band_window"}
    if len(parts) > 1:
        stops = np.cumsum([part.n_samples for part in parts])
        metadata["segments"] = [{"start": int(stop - part.n_samples), "stop": int(stop)} for part, stop in zip(parts, stops)]
    return replace(sample, metadata=metadata)


def sums_pass(executor, payload: bytes, plan: bytes, paths: Sequence[str], validate: Sequence[str],
              options: dict[str, Any], first: SubsamplePass) -> SumsPass:
    """The sums of every training and validation file (:func:`sums_task`), checked against the first pass."""
    banded = dict(options, band=True)  # the training sums with those of the in-band problem (the channel weights)
    train_parts = map_files(executor, sums_task, paths, lambda path: (payload, plan, path, banded, file_stamp(path)))
    recorded = dict(options, as_recorded=True)  # the Fourier path validates on every sample (estimation.streaming.periods)
    validate_parts = map_files(executor, sums_task, validate, lambda path: (payload, plan, path, recorded, file_stamp(path)))
    for path, (sums, _), count in zip(paths, train_parts, first.counts):
        if sums.n_samples != count:
            raise MeasurementError(f"{path}: {sums.n_samples} samples summed, {count} read in the first pass (did the "
                                   "file change while it was read?)")
    _same_columns(validate, [record for _, record in validate_parts], paths[0], first.records[0])
    return SumsPass(functools.reduce(lambda a, b: a + b, [sums for sums, _ in train_parts]),
                    functools.reduce(lambda a, b: a + b, [sums for sums, _ in validate_parts]),
                    tuple(train_parts), tuple(validate_parts))


def scores_pass(executor, payload: bytes, plan: bytes, paths: Sequence[str], options: dict[str, Any],
                theta: np.ndarray, weights: np.ndarray) -> list[BatchScores]:
    """Each training file's batch scores at the final estimate (:func:`scores_task`)."""
    return map_files(executor, scores_task, paths, lambda path: (payload, plan, path, options, theta, weights,
                                                                 file_stamp(path)))


def window_floor(paths: Sequence[str | Path], model: IdentificationModel, *, window: int = FLOOR_WINDOW,
                 frequency_hz: float | None = None) -> tuple[NoiseFloor | None, str]:
    """The noise floor of the first ``window`` rows of each file as recorded (no filtering), pooled
    over the files; ``None`` and why when none can be had."""
    floors, failures = [], []
    for path in paths:
        # as logged: a resampled file's own samples, as the in-memory floor takes them (interpolation smooths noise)
        first = next(logged_chunks(path, model, chunk_size=max(int(window), model.n_base + 1)))
        try:
            floors.append(noise_floor(first, model.channels, frequency_hz=frequency_hz))
        except NoiseFloorError as error:
            failures.append(f"{path}: {error}")
    floor = pooled_floor(floors)
    if floor is None:
        return None, "no noise floor: " + "; ".join(failures)
    note = (f"estimated from the first {window} rows of each validation file as recorded "
            f"({len(floors)} of {len(list(paths))} file(s))")
    return floor, note + ("; none from " + "; ".join(failures) if failures else "")
