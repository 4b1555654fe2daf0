"""``oed predict`` on a record read in blocks: the errors of an identified model on a record larger than memory.

The in-memory :meth:`~estimation.identification.identified_model.IdentifiedModel.evaluate` reads the record whole,
prepares it as the model file's preprocessing says, predicts and compares with the channels as recorded. Here the
same record is read and prepared chunk by chunk (:func:`estimation.streaming.periods.plan_chunks`: the filter path's
overlapping windows, equal to the whole record's samples to
:data:`~estimation.streaming.chunks.MARGIN_TOLERANCE`; the Fourier path's periods) and the squared errors summed:
at the recorded time stamps of a resampled (jittered) record, its motion interpolated there and its channels never
(:func:`~estimation.streaming.recorded_errors.counted_errors_at_stamps`), the motion moved by the file's delay among
the scored samples, on the regular clock when the model file's ``time_base`` says so
(:class:`~estimation.streaming.time_base.RegularClock`, as
:meth:`~estimation.identification.identified_model.IdentifiedModel.on_time_base`). The model's prediction is the
file's own (:meth:`~estimation.identification.identified_model.IdentifiedModel.predict`: shaped laws at their
shapes, a payload, the subtracted load, torque gains); the zero and nominal predictors are scored on the torques the
model holds, as memory's :func:`~estimation.identification.trivial_predictors.trivial_mse` of the prepared record.
Each joint's training range is checked chunk by chunk on the prepared samples (the largest excursions, the share of
samples outside pooled; :meth:`~estimation.identification.training_range.TrainingRange.check`).

The record's noise floor is memory's (:func:`~estimation.streaming.record_floor.record_floor`: each segment's
difference estimate by exact selection over passes, pooled), and so is the record-change check
(:mod:`estimation.identification.record_changes`: a payload, gravity turned): one more pass gathers the evenly
spaced samples its families are fitted on (:func:`~estimation.identification.record_changes.sampled_rows` of the
record's scored samples, the motion moved by the delay) with the model's residual there; the fits, the HAC
covariance and the cross-fitted halves are then memory's own
(:func:`~estimation.identification.record_changes.sampled_record_changes`), and one more pass sums the error with
each family's change over every sample. Only the per-sample predictions and their bands (``--out``, ``--plot``)
are not kept, and :attr:`StreamedEvaluation.not_computed` says so. A model file whose reading the streamed reader
does not make (rows at rest dropped, a trimmed filter or one of another order) is
refused with :class:`~estimation.streaming.chunks.StreamingUnsupportedError`, naming the in-memory route; motor-side
columns, joint zeros and reversed joint directions are read from joint-side copies of the files the caller makes
(:func:`needs_joint_side`).
"""

from __future__ import annotations

import functools
import warnings
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from dynamics.measurements import Measurements

from estimation.estimators.normal_equations import DEFAULT_CHUNK_SIZE
from estimation.identification.record_changes import (RecordChanges, RecordSample, checked_channels, record_segments,
                                                      sampled_record_changes, sampled_rows)
from estimation.identification.training_range import UNKNOWN_RANGE, JointExcursion, RangeCheck
from estimation.preprocessing.differentiation import ButterworthDifferentiation
from estimation.streaming.chunks import (StreamingUnsupportedError, clock_source, positions_source, segment_sources,
                                        source_rows)
from estimation.streaming.periods import plan_chunks
from estimation.streaming.record_floor import record_floor
from estimation.streaming.recorded_errors import counted_errors_at_stamps, scored_records
from estimation.streaming.time_base import NoRegularClockError
from estimation.uncertainty.floor_comparison import mse_over_floor

if TYPE_CHECKING:
    from estimation.identification.identified_model import IdentifiedModel

__all__ = ["STREAMED_PREDICT_NOT_COMPUTED", "StreamedEvaluation", "check_streamable", "needs_joint_side",
           "pooled_range", "streamed_evaluation"]

#: what the streamed ``oed predict`` leaves out (the metrics' ``not_computed``), each with its reason
STREAMED_PREDICT_NOT_COMPUTED = {
    "predictions": "the per-sample predictions, their 95 % bands and the figure (--out, --plot) are written by the "
                   "in-memory path only (leave out --chunk-size; the record must then fit in memory)",
}
#: why the record-change check is not made on a record whose scored samples come out of their order
OUT_OF_ORDER = ("changed", "the record-change check gathers the record's samples in their order, and stamps before a "
                           "resampled file's grid come last on the streamed path: predict it in memory")

#: the route where the streamed reading cannot be made
IN_MEMORY = "leave out --chunk-size to predict the record in memory"


@dataclass(frozen=True)
class StreamedEvaluation:
    """What the streamed ``oed predict`` measured (the keys of the in-memory
    :class:`~estimation.identification.identified_model.Evaluation`'s ``to_dict``, those it cannot compute
    ``None`` and named in :attr:`not_computed`)."""

    mse: dict[str, float]
    n_samples: int
    zero_mse: dict[str, float]
    nominal_mse: dict[str, float]
    reported_validation_mse: dict[str, float] | None
    model: str
    range_check: RangeCheck | None
    not_computed: dict[str, str] = field(default_factory=lambda: dict(STREAMED_PREDICT_NOT_COMPUTED))
    chunk_size: int = DEFAULT_CHUNK_SIZE
    #: the record's noise floor per channel (memory's), ``None`` when no segment gives one
    floor_mse: dict[str, float] | None = None
    #: the record-change check (memory's), ``None`` when not checked
    changes: RecordChanges | None = None

    @property
    def mse_over_floor(self) -> dict[str, float] | None:
        return mse_over_floor(self.mse, self.floor_mse)

    def to_dict(self) -> dict[str, Any]:
        return {"mse": dict(self.mse), "mse_over_floor": self.mse_over_floor, "n_samples": int(self.n_samples),
                "channel_samples": None,  # the streamed path masks no sample (its clipped ones are said, not masked)
                "zero_mse": dict(self.zero_mse), "nominal_mse": dict(self.nominal_mse),
                "noise_floor_mse": None if self.floor_mse is None else dict(self.floor_mse),
                "reported_validation_mse": self.reported_validation_mse, "model": self.model,
                "outside_training_range": None if self.range_check is None else self.range_check.to_dict(),
                "training_range_note": UNKNOWN_RANGE if self.range_check is None else None,
                "changed": None if self.changes is None else self.changes.to_dict(), "prediction_path": "streamed",
                "streaming": {"chunk_size": int(self.chunk_size)}, "not_computed": dict(self.not_computed)}


def needs_joint_side(identified: IdentifiedModel) -> bool:
    """Whether the model file reads a record through a transmission (motor-side columns), joint zeros or reversed
    joint directions: the streamed reader then reads joint-side copies of the files
    (:func:`estimation.data.motor_side.joint_side_copies`, made chunk by chunk), as the streamed verbs do."""
    file = identified.file
    return identified.transmission is not None or file.joint_offsets is not None or (
        file.joint_directions is not None and file.joint_directions.reversed)


def check_streamable(identified: IdentifiedModel) -> None:
    """:class:`StreamingUnsupportedError` naming what of the model file's reading the streamed reader does not make
    (module docstring); nothing when it makes it all (the joint side: :func:`needs_joint_side`)."""
    file, plan = identified.file, identified.preprocessing
    reasons = []
    if file.rest is not None and file.rest.get("rest") == "drop" and file.rest.get("min_speed"):
        reasons.append("rows at rest dropped (--min-speed)")
    if plan.method not in ("butterworth", "measured", "fourier"):
        reasons.append(f"the {plan.method} preprocessing")
    if plan.method == "butterworth" and plan.order != ButterworthDifferentiation().order:
        reasons.append(f"a Butterworth filter of order {plan.order}")
    if plan.trimmed_s:
        reasons.append(f"{plan.trimmed_s:g} s trimmed at each end")
    if reasons:
        raise StreamingUnsupportedError(f"the model file's reading holds {', '.join(reasons)}: the streamed "
                                        f"`oed predict` does not make it; {IN_MEMORY}")


def _sources(identified: IdentifiedModel, paths: Sequence[str | Path], chunk_size: int) -> list:
    """The record's streamed sources: each file's segments (split at its holes, as memory reads it), each on its
    regular clock when the model file's time base is ``regular`` and its stamps give one (else at its stamps, said
    as memory says it)."""
    model = identified.model
    for path in paths:
        if not Path(path).is_file():
            raise StreamingUnsupportedError(f"{path}: the streamed `oed predict` reads .csv and .parquet files")
    sources = segment_sources(list(paths), model, chunk_size=chunk_size)
    if identified.preprocessing.velocity_from_positions:  # dq made from the positions, as memory's plan makes it
        return [positions_source(source) for source in _clocked(identified, sources)]
    return _clocked(identified, sources)


def _clocked(identified: IdentifiedModel, sources: list) -> list:
    """``sources`` each on its regular clock when the model file's time base is ``regular`` (:func:`_sources`)."""
    model = identified.model
    if identified.preprocessing.time_base != "regular":
        return sources
    placed = []
    for source in sources:
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")  # said when the source is read
                source_rows(clock_source(source), model)
            placed.append(clock_source(source))
        except NoRegularClockError:
            warnings.warn(f"{source}: the model was identified with the samples on a regular clock, but this "
                          "record's stamps give none (a dropped row or a stall inside a segment): its samples are "
                          "taken at their stamps", stacklevel=4)
            placed.append(source)
    return placed


def _range(identified: IdentifiedModel, sources: Sequence, reading: dict[str, Any]) -> RangeCheck | None:
    """Each joint's training range against the prepared samples of ``sources``, checked chunk by chunk and pooled:
    the largest excursions and the share of samples outside, as the check of the whole record gives them."""
    ranges = identified.file.training_range
    if ranges is None:
        return None
    checks: list[RangeCheck] = []
    for source in sources:
        for chunk in plan_chunks(source, identified.model, **reading):
            checks.append(ranges.check(chunk.q, chunk.dq))
    return pooled_range(checks)


def pooled_range(checks: Sequence[RangeCheck]) -> RangeCheck | None:
    """The :class:`RangeCheck` of the samples of several checks together (the same ranges): each joint's largest
    excursions, its share of samples outside weighted by the samples, outside when it is in one."""
    if not checks:
        return None
    total = sum(check.n_samples for check in checks)
    joints = []
    for index, first in enumerate(checks[0].joints):
        items = [check.joints[index] for check in checks]
        speeds = [item.speed_above for item in items if item.speed_above is not None]
        share = sum((item.fraction or 0.0) * check.n_samples for item, check in zip(items, checks))
        joints.append(JointExcursion(first.joint, max(item.below for item in items),
                                     max(item.above for item in items), max(speeds) if speeds else None,
                                     float(share / total) if total else 0.0, any(item.outside for item in items),
                                     first.training, first.tolerance))
    return RangeCheck(tuple(joints), int(total))


def streamed_evaluation(identified: IdentifiedModel, paths: Sequence[str | Path], *,
                        chunk_size: int = DEFAULT_CHUNK_SIZE) -> StreamedEvaluation:
    """``oed predict`` of ``identified`` on the record of ``paths`` (its segments), read ``chunk_size`` rows at a
    time (module docstring); read as they are: motor-side columns, joint zeros and reversed directions already
    turned to the joint side (:func:`needs_joint_side`).

    Raises
    ------
    StreamingUnsupportedError
        The model file's reading is one the streamed reader does not make (:func:`check_streamable`), a file is not
        a .csv or .parquet one, or the loader drops rows of a resampled file the streamed grid interpolates.
    """
    check_streamable(identified)
    model, plan = identified.model, identified.preprocessing
    sources = _sources(identified, paths, chunk_size)
    fourier = plan.method == "fourier"
    reading: dict[str, Any] = {"chunk_size": chunk_size, "decimation": plan.decimation,
                               "held_torques": bool(plan.held_torques)}
    if fourier:
        reading.update(frequency_hz=plan.frequency_hz, harmonics=plan.harmonics or 5,
                       average=plan.average_periods or "auto")
    else:
        reading["cutoff_hz"] = plan.cutoff_hz if plan.method == "butterworth" else None
    nominal_theta = model.nominal_parameters()

    def zero(q: NDArray, dq: NDArray, ddq: NDArray) -> NDArray:  # against the torques the model holds
        return -identified.subtracted_load(q)

    def nominal(q: NDArray, dq: NDArray, ddq: NDArray) -> NDArray:
        return model.predict(nominal_theta, q, dq, ddq) - identified.subtracted_load(q)

    predictors = {"model": identified.predict, "zero_mse": zero, "nominal_mse": nominal}
    counted = counted_errors_at_stamps(model, {}, sources, predictors=predictors,
                                       delays={"model": identified.delay}, **reading)
    if counted is None:
        raise StreamingUnsupportedError(f"{', '.join(map(str, paths))}: the loader drops rows of a resampled file "
                                        f"that the streamed grid interpolates; {IN_MEMORY}")
    errors, count = counted
    range_options = {key: value for key, value in reading.items() if key != "average"}
    if fourier:
        range_options["average"] = reading["average"]
    check = _range(identified, sources, range_options)
    floor = record_floor(sources, model, chunk_size=chunk_size, frequency_hz=plan.frequency_hz if fourier else None)
    not_computed = dict(STREAMED_PREDICT_NOT_COMPUTED)
    changes = None
    if checked_channels(identified) and count >= 20:
        sample = _sample(identified, sources, count, reading)
        if sample is None:
            not_computed.update([OUT_OF_ORDER])
        else:
            changes = sampled_record_changes(identified, sample, floor,
                                             functools.partial(_squared_with_changes, identified, sources, reading))
    return StreamedEvaluation(errors["model"], count, errors["zero_mse"], errors["nominal_mse"],
                              identified.reported_validation_mse, identified.estimate, check, not_computed,
                              chunk_size=chunk_size, floor_mse=floor, changes=changes)


def _residuals(identified: IdentifiedModel, sources: Sequence, reading: dict[str, Any]
               ) -> Iterator[tuple[int, Measurements | None, NDArray[np.float64] | None]]:
    """The record's scored samples block by block (the motion moved by the model's delay) with the model's residual
    there in the log's directions (as :meth:`IdentifiedModel.predict_record` pairs them), each with its source's
    index; ``(index, None, None)`` for samples out of their order."""
    signs = identified.channel_signs()
    for index, record, late in scored_records(identified.model, sources, delay=identified.delay, **reading):
        if record is None or late:
            yield index, None, None
            return
        predicted = identified.predict(record.q, record.dq, record.ddq)
        yield index, record, (record.channels(identified.channels) - predicted) * signs


def _sample(identified: IdentifiedModel, sources: Sequence, count: int, reading: dict[str, Any]
            ) -> RecordSample | None:
    """The samples the record-change check fits its families on, gathered in one pass (memory's rows of the
    record's ``count`` scored samples); ``None`` when samples come out of their order."""
    rows = sampled_rows(count)
    parts: list[tuple[NDArray, ...]] = []
    bounds: list[list[int]] = []
    offset = 0
    for index, record, residual in _residuals(identified, sources, reading):
        if record is None or residual is None:
            return None
        while len(bounds) <= index:
            bounds.append([offset, offset])
        bounds[index][1] = offset + record.n_samples
        inside = rows[(rows >= offset) & (rows < offset + record.n_samples)] - offset
        parts.append((record.q[inside], record.dq[inside], record.ddq[inside], residual[inside]))
        offset += record.n_samples
    if offset != count:
        return None
    q, dq, ddq, target = (np.concatenate([part[k] for part in parts]) for k in range(4))
    return RecordSample(q, dq, ddq, target, record_segments([(start, stop) for start, stop in bounds if stop > start],
                                                            rows), count)


def _squared_with_changes(identified: IdentifiedModel, sources: Sequence, reading: dict[str, Any],
                          changes: list[tuple[Any, NDArray[np.float64]]]) -> list[NDArray[np.float64]]:
    """The squared error with each family's change over every scored sample, summed per channel: one pass."""
    totals = [np.zeros(len(identified.channels)) for _ in changes]
    for _, record, residual in _residuals(identified, sources, reading):
        if record is None or residual is None:
            raise StreamingUnsupportedError(OUT_OF_ORDER[1])
        for total, (family, beta) in zip(totals, changes):
            total += np.sum((residual - family.change(beta, record.q, record.dq, record.ddq)) ** 2, axis=0)
    return totals
