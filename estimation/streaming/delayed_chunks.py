"""A record's prepared chunks moved by a delay between torques and motion (:mod:`estimation.preprocessing.delay`), as
the in-memory diagnosis moves the whole record (:func:`estimation.preprocessing.delay.delayed`).

The motion at ``t − d`` is interpolated linearly between the record's samples, and past a piece's ends
extrapolated by the Taylor series of its end sample. A chunk's samples near its edges need samples of the chunks
either side: each chunk is moved inside a window reaching :func:`reach` samples into the chunks before and after it
(carried across the boundaries: the previous chunk's last samples kept, the next chunk read ahead), and only its own
samples kept. Inside the record every target time ``t − d`` of a kept sample then falls between two of the window's
samples, or past a true end of the record: the kept samples equal those of the whole record moved at once.
The channels as recorded (:attr:`~dynamics.measurements.Measurements.recorded`) stay as they are. A chunk's in-band window (:class:`~estimation.estimators.identification_problem.BandWindow`, the channel weights'
problem) is moved as one record: it reaches the band's margin beyond the chunk, whose edge samples the low-pass
filter has forgotten at the samples kept.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Iterator
from dataclasses import replace

import numpy as np

from dynamics.measurements import Measurements
from estimation.estimators.identification_problem import BandWindow
from estimation.preprocessing.delay import delayed
from estimation.streaming.diagnosis_sums import concatenate

__all__ = ["moved_chunks", "reach"]

#: samples carried beyond the delay's own reach on each side (the interpolation's bracketing sample, and slack)
EXTRA_SAMPLES = 3


def reach(delay: float, step: float) -> int:
    """Samples of a neighbouring chunk a window needs on each side for a delay of ``delay`` s at steps of ``step`` s."""
    if not step > 0:
        return EXTRA_SAMPLES
    return int(math.ceil(abs(delay) / step)) + EXTRA_SAMPLES


def _window_moved(chunk: Measurements, delay: float) -> Measurements:
    window = chunk.metadata.get("band_window")
    if not isinstance(window, BandWindow):
        return chunk
    moved = replace(window, samples=delayed(window.samples, delay))
    return replace(chunk, metadata={**chunk.metadata, "band_window": moved})


def _plain(chunk: Measurements) -> Measurements:
    """The chunk's samples without the per-chunk metadata a window of several chunks cannot hold."""
    metadata = {key: value for key, value in chunk.metadata.items() if key not in ("band_window", "segments")}
    return replace(chunk, metadata=metadata, recorded=None, recorded_rows=None)


def moved_chunks(chunks: Iterable[Measurements], delay: float | None,
                 pairs: bool = False) -> Iterator[Measurements] | Iterator[tuple[Measurements, Measurements]]:
    """The ``chunks`` of one record with their motion moved to ``t − delay`` (module docstring); ``None`` or zero: as
    they are. ``pairs``: each chunk as read beside it, ``(as read, moved)``."""
    iterator = iter(chunks)
    if delay is None or delay == 0.0:
        for chunk in iterator:
            yield (chunk, chunk) if pairs else chunk
        return
    before: Measurements | None = None  # the last samples of the chunks already moved
    current = next(iterator, None)
    ahead: list[Measurements] = []
    while current is not None:
        steps = np.diff(current.t)
        step = float(np.median(steps)) if steps.size else 0.0
        need = reach(delay, step)
        exhausted = False
        while sum(part.n_samples for part in ahead) < need:
            following = next(iterator, None)
            if following is None:
                exhausted = True
                break
            ahead.append(following)
        after = concatenate([_plain(part) for part in ahead]) if ahead else None
        parts = ([] if before is None else [before]) + [_plain(current)] + (
            [] if after is None else [after.select(slice(0, min(need, after.n_samples)))])
        window = concatenate(parts) if len(parts) > 1 else parts[0]
        start = 0 if before is None else before.n_samples
        moved = delayed(window, delay).select(slice(start, start + current.n_samples))
        moved = replace(moved, metadata=current.metadata, recorded=current.recorded,
                        recorded_rows=current.recorded_rows)  # the channels as recorded: untouched
        moved = _window_moved(moved, delay)
        yield (current, moved) if pairs else moved
        kept = _plain(current) if before is None else concatenate([before, _plain(current)])
        before = kept.select(slice(max(0, kept.n_samples - need), kept.n_samples))
        current = ahead.pop(0) if ahead else None
        if exhausted and current is None:
            break
