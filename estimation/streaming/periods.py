"""The Fourier path of a streamed record: periods averaged chunk by chunk, then one fit.

:class:`estimation.preprocessing.differentiation.FourierDifferentiation` averages the whole periods of a periodic
record sample by sample and fits the finite Fourier series of eq. 18 (PUMA paper) to the averaged
positions. The average is a sum: :func:`average_periods_streamed` adds each chunk's samples into
``P`` running sums (``P = rate / f`` samples a period), keeping only whole periods, in ``P x
columns`` memory. The fit and the analytic derivatives then run on that one averaged period
exactly as in memory (:func:`estimation.preprocessing.differentiation.fill_derivatives`), and its sums are those
of the file: two passes in one (average, then fit and evaluate on ``P`` samples).

The streamed diagnosis reads a file on this path as the in-memory one holds it (:func:`plan_chunks`): a training
file is its averaged period (the samples the in-memory estimation fits), a validation file every sample of its
whole periods with the fit's motion at their instants and the channels as recorded (the samples the in-memory
diagnosis validates on), read in a second pass.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from dynamics.runtime.memory import check_allocation
from dynamics.models import IdentificationModel
from dynamics.measurements import Measurements
from estimation.estimators.normal_equations import DEFAULT_CHUNK_SIZE, accumulate
from estimation.identification.training_range import TrainingRange
from estimation.preprocessing.differentiation import FourierDifferentiation, fill_derivatives, fit_fourier
from estimation.preprocessing.plan import Preprocessing
from estimation.streaming.chunks import FileSums, StreamingUnsupportedError, preprocessed_chunks, read_chunks

__all__ = ["average_periods_streamed", "periodic_chunks", "periodic_file_sums", "periodic_prepared", "plan_chunks",
           "plan_options"]

_GROUPS = ("q", "dq", "ddq", "tau", "wrench")


def average_periods_streamed(path: str | Path, model: IdentificationModel, frequency_hz: float, *,
                             chunk_size: int = DEFAULT_CHUNK_SIZE) -> tuple[Measurements, int]:
    """The average of the whole periods of ``path`` (as :func:`estimation.preprocessing.differentiation.average_periods`)
    and the rows read."""
    chunks = read_chunks(path, model, chunk_size=chunk_size)
    first = next(chunks)
    step = float(np.median(np.diff(first.t)))
    rate = 1.0 / step
    per_period = rate / frequency_hz
    samples = int(round(per_period))
    if abs(per_period - samples) > 1e-6 * per_period:
        raise ValueError(f"{path}: the sampling rate {rate:.6g} Hz is not a multiple of the excitation frequency "
                         f"{frequency_hz} Hz: periods cannot be averaged sample by sample")
    present = [name for name in _GROUPS if getattr(first, name) is not None]
    widths = [getattr(first, name).shape[1] for name in present]
    check_allocation(8.0 * 2 * samples * (sum(widths) + 1), f"one period of {samples} samples")
    total = np.zeros((samples, sum(widths)))
    current = np.empty((samples, sum(widths)))  # the period being read
    t_first = np.empty(samples)
    filled, periods, rows = 0, 0, 0
    for chunk in _chained(first, chunks):
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
        rows += chunk.n_samples
    if periods < 1:
        raise ValueError(f"{path}: {rows} samples hold less than one period ({samples} samples at {frequency_hz} Hz)")
    average = total / periods
    arrays, start = {}, 0
    for name, width in zip(present, widths):
        arrays[name] = average[:, start:start + width]
        start += width
    metadata = dict(first.metadata, periods_averaged=periods, source=str(path))
    return Measurements(t_first, arrays["q"], arrays.get("dq"), arrays.get("ddq"), arrays.get("tau"),
                        arrays.get("wrench"), metadata), rows


def _chained(first, rest):
    yield first
    yield from rest


def periodic_prepared(path: str | Path, model: IdentificationModel, *, frequency_hz: float, harmonics: int = 5,
                      chunk_size: int = DEFAULT_CHUNK_SIZE, decimation: int = 1, held_torques: bool = False
                      ) -> tuple[Measurements, Measurements, int]:
    """One periodic file on the Fourier path: the prepared averaged period (derivatives of the fit),
    the averaged period as read, and the rows read."""
    averaged, rows = average_periods_streamed(path, model, frequency_hz, chunk_size=chunk_size)
    method = FourierDifferentiation(frequency_hz, harmonics, average=False)
    return fill_derivatives(averaged, method, decimation=decimation, held_torques=held_torques), averaged, rows


def periodic_file_sums(path: str | Path, model: IdentificationModel, *, frequency_hz: float, harmonics: int = 5,
                       chunk_size: int = DEFAULT_CHUNK_SIZE, decimation: int = 1, held_torques: bool = False,
                       **ignored) -> FileSums:
    """Sums of one periodic file on the Fourier path: streamed period average, then the in-memory fit
    (``ignored``: the Butterworth options of :func:`estimation.streaming.chunks.file_sums`)."""
    prepared, averaged, rows = periodic_prepared(path, model, frequency_hz=frequency_hz, harmonics=harmonics,
                                                 chunk_size=chunk_size, decimation=decimation, held_torques=held_torques)
    sums = accumulate(model, prepared, chunk_size=chunk_size, source=str(path))
    metadata = {"decimation": int(decimation), "margin": 0, "differentiation": "fourier",
                "frequency_hz": float(frequency_hz), "harmonics": int(harmonics),
                "periods_averaged": int(averaged.metadata["periods_averaged"]), "expected_samples": prepared.n_samples}
    if "resampled_from" in averaged.metadata:
        metadata["resampled_from"] = int(averaged.metadata["resampled_from"])
    columns = tuple(name for name in ("dq", "ddq", "tau", "wrench") if getattr(averaged, name) is not None)
    joint_range = TrainingRange.of(prepared.q, prepared.dq, model.robot.joint_names) if prepared.n_samples else None
    return FileSums(str(path), sums, rows, columns, metadata, joint_range)


def periodic_chunks(path: str | Path, model: IdentificationModel, *, frequency_hz: float, harmonics: int = 5,
                    chunk_size: int = DEFAULT_CHUNK_SIZE, decimation: int = 1, held_torques: bool = False,
                    as_recorded: bool = False, record: dict | None = None) -> Iterator[Measurements]:
    """One periodic file on the Fourier path, chunk by chunk (module docstring): its averaged period prepared,
    or, ``as_recorded``, the rows of its whole periods with the fit's motion at their instants (held torques:
    the motion half a sample later, from the fit itself). ``record`` receives ``rows``, ``columns`` and
    ``metadata`` as :func:`estimation.streaming.chunks.preprocessed_chunks` gives them."""
    if decimation != 1:
        raise StreamingUnsupportedError(f"{path}: decimation with a Fourier fit is done in memory (leave out "
                                        "--decimate, or the streamed path)")
    prepared, averaged, rows = periodic_prepared(path, model, frequency_hz=frequency_hz, harmonics=harmonics,
                                                 chunk_size=chunk_size, held_torques=held_torques)
    periods = int(averaged.metadata["periods_averaged"])
    if record is not None:
        record.update(rows=rows, chunk_size=chunk_size,
                      columns=tuple(name for name in ("dq", "ddq", "tau", "wrench") if getattr(averaged, name) is not None),
                      metadata={"decimation": 1, "margin": 0, "trimmed_samples": 0, "differentiation": "fourier",
                                "frequency_hz": float(frequency_hz), "harmonics": int(harmonics),
                                "periods_averaged": periods})
    if not as_recorded:
        prepared = replace(prepared, recorded=None)
        for start in range(0, prepared.n_samples, chunk_size):
            yield prepared.select(slice(start, start + chunk_size))
        return
    fit = fit_fourier(averaged.t, averaged.q, frequency_hz, harmonics)
    kept, done = periods * averaged.n_samples, 0
    for chunk in read_chunks(path, model, chunk_size=chunk_size):
        chunk = chunk.select(slice(0, max(min(chunk.n_samples, kept - done), 0)))
        done += chunk.n_samples
        if not chunk.n_samples:
            continue
        q, dq, ddq = fit.evaluate(chunk.t)
        if held_torques:  # the fit half a sample later (compensate_hold, with the fit's own next sample)
            step = float(averaged.t[1] - averaged.t[0])
            later = [np.array(values) for values in fit.evaluate(chunk.t + step)]
            if done == kept:  # the last sample kept: extrapolated from the one before, as compensate_hold does
                before = fit.evaluate(chunk.t[-1:] - step)
                for values, now, previous in zip(later, (q, dq, ddq), before):
                    values[-1] = 2 * now[-1] - previous[-1]
            q, dq, ddq = ((now + next_) / 2 for now, next_ in zip((q, dq, ddq), later))
        yield replace(chunk, q=q, dq=dq, ddq=ddq, recorded=None)


def plan_chunks(path: str | Path, model: IdentificationModel, *, frequency_hz: float | None = None,
                harmonics: int = 5, as_recorded: bool = False, record: dict | None = None,
                **options: Any) -> Iterator[Measurements]:
    """One file's prepared chunks: on the Fourier path (:func:`periodic_chunks`) when ``frequency_hz`` is given
    and the file lacks ``dq``/``ddq``, else :func:`estimation.streaming.chunks.preprocessed_chunks` (``options``:
    its keyword arguments; its ``load``, a load the logged torques lack added back, on that path only)."""
    if frequency_hz is not None:
        chunk_size = options.get("chunk_size", DEFAULT_CHUNK_SIZE)
        first = next(read_chunks(path, model, chunk_size=chunk_size))
        if first.dq is None or first.ddq is None:
            if options.get("load") is not None:
                raise StreamingUnsupportedError(f"{path}: a load the torques lack is added back on the filter path "
                                                "and with measured derivatives, not to averaged periods")
            yield from periodic_chunks(path, model, frequency_hz=frequency_hz, harmonics=harmonics,
                                       chunk_size=chunk_size, decimation=options.get("decimation", 1),
                                       held_torques=options.get("held_torques", False), as_recorded=as_recorded,
                                       record=record)
            return
    yield from preprocessed_chunks(path, model, record=record, **options)


def plan_options(plan: Preprocessing) -> dict[str, Any]:
    """The reading options of :func:`plan_chunks` that apply ``plan`` (a filter, a Fourier fit of averaged periods,
    measured derivatives): ``cutoff_hz``, ``order``, ``frequency_hz``, ``harmonics``, ``decimation``,
    ``held_torques``.

    Raises
    ------
    StreamingUnsupportedError
        A Fourier fit of every sample (``average_periods="no"``): made in memory.
    """
    options: dict[str, Any] = {"cutoff_hz": None, "order": plan.order, "frequency_hz": None, "harmonics": 5,
                               "decimation": plan.decimation, "held_torques": plan.held_torques}
    if plan.method == "butterworth":
        options["cutoff_hz"] = plan.cutoff_hz
    elif plan.method == "fourier":
        if plan.average_periods == "no":
            raise StreamingUnsupportedError("a Fourier fit of every sample (--average-periods no) is made in memory: "
                                            "not on the streamed path, which averages whole periods")
        options.update(frequency_hz=plan.frequency_hz, harmonics=plan.harmonics)
    return options
