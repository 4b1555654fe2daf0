"""The Fourier path of a streamed record: periods averaged chunk by chunk, then one fit.

:class:`estimation.preprocessing.differentiation.FourierDifferentiation` averages the whole periods of a periodic
record sample by sample and fits the finite Fourier series of eq. 18 (PUMA paper) to the averaged
positions. The average is a sum: :func:`average_periods_streamed` adds each chunk's samples into
``P`` running sums (``P = rate / f`` samples a period), keeping only whole periods, in ``P x
columns`` memory. The fit and the analytic derivatives then run on that one averaged period
exactly as in memory (:func:`estimation.preprocessing.differentiation.fill_derivatives`), and its sums are those
of the file: two passes in one (average, then fit and evaluate on ``P`` samples).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from dynamics.runtime.memory import check_allocation
from dynamics.models import IdentificationModel
from dynamics.measurements import Measurements
from estimation.estimators.normal_equations import DEFAULT_CHUNK_SIZE, accumulate
from estimation.preprocessing.differentiation import FourierDifferentiation, fill_derivatives
from estimation.streaming.chunks import FileSums, read_chunks

__all__ = ["average_periods_streamed", "periodic_file_sums", "periodic_prepared"]

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
    return FileSums(str(path), sums, rows, columns, metadata)
