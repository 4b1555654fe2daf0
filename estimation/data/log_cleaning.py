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
  others not is no dropout, and stays an error.
* **Lost frames written as zeros.** A fieldbus logger that misses a frame may write the row with every value ``0``
  (:func:`zero_rows`): on a robot of two joints or more, every position and torque exactly zero at once is no
  measurement (the torque sensors' noise alone forbids it), so such a row is a dropout like a blank one. Rows
  without torques are not judged: a planned trajectory may start at the zero pose.

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
