"""The Fourier path of a streamed record: periods averaged chunk by chunk, or every sample fitted by summed sums.

:class:`estimation.preprocessing.differentiation.FourierDifferentiation` averages the whole periods of a periodic
record sample by sample and fits the finite Fourier series of eq. 18 (PUMA paper) to the averaged positions when
the record holds two or more whole periods of a whole number of samples (``average="auto"``,
:func:`~estimation.preprocessing.differentiation.averages_periods`); else it fits every sample on its time stamp.
:func:`read_periodic` reads a file once and does what that rule says of it:

* averaged: each chunk's samples are added into ``P`` running sums (``P = rate / f`` samples a period), keeping
  only whole periods, in ``P x columns`` memory; the fit and the analytic derivatives then run on that one averaged
  period exactly as in memory (:func:`estimation.preprocessing.differentiation.fill_derivatives`);
* every sample (a rate that is not a multiple of the excitation frequency, a jittered log's grid among them, or
  fewer than two whole periods): the fit is a linear least squares in the series' coefficients, so its normal
  equations are sums over the samples, added chunk by chunk
  (:class:`~estimation.preprocessing.fourier_series.SummedFourierFit`) and solved as memory solves the whole
  record's; a second pass evaluates the fit's motion at every sample.

The streamed diagnosis reads a file on this path as the in-memory one holds it (:func:`plan_chunks`): a training
file is its averaged period (the samples the in-memory estimation fits) or every sample with the fit's motion, a
validation file every sample of its whole periods (every sample, when not averaged) with the fit's motion at their
instants and the channels as recorded (the samples the in-memory diagnosis validates on), read in a second pass.
"""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from dynamics.runtime.memory import check_allocation
from dynamics.models import IdentificationModel
from dynamics.measurements import Measurements
from estimation.estimators.normal_equations import DEFAULT_CHUNK_SIZE, NormalEquations, accumulate
from estimation.identification.training_range import TrainingRange
from estimation.preprocessing.differentiation import (
    FourierDifferentiation,
    averages_periods,
    fill_derivatives,
    fit_fourier,
    periods_at_rate,
)
from estimation.preprocessing.fourier_series import FourierSeries, SummedFourierFit, TriangularFourierFit
from estimation.preprocessing.plan import Preprocessing
from estimation.identification.subtracted_load import SubtractedLoad
from estimation.streaming.chunks import FileSums, StreamingUnsupportedError, loaded_chunk, preprocessed_chunks, read_chunks

__all__ = ["PeriodicFile", "average_periods_streamed", "check_averaged", "periodic_chunks", "periodic_file_sums", "periodic_prepared",
           "plan_chunks", "plan_options", "read_periodic"]

_GROUPS = ("q", "dq", "ddq", "tau", "wrench")


@dataclass(frozen=True)
class PeriodicFile:
    """One file on the Fourier path after its reading pass (module docstring).

    Attributes
    ----------
    averaged
        The average of its whole periods (:func:`estimation.preprocessing.differentiation.average_periods`),
        ``metadata["periods_averaged"]`` their count; ``None`` when its every sample is fitted.
    fit
        The fit of its every sample (``None`` when averaged: the averaged period is fitted as in memory).
    samples
        Samples read (on the uniform grid when the file was resampled).
    step
        Its sampling step, s (the first chunk's median step).
    columns
        The column groups it holds among ``dq, ddq, tau, wrench``.
    metadata
        The first chunk's metadata (``resampled_from`` of a resampled file).
    """

    averaged: Measurements | None
    fit: FourierSeries | None
    samples: int
    step: float
    columns: tuple[str, ...]
    metadata: dict


def read_periodic(path: str | Path, model: IdentificationModel, frequency_hz: float, harmonics: int, *,
                  chunk_size: int = DEFAULT_CHUNK_SIZE, average: str = "auto") -> PeriodicFile:
    """Read ``path`` once: its periods averaged when memory's rule averages them (``average``:
    :func:`~estimation.preprocessing.differentiation.averages_periods`'s choice), else the Fourier fit of its every
    sample from the normal equations summed chunk by chunk (and, when these are not well conditioned, the
    triangular factor over one more pass: the SVD's answer, as in memory). Raises as
    :meth:`FourierDifferentiation.apply` for a record shorter than a period or harmonics reaching the Nyquist
    frequency, and for ``average="yes"`` when a period is not a whole number of samples."""
    chunks = read_chunks(path, model, chunk_size=chunk_size)
    first = next(chunks)
    step = float(np.median(np.diff(first.t)))
    rate = 1.0 / step
    layout = periods_at_rate(rate, 0, frequency_hz)  # the samples of a period, when a whole number
    if layout is None and average == "yes":
        raise ValueError(f"{path}: the sampling rate {rate:.6g} Hz is not a multiple of the excitation frequency "
                         f"{frequency_hz} Hz: periods cannot be averaged sample by sample")
    present = [name for name in _GROUPS if getattr(first, name) is not None]
    widths = [getattr(first, name).shape[1] for name in present]
    samples = 0 if layout is None or average == "no" else layout[1]
    if samples:
        check_allocation(8.0 * 2 * samples * (sum(widths) + 1), f"one period of {samples} samples")
    total = np.zeros((samples, sum(widths)))
    current = np.empty((samples, sum(widths)))  # the period being read
    t_first = np.empty(samples)
    summed: SummedFourierFit | None = SummedFourierFit(frequency_hz, harmonics, float(first.t[0]), first.q.shape[1])
    filled, periods, rows, last = 0, 0, 0, float(first.t[0])
    for chunk in _chained(first, chunks):
        if summed is not None:
            summed.add(chunk.t, chunk.q)
        if samples:
            values = np.hstack([getattr(chunk, name) for name in present])
            index = 0
            while index < chunk.n_samples:
                take = min(samples - filled, chunk.n_samples - index)
                current[filled:filled + take] = values[index:index + take]
                if periods == 0:
                    t_first[filled:filled + take] = chunk.t[index:index + take]
                filled += take
                index += take
                if filled == samples:
                    total += current
                    periods += 1
                    filled = 0
            if periods >= 2 and average != "no":  # averaged whatever follows: the every-sample sums not needed
                summed = None
        rows += chunk.n_samples
        last = float(chunk.t[-1])
    metadata = dict(first.metadata)
    columns = tuple(name for name in present if name != "q")
    if averages_periods(average, None if layout is None else (periods, samples)):
        if periods < 1:
            raise ValueError(f"{path}: {rows} samples hold less than one period ({samples} samples at "
                             f"{frequency_hz} Hz)")
        average_values = total / periods
        arrays, start = {}, 0
        for name, width in zip(present, widths):
            arrays[name] = average_values[:, start:start + width]
            start += width
        averaged = Measurements(t_first, arrays["q"], arrays.get("dq"), arrays.get("ddq"), arrays.get("tau"),
                                arrays.get("wrench"), dict(metadata, periods_averaged=periods, source=str(path)))
        return PeriodicFile(averaged, None, rows, step, columns, metadata)
    duration = last - float(first.t[0]) + step
    if duration * frequency_hz < 1 - 1e-9:  # as FourierDifferentiation.apply says it
        raise ValueError(f"{path}: {rows} samples ({duration:.4g} s) hold less than one period of {frequency_hz:g} Hz: "
                         "the Fourier fit is not determined (use a cut-off instead)")
    if harmonics * frequency_hz >= 0.5 * rate:
        raise ValueError(f"{path}: {harmonics} harmonics of {frequency_hz:g} Hz reach the Nyquist frequency "
                         f"{0.5 * rate:.6g} Hz")
    assert summed is not None  # not averaged: summed to the end
    fit = summed.series()
    if fit is None:  # not well conditioned: the triangular factor, the SVD's answer, over one more pass
        triangular = TriangularFourierFit(frequency_hz, harmonics, float(first.t[0]), first.q.shape[1])
        for chunk in read_chunks(path, model, chunk_size=chunk_size):
            triangular.add(chunk.t, chunk.q)
        fit = triangular.series()
    return PeriodicFile(None, fit, rows, step, columns, metadata)


def average_periods_streamed(path: str | Path, model: IdentificationModel, frequency_hz: float, *,
                             chunk_size: int = DEFAULT_CHUNK_SIZE) -> tuple[Measurements, int]:
    """The average of the whole periods of ``path`` (as :func:`estimation.preprocessing.differentiation.average_periods`)
    and the rows read."""
    read = read_periodic(path, model, frequency_hz, 1, chunk_size=chunk_size, average="yes")
    assert read.averaged is not None  # "yes": averaged, or raised
    return read.averaged, read.samples


def _chained(first, rest):
    yield first
    yield from rest


def periodic_prepared(path: str | Path, model: IdentificationModel, *, frequency_hz: float, harmonics: int = 5,
                      chunk_size: int = DEFAULT_CHUNK_SIZE, decimation: int = 1, held_torques: bool = False
                      ) -> tuple[Measurements, Measurements, int]:
    """One periodic file on the Fourier path whose periods are averaged: the prepared averaged period (derivatives
    of the fit), the averaged period as read, and the rows read."""
    averaged, rows = average_periods_streamed(path, model, frequency_hz, chunk_size=chunk_size)
    return _prepared(averaged, frequency_hz, harmonics, decimation, held_torques), averaged, rows


def _prepared(averaged: Measurements, frequency_hz: float, harmonics: int, decimation: int,
              held_torques: bool) -> Measurements:
    """The averaged period prepared as in memory (the fit of the averaged period and its derivatives)."""
    method = FourierDifferentiation(frequency_hz, harmonics, average=False)
    return fill_derivatives(averaged, method, decimation=decimation, held_torques=held_torques)


def periodic_file_sums(path: str | Path, model: IdentificationModel, *, frequency_hz: float, harmonics: int = 5,
                       chunk_size: int = DEFAULT_CHUNK_SIZE, decimation: int = 1, held_torques: bool = False,
                       average: str = "auto", load: SubtractedLoad | None = None, **ignored) -> FileSums:
    """Sums of one periodic file on the Fourier path: its averaged period (streamed average, then the in-memory
    fit), or its every sample with the fit's motion (module docstring) (``ignored``: the Butterworth options of
    :func:`estimation.streaming.chunks.file_sums`; ``load``: :func:`periodic_chunks`')."""
    record: dict = {}
    sums, joint_range = NormalEquations.empty(model.channels, model.base.names, model.base.expressions), None
    for chunk in periodic_chunks(path, model, frequency_hz=frequency_hz, harmonics=harmonics, chunk_size=chunk_size,
                                 decimation=decimation, held_torques=held_torques, record=record, average=average,
                                 load=load):
        sums = accumulate(model, chunk, chunk_size=chunk_size, sums=sums)
        if chunk.n_samples:  # the samples summed: the training range, in the same pass
            joint_range = TrainingRange.of(chunk.q, chunk.dq, model.robot.joint_names).merged(joint_range)
    sums = replace(sums, sources=(str(path),))
    metadata = {key: value for key, value in record["metadata"].items() if key != "trimmed_samples"}
    metadata["expected_samples"] = record["samples"]
    if record.get("resampled_from") is not None:  # an averaged period's file too, as before
        metadata["resampled_from"] = int(record["resampled_from"])
    return FileSums(str(path), sums, record["rows"], record["columns"], metadata, joint_range)


def periodic_chunks(path: str | Path, model: IdentificationModel, *, frequency_hz: float, harmonics: int = 5,
                    chunk_size: int = DEFAULT_CHUNK_SIZE, decimation: int = 1, held_torques: bool = False,
                    as_recorded: bool = False, record: dict | None = None,
                    average: str = "auto", load: SubtractedLoad | None = None) -> Iterator[Measurements]:
    """One periodic file on the Fourier path, chunk by chunk (module docstring): its averaged period prepared,
    or, ``as_recorded``, the rows of its whole periods with the fit's motion at their instants (held torques:
    the motion half a sample later, from the fit itself); a file whose periods are not averaged: its every row with
    the fit's motion at its instant, either way. ``record`` receives ``rows``, ``columns`` and ``metadata`` as
    :func:`estimation.streaming.chunks.preprocessed_chunks` gives them, and ``samples`` (those yielded when not
    ``as_recorded``) and ``resampled_from``. ``average``: memory's choice of averaging the periods
    (``--average-periods``: :func:`read_periodic`'s). ``load``: a load of the description the logged torques lack
    (:class:`~estimation.identification.subtracted_load.SubtractedLoad`), added to each chunk's torques at its
    positions, which are the fit's (:func:`estimation.streaming.chunks.loaded_chunk`), as memory adds it to the
    prepared record, the averaged period and the recorded samples beside it
    (:func:`~estimation.identification.subtracted_load.added_back`); ``None``: the torques as logged."""
    chunks = _periodic_chunks(path, model, frequency_hz=frequency_hz, harmonics=harmonics, chunk_size=chunk_size,
                              decimation=decimation, held_torques=held_torques, as_recorded=as_recorded, record=record,
                              average=average)
    if load is None:
        yield from chunks
        return
    for chunk in chunks:
        yield loaded_chunk(chunk, load, model)


def _periodic_chunks(path: str | Path, model: IdentificationModel, *, frequency_hz: float, harmonics: int,
                     chunk_size: int, decimation: int, held_torques: bool, as_recorded: bool, record: dict | None,
                     average: str) -> Iterator[Measurements]:
    """:func:`periodic_chunks` without a load."""
    read = read_periodic(path, model, frequency_hz, harmonics, chunk_size=chunk_size, average=average)
    averaged = read.averaged
    if decimation != 1 and (as_recorded or averaged is None):
        raise StreamingUnsupportedError(f"{path}: decimation with a Fourier fit is done in memory (leave out "
                                        "--decimate, or the streamed path)")
    periods = 0 if averaged is None else int(averaged.metadata["periods_averaged"])
    prepared = None if averaged is None else _prepared(averaged, frequency_hz, harmonics, decimation, held_torques)
    if record is not None:
        record.update(rows=read.samples, chunk_size=chunk_size, columns=read.columns,
                      samples=read.samples if prepared is None else prepared.n_samples,
                      resampled_from=read.metadata.get("resampled_from"),
                      metadata={"decimation": int(decimation), "margin": 0, "trimmed_samples": 0,
                                "differentiation": "fourier", "frequency_hz": float(frequency_hz),
                                "harmonics": int(harmonics), "periods_averaged": periods,
                                # every sample of a resampled file fitted: its grid, scored at its stamps
                                **({"resampled_from": int(read.metadata["resampled_from"])}
                                   if averaged is None and read.metadata.get("resampled_from") is not None else {})})
    if prepared is not None and not as_recorded:
        prepared = replace(prepared, recorded=None)
        for start in range(0, prepared.n_samples, chunk_size):
            yield prepared.select(slice(start, start + chunk_size))
        return
    if averaged is not None:
        # every recorded row, the tail past the last whole period too, as memory scores them (FourierDifferentiation)
        fit, kept = fit_fourier(averaged.t, averaged.q, frequency_hz, harmonics), read.samples
    else:
        assert read.fit is not None
        fit, kept = read.fit, read.samples
    done = 0
    for chunk in read_chunks(path, model, chunk_size=chunk_size):
        chunk = chunk.select(slice(0, max(min(chunk.n_samples, kept - done), 0)))
        done += chunk.n_samples
        if not chunk.n_samples:
            continue
        q, dq, ddq = fit.evaluate(chunk.t)
        if held_torques:  # the fit half a sample later (compensate_hold, with the fit's own next sample)
            later = [np.array(values) for values in fit.evaluate(chunk.t + read.step)]
            if done == kept:  # the last sample kept: extrapolated from the one before, as compensate_hold does
                before = fit.evaluate(chunk.t[-1:] - read.step)
                for values, now, previous in zip(later, (q, dq, ddq), before):
                    values[-1] = 2 * now[-1] - previous[-1]
            q, dq, ddq = ((now + next_) / 2 for now, next_ in zip((q, dq, ddq), later))
        yield replace(chunk, q=q, dq=dq, ddq=ddq, recorded=None)


def plan_chunks(path: str | Path, model: IdentificationModel, *, frequency_hz: float | None = None,
                harmonics: int = 5, as_recorded: bool = False, record: dict | None = None, average: str = "auto",
                **options: Any) -> Iterator[Measurements]:
    """One file's prepared chunks: on the Fourier path (:func:`periodic_chunks`) when ``frequency_hz`` is given
    and the file lacks ``dq``/``ddq`` (``average``: ``--average-periods``), else
    :func:`estimation.streaming.chunks.preprocessed_chunks` (``options``: its keyword arguments; its ``load``, a load
    the logged torques lack added back, on either path; its ``scans``, the run's
    :class:`~estimation.streaming.chunks.FileScans`)."""
    if frequency_hz is not None:
        chunk_size = options.get("chunk_size", DEFAULT_CHUNK_SIZE)
        first = next(read_chunks(path, model, chunk_size=chunk_size, scans=options.get("scans")))
        if first.dq is None or first.ddq is None:
            yield from periodic_chunks(path, model, frequency_hz=frequency_hz, harmonics=harmonics,
                                       chunk_size=chunk_size, decimation=options.get("decimation", 1),
                                       held_torques=options.get("held_torques", False), as_recorded=as_recorded,
                                       record=record, average=average, load=options.get("load"))
            return
    yield from preprocessed_chunks(path, model, record=record, **options)


def check_averaged(plan: Preprocessing, paths: Sequence[str | Path], model: IdentificationModel, *,
                   chunk_size: int = DEFAULT_CHUNK_SIZE) -> None:
    """``ValueError`` as memory raises it when ``plan`` averages periods by the user's ``yes`` and a file of
    ``paths`` (in order) is not sampled at a multiple of the excitation frequency: the streamed reading applies
    ``auto``'s rule (:func:`read_periodic`), which would fit its every sample where memory stops."""
    if plan.method != "fourier" or plan.average_periods != "yes":
        return
    for path in paths:
        first = next(read_chunks(path, model, chunk_size=chunk_size))
        if first.dq is not None and first.ddq is not None:
            continue
        rate = 1.0 / float(np.median(np.diff(first.t)))
        if periods_at_rate(rate, 0, plan.frequency_hz) is None:
            raise ValueError(f"{path}: the sampling rate {rate:.6g} Hz is not a multiple of the excitation frequency "
                             f"{plan.frequency_hz} Hz: periods cannot be averaged sample by sample")


def plan_options(plan: Preprocessing, *, average: bool = False) -> dict[str, Any]:
    """The reading options of :func:`plan_chunks` that apply ``plan`` (a filter, a Fourier fit of averaged periods,
    measured derivatives): ``cutoff_hz``, ``order``, ``frequency_hz``, ``harmonics``, ``decimation``,
    ``held_torques``; ``average``: and ``average`` (``plan``'s ``average_periods``, any of them: the reader of the
    caller applies it, :func:`read_periodic`).

    Raises
    ------
    StreamingUnsupportedError
        A Fourier fit of every sample by the user's choice (``average_periods="no"``) without ``average``.
    """
    options: dict[str, Any] = {"cutoff_hz": None, "order": plan.order, "frequency_hz": None, "harmonics": 5,
                               "decimation": plan.decimation, "held_torques": plan.held_torques}
    if average:
        options["average"] = plan.average_periods if plan.method == "fourier" else "auto"
    if plan.method == "butterworth":
        options["cutoff_hz"] = plan.cutoff_hz
    elif plan.method == "fourier":
        if plan.average_periods == "no" and not average:
            raise StreamingUnsupportedError("a Fourier fit of every sample (--average-periods no) is made in memory: "
                                            "not on the streamed path, which averages whole periods")
        options.update(frequency_hz=plan.frequency_hz, harmonics=plan.harmonics)
    return options
