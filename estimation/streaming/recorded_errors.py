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

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from dynamics.models import IdentificationModel
from estimation.preprocessing.differentiation import ButterworthDifferentiation
from estimation.streaming.periods import plan_chunks

__all__ = ["streamed_plan", "streamed_recorded_errors", "streamed_recorded_mse"]


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
    vectors = {name: np.asarray(theta, dtype=float) for name, theta in thetas.items()}
    for theta in vectors.values():
        if theta.shape != (model.n_base,):
            raise ValueError(f"theta must hold the model's {model.n_base} base parameters, got shape {theta.shape}")
    if not paths:
        raise ValueError("no files to measure the error on")
    squares = {name: np.zeros(model.n_channels) for name in vectors}
    count = 0
    for path in paths:
        for chunk in plan_chunks(path, model, frequency_hz=frequency_hz, harmonics=harmonics, as_recorded=True,
                                 chunk_size=chunk_size, cutoff_hz=cutoff_hz, decimation=decimation,
                                 held_torques=held_torques):
            record = chunk.as_recorded
            measured = record.channels(model.channels)
            for name, theta in vectors.items():
                residual = measured - model.predict(theta, record.q, record.dq, record.ddq)
                squares[name] += np.sum(residual**2, axis=0)
            count += measured.shape[0]
    if count == 0:
        raise ValueError("the files hold no samples once preprocessed")
    return {name: dict(zip(model.channels, map(float, total / count))) for name, total in squares.items()}
