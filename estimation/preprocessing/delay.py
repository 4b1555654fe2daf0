"""A delay between the recorded torques and the motion they answer: one per record, a property of the
measurement chain (a torque sensor's or a drive's latency, a causal filter on the encoders).

With a delay ``d`` the torque recorded at ``t`` is the model's torque along the motion at ``t − d``:
``τ_rec(t) = Y(q(t−d), q̇(t−d), q̈(t−d)) θ``. ``d > 0``: the torques lag the motion; ``d < 0``: the
motion lags the torques (positions filtered causally before they were logged). The torques stay as
recorded; :func:`delayed` moves the motion, so errors are still measured against the recording.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from dynamics.measurements import Measurements
from estimation.data.segments import segment_slices


class DelayBoundsError(ValueError):
    """The bounds of a delay search are empty, reversed or not finite."""


#: the declared name of the effect (``--friction viscous,delay``), and of its shape parameter
DELAY = "delay"


@dataclass(frozen=True)
class DelayBounds:
    """Where a delay is searched, seconds, and how many grid points start the search.

    The default, ±50 ms, covers a drive's or a torque sensor's latency and the lag of a causal
    filter on the encoders; it is cut to a tenth of the longest piece of continuous motion when that is short.
    """

    lower: float = -0.05
    upper: float = 0.05
    points: int = 21

    def __post_init__(self) -> None:
        if not (math.isfinite(self.lower) and math.isfinite(self.upper)):
            raise DelayBoundsError(f"delay bounds must be finite, got [{self.lower}, {self.upper}]")
        if not self.lower < self.upper:
            raise DelayBoundsError(f"delay bounds are empty or reversed: [{self.lower}, {self.upper}] s")
        if self.points < 3:
            raise DelayBoundsError(f"a delay search needs at least 3 grid points, got {self.points}")

    def within(self, duration: float) -> DelayBounds:
        """The bounds cut to a tenth of a record of ``duration`` seconds."""
        limit = 0.1 * duration
        lower, upper = max(self.lower, -limit), min(self.upper, limit)
        if not lower < upper:
            raise DelayBoundsError(f"delay bounds [{self.lower}, {self.upper}] s leave nothing within a tenth of a "
                                   f"{duration:.3g} s record")
        return dataclasses.replace(self, lower=lower, upper=upper)

    def grid(self) -> NDArray[np.float64]:
        return np.linspace(self.lower, self.upper, self.points)


def _shifted(t: NDArray[np.float64], values: NDArray[np.float64], derivatives: tuple[NDArray[np.float64], ...],
             delay: float) -> NDArray[np.float64]:
    """``values`` at ``t − delay``: linear interpolation inside, the Taylor series of the end sample
    in its ``derivatives`` (first, second…) past the ends."""
    target = t - delay
    shifted = np.empty_like(values)
    for column in range(values.shape[1]):
        shifted[:, column] = np.interp(target, t, values[:, column])
    for outside, edge in ((target < t[0], 0), (target > t[-1], -1)):
        if np.any(outside):
            step = (target[outside] - t[edge])[:, None]
            extrapolated = np.broadcast_to(values[edge], (step.shape[0], values.shape[1])).copy()
            factor = np.ones_like(step)
            for order, derivative in enumerate(derivatives, start=1):
                factor = factor * step / order
                extrapolated += factor * derivative[edge]
            shifted[outside] = extrapolated
    return shifted


#: a time step this many times the median step ends a piece of continuous motion (rows dropped there)
GAP_STEPS = 3.0


def motion_pieces(measurements: Measurements) -> list[slice]:
    """The pieces of continuous motion: the segments of a concatenation, split again wherever the time
    goes back (a segment boundary the metadata lost when rows were selected) or jumps by more than
    :data:`GAP_STEPS` median steps (rows at rest dropped). The motion is moved piece by piece."""
    pieces = []
    for segment in segment_slices(measurements):
        t = measurements.t[segment]
        steps = np.diff(t)
        if steps.size == 0:
            pieces.append(segment)
            continue
        positive = steps[steps > 0]
        typical = float(np.median(positive)) if positive.size else 0.0
        cuts = np.flatnonzero((steps <= 0) | (steps > GAP_STEPS * typical)) + 1
        edges = [0, *cuts.tolist(), t.shape[0]]
        pieces += [slice(segment.start + a, segment.start + b) for a, b in zip(edges[:-1], edges[1:])]
    return pieces


def longest_piece(measurements: Measurements) -> float:
    """Duration of the longest piece of continuous motion, s (the record's length for the delay's
    bounds: rows at rest dropped leave many short pieces between long ones)."""
    durations = [float(measurements.t[piece][-1] - measurements.t[piece][0]) for piece in motion_pieces(measurements)
                 if piece.stop - piece.start > 1]
    return max(durations) if durations else 0.0


def check_delay(delay: object) -> float:
    """A given delay as a finite number of seconds, or a named error."""
    if isinstance(delay, bool) or not isinstance(delay, (int, float, np.integer, np.floating)):
        raise DelayBoundsError(f"a delay is a number of seconds (or DelayBounds to estimate it), got {delay!r}")
    if not math.isfinite(float(delay)):
        raise DelayBoundsError(f"a delay must be finite, got {delay}")
    return float(delay)


def delayed(measurements: Measurements, delay: float) -> Measurements:
    """The record with its motion (``q, dq, ddq``) moved to ``t − delay``, each piece of continuous
    motion on its own (:func:`motion_pieces`); the channels (and the recorded ones,
    :attr:`Measurements.recorded`) untouched."""
    delay = check_delay(delay)
    if delay == 0.0:
        return measurements
    if measurements.dq is None or measurements.ddq is None:
        raise ValueError("a delay moves q, dq and ddq: derive dq/ddq first (estimation.preprocessing.plan.prepare)")
    q, dq, ddq = (np.array(values, dtype=float) for values in (measurements.q, measurements.dq, measurements.ddq))
    for where in motion_pieces(measurements):
        t = measurements.t[where]
        q_part, dq_part, ddq_part = measurements.q[where], measurements.dq[where], measurements.ddq[where]
        q[where] = _shifted(t, q_part, (dq_part, ddq_part), delay)
        dq[where] = _shifted(t, dq_part, (ddq_part,), delay)
        ddq[where] = _shifted(t, ddq_part, (), delay)
    recorded = None if measurements.recorded is None else delayed(measurements.recorded, delay)
    return dataclasses.replace(measurements, q=q, dq=dq, ddq=ddq, recorded=recorded)


def split_delay(spec: str | None) -> tuple[str | None, DelayBounds | None]:
    """``--friction`` without its ``delay`` item, and the delay's bounds: ``delay`` (±50 ms) or
    ``delay:S`` (±S seconds). ``(spec, None)`` when there is no such item."""
    if spec is None:
        return None, None
    items = [item.strip() for item in spec.split(",")]
    bounds = None
    kept = []
    for item in items:
        name, _, value = item.partition("@")[0].partition(":")
        if name.strip() != DELAY:
            kept.append(item)
            continue
        if bounds is not None:
            raise DelayBoundsError(f"{spec!r}: one delay per record (the item 'delay' is given twice)")
        if "@" in item:
            raise DelayBoundsError(f"effect {item!r}: the delay moves every channel at once, so it takes no @JOINTS")
        if not value:
            bounds = DelayBounds()
            continue
        try:
            limit = float(value)
        except ValueError:
            raise DelayBoundsError(f"effect {item!r}: delay:S wants the largest delay searched, in seconds "
                                   f"(delay:0.05), got {value!r}") from None
        if not (math.isfinite(limit) and limit > 0):
            raise DelayBoundsError(f"effect {item!r}: the largest delay must be a positive number of seconds, got {value}")
        bounds = DelayBounds(-limit, limit)
    return (",".join(kept) if kept else "none"), bounds
