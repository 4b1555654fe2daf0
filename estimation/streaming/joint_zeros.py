"""The joint-zero check of a record read in blocks: the in-memory check on the same samples.

:func:`estimation.identification.joint_zeros.check_joint_zeros` thins each prepared record to
:data:`~estimation.identification.joint_zeros.MAX_SAMPLES` evenly spaced samples (the validation record's, or, without
one, each half of the training record's) and works on those alone. A record over the memory budget is prepared in
blocks (:func:`estimation.streaming.periods.plan_chunks`, the preprocessing of the streamed fit): knowing each file's
count of prepared samples (the sums'), one more pass over the files keeps the samples the in-memory check would keep,
by their index in the records' samples one file after the other, and the check runs on them as in memory.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from dynamics.measurements import Measurements
from dynamics.models import IdentificationModel
from estimation.identification.joint_zeros import MAX_SAMPLES, JointZeroCheck, check_joint_zeros
from estimation.streaming.periods import plan_chunks

__all__ = ["kept_samples", "streamed_joint_zeros", "thinned_rows"]


def thinned_rows(n_samples: int, max_samples: int = MAX_SAMPLES) -> NDArray[np.int64]:
    """The rows of a record of ``n_samples`` samples the in-memory check keeps: all, or ``max_samples`` evenly
    spaced (:func:`~estimation.identification.joint_zeros.check_joint_zeros`)."""
    rows = np.arange(int(n_samples))
    if rows.size > max_samples:
        rows = rows[np.round(np.linspace(0, rows.size - 1, max_samples)).astype(int)]
    return rows


def kept_samples(model: IdentificationModel, paths: Sequence[str | Path], rows: Iterable[int],
                 options: Mapping[str, Any], *, segments: bool = False,
                 n_samples: int | None = None) -> Measurements | None:
    """The prepared samples ``rows`` (indices in the records' samples, the files one after the other) of ``paths``,
    read in blocks; ``None`` when the files hold fewer samples. ``segments``: the samples kept of each file a segment
    (``metadata["segments"]``, as the in-memory record of several files holds them,
    :func:`estimation.data.segments.concatenate`). ``n_samples``: the count of prepared samples the rows were
    chosen among; ``None`` too when the files yield another count (the rows would not be those memory keeps)."""
    wanted = np.asarray(sorted(set(int(row) for row in rows)), dtype=int)
    pieces: list[Measurements] = []
    bounds: list[dict[str, Any]] = []
    start = 0
    for path in paths:
        first = start
        for chunk in plan_chunks(path, model, **options):
            stop = start + chunk.n_samples
            inside = wanted[(wanted >= start) & (wanted < stop)] - start
            if inside.size:
                pieces.append(chunk.select(inside))
            start = stop
        bounds.append({"source": str(path), "start": int(np.searchsorted(wanted, first)),
                       "stop": int(np.searchsorted(wanted, start))})
    if n_samples is not None and start != int(n_samples):
        return None
    if sum(piece.n_samples for piece in pieces) != wanted.size or any(piece.dq is None or piece.ddq is None
                                                                       for piece in pieces):
        return None

    def stacked(name: str) -> NDArray[np.float64] | None:
        values = [getattr(piece, name) for piece in pieces]
        return None if any(value is None for value in values) else np.vstack(values)

    return Measurements(t=np.arange(wanted.size, dtype=float), q=stacked("q"), dq=stacked("dq"), ddq=stacked("ddq"),
                        tau=stacked("tau"), wrench=stacked("wrench"),
                        metadata={"segments": [entry for entry in bounds if entry["stop"] > entry["start"]]}
                        if segments and len(bounds) > 1 else {})


def streamed_joint_zeros(model: IdentificationModel, train: Sequence[str | Path], train_samples: int,
                         held_out: Sequence[str | Path] = (), held_out_samples: int = 0, *,
                         options: Mapping[str, Any], max_samples: int = MAX_SAMPLES) -> JointZeroCheck | None:
    """:func:`~estimation.identification.joint_zeros.check_joint_zeros` of the records ``train`` and ``held_out``
    (each its files one after the other, ``train_samples`` and ``held_out_samples`` prepared samples in all; no
    ``held_out``: the halves of the training record) read in blocks prepared by ``options``
    (:func:`~estimation.streaming.periods.plan_chunks`' keywords), on the samples the in-memory check thins them to
    (module docstring). No warning is issued (the caller says the check's message)."""
    if held_out:
        fitted = kept_samples(model, train, thinned_rows(train_samples, max_samples), options,
                              n_samples=train_samples)
        scored = kept_samples(model, held_out, thinned_rows(held_out_samples, max_samples), options,
                              n_samples=held_out_samples)
        if fitted is None or scored is None:
            return None
        return check_joint_zeros(model, fitted, scored, max_samples=max_samples, warn=False)
    half = int(train_samples) // 2
    if half < 20:
        return None
    first, second = thinned_rows(half, max_samples), half + thinned_rows(train_samples - half, max_samples)
    kept = kept_samples(model, train, np.concatenate([first, second]), options, n_samples=train_samples)
    if kept is None:
        return None
    fitted, scored = kept.select(np.arange(first.size)), kept.select(np.arange(first.size, kept.n_samples))
    return check_joint_zeros(model, fitted, scored, max_samples=max_samples, warn=False,
                             label="second half of the training record")
