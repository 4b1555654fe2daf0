"""A record of several segments (pieces of a split file, or several files), stacked for estimation.

Each segment is preprocessed on its own (never filtered across a boundary); the prepared segments
are then concatenated sample by sample: the regressor is evaluated per sample, so the stacked
problem of the concatenation is the stack of the segments' problems. The concatenated
:class:`~dynamics.measurements.Measurements` keeps each segment's time stamps (``t`` restarts at
each boundary) and ``metadata["segments"]``: ``[{source, start, stop}]`` rows of each.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from dynamics.measurements import Measurements

#: the optional column groups whose presence must agree between segments
_GROUPS = ("dq", "ddq", "tau", "wrench")


class SegmentColumnsError(ValueError):
    """Segments with different column sets cannot be one record."""


class ConstantChannelError(ValueError):
    """A measured channel that holds one value in every sample of a record: it shows nothing to identify."""


def as_segments(data: Measurements | Sequence[Measurements], name: str = "data") -> tuple[Measurements, ...]:
    """``data`` as a non-empty tuple of segments (``TypeError`` for anything else)."""
    segments = (data,) if isinstance(data, Measurements) else tuple(data) if isinstance(data, (list, tuple)) else None
    if not segments or not all(isinstance(segment, Measurements) for segment in segments):
        raise TypeError(f"{name} must be Measurements or a non-empty sequence of them, got {type(data).__name__}")
    return segments


def column_set(segment: Measurements) -> tuple[str, ...]:
    """The optional groups a segment holds (``dq``, ``ddq``, ``tau``, ``wrench``)."""
    return tuple(group for group in _GROUPS if getattr(segment, group) is not None)


def check_same_columns(segments: Sequence[Measurements], name: str = "record") -> None:
    """Every segment has the same joints and column groups, or :class:`SegmentColumnsError` naming them."""
    first = segments[0]
    for segment in segments[1:]:
        if segment.n_joints != first.n_joints or column_set(segment) != column_set(first):
            raise SegmentColumnsError(
                f"{name}: segments with different columns: {_label(first)} has {first.n_joints} joints and "
                f"{', '.join(column_set(first)) or 'positions only'}, {_label(segment)} {segment.n_joints} joints and "
                f"{', '.join(column_set(segment)) or 'positions only'}; a record's segments must hold the same columns")


def check_varying_channels(segments: Sequence[Measurements], channels: Sequence[str], name: str = "record") -> None:
    """Every measured channel of ``channels`` (``tau2``, ``fz``…) varies over the record's segments, or
    :class:`ConstantChannelError` naming the channels that hold one value throughout (zero: a dead sensor or an
    empty column; another value: a column filled by hand, or a sensor that was off)."""
    values = np.concatenate([segment.channels(list(channels)) for segment in segments], axis=0)
    constant = [(channel, float(column[0])) for channel, column in zip(channels, values.T)
                if column.size and np.all(column == column[0])]
    if constant:
        shown = ", ".join(f"{channel} = {value:g}" for channel, value in constant)
        raise ConstantChannelError(
            f"{name}: channel(s) {shown} hold one value in every sample (a dead sensor, a column left empty or "
            "filled by hand?): a constant channel shows nothing to identify; check the data")


def concatenate(data: Measurements | Sequence[Measurements]) -> Measurements:
    """One :class:`Measurements` stacking the segments' samples (and their ``recorded`` channels)."""
    segments = as_segments(data)
    if len(segments) == 1:
        return segments[0]
    check_same_columns(segments)

    def joined(name: str, parts: Sequence[Measurements]):
        values = [getattr(part, name) for part in parts]
        return None if values[0] is None else np.concatenate(values, axis=0)

    recorded, rows = None, None
    if any(segment.recorded is not None for segment in segments):
        recorded = concatenate([segment.as_recorded for segment in segments])
        if any(segment.recorded_rows is not None for segment in segments):
            offsets = np.cumsum([0] + [segment.n_samples for segment in segments[:-1]])
            rows = np.concatenate([segment.beside_recorded() + offset for segment, offset in zip(segments, offsets)])
    bounds, start = [], 0
    for segment in segments:
        bounds.append({"source": _label(segment), "start": start, "stop": start + segment.n_samples})
        start += segment.n_samples
    metadata = dict(segments[0].metadata, segments=bounds)
    return Measurements(joined("t", segments), joined("q", segments), joined("dq", segments), joined("ddq", segments),
                        joined("tau", segments), joined("wrench", segments), metadata, recorded, rows)


def segment_slices(measurements: Measurements) -> list[slice]:
    """The samples of each segment of a concatenation (one slice for a plain record)."""
    bounds = measurements.metadata.get("segments")
    if not bounds or bounds[-1]["stop"] != measurements.n_samples:
        return [slice(0, measurements.n_samples)]
    return [slice(entry["start"], entry["stop"]) for entry in bounds]


def _label(segment: Measurements) -> str:
    source = str(segment.metadata.get("source", "data"))
    index = segment.metadata.get("segment")
    return f"{source} (segment {index})" if segment.metadata.get("segments_in_file", 1) > 1 else source
