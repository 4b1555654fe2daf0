"""Which clock the samples follow: the time stamps, or a regular clock the stamps only approximate.

A log with irregular stamps is resampled by them onto a uniform grid (:func:`estimation.data.loading.uniform_grid`),
which is right when each sample was taken at its stamp. Many loggers stamp a sample when it *arrives* (a
non-real-time process reading a real-time controller's samples): the samples were taken on the controller's
regular clock and the stamps jitter around it. Interpolating by such stamps moves each position by about its speed
times its stamp's error, a noise in proportion to the speed that every derivative, fit and error then carries and
that no filter removes without blurring the motion (``benchmarks/README.md``, h-jitter: the EMPS records with
stamps moved by up to 40 % of a step, the samples where they were: the best validation error six times the clean
records' (37 against 5.8 N²), and the cut-off the validation record prefers no longer the test record's).

The positions tell the two apart (:func:`clock_roughness`). A smooth motion's sample is close to the linear
interpolation of its two neighbours at the instants the samples were taken: at the stamps (weights from the
stamps' gaps) if the stamps are the sampling instants, at equal weights if the samples were taken on a regular
clock. The interpolation residuals on the right clock are those of the motion's curvature and the sensor's
noise; on the wrong clock they gain the speed times the stamps' error. The ratio of their root mean squares
(median over the joints) is the evidence: on the EMPS records with moved stamps 79 to 91; on the real KUKA
LWR4+ logs 2.8 to 4.7 (the stamps jitter 3.4–6.5 ms around 5 ms, the positions smoother on a regular clock); on
the real Franka Panda 0.97 to 1.03 (its stamps are its samples' instants); on the simulated corpus's jittered
logs (samples taken at their stamps) below 1.

Only interior samples whose two gaps are regular steps (between half and :data:`~estimation.data.log_cleaning.STALL_FACTOR`
times the record's grid step) are compared, so that a dropped row or a stall (a gap of several steps, where equal weights
are wrong) does not count against the regular clock.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from dynamics.measurements import Measurements
from estimation.data.loading import ReceiveTimesWarning
from estimation.data.log_cleaning import STALL_FACTOR

__all__ = ["CLOCK_TOLERANCE", "QUANTUM_STEPS", "RECEIVE_TIMES_RATIO", "ClockSums", "clock_instants",
           "clock_roughness", "on_regular_clock", "quantised_clock", "receive_times_ratio", "regular_clock", "regular_clock_line", "said_receive_times"]

#: the positions are said to follow a regular clock rather than the stamps when their interpolation residuals at
#: the stamps are at least this many times those on a regular clock (root mean square, median over the joints)
RECEIVE_TIMES_RATIO = 2.0
#: fewest interior samples with regular gaps the evidence is taken on
MIN_COMPARED = 100
#: interpolation residuals below this fraction of a joint's range are rounding (a joint at constant speed)
ROUNDING = 1e-12


@dataclass(frozen=True)
class ClockSums:
    """Sums of the interpolation residuals of a record's positions, at its stamps and on a regular clock, over its
    interior samples with regular gaps (module docstring): added block by block, they give the whole record's
    :attr:`ratio` (the streamed reader's blocks, :mod:`estimation.streaming.chunks`).

    Attributes
    ----------
    at_stamps, on_clock
        ``(n,)`` each joint's sum of squared residuals, at the stamps and with equal weights.
    compared
        Samples summed.
    low, high
        ``(n,)`` each joint's smallest and largest position seen (the rounding's scale).
    """

    at_stamps: NDArray[np.float64]
    on_clock: NDArray[np.float64]
    compared: int
    low: NDArray[np.float64]
    high: NDArray[np.float64]

    @classmethod
    def of(cls, t: NDArray[np.float64], q: NDArray[np.float64], step: float) -> ClockSums:
        """The sums over the interior rows of ``t`` (stamps, increasing) and ``q`` (``(N, n)`` positions) whose two
        gaps lie between half and :data:`~estimation.data.log_cleaning.STALL_FACTOR` times ``step`` (the record's
        grid step)."""
        gaps = np.diff(t)
        regular = (gaps >= 0.5 * step) & (gaps <= STALL_FACTOR * step)
        rows = np.flatnonzero(regular[:-1] & regular[1:]) + 1
        before = (t[rows + 1] - t[rows]) / (t[rows + 1] - t[rows - 1])
        at_stamps = q[rows] - (before[:, None] * q[rows - 1] + (1.0 - before)[:, None] * q[rows + 1])
        on_clock = q[rows] - 0.5 * (q[rows - 1] + q[rows + 1])
        return cls(np.sum(at_stamps**2, axis=0), np.sum(on_clock**2, axis=0), int(rows.shape[0]),
                   np.min(q, axis=0), np.max(q, axis=0))

    def __add__(self, other: ClockSums) -> ClockSums:
        return ClockSums(self.at_stamps + other.at_stamps, self.on_clock + other.on_clock,
                         self.compared + other.compared, np.minimum(self.low, other.low),
                         np.maximum(self.high, other.high))

    @property
    def ratio(self) -> float | None:
        """The root mean square of the residuals at the stamps over that on a regular clock, median over the
        joints that move; ``None`` with fewer than :data:`MIN_COMPARED` samples or no joint moving."""
        if self.compared < MIN_COMPARED:
            return None
        stamps_rms = np.sqrt(self.at_stamps / self.compared)
        clock_rms = np.sqrt(self.on_clock / self.compared)
        rounding = ROUNDING * np.maximum(self.high - self.low, 1.0)  # residuals below it are the arithmetic's
        moving = np.maximum(stamps_rms, clock_rms) > rounding
        if not moving.any():
            return None
        return float(np.median(np.maximum(stamps_rms[moving], rounding[moving])
                               / np.maximum(clock_rms[moving], rounding[moving])))


def clock_roughness(t: NDArray[np.float64], q: NDArray[np.float64], step: float | None = None) -> float | None:
    """The root mean square of each interior position's residual against the linear interpolation of its
    neighbours at the stamps ``t``, over the same on a regular clock (equal weights), median over the joints
    (module docstring); ``None`` when fewer than :data:`MIN_COMPARED` samples have regular gaps or no joint moves.

    Parameters
    ----------
    t
        ``(N,)`` the stamps as recorded (increasing).
    q
        ``(N, n)`` the positions at those rows.
    step
        The record's step (its resampling grid's); by default the median of the gaps.
    """
    if t.shape[0] < 3:
        return None
    step = float(np.median(np.diff(t))) if step is None else step
    if step <= 0:
        return None
    return ClockSums.of(t, q, step).ratio


def said_receive_times(ratio: float | None, first: float, last: float, samples: int, source: str, *,
                       stacklevel: int = 4) -> None:
    """A :class:`~estimation.data.loading.ReceiveTimesWarning` when the positions of a resampled record follow a
    regular clock rather than its stamps (``ratio``, :func:`clock_roughness` or :attr:`ClockSums.ratio`, at least
    :data:`RECEIVE_TIMES_RATIO`): the resampling by the stamps then adds noise in proportion to the speed. Nothing
    is changed: which clock the samples were taken on is the logger's to say. ``first``, ``last``, ``samples``:
    the record's first and last stamps and its count of samples (the regular clock through them is named)."""
    if ratio is None or ratio < RECEIVE_TIMES_RATIO:
        return
    step = (last - first) / max(samples - 1, 1)
    warnings.warn(
        f"{source}: the positions are {ratio:.3g} times smoother on a regular clock (a sample every {step:.6g} s) "
        "than at the stamps of column t: the stamps look like a logger's receive times, not the instants the "
        "samples were taken; resampling by them adds noise in proportion to the speed to the derivatives and to "
        "every error. If the samples were taken on a regular clock, write t as that clock (t0 + k * step, k the "
        "sample's index)", ReceiveTimesWarning, stacklevel=stacklevel)


#: a stamp farther than this fraction of a step from its instant on the regular clock could be another
#: sample's: the regular clock is then not identified from the stamps (a dropped row, a stall)
CLOCK_TOLERANCE = 0.5


def regular_clock(t: NDArray[np.float64]) -> NDArray[np.float64] | None:
    """The regular clock the samples of stamps ``t`` were taken on, one sample a step: ``t0 + k * step``, ``k``
    the sample's index, ``t0`` and ``step`` the least-squares fit of the stamps on ``k`` (the clock the
    :class:`~estimation.data.loading.ReceiveTimesWarning` names, through the stamps rather than through the first
    and last alone, whose own errors would tilt it). ``None`` when a stamp lies :data:`CLOCK_TOLERANCE` of a step
    or more from its instant (a row dropped or a stall inside the segment: the sample's index is then not its
    instant) or the fit's step is not positive."""
    line = regular_clock_line(t)
    return None if line is None else clock_instants(*line, 0, t.shape[0])


def regular_clock_line(t: NDArray[np.float64]) -> tuple[float, float] | None:
    """``(t0, step)`` of :func:`regular_clock` (its instants are :func:`clock_instants` of them from row 0: one
    formula for a whole record and for a streamed block of it); ``None`` where :func:`regular_clock` is."""
    count = t.shape[0]
    if count < 3:
        return None
    k = np.arange(count, dtype=float)
    step, t0 = np.polyfit(k, t, 1)
    if not step > 0:
        return None
    if np.max(np.abs(t - (t0 + step * k))) >= CLOCK_TOLERANCE * step:
        return None
    return float(t0), float(step)


#: a time column's resolution at most this many samples' steps is read as the clock of the samples it cannot tell
#: apart (:func:`quantised_clock`); a coarser one (whole seconds at 100 Hz) says too little of the instants
QUANTUM_STEPS = 2.0
#: ternary steps of the narrowest band's slope search (each keeps two thirds of the bracket: (2/3)^80 ~ 1e-14)
NARROWEST_ITERATIONS = 80


def quantised_clock(t: NDArray[np.float64]) -> tuple[float, float, float] | None:
    """The regular clock ``t0 + k * step`` through stamps ``t`` of a resolution as coarse as the samples' step (a
    1 kHz controller's millisecond counter): ``(t0, step, resolution)``; ``None`` elsewhere.

    Such a clock writes the same stamp on two samples now and then (the counter and the sampling clock a little
    apart): new values at a repeated stamp, which the loader otherwise drops as a clock that did not tick, losing
    a sample and putting the next one a whole step early. Each stamp is its sample's instant truncated or rounded to
    the resolution ``r``: the instants lie on a regular clock when the stamps' deviations from the narrowest line
    through them (on the sample's index ``k``) span at most ``r``; that line places every row, each within its
    stamp's resolution. Only when some row repeats the previous stamp and every other step is one tick ``r`` (the
    samples at least as frequent as the ticks: a clock that did not tick once, its next stamp two ticks on, is the
    loader's dropped row), ``r`` is at most :data:`QUANTUM_STEPS` fitted steps and the deviations span at most ``r``
    (a lost row or a stall spans a step more). ``t``: the stamps as recorded."""
    count = t.shape[0]
    if count < MIN_COMPARED:
        return None
    steps = np.diff(t)
    if np.any(steps < 0) or not np.any(steps == 0) or not np.any(steps > 0):
        return None
    positive = steps[steps > 0]
    resolution = float(np.min(positive))
    if float(np.max(positive)) > resolution * (1.0 + 1e-6):  # a stamp skipped: a clock that did not tick, the
        return None  # next stamp two ticks on (the loader drops the row), or stamps not quantised
    fitted = _narrowest_line(t)
    if fitted is None:
        return None
    t0, step, width = fitted
    if not step > 0 or resolution > QUANTUM_STEPS * step or width > resolution * (1.0 + 1e-6):
        return None
    return t0, step, resolution


def clock_instants(t0: float, step: float, first: int, count: int) -> NDArray[np.float64]:
    """The instants ``t0 + step * k`` of rows ``k = first .. first + count - 1`` on a regular clock (one formula for
    a whole record and for a streamed block of it, so that both give the same numbers)."""
    return t0 + step * (first + np.arange(count, dtype=float))


def _narrowest_line(t: NDArray[np.float64]) -> tuple[float, float, float] | None:
    """The line ``t0 + step * k`` (``k`` the row's index) whose band holds every stamp of ``t`` narrowest (the
    Chebyshev fit: least maximal deviation), and the band's width (``max − min`` of the deviations). The width is a
    convex function of the slope alone (the offset centres the band), minimised by a ternary search within
    ``±2 w / (N − 1)`` of the least-squares slope (``w`` its width: no slope farther can do better). ``None`` for
    fewer than three stamps."""
    count = t.shape[0]
    if count < 3:
        return None
    k = np.arange(count, dtype=float)
    centred = t - t[0]

    def width(slope: float) -> float:
        return float(np.ptp(centred - slope * k))

    slope = float(np.polyfit(k, centred, 1)[0])
    reach = 2.0 * width(slope) / (count - 1)
    low, high = slope - reach, slope + reach
    for _ in range(NARROWEST_ITERATIONS):
        first, second = low + (high - low) / 3.0, high - (high - low) / 3.0
        if width(first) <= width(second):
            high = second
        else:
            low = first
    slope = 0.5 * (low + high)
    deviations = centred - slope * k
    return float(t[0] + 0.5 * (deviations.max() + deviations.min())), slope, float(np.ptp(deviations))


def receive_times_ratio(segment: Measurements) -> float | None:
    """:func:`clock_roughness` of a segment as read, on its samples as recorded; ``None`` when it was not resampled
    by its stamps (their gaps regular: nothing to tell apart) or the evidence is too thin."""
    if segment.recorded is None:
        return None
    recorded = segment.recorded
    step = (segment.t[-1] - segment.t[0]) / max(segment.t.shape[0] - 1, 1)
    return clock_roughness(recorded.t, recorded.q, step)


def on_regular_clock(segment: Measurements) -> Measurements | None:
    """A segment as read with its samples as recorded placed on :func:`regular_clock` instead of their stamps:
    nothing is interpolated (the clock is the segment's grid, one sample a step); the segment itself when it was
    not resampled (its stamps already regular); ``None`` when its stamps give no regular clock."""
    if segment.recorded is None:
        return segment
    recorded = segment.recorded
    clock = regular_clock(recorded.t)
    if clock is None:
        return None
    metadata = {key: value for key, value in segment.metadata.items() if key not in ("resampled_from", "recorded_stamps")}
    metadata["time_base"] = "regular"
    return Measurements(clock, recorded.q, recorded.dq, recorded.ddq, recorded.tau, recorded.wrench, metadata)
