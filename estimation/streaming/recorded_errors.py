"""What ``oed predict`` needs from the streamed path: the preprocessing as a plan, and the errors of an
estimate against the channels as recorded, file by file in bounded memory.

:func:`streamed_plan` is the in-memory :class:`estimation.preprocessing.plan.Preprocessing` (as its
``to_dict``) that derives the motion as the streamed chunks do (the filter path covers the record's ends,
nothing trimmed, as the in-memory preprocessing does).

The streamed identification sums the channels it was fitted on: on the filter path those are
filtered, so its MSEs are against the filtered channels (``mse_filtered``). The model file promises
the error ``oed predict`` measures: the prediction along the derived motion against the channels as
recorded, on every sample, as the in-memory preprocessing keeps them. :func:`streamed_recorded_mse` is that error,
from one more pass over the files, chunk by chunk (:func:`estimation.streaming.chunks.preprocessed_chunks`: the
samples equal the whole-record ones to :data:`estimation.streaming.chunks.MARGIN_TOLERANCE`).
"""

from __future__ import annotations

import functools
import itertools
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from dynamics.measurements import Measurements
from dynamics.models import IdentificationModel
from estimation.identification.subtracted_load import SubtractedLoad, load_channels, subtracted_torque
from estimation.preprocessing.differentiation import ButterworthDifferentiation
from estimation.data.channel_mask import masked_cells, valid_sum
from estimation.streaming.block_errors import BlockSquares
from estimation.streaming.chunks import FileScans, logged_chunks
from estimation.streaming.delayed_chunks import moved_chunks
from estimation.streaming.periods import plan_chunks

__all__ = ["Predictor", "counted_errors_at_stamps", "counted_predicted_errors", "counted_recorded_errors",
           "delay_groups", "less_load", "recorded_training_errors", "scored_records", "streamed_errors_at_stamps", "streamed_plan", "streamed_recorded_errors",
           "streamed_recorded_mse", "theta_predictors"]


def streamed_plan(path: str | Path, model: IdentificationModel, *, cutoff_hz: float | None, decimation: int = 1,
                  held_torques: bool = False, chunk_size: int) -> dict[str, Any]:
    """The preprocessing plan (``Preprocessing.to_dict`` keys) of the streamed filter path at ``cutoff_hz``, or of
    measured derivatives without one; nothing trimmed (``path`` is read for its interface's sake only)."""
    common = {"decimation": int(decimation), "held_torques": bool(held_torques)}
    if cutoff_hz is None:
        return {"method": "measured", "trimmed_s": 0.0, **common}
    return {"method": "butterworth", "cutoff_hz": float(cutoff_hz), "filter_order": ButterworthDifferentiation().order,
            "trimmed_s": 0.0, **common}


def streamed_recorded_mse(model: IdentificationModel, theta: ArrayLike, paths: Sequence[str | Path], *, chunk_size: int,
                 cutoff_hz: float | None = None, decimation: int = 1, held_torques: bool = False) -> dict[str, float]:
    """Per channel, ``Σ (y − Y_b θ)² / N`` over ``paths`` (the samples of all files pooled), ``y`` the
    channels as recorded and ``Y_b`` the base regressor along the motion derived as the streamed path derives it."""
    return streamed_recorded_errors(model, {"theta": theta}, paths, chunk_size=chunk_size, cutoff_hz=cutoff_hz,
                                    decimation=decimation, held_torques=held_torques)["theta"]


def streamed_recorded_errors(model: IdentificationModel, thetas: Mapping[str, ArrayLike], paths: Sequence[str | Path], *,
                             chunk_size: int, cutoff_hz: float | None = None, decimation: int = 1,
                             held_torques: bool = False, frequency_hz: float | None = None,
                             harmonics: int = 5) -> dict[str, dict[str, float]]:
    """:func:`streamed_recorded_mse` of several parameter vectors in one pass over ``paths`` (by the names of
    ``thetas``): e.g. the estimate's and the trivial predictors' (zero, nominal:
    :mod:`estimation.identification.trivial_predictors`). ``frequency_hz``: the Fourier path (a file without
    ``dq``, ``ddq`` is read as the in-memory validation and ``oed predict`` read it: every sample of its whole
    periods, the fit of its averaged period at their instants, :func:`estimation.streaming.periods.plan_chunks`)."""
    return counted_recorded_errors(model, thetas, paths, chunk_size=chunk_size, cutoff_hz=cutoff_hz,
                                   decimation=decimation, held_torques=held_torques, frequency_hz=frequency_hz,
                                   harmonics=harmonics)[0]


def counted_recorded_errors(model: IdentificationModel, thetas: Mapping[Any, ArrayLike], paths: Sequence[str | Path],
                            *, chunk_size: int, cutoff_hz: float | None = None, decimation: int = 1,
                            held_torques: bool = False, frequency_hz: float | None = None,
                            harmonics: int = 5) -> tuple[dict[Any, dict[str, float]], int]:
    """:func:`streamed_recorded_errors` and the number of samples they are measured on (the files pooled)."""
    return counted_predicted_errors(model, theta_predictors(model, thetas), paths, chunk_size=chunk_size,
                                    cutoff_hz=cutoff_hz, decimation=decimation, held_torques=held_torques,
                                    frequency_hz=frequency_hz, harmonics=harmonics)


#: a prediction of the channels ``(N, m)`` along the motion ``q, dq, ddq`` (each ``(N, n)``)
Predictor = Callable[[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]], NDArray[np.float64]]


def theta_predictors(model: IdentificationModel, thetas: Mapping[Any, ArrayLike]) -> dict[Any, Predictor]:
    """``model``'s prediction at each base-parameter vector of ``thetas`` (by the same keys)."""
    predictors = {}
    for name, theta in thetas.items():
        vector = np.asarray(theta, dtype=float)
        if vector.shape != (model.n_base,):
            raise ValueError(f"theta must hold the model's {model.n_base} base parameters, got shape {vector.shape}")
        predictors[name] = functools.partial(model.predict, vector)
    return predictors


def less_load(model: IdentificationModel, predictors: Mapping[Any, Predictor], load: SubtractedLoad | None
              ) -> dict[Any, Predictor]:
    """``predictors`` as the log records their torques when it lacks ``load`` (a load of ``model``'s description,
    :mod:`estimation.identification.subtracted_load`): each prediction less the load at the positions it predicts
    at, as ``oed predict`` subtracts it (:meth:`~estimation.identification.identified_model.IdentifiedModel.predict`);
    scored against the channels as recorded, the errors of the model against the torques with the load added back,
    sample by sample, as memory measures them. ``load`` ``None``: ``predictors`` unchanged."""
    if load is None:
        return dict(predictors)
    channels = list(load_channels(model))
    if not channels:
        raise ValueError("a subtracted load needs a model of the joint torques (tau<k> channels)")

    def less(predict: Predictor) -> Predictor:
        def predicted(q: NDArray[np.float64], dq: NDArray[np.float64], ddq: NDArray[np.float64]) -> NDArray[np.float64]:
            return predict(q, dq, ddq) - subtracted_torque(load, model.robot, q)[:, channels]
        return predicted

    return {name: less(predict) for name, predict in predictors.items()}


def delay_groups(predictors: Mapping[Any, Predictor], delays: Mapping[Any, float | None] | None
                 ) -> list[tuple[float | None, dict[Any, Predictor]]]:
    """``predictors`` grouped by the delay of their model files (``delays`` by name; absent or ``None``: none), one
    pass over the files for each group: no delay first, then the delays in increasing order."""
    delays = {} if delays is None else delays
    order = sorted({delays.get(name) for name in predictors}, key=lambda value: (value is not None, value or 0.0))
    return [(delay, {name: predict for name, predict in predictors.items() if delays.get(name) == delay})
            for delay in order]


def counted_predicted_errors(model: IdentificationModel, predictors: Mapping[Any, Predictor],
                             paths: Sequence[str | Path], *, chunk_size: int, cutoff_hz: float | None = None,
                             decimation: int = 1, held_torques: bool = False, frequency_hz: float | None = None,
                             harmonics: int = 5, blocks: Mapping[Any, BlockSquares] | None = None,
                             delays: Mapping[Any, float | None] | None = None, average: str = "auto",
                             scans: FileScans | None = None) -> tuple[dict[Any, dict[str, float]], int]:
    """:func:`counted_recorded_errors` of any predictions (``predictors``: e.g. a model file's, shaped laws at its
    shapes); ``model`` reads the files (its joints and channels). ``blocks``: by predictor name, the accumulators
    of each validation block's squared residuals, filled as the rows pass (:mod:`estimation.streaming.block_errors`).
    ``delays``: by predictor name, the delay between torques and motion its model file holds (absent or ``None``:
    none); the motion of the samples as recorded is then moved to ``t − delay`` block by block
    (:func:`~estimation.streaming.delayed_chunks.moved_chunks`), as ``oed predict`` moves the whole record, the
    channels untouched: one pass for each delay. ``average``: ``--average-periods`` on the Fourier path. ``scans``:
    the run's :class:`~estimation.streaming.chunks.FileScans` (made here when not given: each file scanned once for
    all the passes)."""
    if not paths:
        raise ValueError("no files to measure the error on")
    scans = FileScans() if scans is None else scans
    squares = {name: np.zeros(model.n_channels) for name in predictors}
    count = 0  # the samples of one pass: every pass reads the same (moving the motion drops none)
    for delay, named in delay_groups(predictors, delays):
        count, valid = 0, np.zeros(model.n_channels)  # rows; each channel's valid samples (a masked one left out)
        for path in paths:
            records = (chunk.as_recorded for chunk in plan_chunks(
                path, model, frequency_hz=frequency_hz, harmonics=harmonics, as_recorded=True, chunk_size=chunk_size,
                cutoff_hz=cutoff_hz, decimation=decimation, held_torques=held_torques, average=average,
                scans=scans))
            for record in moved_chunks(records, delay):
                measured = record.channels(model.channels)
                masked = masked_cells(measured)
                for name, predict in named.items():
                    squared = (measured - predict(record.q, record.dq, record.ddq)) ** 2
                    squares[name] += valid_sum(squared, masked)
                    if blocks is not None and name in blocks:
                        blocks[name].add(squared)
                count += measured.shape[0]
                valid = valid + (measured.shape[0] if masked is None else np.sum(~masked, axis=0))
    if count == 0:
        raise ValueError("the files hold no samples once preprocessed")
    return {name: dict(zip(model.channels, map(float, total / valid))) for name, total in squares.items()}, count


def streamed_errors_at_stamps(model: IdentificationModel, thetas: Mapping[Any, ArrayLike], paths: Sequence[str | Path],
                              *, chunk_size: int, cutoff_hz: float | None = None, decimation: int = 1,
                              held_torques: bool = False) -> dict[Any, dict[str, float]] | None:
    """:func:`counted_errors_at_stamps` without the count (see there)."""
    counted = counted_errors_at_stamps(model, thetas, paths, chunk_size=chunk_size, cutoff_hz=cutoff_hz,
                                       decimation=decimation, held_torques=held_torques)
    return None if counted is None else counted[0]


def counted_errors_at_stamps(model: IdentificationModel, thetas: Mapping[Any, ArrayLike], paths: Sequence[str | Path],
                             *, chunk_size: int, cutoff_hz: float | None = None, decimation: int = 1,
                             held_torques: bool = False, predictors: Mapping[Any, Predictor] | None = None,
                             frequency_hz: float | None = None, harmonics: int = 5,
                             blocks: Mapping[Any, BlockSquares] | None = None,
                             delays: Mapping[Any, float | None] | None = None, average: str = "auto",
                             scans: FileScans | None = None) -> tuple[dict[Any, dict[str, float]], int] | None:
    """:func:`streamed_recorded_errors` at the samples as logged, block by block: on a file the streamed path
    resampled onto a uniform grid (jittered stamps), the derived motion of its grid blocks
    (:func:`~estimation.streaming.chunks.preprocessed_chunks`) is interpolated linearly at the recorded time stamps
    (:func:`~estimation.streaming.chunks.logged_chunks`) and the prediction compared with the channels as recorded
    there, never interpolated (:func:`estimation.preprocessing.plan.at_recorded_stamps` of the whole record, what
    ``oed predict`` measures); stamps outside the grid's span are left out as there. A file the streamed path reads
    as logged is scored on its own samples. ``frequency_hz``: the Fourier path (the motion of the grid's whole periods,
    the fit of the averaged period at each grid sample, :func:`estimation.streaming.periods.plan_chunks`, interpolated
    alike). The samples of all files pooled; memory: a few blocks and the time
    stamps (8 bytes a sample, as the scan of the streamed path's grid holds them), checked at the end.

    ``None`` when the loader resamples a file from other samples than the streamed path interpolates (rows it drops:
    a logger's re-sent rows, :func:`estimation.data.records.segments_from_frame`): its grid is then another, and the
    caller measures the files whole. A stall shorter than ``max_gap`` is bridged alike on both paths (the same grid
    over the same samples). ``blocks``: by name, the accumulators of each validation block's squared residuals
    (:mod:`estimation.streaming.block_errors`), filled as the samples pass in their order; spoiled
    (:meth:`~estimation.streaming.block_errors.BlockSquares.spoil`) when stamps before a grid's start are scored,
    which come last.

    ``delays``: by predictor name, the delay between torques and motion its model file holds (absent or ``None``:
    none), one pass for each delay (:func:`delay_groups`): the motion at the scored samples (interpolated at the
    recorded stamps, or as logged) is moved to ``t − delay`` among those samples block by block
    (:func:`~estimation.streaming.delayed_chunks.moved_chunks`), as ``oed predict`` moves the record it scores
    (:func:`estimation.preprocessing.delay.delayed` of the prepared record moves its samples at the recorded stamps
    among themselves), the channels untouched. ``None`` too when stamps before a grid's start would be scored on a
    pass with a delay (never met: a grid starts at the first sample kept): they come last, out of the order a move
    needs.

    ``scans``: the run's :class:`~estimation.streaming.chunks.FileScans` (made here when not given): each file
    scanned once for every pass, its grid's reading and its samples as logged."""
    scans = FileScans() if scans is None else scans
    if predictors is None:
        predictors = {name: functools.partial(model.predict, np.asarray(theta, dtype=float))
                      for name, theta in thetas.items()}
    if not paths:
        raise ValueError("no files to measure the error on")
    squares = {name: np.zeros(model.n_channels) for name in predictors}
    count = 0  # the samples of one pass: every pass scores the same (moving the motion drops none)
    for delay, named in delay_groups(predictors, delays):
        count, valid = 0, np.zeros(model.n_channels)  # rows; each channel's valid samples (a masked one left out)
        for _, record, late in scored_records(model, paths, delay=delay, chunk_size=chunk_size, cutoff_hz=cutoff_hz,
                                              decimation=decimation, held_torques=held_torques,
                                              frequency_hz=frequency_hz, harmonics=harmonics, average=average,
                                              scans=scans):
            if record is None:
                return None
            measured = record.channels(model.channels)
            masked = masked_cells(measured)
            for name, predict in named.items():
                squared = (measured - predict(record.q, record.dq, record.ddq)) ** 2
                squares[name] += valid_sum(squared, masked)
                if blocks is not None and name in blocks:
                    if late:  # out of the samples' order: no blocks
                        blocks[name].spoil()
                    blocks[name].add(squared)
            count += measured.shape[0]
            valid = valid + (measured.shape[0] if masked is None else np.sum(~masked, axis=0))
    if count == 0:
        raise ValueError("the files hold no samples once preprocessed")
    return {name: dict(zip(model.channels, map(float, total / valid))) for name, total in squares.items()}, count


def scored_records(model: IdentificationModel, paths: Sequence[str | Path], *, delay: float | None = None,
                   chunk_size: int, cutoff_hz: float | None = None, decimation: int = 1, held_torques: bool = False,
                   frequency_hz: float | None = None, harmonics: int = 5, average: str = "auto",
                   scans: FileScans | None = None) -> Iterator[tuple[int, Measurements | None, bool]]:
    """The samples :func:`counted_errors_at_stamps` scores, block by block in the files' order: each block with the
    index of its file in ``paths`` and whether it comes out of the samples' order (stamps before a grid's start,
    scored last), its motion moved by ``delay``; a block ``None`` ends the pass (a file whose rows the loader drops,
    or samples out of their order on a pass with a delay: the files are then measured whole). ``scans``: the run's
    :class:`~estimation.streaming.chunks.FileScans` (made here when not given)."""
    scans = FileScans() if scans is None else scans
    for index, path in enumerate(paths):
        scored = _scored_samples(model, path, chunk_size=chunk_size, cutoff_hz=cutoff_hz, decimation=decimation,
                                 held_torques=held_torques, frequency_hz=frequency_hz, harmonics=harmonics,
                                 average=average, scans=scans)
        if delay is not None and delay != 0.0:
            scored = _moved(scored, delay)
        for record, late in scored:
            yield index, record, late


#: the samples one file is scored on, block by block: each with whether it comes out of the samples' order (stamps
#: before the grid's start, scored last); ``None`` ends a file whose rows the loader drops
_Scored = Iterator[tuple[Measurements | None, bool]]


def _scored_samples(model: IdentificationModel, path: str | Path, *, chunk_size: int, cutoff_hz: float | None,
                    decimation: int, held_torques: bool, frequency_hz: float | None, harmonics: int,
                    average: str = "auto", scans: FileScans | None = None) -> _Scored:
    """The samples of one file :func:`counted_errors_at_stamps` scores, block by block: the motion there beside the
    channels as recorded. The file is scanned once for both of its readings (the grid's, the samples as logged): the
    scan its first reading makes handed to the second (:class:`~estimation.streaming.chunks.FileScans`; ``scans``,
    the run's, made here when not given)."""
    scans = FileScans() if scans is None else scans
    grid = (chunk.as_recorded for chunk in plan_chunks(
        path, model, frequency_hz=frequency_hz, harmonics=harmonics, as_recorded=True, chunk_size=chunk_size,
        cutoff_hz=cutoff_hz, decimation=decimation, held_torques=held_torques, average=average, scans=scans))
    first = next(grid, None)
    if first is None:
        return
    if first.metadata.get("resampled_from") is None:  # read as logged: its own samples
        for chunk in (first, *grid):
            yield chunk, False
        return
    stamps: list[NDArray[np.float64]] = []
    logged = _watched(logged_chunks(path, model, chunk_size=chunk_size, scans=scans), model, stamps)
    opening = next(logged)
    # the logged derivatives where the path uses them (no filter, no Fourier fit of the file's positions)
    measured = cutoff_hz is None and decimation == 1 and opening.dq is not None and opening.ddq is not None
    yield from _at_stamps(model, first, grid, itertools.chain([opening], logged), measured=measured)
    t = np.concatenate(stamps)
    if t.shape[0] != first.metadata["resampled_from"] or not np.all(np.isfinite(t)):
        yield None, False  # rows the loader drops: its grid interpolates other samples than the streamed one


def _moved(scored: _Scored, delay: float) -> _Scored:
    """``scored`` with the motion moved to ``t − delay`` among the scored samples (:func:`counted_errors_at_stamps`);
    ``None`` in place of samples out of their order, or of a file whose rows the loader drops."""
    ended: list[bool] = []

    def in_order() -> Iterator[Measurements]:
        for record, late in scored:
            if record is None or late:
                ended.append(True)
                return
            yield record

    for record in moved_chunks(in_order(), delay):
        yield record, False
    if ended:
        yield None, False


def _watched(chunks: Any, model: IdentificationModel, stamps: list[NDArray[np.float64]]) -> Any:
    """``chunks``, their time stamps appended to ``stamps`` as they pass (``nan`` for a block whose first row
    repeats the last of the block before: a row the loader drops, unseen within a block)."""
    previous = None
    for chunk in chunks:
        row = np.concatenate([chunk.q[0], chunk.channels(model.channels)[0]])
        if previous is not None and np.array_equal(row, previous):
            stamps.append(np.full(1, np.nan))
        previous = np.concatenate([chunk.q[-1], chunk.channels(model.channels)[-1]])
        stamps.append(chunk.t)
        yield chunk


def _at_stamps(model: IdentificationModel, first: Any, grid: Any, logged: Any, *, measured: bool) -> _Scored:
    """The logged samples of one resampled file with the motion of its grid blocks (``first``, then ``grid``) at
    their stamps, each interpolated between the two grid samples around it (:func:`counted_errors_at_stamps`)."""
    t_grid, motion = first.t, [first.q, first.dq, first.ddq]
    start, done = float(first.t[0]), False
    opening = [values[:1] for values in motion]  # what a stamp before the grid's start is interpolated to
    held: list[Any] = []  # stamps before the grid's start, decided when its span is known
    span_end = None

    def extend() -> bool:
        nonlocal t_grid, motion
        chunk = next(grid, None)
        if chunk is None:
            return False
        t_grid = np.concatenate([t_grid, chunk.t])
        motion = [np.vstack([old, new]) for old, new in zip(motion, (chunk.q, chunk.dq, chunk.ddq))]
        return True

    def scored(stamps: Any, keep: Any, clamped: bool = False) -> Measurements | None:
        kept = np.flatnonzero(keep)
        if kept.size == 0:
            return None
        t = stamps.t[kept]
        if measured:
            q, dq, ddq = stamps.q[kept], stamps.dq[kept], stamps.ddq[kept]
        elif clamped:  # np.interp's value before the first sample
            q, dq, ddq = (np.repeat(values, t.size, axis=0) for values in opening)
        else:
            q, dq, ddq = (np.column_stack([np.interp(t, t_grid, column) for column in values.T]) for values in motion)
        return replace(stamps.select(kept), q=q, dq=dq, ddq=ddq)

    for stamps in logged:
        while not done and t_grid[-1] < stamps.t[-1]:
            done = not extend()
        if done and span_end is None:
            span_end = float(t_grid[-1])
        before = stamps.t < start
        if np.any(before):
            held.append(stamps.select(np.flatnonzero(before)))
        inside = ~before
        if span_end is not None:
            inside &= stamps.t <= span_end + 1e-9 * (span_end - start)
        record = scored(stamps, inside)
        if record is not None:
            yield record, False
        keep_from = max(int(np.searchsorted(t_grid, stamps.t[-1])) - 1, 0)  # the grid sample before the last stamp
        t_grid, motion = t_grid[keep_from:], [values[keep_from:] for values in motion]
    while not done:
        done = not extend()
    end = float(t_grid[-1]) if span_end is None else span_end
    tolerance = 1e-9 * (end - start)
    for stamps in held:
        record = scored(stamps, stamps.t >= start - tolerance, clamped=True)
        if record is not None:
            yield record, True


def recorded_training_errors(model: IdentificationModel, predictors: Mapping[Any, Predictor], paths: Sequence[str | Path],
                             files: Sequence[Mapping[str, Any]], *, chunk_size: int, cutoff_hz: float | None = None,
                             decimation: int = 1, held_torques: bool = False, frequency_hz: float | None = None,
                             harmonics: int = 5, delays: Mapping[Any, float | None] | None = None,
                             average: str = "auto") -> tuple[dict[Any, dict[str, float]], int] | None:
    """The training errors of ``predictors`` (:func:`theta_predictors`, or a model file's) against the channels as recorded, on the samples the in-memory fit measures
    them on, and how many those are, from one more pass over the training ``paths`` block by block (memory: a few
    blocks; a resampled file's time stamps): on the filter path the derived motion against the recorded channels
    (:func:`counted_recorded_errors`), on a file the streamed path resampled onto a uniform grid at the recorded
    stamps (:func:`counted_errors_at_stamps`), on the Fourier path every sample of the files' whole periods with the
    fit of their averaged period at its instant, as the in-memory Fourier fit compares them. ``files``: the
    streamed record of each training file (``streaming.files``: ``resampled_from``). ``None`` where the loader
    drops rows the streamed grid interpolates (:func:`counted_errors_at_stamps`): the caller keeps the errors it
    has. ``delays``: by predictor name, its model file's delay: the motion of the samples scored moved by it, as
    ``oed predict`` moves the record (:func:`counted_predicted_errors`; at a resampled file's stamps,
    :func:`counted_errors_at_stamps`). ``average``: ``--average-periods`` on the Fourier path."""
    if any(record.get("resampled_from") is not None for record in files):
        return counted_errors_at_stamps(model, {}, paths, chunk_size=chunk_size, cutoff_hz=cutoff_hz,
                                        decimation=decimation, held_torques=held_torques, predictors=predictors,
                                        frequency_hz=frequency_hz, harmonics=harmonics, delays=delays,
                                        average=average)
    return counted_predicted_errors(model, predictors, paths, chunk_size=chunk_size, cutoff_hz=cutoff_hz,
                                    decimation=decimation, held_torques=held_torques, frequency_hz=frequency_hz,
                                    harmonics=harmonics, delays=delays, average=average)
