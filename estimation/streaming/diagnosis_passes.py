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
from estimation.data.channel_mask import whole_rows
from estimation.data.loading import MeasurementError
from estimation.uncertainty.noise_floor import NoiseFloor, NoiseFloorError, noise_floor, pooled_floor
from estimation.streaming.chunks import DEFAULT_CHUNK_SIZE, logged_chunks
from estimation.streaming.record_floor import segment_floors
from estimation.streaming.periods import plan_chunks
from estimation.streaming.covariance import BatchScores, chunk_scores
from estimation.streaming.delayed_chunks import moved_chunks
from estimation.streaming.settings import FLOOR_WINDOW
from estimation.estimators.effect_blocks import Block, States
from estimation.identification.subtracted_load import SubtractedLoad
from estimation.identification.training_range import TrainingRange

__all__ = ["FLOOR_WINDOW", "LagSums", "SubsamplePass", "SumsPass", "block_sums_task", "map_files", "scores_pass",
           "scores_task", "subsample_pass", "subsample_task", "stretch_pass", "stretch_task", "sums_pass", "sums_task",
           "validation_blocks_pass", "window_floor"]



def _whole_rows(chunks):
    """The prepared ``chunks`` without their samples where a channel is masked (a clipped sensor's, a held channel's
    repeats: :func:`~estimation.data.channel_mask.whole_rows`), as memory's diagnosis search takes whole rows, the
    derivatives made from every row's positions before; a chunk that lost rows loses its band window too (its
    in-band sums are had over contiguous samples: the weights then from the residual)."""
    for chunk in chunks:
        kept = whole_rows(chunk)
        if kept is not chunk and kept.metadata.get("band_window") is not None:
            kept = replace(kept, metadata={**kept.metadata, "band_window": None})
        yield kept


def _subsample(path: str, model: IdentificationModel, options: dict[str, Any], cap: int):
    record: dict = {}
    subsample = EvenSubsample(cap)
    for chunk in _whole_rows(plan_chunks(path, model, record=record, **options)):
        subsample.add(chunk)
    return subsample.measurements(), subsample.seen, record


def subsample_task(payload: bytes, path: str, options: dict[str, Any], cap: int, stamp=None):
    """Picklable: the evenly spread subsample of one file, samples seen, and its reading record."""
    return caught_warnings(_subsample, path, model_from_payload(payload), options, cap)


def _chunks(path: str, model: IdentificationModel, options: dict[str, Any], record: dict | None = None,
            pairs: bool = False):
    """The file's prepared chunks (:func:`~estimation.streaming.periods.plan_chunks`), moved by ``options["delay"]``
    when it is given (:func:`~estimation.streaming.delayed_chunks.moved_chunks`, the diagnosis's adopted delay;
    ``pairs``: each beside the chunk as read)."""
    options = dict(options)
    delay = options.pop("delay", None)
    extra = {} if record is None else {"record": record}
    return moved_chunks(_whole_rows(plan_chunks(path, model, **extra, **options)), delay, pairs=pairs)


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
    joint_range = None  # each joint's range on the samples summed (estimation.identification.training_range)
    moving = options.get("delay") is not None
    declared = ChannelSums.empty(ColumnLayout.build(model, [])) if moving else None
    for read, chunk in _chunks(path, model, options, record, pairs=True):
        try:
            sums = chunk_sums(model, layout, blocks, shapes, chunk, sums)
            if declared is not None:  # the declared model along the motion as read (the diagnosis's "before")
                declared = chunk_sums(model, declared.layout, (), (), read, declared)
        except ValueError as error:
            raise MeasurementError(f"{path} (near sample {sums.n_samples}): {error}") from None
        if chunk.n_samples:
            joint_range = TrainingRange.of(chunk.q, chunk.dq, model.robot.joint_names).merged(joint_range)
    record["joint_range"] = joint_range
    if declared is not None:
        record[DECLARED_AS_READ] = declared
    return sums, record


#: the key of a file's reading record holding, on a pass along a moved motion, the declared model's sums along the
#: motion as read (:func:`sums_pass` takes it out: :attr:`SumsPass.declared`)
DECLARED_AS_READ = "declared_as_read"


@dataclass
class LagSums:
    """Per channel, over consecutive pairs of samples of each file: ``Σ x_t x_{t−1}ᵀ``, ``Σ x_t y_{t−1}``,
    ``Σ x_{t−1} y_t``, ``Σ y_t y_{t−1}``, and ``Σ x``, ``Σ y``, the first and last sample's ``x`` and ``y`` of each
    file (summed over files): the lag-1 autocorrelation of any model's residual (:meth:`rho`), as
    :func:`estimation.uncertainty.batch_means.batch_length` measures it, from sums."""

    cross: list[np.ndarray]
    x_prev_y: list[np.ndarray]  # Σ x_{t−1} y_t
    x_y_prev: list[np.ndarray]  # Σ x_t y_{t−1}
    yy: np.ndarray
    sx: list[np.ndarray]
    sy: np.ndarray
    first: list[np.ndarray]  # [x, y] of each file's first sample, summed
    last: list[np.ndarray]
    n_samples: int = 0
    n_files: int = 0

    @classmethod
    def empty(cls, layout: ColumnLayout) -> LagSums:
        sizes = [len(layout.channel_columns(c)) for c in range(layout.n_channels)]
        m = layout.n_channels
        return cls([np.zeros((k, k)) for k in sizes], [np.zeros(k) for k in sizes], [np.zeros(k) for k in sizes],
                   np.zeros(m), [np.zeros(k) for k in sizes], np.zeros(m), [np.zeros(k + 1) for k in sizes],
                   [np.zeros(k + 1) for k in sizes])

    def __add__(self, other: LagSums) -> LagSums:
        def add(a, b):
            return [x + y for x, y in zip(a, b)]
        return LagSums(add(self.cross, other.cross), add(self.x_prev_y, other.x_prev_y),
                       add(self.x_y_prev, other.x_y_prev), self.yy + other.yy, add(self.sx, other.sx),
                       self.sy + other.sy, add(self.first, other.first), add(self.last, other.last),
                       self.n_samples + other.n_samples, self.n_files + other.n_files)

    def add(self, columns: list[np.ndarray], targets: np.ndarray, previous: list[np.ndarray] | None) -> None:
        """The next consecutive samples of one file: ``columns[c]`` ``(n, k_c)``, ``targets`` ``(n, m)``; ``previous``:
        the last ``[x, y]`` row of each channel before them (``None``: the file's first samples)."""
        for c, X in enumerate(columns):
            y = targets[:, c]
            rows = np.column_stack([X, y])
            if previous is not None:
                rows = np.vstack([previous[c], rows])
            else:
                self.first[c] += rows[0]
            self.cross[c] += rows[1:, :-1].T @ rows[:-1, :-1]
            self.x_prev_y[c] += rows[:-1, :-1].T @ rows[1:, -1]
            self.x_y_prev[c] += rows[1:, :-1].T @ rows[:-1, -1]
            self.yy[c] += rows[1:, -1] @ rows[:-1, -1]
            self.sx[c] += X.sum(axis=0)
            self.sy[c] += y.sum()
        self.n_samples += targets.shape[0]

    def rho(self, sums: ChannelSums, selection, theta: np.ndarray, weights: np.ndarray) -> float:
        """The weighted mean lag-1 autocorrelation of the centred residuals of ``theta`` on the columns ``selection``
        (prepared channels; ``sums``: the training sums of the same samples)."""
        theta, weights = np.asarray(theta, dtype=float), np.asarray(weights, dtype=float)
        rss = sums.channel_rss(selection, theta, target=0)
        n, pairs = self.n_samples, self.n_samples - self.n_files
        covariance, variance = np.zeros_like(weights), np.zeros_like(weights)
        for c in range(len(self.cross)):
            outer, inner = sums._positions(c, selection)
            part = theta[outer]
            total = self.sy[c] - part @ self.sx[c][inner]
            mean = total / max(n, 1)
            first = self.first[c][-1] - part @ self.first[c][inner]
            last = self.last[c][-1] - part @ self.last[c][inner]
            lagged = (self.yy[c] - part @ self.x_prev_y[c][inner] - part @ self.x_y_prev[c][inner]
                      + part @ self.cross[c][np.ix_(inner, inner)] @ part)
            covariance[c] = lagged - mean * ((total - first) + (total - last)) + pairs * mean**2
            variance[c] = rss[c] - n * mean**2
        return float(np.clip(np.sum(weights * covariance) / max(np.sum(weights * variance), 1e-300), 0.0, 0.999))


def _channel_columns(model: IdentificationModel, layout: ColumnLayout, blocks, shapes, chunk: Measurements
                     ) -> tuple[list[np.ndarray], np.ndarray]:
    """Each channel's columns (:meth:`ColumnLayout.channel_columns`) on ``chunk`` and its prepared channels."""
    Y = model.evaluate_base(chunk.q, chunk.dq, chunk.ddq)
    states = States(chunk.q, chunk.dq, chunk.ddq)
    values = [block.evaluate(states, shape) for block, shape in zip(blocks, shapes)]
    columns = [np.concatenate([Y[:, c, :]] + [v[:, rows.index(c), :] for v, rows in zip(values, layout.rows)
                                              if c in rows], axis=1) for c in range(layout.n_channels)]
    return columns, chunk.channels(model.channels)


@single_threaded_blas()
def _stretch_sums(path: str, model: IdentificationModel, payload: bytes, plan: bytes, options: dict[str, Any],
                  start: int, total: int, n_blocks: int, lags: bool = False):
    layout, blocks, shapes = _plan(payload, plan)
    sums = [ChannelSums.empty(layout) for _ in range(n_blocks)]
    lag, previous = (LagSums.empty(layout), None) if lags else (None, None)
    seen = start
    for chunk in _chunks(path, model, options):
        labels = np.minimum((n_blocks * (seen + np.arange(chunk.n_samples))) // max(total, 1), n_blocks - 1)
        seen += chunk.n_samples
        for block in np.unique(labels):
            sums[block] = chunk_sums(model, layout, blocks, shapes, chunk.select(np.flatnonzero(labels == block)),
                                     sums[block])
        if lag is not None and chunk.n_samples:
            columns, targets = _channel_columns(model, layout, blocks, shapes, chunk)
            lag.add(columns, targets, previous)
            previous = [np.append(X[-1], targets[-1, c]) for c, X in enumerate(columns)]
    if lag is not None and previous is not None:
        for c, row in enumerate(previous):
            lag.last[c] += row
        lag.n_files = 1
    return sums if lag is None else (sums, lag)


def stretch_task(payload: bytes, plan: bytes, path: str, options: dict[str, Any], start: int, total: int,
                 n_blocks: int, lags: bool = False, stamp=None):
    """Picklable: one training file's :class:`ChannelSums` on each of ``n_blocks`` stretches of the training record
    (sample ``i`` of the record, ``start`` the file's first, in stretch ``⌊n_blocks i / total⌋``)."""
    return caught_warnings(_stretch_sums, path, model_from_payload(payload), payload, plan, options, start, total,
                           n_blocks, lags)


@single_threaded_blas()
def _block_sums(path: str, model: IdentificationModel, payload: bytes, plan: bytes, options: dict[str, Any],
                start: int, bounds: tuple[int, ...]) -> list[ChannelSums]:
    layout, blocks, shapes = _plan(payload, plan)
    edges = np.asarray(bounds, dtype=np.int64)
    sums = [ChannelSums.empty(layout) for _ in range(edges.size - 1)]
    seen = start
    for chunk in _chunks(path, model, options):
        labels = np.searchsorted(edges, seen + np.arange(chunk.n_samples), side="right") - 1
        seen += chunk.n_samples
        for block in np.unique(labels):
            if not 0 <= block < len(sums):
                raise MeasurementError(f"{path}: more samples than the validation sums counted (did the file change "
                                       "while it was read?)")
            sums[block] = chunk_sums(model, layout, blocks, shapes, chunk.select(np.flatnonzero(labels == block)),
                                     sums[block])
    return sums


def block_sums_task(payload: bytes, plan: bytes, path: str, options: dict[str, Any], start: int,
                    bounds: tuple[int, ...], stamp=None):
    """Picklable: one validation file's :class:`ChannelSums` on each block of the validation record (its rows
    ``bounds[b] .. bounds[b + 1]``, ``start`` the file's first row in the record)."""
    return caught_warnings(_block_sums, path, model_from_payload(payload), payload, plan, options, start, bounds)


def validation_blocks_pass(executor, payload: bytes, plan: bytes, paths: Sequence[str], options: dict[str, Any],
                           counts: Sequence[int], bounds: Sequence[int]) -> list[ChannelSums]:
    """The validation sums (the second pass's, :func:`sums_pass`: the files as recorded, in order, ``counts`` their
    samples) on each contiguous block of the record, the rows ``bounds[b] .. bounds[b + 1]``
    (:func:`estimation.streaming.block_errors.block_bounds`: the blocks memory cuts its validation samples into):
    any parameter vector's errors on each block follow without another pass."""
    starts = np.concatenate([[0], np.cumsum(counts)[:-1]]).astype(int)
    start_of = dict(zip(paths, map(int, starts)))
    edges = tuple(int(bound) for bound in bounds)
    recorded = dict(options, as_recorded=True)
    parts = map_files(executor, block_sums_task, paths, lambda path: (payload, plan, path, recorded, start_of[path],
                                                                     edges, file_stamp(path)))
    return [functools.reduce(lambda a, b: a + b, [part[block] for part in parts]) for block in range(len(edges) - 1)]


def stretch_pass(executor, payload: bytes, plan: bytes, paths: Sequence[str], options: dict[str, Any],
                 first: SubsamplePass, n_blocks: int, lags: bool = False):
    """The training sums on each of ``n_blocks`` consecutive stretches of the training record (the files in order,
    as the in-memory record stacks them; :class:`~estimation.diagnosis.confirmation.HeldOutBlocks` by time):
    what the comparison of candidates on stretches their fits did not see needs when the validation record is at
    rest (:class:`~estimation.streaming.selection.SummedFits`), or the batches of the search's robust covariance;
    with ``lags``, also the record's :class:`LagSums`: ``(stretches, lags)``."""
    starts = np.concatenate([[0], np.cumsum(first.counts)[:-1]]).astype(int)
    start_of = dict(zip(paths, map(int, starts)))
    parts = map_files(executor, stretch_task, paths, lambda path: (payload, plan, path, options, start_of[path],
                                                                  first.seen, n_blocks, lags, file_stamp(path)))
    stretches = [part[0] for part in parts] if lags else parts
    summed = [functools.reduce(lambda a, b: a + b, [part[block] for part in stretches]) for block in range(n_blocks)]
    if not lags:
        return summed
    return summed, functools.reduce(lambda a, b: a + b, [part[1] for part in parts])


def sums_task(payload: bytes, plan: bytes, path: str, options: dict[str, Any], stamp=None):
    """Picklable: one file's :class:`ChannelSums` (base and candidate columns at fixed shapes)."""
    return caught_warnings(_sums, path, model_from_payload(payload), payload, plan, options)


@single_threaded_blas()
def _scores(path: str, model: IdentificationModel, payload: bytes, plan: bytes, options: dict[str, Any],
            theta: np.ndarray, weights: np.ndarray) -> BatchScores:
    layout, blocks, shapes = _plan(payload, plan)
    scores = BatchScores.empty(len(layout.names), layout.n_channels)
    for chunk in _chunks(path, model, options):
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
    #: with an adopted delay (the sums along the moved motion), the declared model's training and validation sums
    #: along the motion as read (what the in-memory diagnosis's declared fit sees); ``None``: no delay
    declared: tuple[ChannelSums, ChannelSums] | None = None


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
    declared = None
    if options.get("delay") is not None:
        train_declared = [record.pop(DECLARED_AS_READ) for _, record in train_parts]
        validate_declared = [record.pop(DECLARED_AS_READ) for _, record in validate_parts]
        declared = (functools.reduce(lambda a, b: a + b, train_declared),
                    functools.reduce(lambda a, b: a + b, validate_declared))
    return SumsPass(functools.reduce(lambda a, b: a + b, [sums for sums, _ in train_parts]),
                    functools.reduce(lambda a, b: a + b, [sums for sums, _ in validate_parts]),
                    tuple(train_parts), tuple(validate_parts), declared)


def scores_pass(executor, payload: bytes, plan: bytes, paths: Sequence[str], options: dict[str, Any],
                theta: np.ndarray, weights: np.ndarray) -> list[BatchScores]:
    """Each training file's batch scores at the final estimate (:func:`scores_task`)."""
    return map_files(executor, scores_task, paths, lambda path: (payload, plan, path, options, theta, weights,
                                                                 file_stamp(path)))


def window_floor(paths: Sequence[str | Path], model: IdentificationModel, *, window: int | None = None,
                 frequency_hz: float | None = None, load: SubtractedLoad | None = None,
                 chunk_size: int = DEFAULT_CHUNK_SIZE) -> tuple[NoiseFloor | None, str]:
    """The noise floor of each file (or segment) as recorded (no filtering), pooled over them; ``None`` and why when
    none can be had. ``window=None``: every row, memory's floor of the validation record
    (:func:`~estimation.streaming.record_floor.segment_floors`: exact medians by passes, the periodic estimates of a
    long segment by sums; the same floor as ``PreparedRecord.noise_floor``); else the first ``window`` rows of each
    (``--floor-window``). ``load``: a load the logged torques lack, added back at the logged positions (the torques
    the model holds, as memory's floor takes them)."""
    if window is None:
        floors, failures = segment_floors(paths, model, chunk_size=chunk_size, frequency_hz=frequency_hz, load=load)
    else:
        floors, failures = [], []
        for path in paths:
            # as logged: a resampled file's own samples, as the in-memory floor takes them (interpolation smooths
            # noise)
            first = next(logged_chunks(path, model, chunk_size=max(int(window), model.n_base + 1), load=load))
            try:
                floors.append(noise_floor(first, model.channels, frequency_hz=frequency_hz))
            except NoiseFloorError as error:
                failures.append(f"{path}: {error}")
    floor = pooled_floor(floors)
    if floor is None:
        return None, "no noise floor: " + "; ".join(failures)
    what = "every row" if window is None else f"the first {window} rows"
    note = (f"estimated from {what} of each validation file as recorded "
            f"({len(floors)} of {len(list(paths))} file(s))")
    return floor, note + ("; none from " + "; ".join(failures) if failures else "")
