"""What a real logger does to a record, found in its time stamps and rows.

* **Re-sent packets.** A row whose data columns (``q``, ``dq``, ``ddq``, ``tau``, wrench: every
  channel read) all equal those of the row before is a logger re-sending its last packet, whether
  its time stamp repeats or advanced: a real sensor's readings (noise, the next encoder count,
  the torque) never repeat exactly on every channel at once. Such rows are dropped (and counted):
  the stale copy is not a measurement of its instant; the samples it stood for are interpolated. A robot
  at rest whose channels are quantised repeats its rows too: interpolating between equal rows gives them
  back, so both cases come out right.
* **Stalls and holes.** A step of the time column that leaves samples missing (by the local median
  step, so that a logger that stalls and then delivers its backlog in a burst is not one) is a
  stall when it lasts at most ``max_gap`` seconds — bridged by the loader's interpolation onto a
  uniform grid — and a hole otherwise, where the record is split into segments. Gaps are judged on the time
  stamps alone (:func:`time_stamps_jump`): the rows dropped as repeated leave none, however many there are.
* **Dropouts.** A row whose data columns are all blank (its time stamp written or not) is a sample the logger
  did not deliver (:func:`blank_rows`): it is dropped before anything else, and the time it leaves without a
  sample is a gap like any other, bridged up to ``max_gap`` and split beyond. A row with some cells blank and
  others not is no dropout, and stays an error, but at the record's edges (:func:`unstarted_rows`).
* **Channels that start late or stop early.** A logger whose channels report on their own (a drive per joint, a
  topic per sensor, tables merged by time) writes rows before every channel's first value, or after one's last,
  with some cells blank: the rows before the first row that holds every channel, and after the last, are no
  samples of the record (there is nothing to interpolate from on one side) and are left out; the record is the
  rows between. Blanks between complete rows stay an error.
* **Lost frames written as zeros.** A fieldbus logger that misses a frame may write the row with every value ``0``
  (:func:`zero_rows`): on a robot of two joints or more, every position and torque exactly zero at once is no
  measurement (the torque sensors' noise alone forbids it), so such a row is a dropout like a blank one. Rows
  without torques are not judged: a planned trajectory may start at the zero pose.
* **Encoder read errors.** One sample of one joint's position off, or a run of up to :data:`GLITCH_RUN`, the next
  right again (a bit error on the encoder's bus, a stale reading held a few samples): a step into that value and a
  step out of it, each longer than the joint could travel in a sample
  period (twice its velocity limit in the description; without one, :data:`GLITCH_RECORD_FACTOR` times the speed
  under which :data:`GLITCH_QUANTILE` of the record's steps lie) and than :data:`GLITCH_COUNTS` of the channel's
  smallest step (its encoder count: a quantised encoder flickering between counts is no error), the samples around
  it agreeing and the run's own steps short beside them (:func:`position_steps`, :func:`encoder_glitches`). Steps are taken modulo a whole turn (an angle
  wrapped at ±π is no error). Such a row is a dropout: dropped, its time bridged as any gap. A true motion never
  leaves and comes back within a few samples by more than its velocity allows.
* **A torque sensor past its range.** A channel that holds its largest (or smallest) value on a run of samples
  while the joint moves, where its values elsewhere vary, is clipped there (:func:`saturated_samples`): its reading
  is the sensor's limit, not the torque. A quantised channel repeats its extremes too, but no more than its other
  values: the extreme must be held :data:`SATURATION_FACTOR` times as often as the channel's values are on average,
  and a coarsely quantised signal's smooth peak, held long because its slope vanishes there, is told from a clip by
  the samples around the hold (:func:`quantised_peak`: whole quanta away, their trend within a quantum of the hold);
  a joint at rest against a hard stop holds its torque while its position holds too, and is left alone. Such samples
  are no measurement: the reader leaves them out of the samples as recorded (the fit and every error), the
  positions kept for the derivatives. A wrench channel (a force plate's, a force/torque sensor's) alike, judged
  while any joint moves (:func:`saturated_wrench`).

Pure functions on arrays; :mod:`estimation.data.loading` turns their findings into warnings and errors.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

#: a step longer than this many median steps may leave samples missing
STALL_FACTOR = 1.5
#: default longest time without samples that is bridged by interpolation, s (``--max-gap``)
DEFAULT_MAX_GAP = 0.05


@dataclass(frozen=True)
class Gap:
    """Samples missing after row ``row`` (of the de-duplicated record).

    Attributes
    ----------
    row
        Index of the last sample before the gap.
    t
        Its time, s.
    duration
        Time between the samples around the gap, s.
    missing
        Samples missing: the gap over the median step, less one.
    """

    row: int
    t: float
    duration: float
    missing: float


def blank_rows(empty: NDArray[np.bool_]) -> NDArray[np.bool_]:
    """``(N,)`` true where every cell of a row is empty (``empty (N, k)``: the data columns' cells that hold no
    value, not those that hold text): a dropout, the logger wrote no value in the row; ``k = 0`` gives none."""
    if empty.shape[1] == 0:
        return np.zeros(empty.shape[0], dtype=bool)
    return np.all(empty, axis=1)


def unstarted_rows(empty: NDArray[np.bool_]) -> NDArray[np.bool_]:
    """``(N,)`` true on the rows before the first row with no empty cell and after the last one (``empty (N, k)``:
    the data columns' cells that hold no value): the rows a logger wrote before all its channels had reported, or
    after one had stopped. None without a complete row (every row lacks a channel: the column checks name it), nor
    for ``k = 0``."""
    complete = ~np.any(empty, axis=1) if empty.shape[1] else np.ones(empty.shape[0], dtype=bool)
    edges = np.zeros(empty.shape[0], dtype=bool)
    if empty.shape[1] == 0 or not complete.any():
        return edges
    found = np.flatnonzero(complete)
    edges[:found[0]] = True
    edges[found[-1] + 1:] = True
    return edges


#: the fewest joints a robot must have for a row of zeros to be a lost frame: one axis at rest at its zero pose,
#: its encoder and torque quantised, may log zeros
ZERO_ROW_JOINTS = 2


def zero_rows(data: NDArray[np.float64], n_joints: int) -> NDArray[np.bool_]:
    """``(N,)`` true where every cell of a row of ``data`` (``(N, k)``, the data columns of a robot of ``n_joints``
    as numbers; text and blanks as NaN) is exactly zero: a lost frame written as zeros. None on a robot of fewer
    than :data:`ZERO_ROW_JOINTS` joints."""
    if n_joints < ZERO_ROW_JOINTS or data.shape[1] == 0:
        return np.zeros(data.shape[0], dtype=bool)
    return np.all(data == 0.0, axis=1)


#: how many times the joint's velocity limit a step must pass to be no motion (the limit is what the joint can do;
#: the position's noise and the stamps' jitter are the margin)
GLITCH_SPEED_MARGIN = 2.0
#: without a velocity limit, how many times the record's own fast speed (:data:`GLITCH_QUANTILE`) a step must pass
GLITCH_RECORD_FACTOR = 4.0
#: the share of a joint's steps whose speed defines its fast speed when the description gives no limit
GLITCH_QUANTILE = 0.99
#: how many of the channel's smallest step (an encoder's count) a step must pass: a quantised encoder flickers
#: between neighbouring counts, and its noise by a few
GLITCH_COUNTS = 4.0
#: the most samples an encoder read error lasts (a run of samples off, then right again; h-sensorfaults' rule was one)
GLITCH_RUN = 5
#: the speed bins (rad/s or m/s) of :class:`PositionSteps`: log-spaced, 20 a decade
SPEED_EDGES = np.logspace(-6.0, 6.0, 241)


@dataclass(frozen=True)
class PositionSteps:
    """What a record's position steps say about encoder read errors, summed block by block (:meth:`merged`): the
    same for a record read whole and one streamed in chunks.

    Attributes
    ----------
    counts
        ``(n, len(SPEED_EDGES) + 1)`` steps per joint and speed bin (``|Δq| / Δt``; below the first edge and above
        the last in the end bins).
    smallest
        ``(n,)`` each joint's smallest step that is not zero (``inf`` when none).
    rows, joints
        The runs of samples that leave and come back (:func:`position_steps`): their first row among those read, and
        the joint.
    steps, spans
        The shorter of each such run's two steps (in and out), and the time of a sample around it (the time from the
        sample before the run to the one after it over the run's samples and one), s.
    lengths
        Each run's samples (1 to :data:`GLITCH_RUN`).
    """

    counts: NDArray[np.int64]
    smallest: NDArray[np.float64]
    rows: NDArray[np.int64]
    joints: NDArray[np.int64]
    steps: NDArray[np.float64]
    spans: NDArray[np.float64]
    lengths: NDArray[np.int64]

    def merged(self, other: PositionSteps) -> PositionSteps:
        """Both blocks' steps (``other`` read after this one)."""
        return PositionSteps(self.counts + other.counts, np.minimum(self.smallest, other.smallest),
                             np.concatenate([self.rows, other.rows]), np.concatenate([self.joints, other.joints]),
                             np.concatenate([self.steps, other.steps]), np.concatenate([self.spans, other.spans]),
                             np.concatenate([self.lengths, other.lengths]))


def _turn_wrapped(step: NDArray[np.float64]) -> NDArray[np.float64]:
    """``step`` modulo a whole turn, in ``[-π, π)`` where it is longer than half a turn (an angle logged wrapped at
    ±π steps by a turn there), as it is elsewhere."""
    far = np.abs(step) > np.pi
    if not far.any():
        return step
    wrapped = step.copy()
    wrapped[far] = np.mod(step[far] + np.pi, 2.0 * np.pi) - np.pi
    return wrapped


def position_steps(q: NDArray[np.float64], t: NDArray[np.float64], velocity_limit: NDArray[np.float64], *,
                   first_row: int = 0, carried: int = 0) -> PositionSteps:
    """The :class:`PositionSteps` of the rows ``q (m, n)`` stamped ``t (m,)``, the first ``carried`` of them the
    last rows of the block before (at most :data:`GLITCH_RUN` + 1; their steps and their runs already counted), the
    others numbered from ``first_row``. A run is judged once the sample after it is read: the runs ending on a
    block's last rows are judged with the next block, which carries them (and the sample before them). Rows with a
    non-finite value or stamp, and steps of no time, count for nothing, and a run is judged only where its samples
    and those around it follow each other in time; steps are taken modulo a whole turn (:func:`_turn_wrapped`).
    ``velocity_limit`` (``(n,)``, the description's; ``inf`` where it gives none): the speeds are counted for the
    joints without one only (:func:`fast_speeds` bounds those), and a run that leaves and comes back is kept as a
    candidate only when it is faster than :data:`GLITCH_SPEED_MARGIN` times the joint's limit (what
    :func:`encoder_glitches` asks).

    A run of ``k`` samples (1 to :data:`GLITCH_RUN`) leaves and comes back when the step into its first sample and
    the step out of its last are each longer than twice every step within it and than twice the step across it
    (from the sample before the run to the sample after it): the samples around the run agree, and the run's own
    samples follow each other as the motion does, all of them off by about the same. A true motion cannot do that
    faster than its velocity allows: the steps in and out are each judged over the time of a sample around the run
    (the time from the sample before it to the sample after it over ``k + 1``; half the time between the
    neighbours for one sample, h-sensorfaults' rule). Of the runs found at a sample, the shortest is kept."""
    m, n = q.shape
    counts = np.zeros((n, SPEED_EDGES.shape[0] + 1), dtype=np.int64)
    smallest = np.full(n, np.inf)
    none = np.zeros(0, dtype=np.int64)
    if m < 2:
        return PositionSteps(counts, smallest, none, none, np.zeros(0), np.zeros(0), none)
    limit = np.asarray(velocity_limit, dtype=float)
    bounded = np.isfinite(limit) & (limit > 0)
    with np.errstate(invalid="ignore", divide="ignore"):
        step = _turn_wrapped(np.diff(q, axis=0))
        size = np.abs(step)
        new = slice(max(carried - 1, 0), None)
        smallest = np.where(size[new] > 0, size[new], np.inf).min(axis=0) if size[new].size else smallest
        if not bounded.all():
            dt = np.diff(t)[new]
            for joint in np.flatnonzero(~bounded):
                speed = size[new, joint][dt > 0] / dt[dt > 0]
                counts[joint] = np.bincount(np.searchsorted(SPEED_EDGES, speed[np.isfinite(speed)], side="right"),
                                            minlength=counts.shape[1])
        floor = np.where(bounded, GLITCH_SPEED_MARGIN * np.where(bounded, limit, 0.0), 0.0)
        forward = np.r_[False, np.diff(t) > 0]  # forward[i]: row i after row i - 1 in time
        found_rows, found_joints, found_steps, found_spans, found_lengths = [], [], [], [], []
        taken = np.zeros((m, n), dtype=bool)  # a run already kept starting at that row and joint (a shorter one)
        within = np.zeros((max(m - 2, 0), n))  # the longest step within the runs of each start, so far
        ordered = np.ones(max(m - 2, 0), dtype=bool)  # the run's rows and the row after it in order, so far
        steps_dt = np.diff(t)
        least = float(steps_dt[steps_dt > 0].min()) if np.any(steps_dt > 0) else 0.0
        possible = bool(np.any((size > floor * least) & (size > 0)))  # a step a run could leave or come back by
        # (a span is at least the shortest step of time): none on a clean log of joints with limits, the runs skipped
        for length in range(1, GLITCH_RUN + 1) if possible else ():
            starts = m - length - 1  # runs from row 1 to row m - length - 1 (a sample before and after each)
            if starts < 1:
                break
            # the run's first rows 1 .. starts, its last rows length .. starts + length - 1 (slices: a gather of
            # rows costs ten times as much)
            if length > 1:
                within[:starts] = np.maximum(within[:starts], size[length - 1:length - 1 + starts])
            ordered[:starts] &= forward[length:length + starts] & forward[length + 1:length + 1 + starts]
            into, out = size[:starts], size[length:length + starts]
            shorter = np.minimum(into, out)
            span = np.where(ordered[:starts], (t[length + 1:length + 1 + starts] - t[:starts]) / (length + 1), 0.0)
            maybe = ((shorter > floor * np.where(span > 0, span, 0.0)[:, None]) & (shorter > 0)
                     & (span > 0)[:, None] & (within[:starts] < 0.5 * shorter))
            maybe[:max(carried - length - 1, 0)] = False  # the sample after the run read in the block before
            if not maybe.any():
                continue
            row, joint = np.nonzero(maybe)
            keep = ~taken[row + 1, joint]
            row, joint = row[keep], joint[keep]
            through = np.abs(_turn_wrapped(q[row + length + 1, joint] - q[row, joint]))
            keep = through < 0.5 * shorter[row, joint]
            row, joint = row[keep], joint[keep]
            taken[row + 1, joint] = True
            found_rows.append(row + 1)
            found_joints.append(joint)
            found_steps.append(shorter[row, joint])
            found_spans.append(span[row])
            found_lengths.append(np.full(row.shape[0], length))
    if not found_rows:
        return PositionSteps(counts, smallest, none, none, np.zeros(0), np.zeros(0), none)
    rows = np.concatenate(found_rows)
    return PositionSteps(counts, smallest, (first_row - carried + rows).astype(np.int64),
                         np.concatenate(found_joints).astype(np.int64), np.concatenate(found_steps),
                         np.concatenate(found_spans), np.concatenate(found_lengths).astype(np.int64))


def fast_speeds(steps: PositionSteps) -> NDArray[np.float64]:
    """``(n,)`` the speed under which :data:`GLITCH_QUANTILE` of each joint's steps lie (the upper edge of its bin
    in :data:`SPEED_EDGES`; ``inf`` for a joint without steps or with its quantile past the last edge)."""
    totals = steps.counts.sum(axis=1)
    bins = np.array([np.searchsorted(np.cumsum(row), GLITCH_QUANTILE * total, side="left") if total else
                     SPEED_EDGES.shape[0] for row, total in zip(steps.counts, totals)])
    return np.where(bins < SPEED_EDGES.shape[0], SPEED_EDGES[np.minimum(bins, SPEED_EDGES.shape[0] - 1)], np.inf)


def encoder_glitches(steps: PositionSteps, velocity_limit: NDArray[np.float64]) -> tuple[NDArray[np.int64],
                                                                                          NDArray[np.int64]]:
    """The encoder read errors among ``steps``' runs of samples that leave and come back: the rows and joints of
    their samples (sorted by row, then joint; each once). A step no joint may make: longer than
    :data:`GLITCH_SPEED_MARGIN` times ``velocity_limit`` (``(n,)``, rad/s or m/s; ``inf`` where the description
    gives none: :data:`GLITCH_RECORD_FACTOR` times :func:`fast_speeds` instead) over the time of a sample around the
    run, and than :data:`GLITCH_COUNTS` of the joint's smallest step."""
    limit = np.asarray(velocity_limit, dtype=float)
    speed = np.where(np.isfinite(limit) & (limit > 0), GLITCH_SPEED_MARGIN * limit,
                     GLITCH_RECORD_FACTOR * fast_speeds(steps))
    joints = steps.joints
    glitch = ((steps.steps > speed[joints] * steps.spans) & (steps.steps > GLITCH_COUNTS * steps.smallest[joints]))
    lengths = steps.lengths[glitch]
    rows = np.repeat(steps.rows[glitch], lengths) + (np.arange(lengths.sum()) - np.repeat(np.cumsum(lengths) - lengths,
                                                                                            lengths))
    joints = np.repeat(joints[glitch], lengths)
    pairs = np.unique(np.column_stack([rows, joints]), axis=0) if rows.size else np.zeros((0, 2), dtype=np.int64)
    return pairs[:, 0].astype(np.int64), pairs[:, 1].astype(np.int64)


#: how many times as often as the channel's values are on average (samples over distinct values) its extreme must
#: be held to be a sensor's limit: a quantised channel's extremes are held no more often than its other values
SATURATION_FACTOR = 10.0
#: the fewest samples at a channel's extreme that make it clipped
SATURATION_LEAST = 5
#: the most samples kept on each side of a held extreme, in which the signal's trend through the hold is judged
#: (:func:`quantised_peak`): a hold of ``L`` samples is judged on ``L`` samples on each side, at least
#: :data:`PEAK_WINDOW_LEAST`, at most this many
PEAK_WINDOW = 256
#: the fewest samples on each side of a hold in which its trend is judged; holds closer than this are one hold
PEAK_WINDOW_LEAST = 16
#: the holds judged by :func:`quantised_peak`: those within this many rows of the first row held at the extreme
#: (the samples kept around them bounded whatever the record's length, the same rows whole or in blocks)
PEAK_SPAN = 4096
#: the fewest levels of the channel's quantum (the hold's own included) around a hold that make it quantised
PEAK_LEVELS = 3
#: how far off a whole number of quanta a value around the hold may lie, in quanta (a log's decimal rounding)
PEAK_GRID_TOLERANCE = 0.05


def saturated_samples(tau: NDArray[np.float64], q: NDArray[np.float64]) -> NDArray[np.bool_]:
    """``(N, n)`` true where torque channel ``j`` of ``tau (N, n)`` holds its largest or smallest value on a run of
    samples while joint ``j``'s position ``q (N, n)`` changes within the run (a lone sample at the extreme: between
    its neighbours, the noise taking the reading in and out of the limit), the extreme held on at least
    :data:`SATURATION_LEAST` samples and :data:`SATURATION_FACTOR` times as often as the channel's values on average
    (a quantised channel holds its extremes no more often than its other values). A run where the position holds
    too (a joint at rest against a hard stop) is left alone. Non-finite values count for nothing. One block of
    :class:`HeldExtremes` (the streamed reader's rule, block by block)."""
    scan = HeldExtremes(tau.shape[1], q.shape[1], wrench=False)
    scan.add(tau, q)
    return scan.found(tau.shape[0])


def saturated_wrench(wrench: NDArray[np.float64], q: NDArray[np.float64]) -> NDArray[np.bool_]:
    """``(N, 6)`` true where a wrench channel of ``wrench (N, 6)`` (a force plate's or a force/torque sensor's
    ``fx … mz``) is clipped: held at its largest or smallest value as :func:`saturated_samples` asks of a torque
    channel, while any joint of ``q (N, n)`` moves within the run (every joint's motion loads the base); a run where
    every joint holds (the robot at rest, its wrench steady) is left alone."""
    scan = HeldExtremes(wrench.shape[1], q.shape[1], wrench=True)
    scan.add(wrench, q)
    return scan.found(wrench.shape[0])


#: each channel's distinct values are counted exactly up to this many, beyond it estimated from this many smallest
#: of their hashes (a k-minimum-values sketch, relative error about 1 / sqrt of it: 0.4 %); the same count for a
#: record read whole and one streamed in blocks (the smallest hashes of a union are those of its blocks' merged)
DISTINCT_SKETCH = 65536


def value_hashes(values: NDArray[np.float64]) -> NDArray[np.uint64]:
    """The sorted distinct hashes of the finite ``values`` (``-0.0`` as ``0.0``): their 64 bits through the
    bijective finaliser of SplitMix64 (Steele, Lea & Flood 2014), so that distinct values have distinct hashes and
    the hashes are spread evenly over ``[0, 2⁶⁴)``."""
    bits = np.ascontiguousarray(values[np.isfinite(values)] + 0.0, dtype=np.float64).view(np.uint64)
    with np.errstate(over="ignore"):
        z = (bits ^ (bits >> np.uint64(30))) * np.uint64(0xBF58476D1CE4E5B9)
        z = (z ^ (z >> np.uint64(27))) * np.uint64(0x94D049BB133111EB)
        z = z ^ (z >> np.uint64(31))
    return _smallest_distinct(z)


def _smallest_distinct(hashes: NDArray[np.uint64]) -> NDArray[np.uint64]:
    """The :data:`DISTINCT_SKETCH` smallest distinct of ``hashes``, sorted (a sort: ``numpy.unique`` hashes
    64-bit integers about ten times slower)."""
    ordered = np.sort(hashes)
    if ordered.size:
        ordered = ordered[np.r_[True, ordered[1:] != ordered[:-1]]]
    return ordered[:DISTINCT_SKETCH]


def distinct_count(hashes: NDArray[np.uint64]) -> float:
    """The distinct values whose :data:`DISTINCT_SKETCH` smallest hashes are ``hashes`` (exact below it)."""
    if hashes.shape[0] < DISTINCT_SKETCH:
        return float(hashes.shape[0])
    return (DISTINCT_SKETCH - 1) / ((float(hashes[-1]) + 1.0) / 2.0**64)


class HeldExtremes:
    """The samples where each channel of a record is held at its extreme while the robot moves
    (:func:`saturated_samples`, :func:`saturated_wrench`), judged block by block: the same for a record read whole
    and one streamed (its blocks in order, :meth:`add`). For each channel it keeps its finite samples, the smallest
    hashes of its distinct values (:func:`value_hashes`), its lowest and highest values so far, and the rows held at
    them with the positions at each and at its neighbours (a row's next neighbour filled from the next block): memory
    in the rows at the extremes, not in the record's length.

    Parameters
    ----------
    channels, joints
        The channels judged and the joints of the positions.
    wrench
        Whether the channels are a wrench (any joint's motion counts) or torques (channel ``j``: joint ``j``'s).
    """

    def __init__(self, channels: int, joints: int, *, wrench: bool) -> None:
        self.wrench = wrench
        self.rows = 0
        self.finite = np.zeros(channels, dtype=np.int64)
        self.seen: list[NDArray[np.float64] | None] = [np.zeros(0) for _ in range(channels)]  # distinct values,
        # exact while fewer than DISTINCT_SKETCH; then None and the sketch in ``hashes``
        self.hashes = [np.zeros(0, dtype=np.uint64) for _ in range(channels)]
        width = joints if wrench else 1
        # per channel and side (0: lowest, 1: highest): the value, the rows at it, positions before, at and after
        self.value = np.full((channels, 2), np.nan)
        self.held = [[np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64)] for _ in range(channels)]
        self.around = [[np.zeros((0, 3, width)), np.zeros((0, 3, width))] for _ in range(channels)]
        self.stamps = [[np.zeros(0), np.zeros(0)] for _ in range(channels)]  # the time stamps of the rows held
        self.last_q: NDArray[np.float64] | None = None  # the block before's last row of positions
        # per channel and side: the rows within PEAK_WINDOW of a row held at the extreme and their values (the
        # signal's trend through each hold, :func:`quantised_peak`), and the last row whose values are still wanted
        self.near_rows = [[np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64)] for _ in range(channels)]
        self.near_values = [[np.zeros(0), np.zeros(0)] for _ in range(channels)]
        self.wanted = np.full((channels, 2), -1, dtype=np.int64)
        self.first_held = np.full((channels, 2), -1, dtype=np.int64)  # the first row held at the extreme
        self.tail = np.zeros((0, channels))  # the last PEAK_WINDOW rows of values before the block

    def _positions(self, q: NDArray[np.float64], channel: int) -> NDArray[np.float64]:
        return q if self.wrench else q[:, channel:channel + 1]

    def add(self, values: NDArray[np.float64], q: NDArray[np.float64], t: NDArray[np.float64] | None = None) -> None:
        """The next block: ``values (m, channels)``, ``q (m, joints)``, stamped ``t (m,)`` (``None``: not kept)."""
        m = values.shape[0]
        if m == 0:
            return
        for channel in range(values.shape[1]):
            column = values[:, channel]
            finite = np.isfinite(column)
            self.finite[channel] += int(finite.sum())
            if not finite.any():
                continue
            self._count_distinct(channel, column[finite])
            positions = self._positions(q, channel)
            before = (np.full((1, positions.shape[1]), np.nan) if self.last_q is None
                      else self._positions(self.last_q, channel))
            padded = np.vstack([before, positions, np.full((1, positions.shape[1]), np.nan)])
            for side, extreme in enumerate((column[finite].min(), column[finite].max())):
                held, around, stamps = self.held[channel][side], self.around[channel][side], self.stamps[channel][side]
                if held.size and np.isnan(around[-1, 2]).all() and held[-1] == self.rows - 1:
                    around[-1, 2] = positions[0]  # the row after the block before's last
                current = self.value[channel, side]
                better = np.isnan(current) or (extreme < current if side == 0 else extreme > current)
                if better:
                    self.value[channel, side] = extreme
                    held, around, stamps = np.zeros(0, dtype=np.int64), np.zeros((0, 3, positions.shape[1])), np.zeros(0)
                at = np.flatnonzero(column == self.value[channel, side])
                if at.size:
                    held = np.concatenate([held, self.rows + at])
                    around = np.concatenate([around, np.stack([padded[at], padded[at + 1], padded[at + 2]], axis=1)])
                    stamps = np.concatenate([stamps, np.full(at.size, np.nan) if t is None else t[at]])
                self.held[channel][side], self.around[channel][side], self.stamps[channel][side] = held, around, stamps
                self._keep_near(channel, side, column, at, better)
        self.tail = np.vstack([self.tail, values])[-PEAK_WINDOW:].copy()
        self.last_q = q[-1:].copy()
        self.rows += m

    def _keep_near(self, channel: int, side: int, column: NDArray[np.float64], at: NDArray[np.int64],
                   better: bool) -> None:
        """The values of ``channel`` within :data:`PEAK_WINDOW` rows of its rows held at ``side``'s extreme: the
        block's ``column`` (held at its rows ``at``) with the block before's last rows; forgotten when the extreme
        moved (``better``)."""
        if better:
            self.near_rows[channel][side] = np.zeros(0, dtype=np.int64)
            self.near_values[channel][side] = np.zeros(0)
            self.wanted[channel, side] = -1
            self.first_held[channel, side] = -1
        if at.size:  # the holds judged: within PEAK_SPAN rows of the first (a periodic record's every period not kept)
            if self.first_held[channel, side] < 0:
                self.first_held[channel, side] = self.rows + int(at[0])
            at = at[self.rows + at <= self.first_held[channel, side] + PEAK_SPAN]
        if not at.size and self.wanted[channel, side] < self.rows:
            return  # no hold in the block nor just before it
        before = self.tail[:, channel]
        values = np.concatenate([before, column])
        rows = np.arange(self.rows - before.size, self.rows + column.size)
        marks = np.zeros(values.size + 2 * PEAK_WINDOW + 1, dtype=np.int64)
        marks[at + before.size] = 1
        counted = np.cumsum(marks)  # held rows at or before each position (and PEAK_WINDOW past the end)
        start = np.maximum(np.arange(values.size) - PEAK_WINDOW - 1, -1)
        ahead = counted[np.arange(values.size) + PEAK_WINDOW]
        near = (ahead - np.where(start >= 0, counted[np.maximum(start, 0)], 0)) > 0
        near |= rows <= self.wanted[channel, side]
        if at.size:
            self.wanted[channel, side] = max(self.wanted[channel, side], self.rows + int(at[-1]) + PEAK_WINDOW)
        if not near.any():
            return
        kept_rows = np.concatenate([self.near_rows[channel][side], rows[near]])
        kept_values = np.concatenate([self.near_values[channel][side], values[near]])
        kept_rows, first = np.unique(kept_rows, return_index=True)
        self.near_rows[channel][side], self.near_values[channel][side] = kept_rows, kept_values[first]

    def _count_distinct(self, channel: int, values: NDArray[np.float64]) -> None:
        """The block's finite ``values`` of ``channel`` into its distinct values: kept exactly while fewer than
        :data:`DISTINCT_SKETCH` (a sort of floats), then as the sketch of their hashes (:func:`value_hashes`)."""
        seen = self.seen[channel]
        if seen is not None:
            seen = np.unique(np.concatenate([seen, values + 0.0]))
            if seen.size < DISTINCT_SKETCH:
                self.seen[channel] = seen
                return
            self.seen[channel], values = None, seen
        kept, new = self.hashes[channel], value_hashes(values)
        if kept.size == DISTINCT_SKETCH:  # a full sketch takes only hashes below its largest
            new = new[new < kept[-1]]
        if new.size:
            self.hashes[channel] = new if not kept.size else _smallest_distinct(np.concatenate([kept, new]))

    def distinct(self, channel: int) -> float:
        """The distinct values of ``channel`` so far: exact below :data:`DISTINCT_SKETCH`, else estimated."""
        seen = self.seen[channel]
        return float(seen.size) if seen is not None else distinct_count(self.hashes[channel])

    def clipped_rows(self) -> list[NDArray[np.int64]]:
        """Per channel, the rows held at a sensor's limit (sorted)."""
        found = []
        for channel in range(len(self.seen)):
            distinct = self.distinct(channel)
            rows = []
            typical = self.finite[channel] / distinct if distinct else np.inf
            for side in (0, 1):
                held, around = self.held[channel][side], self.around[channel][side]
                if (self.finite[channel] < SATURATION_LEAST or distinct < 2 or held.size < SATURATION_LEAST
                        or held.size <= SATURATION_FACTOR * typical):
                    continue
                moving = _moving_runs(held, around)
                if moving.size and quantised_peak(moving, self.value[channel, side], side,
                                                  self.near_rows[channel][side], self.near_values[channel][side]):
                    continue
                rows.append(moving)
            found.append(np.unique(np.concatenate(rows)) if rows else np.zeros(0, dtype=np.int64))
        return found

    def described(self) -> list[tuple[int, float, int, float, float]]:
        """Per channel with clipped rows: ``(channel, value at its first clipped row, rows, first and last time
        stamp)`` (the stamps given to :meth:`add`)."""
        said = []
        for channel, rows in enumerate(self.clipped_rows()):
            if not rows.size:
                continue
            where = [(side, np.searchsorted(self.held[channel][side], row)) for row in (rows[0], rows[-1])
                     for side in (0, 1) if row in self.held[channel][side]]
            (side, first), (last_side, last) = where[0], where[-1]
            said.append((channel, float(self.value[channel, side]), int(rows.size),
                         float(self.stamps[channel][side][first]), float(self.stamps[channel][last_side][last])))
        return said

    def found(self, rows: int) -> NDArray[np.bool_]:
        """``(rows, channels)`` true at the clipped samples (:meth:`clipped_rows`)."""
        mask = np.zeros((rows, len(self.seen)), dtype=bool)
        for channel, held in enumerate(self.clipped_rows()):
            mask[held, channel] = True
        return mask


def _moving_runs(held: NDArray[np.int64], around: NDArray[np.float64]) -> NDArray[np.int64]:
    """The rows of ``held`` (sorted rows at a channel's extreme; ``around (k, 3, w)``: the positions at the row
    before, at and after each, NaN beyond the record) on runs where a position changes: within a run of two rows or
    more, between the neighbours of a lone row."""
    if held.size == 0:
        return held
    breaks = np.flatnonzero(np.diff(held) != 1) + 1
    kept = []
    for start, stop in zip(np.r_[0, breaks], np.r_[breaks, held.size]):
        block = around[start:stop, 1] if stop - start >= 2 else around[start]
        with np.errstate(invalid="ignore"):
            spread = np.nanmax(block, axis=0) - np.nanmin(block, axis=0)
        if np.any(spread > 0):
            kept.append(held[start:stop])
    return np.concatenate(kept) if kept else np.zeros(0, dtype=np.int64)


def quantised_peak(held: NDArray[np.int64], value: float, side: int, rows: NDArray[np.int64],
                   values: NDArray[np.float64]) -> bool:
    """Whether a channel's extreme ``value`` (``side`` 0: its lowest, 1: its highest), held at ``held`` (sorted
    rows), is a quantised signal's peak and not a sensor's limit; ``rows``, ``values``: the channel's samples around
    the holds (within :data:`PEAK_WINDOW`).

    A clip cuts the signal: the signal approaches the limit with a slope and would go past it, so its trend through
    the samples on both sides of the hold passes beyond the held value, and it reaches the limit again and again. A
    quantised signal's smooth peak is held because the signal's slope vanishes there: the hold is one level of the
    channel's quantum among others, the samples on both sides step away from it by whole quanta, and their trend
    (a parabola fitted by least squares on ``L / 2`` samples on each side of a hold of ``L`` samples, at least
    :data:`PEAK_WINDOW_LEAST`, widened until each side holds :data:`PEAK_LEVELS` ``- 1`` levels, at most
    :data:`PEAK_WINDOW`) stays within one quantum of the held value over the
    hold (the true peak lies within half a quantum of the level it was rounded to). Holds closer than
    :data:`PEAK_WINDOW_LEAST` rows are one hold (a reading flickering at a level's edge).

    A quantised peak is said only when every hold with samples on both sides is one: the values around it lie on
    the held value's grid (its quantum the step to the nearest other value there; at least :data:`PEAK_LEVELS`
    levels), no other sample there is at the held value, and the trend exceeds it by at most a quantum. A clip that
    cuts less than a quantum off the signal is read as the quantisation it is indistinguishable from (the error
    it leaves is under a quantum)."""
    breaks = np.flatnonzero(np.diff(held) > PEAK_WINDOW_LEAST) + 1
    sign = 1.0 if side == 1 else -1.0
    judged = 0
    for start, stop in zip(np.r_[0, breaks], np.r_[breaks, held.size]):
        first, last = int(held[start]), int(held[stop - 1])
        width = int(np.clip((last - first + 1) // 2, PEAK_WINDOW_LEAST, PEAK_WINDOW))
        while True:  # widened until the samples on each side step PEAK_LEVELS - 1 levels away (a flat peak)
            before = (rows >= first - width) & (rows < first)
            after = (rows > last) & (rows <= last + width)
            window = before | after
            around = values[window]
            if not np.all(np.isfinite(around)) or np.any(around == value):
                return False  # the limit reached again, or a sample unread: not a lone peak
            sides = [np.unique(values[part]).size for part in (before, after)]
            if min(sides) >= PEAK_LEVELS - 1 or width == PEAK_WINDOW:
                break
            width = min(2 * width, PEAK_WINDOW)
        if before.sum() < PEAK_LEVELS or after.sum() < PEAK_LEVELS:
            continue  # at the record's edge: no trend on one side, nothing said by this hold
        judged += 1
        steps = sign * (value - around)  # > 0: every value lies inside the extreme
        quantum = float(steps.min())
        levels = steps / quantum
        if (np.max(np.abs(levels - np.round(levels))) > PEAK_GRID_TOLERANCE
                or np.unique(np.round(levels)).size + 1 < PEAK_LEVELS):
            return False  # not one quantum's levels: a held value on an unquantised signal is a limit
        x = rows[window].astype(np.float64)
        centre, scale = 0.5 * (first + last), max(0.5 * (last - first), 1.0) + width
        trend = np.polynomial.polynomial.polyfit((x - centre) / scale, around, 2)
        over = np.polynomial.polynomial.polyval((np.arange(first, last + 1) - centre) / scale, trend)
        if sign * (over - value).max() > quantum:
            return False
    return judged > 0


def repeated_rows(data: NDArray[np.float64]) -> NDArray[np.bool_]:
    """``(N,)`` true where every column of ``data (N, k)`` equals the previous row's (a re-sent packet)."""
    repeated = np.zeros(data.shape[0], dtype=bool)
    if data.shape[0] > 1:
        repeated[1:] = np.all(data[1:] == data[:-1], axis=1)
    return repeated


def missing_samples(t: NDArray[np.float64], row: int, step: float) -> float:
    """Samples missing around the long step after ``row``: the time spanned by a window around it
    over the local median step, minus the samples there. A logger that stalls and then delivers its
    backlog has a long step but none missing (jitter, resampled); a hole in the record has many."""
    reach = int(2 * (t[row + 1] - t[row]) / step) + 20
    first, last = max(row - reach, 0), min(row + 1 + reach, t.shape[0] - 1)
    around = np.delete(np.diff(t[first:last + 1]), row - first)
    local = float(np.median(around)) if around.size else step
    return float((t[last] - t[first]) / local - (last - first))


def find_gaps(t: NDArray[np.float64], step: float) -> list[Gap]:
    """Steps longer than :data:`STALL_FACTOR` median steps that leave at least half a sample missing
    (counted by the local median step, :func:`missing_samples`: a stall whose backlog arrives in a
    burst leaves none)."""
    steps = np.diff(t)
    gaps = []
    for row in np.flatnonzero(steps > STALL_FACTOR * step):
        missing = missing_samples(t, int(row), step)
        if missing >= 0.5:
            gaps.append(Gap(int(row), float(t[row]), float(steps[row]), float(steps[row] / step - 1)))
    return gaps


def time_stamps_jump(t_recorded: NDArray[np.float64], start: float, stop: float, step: float) -> bool:
    """Whether the recorded time stamps ``t_recorded`` (before any row was dropped) leave a step longer than
    :data:`STALL_FACTOR` median steps ``step`` between the times ``start`` and ``stop``: a gap of the logger,
    not rows dropped as repeated (a robot at rest)."""
    first, last = np.searchsorted(t_recorded, [start, stop], side="left")
    inside = t_recorded[first:min(last + 1, t_recorded.shape[0])]
    return inside.shape[0] < 2 or bool(np.max(np.diff(inside)) > STALL_FACTOR * step)


def split_rows(n_samples: int, holes: list[Gap]) -> list[slice]:
    """The row ranges between holes."""
    starts = [0] + [gap.row + 1 for gap in holes]
    stops = [gap.row + 1 for gap in holes] + [n_samples]
    return [slice(start, stop) for start, stop in zip(starts, stops)]


def describe(gaps: list[Gap], limit: int = 4) -> str:
    """``t = 1.234 s (8.5 ms, 7 samples), …`` for a message."""
    shown = ", ".join(f"t = {gap.t:.6g} s ({_duration(gap.duration)}, {gap.missing:.0f} sample(s))" for gap in gaps[:limit])
    return shown + (f" and {len(gaps) - limit} more" if len(gaps) > limit else "")


def _duration(seconds: float) -> str:
    return f"{1e3 * seconds:.3g} ms" if seconds < 0.1 else f"{seconds:.4g} s"
