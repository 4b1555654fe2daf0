"""The mount and friction-drift checks of records read in blocks: the in-memory checks on the same samples.

:func:`estimation.identification.mount.check_mount` sums at most ``samples`` evenly spaced samples of each prepared
record (:data:`~estimation.identification.mount.MAX_SAMPLES` for ``oed identify``), and
:func:`estimation.identification.friction_drift.check_friction_drift` fits at most
:data:`~estimation.identification.friction_drift.MAX_SAMPLES` evenly spaced samples of each, its batch means
restarting at each segment (each file of a record of several). Both work on those samples alone. A record over the
memory budget is prepared in blocks (:func:`estimation.streaming.periods.plan_chunks`, the preprocessing of the
streamed fit): knowing each record's count of prepared samples (the sums'), one more pass over the files keeps the
samples either check would keep in memory (their union, by their index in the records' samples one file after the
other, each file a segment), and the checks run on them as in memory: the same rows, the same functions, the same
figures up to the streamed preparation's own differences from the in-memory one.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from dynamics.measurements import Measurements
from dynamics.models import IdentificationModel
from estimation.identification.friction_drift import MAX_SAMPLES as DRIFT_SAMPLES
from estimation.identification.friction_drift import FrictionDrift, check_friction_drift
from estimation.identification.mount import MAX_SAMPLES as MOUNT_SAMPLES
from estimation.identification.mount import MountCheck, check_mount
from estimation.streaming.joint_zeros import kept_samples

__all__ = ["StreamedChecks", "evenly_spaced_rows", "prepared_count", "streamed_description_checks"]


def prepared_count(parts: Iterable[tuple[Any, Mapping[str, Any]]]) -> int:
    """The prepared samples of the files whose sums ``parts`` hold, each beside its reading record: what the
    checks' pass (:func:`~estimation.streaming.periods.plan_chunks` without ``as_recorded``) yields of them, the
    in-memory record's samples. On the Fourier path the reading record's ``samples`` (a file's averaged period, though
    a validation file's sums hold its whole periods as recorded); elsewhere the samples summed."""
    return sum(int(record.get("samples", part.n_samples)) for part, record in parts)


def evenly_spaced_rows(n_samples: int, max_samples: int) -> NDArray[np.int64]:
    """The rows of a record of ``n_samples`` samples the mount and drift checks keep: all, or ``max_samples`` evenly
    spaced, rounded down (their rule in memory)."""
    n_samples = int(n_samples)
    return np.unique(np.linspace(0, n_samples - 1, min(n_samples, int(max_samples))).astype(int))


@dataclass(frozen=True)
class StreamedChecks:
    """The checks of records read in blocks (``None``: not asked, or nothing to check, as in memory)."""

    mount: MountCheck | None = None
    friction_drift: FrictionDrift | None = None


def _record(model: IdentificationModel, paths: Sequence[str | Path], n_samples: int, counts: Sequence[int],
            options: Mapping[str, Any]) -> tuple[Measurements | None, list[NDArray[np.int64]]]:
    """The samples of the files ``paths`` that rows ``evenly_spaced_rows(n_samples, count)`` name for each of
    ``counts``, in one pass, and where each set lies among them."""
    sets = [evenly_spaced_rows(n_samples, count) for count in counts]
    union = np.unique(np.concatenate(sets)) if sets else np.zeros(0, dtype=int)
    kept = kept_samples(model, paths, union, options, segments=True, n_samples=n_samples)
    return kept, [np.searchsorted(union, rows) for rows in sets]


def streamed_description_checks(model: IdentificationModel, train: Sequence[str | Path], train_samples: int,
                                validate: Sequence[str | Path], validate_samples: int, *,
                                options: Mapping[str, Any], mount_model: IdentificationModel | None = None,
                                mount_samples: int = MOUNT_SAMPLES,
                                drift_model: IdentificationModel | None = None) -> StreamedChecks:
    """The mount check of ``mount_model`` (:func:`~estimation.identification.mount.check_mount`, at most
    ``mount_samples`` samples a record) and the friction-drift check of ``drift_model``
    (:func:`~estimation.identification.friction_drift.check_friction_drift`), each when given, on the records
    ``train`` and ``validate`` (their files one after the other, ``train_samples`` and ``validate_samples`` prepared
    samples in all) read in blocks prepared by ``options`` (:func:`~estimation.streaming.periods.plan_chunks`'
    keywords; ``model``: the model the streamed fit prepared them for), on the samples the in-memory checks keep
    (module docstring): one pass over the files. Nothing is checked without a validation record."""
    counts = [count for count, asked in ((mount_samples, mount_model), (DRIFT_SAMPLES, drift_model))
              if asked is not None]
    if not validate or not counts or train_samples < 2 or validate_samples < 2:
        return StreamedChecks()
    fitted, fitted_rows = _record(model, train, train_samples, counts, options)
    scored, scored_rows = _record(model, validate, validate_samples, counts, options)
    if fitted is None or scored is None:
        return StreamedChecks()
    pairs = iter(zip(fitted_rows, scored_rows))
    mount = drift = None
    if mount_model is not None:
        rows = next(pairs)
        mount = check_mount(mount_model, fitted.select(rows[0]), scored.select(rows[1]), samples=mount_samples)
    if drift_model is not None:
        rows = next(pairs)
        drift = check_friction_drift(drift_model, fitted.select(rows[0]), scored.select(rows[1]))
    return StreamedChecks(mount, drift)
