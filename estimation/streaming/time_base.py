"""The time base of a streamed file: one scan of column ``t``, then resampling chunk by chunk.

The in-memory loader (:func:`estimation.data.records.read_measurements`) resamples an irregular time
base (jitter, as in the KUKA logs: steps of 3.4–6.5 ms around 5 ms) by linear interpolation onto
``t_0 + k·h``, ``h`` the median step of the whole record. A streamed file gets the same grid:
:func:`scan_time` reads column ``t`` alone first (8 bytes a sample: the exact median needs every
step), and :class:`Resampler` interpolates each chunk onto the grid points it spans, carrying the
last sample of the chunk before so that a grid point between two chunks is interpolated between
the same two samples as in memory.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd
from numpy.typing import NDArray

from dynamics.runtime.memory import check_allocation
from estimation.data.loading import IRREGULAR_TOLERANCE, check_time

__all__ = ["Resampler", "TimeScan", "scan_time"]


@dataclass(frozen=True)
class TimeScan:
    """What one pass over column ``t`` says: first and last time, median step, spread, rows."""

    t0: float
    t_last: float
    step: float
    spread: float
    rows: int

    @property
    def irregular(self) -> bool:
        """The loader would resample (largest deviation from the median step above its tolerance)."""
        return self.spread > IRREGULAR_TOLERANCE

    @property
    def grid_count(self) -> int:
        """Samples of the uniform grid (as :func:`estimation.data.records.read_measurements` makes it)."""
        return int(np.floor((self.t_last - self.t0) / self.step + 1e-9)) + 1


def scan_time(frames, path: str | Path) -> TimeScan | None:
    """Scan the ``t`` column of ``frames`` (an iterator of one-column frames) with the loader's time
    checks on the whole record (:class:`~estimation.data.loading.TimeBaseError`: duplicated or decreasing
    times, a gap); ``None`` when the column is absent or not numeric (the per-chunk checks then name
    the fault)."""
    parts: list[NDArray[np.float64]] = []
    count = 0
    for frame in frames:
        frame = frame.rename(columns=lambda name: str(name).strip())
        if "t" not in frame.columns:
            return None
        t = pd.to_numeric(frame["t"], errors="coerce").to_numpy(dtype=float)
        count += t.shape[0]
        check_allocation(8.0 * 3 * count, f"the time column of {path} ({count} samples)")
        parts.append(t)
    if not parts:
        return None
    t = np.concatenate(parts)
    if t.shape[0] < 2 or not np.all(np.isfinite(t)):
        return None
    check_time(t, str(path))  # the loader's checks on the whole record: duplicates, order, unit, gaps
    steps = np.diff(t)
    step = float(np.median(steps))
    spread = float(np.max(np.abs(steps - step))) / step
    if spread > IRREGULAR_TOLERANCE:  # the loader's grid: a whole number of steps spans the record
        step = float(t[-1] - t[0]) / max(int(round((t[-1] - t[0]) / step)), 1)
    return TimeScan(float(t[0]), float(t[-1]), step, spread, int(t.shape[0]))


class Resampler:
    """Linear interpolation of successive chunks onto the grid of a :class:`TimeScan`."""

    def __init__(self, scan: TimeScan) -> None:
        self.scan = scan
        self.next_index = 0  # first grid point not yet emitted
        self._carry_t: NDArray[np.float64] | None = None
        self._carry_values: NDArray[np.float64] | None = None

    def __call__(self, t: NDArray[np.float64], values: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """The grid times within ``[carried sample, t[-1]]`` not yet emitted, and ``values`` (rows:
        samples) interpolated there."""
        if self._carry_t is not None:
            t = np.concatenate([self._carry_t, t])
            values = np.vstack([self._carry_values, values])
        last = min(int(np.floor((t[-1] - self.scan.t0) / self.scan.step + 1e-9)), self.scan.grid_count - 1)
        grid = self.scan.t0 + self.scan.step * np.arange(self.next_index, last + 1)
        self.next_index = max(self.next_index, last + 1)
        self._carry_t, self._carry_values = t[-1:], values[-1:]
        return grid, np.column_stack([np.interp(grid, t, column) for column in values.T]) if grid.size else \
            np.empty((0, values.shape[1]))
