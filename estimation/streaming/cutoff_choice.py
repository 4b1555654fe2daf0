"""The derivatives of a streamed record, chosen as the in-memory path chooses them, on the same window.

The in-memory path chooses how ``dq, ddq`` are made by held-out evidence
(:func:`estimation.identification.preprocessing_choice.choose_by_evidence`) on a
:class:`~estimation.identification.preprocessing_choice.ChoiceWindow`: the whole record up to
:data:`~estimation.identification.preprocessing_choice.SCORED_SAMPLES` samples, else the first
:data:`~estimation.identification.preprocessing_choice.SCORED_SAMPLES` samples of its longest segment.
:func:`streamed_window` reads that same window from the files (their rows counted without parsing,
:func:`estimation.data.memory_budget.count_rows`; the longest file read up to the window), and
:func:`choose_streamed_preprocessing` hands it to the same function, every candidate family included: one code
path for the choice, whichever way the sums are then computed. Memory stays bounded by the window.

:func:`choose_streamed_cutoff` is the filter-only choice on the first rows of one file (what the streamed path
did before; kept for scripts).
"""

from __future__ import annotations

import warnings
from collections.abc import Sequence
from dataclasses import replace
from pathlib import Path

import numpy as np

from dynamics.measurements import Measurements
from dynamics.models import IdentificationModel
from estimation.identification.preprocessing_choice import (
    SCORED_SAMPLES,
    ChoiceWindow,
    PreprocessingChoice,
    choose_by_evidence,
)
from estimation.identification.preprocessing_on_validation import on_validation
from estimation.preprocessing.plan import Preprocessing, PreprocessingWarning
from estimation.streaming.chunks import from_positions, read_chunks, source_file, source_rows
from estimation.streaming.time_base import Part
from estimation.data.records import read_record

__all__ = ["choose_streamed_cutoff", "choose_streamed_preprocessing", "first_rows", "streamed_window"]


def first_rows(path: str | Path, model: IdentificationModel, rows: int) -> Measurements:
    """The first ``rows`` samples of ``path`` (all of them when it holds fewer), read and checked as the
    streamed path reads every chunk. A resampled file (jitter, stalls, rows dropped) of at most ``rows`` rows is
    read whole as the in-memory loader reads it (the same grid and samples, :mod:`estimation.streaming.time_base`),
    with its samples as recorded beside (:attr:`Measurements.recorded`: errors are taken on them), as the
    in-memory choice scores it."""
    first = next(read_chunks(path, model, chunk_size=max(int(rows), model.n_base + 1)))
    if first.metadata.get("resampled_from") is not None and source_rows(path, model) <= rows \
            and not isinstance(source_file(path)[1], Part):  # a part between holds: read as streamed
        file, segment = source_file(path)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # said by read_chunks
            whole = read_record(file, model=model, split=segment is not None)[0 if segment is None else segment - 1]
            if from_positions(path):  # read without its logged velocities, as read_chunks reads it
                whole = replace(whole, dq=None, recorded=None if whole.recorded is None else
                                replace(whole.recorded, dq=None))
            return whole
    return first if first.n_samples <= rows else first.select(slice(0, int(rows)))


def streamed_window(paths: Sequence[str | Path], model: IdentificationModel,
                    rows: Sequence[int] | None = None) -> ChoiceWindow:
    """The :class:`ChoiceWindow` of the record made of the files ``paths`` (module docstring); ``rows``: their
    row counts when already known."""
    if not paths:
        raise ValueError("no training data files")
    rows = [source_rows(path, model) for path in paths] if rows is None else list(rows)
    if sum(rows) <= SCORED_SAMPLES:  # every file read whole (a resampled file holds other than its rows' count)
        segments = tuple(first_rows(path, model, count) for path, count in zip(paths, rows))
        return ChoiceWindow(segments, min(float(segment.t[-1] - segment.t[0]) for segment in segments))
    longest = int(np.argmax(rows))  # the first of the longest, as max() picks it in memory
    segments = (first_rows(paths[longest], model, SCORED_SAMPLES),)
    return ChoiceWindow(segments, min(_duration(path, model, count) for path, count in zip(paths, rows)), whole=False)


def _duration(path: str | Path, model: IdentificationModel, rows: int) -> float:
    """A file's duration from its row count and its sampling step (read from its first rows)."""
    head = first_rows(path, model, min(rows, 1000))
    return float(np.median(np.diff(head.t))) * (rows - 1)


def choose_streamed_preprocessing(paths: Sequence[str | Path], model: IdentificationModel, *,
                                  frequency_hz: float | None = None, harmonics: int | None = None,
                                  cutoff_hz: float | None = None, average_periods: str = "auto", decimation: int = 1,
                                  held_torques: bool | None = False, rows: Sequence[int] | None = None,
                                  held_out: Sequence[str | Path] = (), validation: Sequence[str | Path] = (),
                                  validation_fits: tuple[str, ...] = (),
                                  validation_model: IdentificationModel | None = None) -> PreprocessingChoice:
    """The preprocessing of the training files ``paths``, chosen as in memory (module docstring); the options
    are those of :func:`~estimation.identification.preprocessing_choice.choose_by_evidence`. ``held_out``: the
    validation (and test) files, whose first :data:`SCORED_SAMPLES` rows every candidate must be able to prepare
    (in bounded memory: a longer file is judged on that window, which only narrows the candidates).
    ``validation_fits``: with ``validation`` files of another motion, the candidates chosen again by the
    validation error of these fits (:func:`estimation.identification.preprocessing_on_validation.on_validation`),
    on the training window and the validation files' first :data:`SCORED_SAMPLES` rows; ``validation_model``: the
    model those fits fit (its channels ``model``'s; ``None``: ``model``), as
    :class:`~estimation.identification.prepared.PreparationSettings` has it."""
    window = streamed_window(paths, model, rows)  # first, as in memory: the findings said in the files' order
    windows = {Path(path): first_rows(path, model, SCORED_SAMPLES) for path in (*held_out, *validation)}
    choice = choose_by_evidence(model, window, frequency_hz=frequency_hz,
                                harmonics=harmonics, cutoff_hz=cutoff_hz, average_periods=average_periods,
                                decimation=decimation, held_torques=held_torques,
                                held_out=tuple(windows[Path(path)] for path in held_out))
    if not (validation_fits and validation):
        return choice
    chooser = model if validation_model is None else validation_model
    if tuple(chooser.channels) != tuple(model.channels):
        raise ValueError(f"validation_model has channels {chooser.channels}, the records {model.channels}")
    chosen = on_validation(choice.chosen, chooser, window.segments, [windows[Path(path)] for path in validation],
                           fits=validation_fits)
    return choice if chosen is choice.chosen else PreprocessingChoice(chosen, chosen)


def choose_streamed_cutoff(path: str | Path, model: IdentificationModel, *, decimation: int = 1,
                           held_torques: bool = False) -> Preprocessing | None:
    """The Butterworth plan chosen on the first rows of ``path`` (filters only), with its evidence; ``None``
    when the file holds measured ``dq, ddq`` (nothing to choose)."""
    first = first_rows(path, model, SCORED_SAMPLES)
    if first.dq is not None and first.ddq is not None:
        return None
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", PreprocessingWarning)
        return choose_by_evidence(model, [first], decimation=decimation, held_torques=held_torques,
                                  families=("butterworth",), velocity_variants=False).chosen
