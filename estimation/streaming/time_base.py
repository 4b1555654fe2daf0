"""The time base of a streamed file: one scan of its rows, then resampling chunk by chunk.

The in-memory loader (:func:`estimation.data.records.segments_from_frame`) drops a logger's dropouts (rows whose data
cells are all empty), re-sent rows and a few
rows stamped with the previous row's time, checks the time base, bridges stalls up to ``max_gap`` and resamples an
irregular time base (jitter, as in the KUKA logs: steps of 3.4–6.5 ms around 5 ms; stalls; rows dropped) by linear
interpolation onto ``t_0 + k·h``, ``h`` the median step of the rows kept
(:func:`estimation.data.loading.resampling_grid`). A streamed file gets the same rows and the same grid, with the same
warnings: :func:`scan_time` reads the file block by block once, keeping column ``t`` and whether each row repeats the
one before on every channel (9 bytes a row: the exact median needs every step), and hands them to the loader's own
rule (:func:`estimation.data.records.clean_time_base`); :class:`Resampler` then interpolates each chunk of the rows
kept onto the grid points it spans, carrying the last sample of the chunk before so that a grid point between two
chunks is interpolated between the same two samples as in memory.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from dynamics.channels import WRENCH_CHANNELS
from dynamics.measurements import joint_columns
from dynamics.models import IdentificationModel
from dynamics.runtime.memory import check_allocation
from estimation.data.loading import SegmentTooShortError, column_floats, resampling_grid
from estimation.data.log_cleaning import (DEFAULT_MAX_GAP, GLITCH_RUN, PositionSteps, position_steps, repeated_rows,
                                          split_rows)
from estimation.data.held_channels import MASKED_GROUPS, HeldChannels, held_rows
from estimation.data.records import (clean_time_base, dropouts, glitch_rows, said_dropouts, said_glitches, said_held,
                                     velocity_limits)
from estimation.data.rest import between_holds, held_runs
from estimation.data.sampling_clock import clock_instants, regular_clock_line

__all__ = ["HeldParts", "NoRegularClockError", "Part", "RegularClock", "Resampler", "TimeScan", "file_parts", "file_segments", "scan_time"]


@dataclass(frozen=True)
class Part:
    """The ``index``-th part (1-based) of a training file cut at its holes and at its holds (every joint's position
    unchanged for longer than ``max_gap``, :func:`estimation.data.rest.holds`), as the in-memory path cuts a training
    record (:func:`estimation.identification.prepared.training_without_holds`)."""

    index: int


@dataclass(frozen=True)
class RegularClock:
    """A file (``of`` ``None``) or its ``of``-th segment (1-based) read on the regular clock its stamps jitter around
    (:func:`estimation.data.sampling_clock.regular_clock`, the least-squares line of the kept rows' stamps on their
    index) instead of resampled by the stamps: each kept row keeps its values, its instant on the clock, as memory's
    :func:`~estimation.data.sampling_clock.on_regular_clock` places a segment's recorded samples
    (:mod:`estimation.identification.time_base_choice`: a logger's receive times). A file whose stamps need no
    resampling is read as it is, as in memory."""

    of: int | None = None


class NoRegularClockError(ValueError):
    """A source's stamps give no regular clock (a stamp half a step or more from it: a row dropped or a stall)."""


@dataclass(frozen=True)
class HeldParts:
    """A file's parts between its holes and holds (:func:`file_parts`): their rows among the rows the loader keeps,
    the rows kept, and those left out at the holds."""

    parts: tuple[NDArray[np.int64], ...]
    rows: int
    dropped: int


@dataclass(frozen=True)
class TimeScan:
    """What one pass over a file's rows says: the rows kept, the first and last time kept, the grid's step, the
    samples kept, and whether they are resampled."""

    t0: float
    t_last: float
    step: float
    rows: int
    keep: NDArray[np.bool_] | None = None
    resampled: bool = False
    clock: tuple[float, float, int] | None = None  # ``(t0, step, first)``: the rows kept on the regular clock
    # ``t0 + step * k`` of a time column as coarse as the samples' step (``k`` from ``first`` for the rows scanned;
    # :attr:`estimation.data.records.CleanedTimes.clock`): each block's instants are taken from it
    #: a measured channel's held repeats among the rows kept (``(group, (rows,) bool)`` for ``tau``, ``wrench``:
    #: masked in that channel only, as in memory), ``None`` when none repeats
    held: tuple[tuple[str, NDArray[np.bool_]], ...] | None = None

    @property
    def irregular(self) -> bool:
        """The loader resamples the rows kept onto a uniform grid."""
        return self.resampled

    @property
    def grid_count(self) -> int:
        """Samples of the uniform grid (as :func:`estimation.data.loading.resampling_grid` makes it)."""
        return int(np.floor((self.t_last - self.t0) / self.step + 1e-9)) + 1


def scan_time(frames, path: str | Path, model: IdentificationModel, *, max_gap: float = DEFAULT_MAX_GAP,
              segment: int | Part | RegularClock | None = None) -> TimeScan | None:
    """Scan the rows of ``frames`` (an iterator of the file's blocks) with the loader's rules on the whole record
    (module docstring; :class:`~estimation.data.loading.TimeBaseError`: many duplicated or decreasing times). A hole
    longer than ``max_gap`` splits the record into segments as in memory: ``segment`` (1-based) is the one scanned
    (its rows alone kept, its own grid); without one, a hole is a :class:`~estimation.data.loading.HoleError`
    (:func:`file_segments` names the segments); a :class:`RegularClock`: the file or segment it names, its kept
    rows on their regular clock where the loader would resample them (:class:`NoRegularClockError` when there is
    none). ``None`` when column ``t`` is absent or not numeric (the per-chunk checks then name the fault)."""
    on_clock = isinstance(segment, RegularClock)
    if on_clock:
        segment = segment.of
    positions: list[NDArray[np.uint64]] = []
    cells: list[dict[str, NDArray[np.bool_]]] = []
    times = _cleaned(frames, path, model, max_gap=max_gap, split=segment is not None, positions=positions,
                     held_cells=cells)
    if times is None:
        return None
    scan = _scanned(times, positions, path, segment, on_clock, max_gap)
    if scan is None or not cells:
        return scan
    keep = np.ones(next(iter(cells[0].values())).shape[0], dtype=bool) if scan.keep is None else scan.keep
    held = tuple((group, rows[keep]) for group, rows in cells[0].items() if rows[keep].any())
    return replace(scan, held=held or None)


def _scanned(times, positions: list[NDArray[np.uint64]], path: str | Path, segment, on_clock: bool, max_gap: float
             ) -> TimeScan:
    """The :class:`TimeScan` of the rows ``times`` keeps (:func:`scan_time`)."""
    keep, kept, name, first = times.keep, times.t, str(path), 0
    if isinstance(segment, Part):  # a training file's part between its holes and holds
        found = _held_parts(times, positions, max_gap)
        if found is None or not 1 <= segment.index <= len(found.parts):
            raise ValueError(f"{path} holds {0 if found is None else len(found.parts)} part(s) between its holds, "
                             f"not a part {segment.index}")
        rows = np.flatnonzero(keep)[found.parts[segment.index - 1]]
        keep = np.zeros_like(keep)
        keep[rows] = True
        first = int(np.arange(kept.shape[0])[found.parts[segment.index - 1]][0])
        kept = kept[found.parts[segment.index - 1]]
        name = f"{path} (part {segment.index})"
        if kept.shape[0] < 3:
            raise SegmentTooShortError(f"{name}: {kept.shape[0]} sample(s) between holds (t = {kept[0]:.6g} s): "
                                       "too few for a time series; cut them from the file")
    elif segment is not None:
        pieces = split_rows(kept.shape[0], times.holes)
        if not 1 <= segment <= len(pieces):
            raise ValueError(f"{path} holds {len(pieces)} segment(s), not a segment {segment}")
        rows = np.flatnonzero(keep)[pieces[segment - 1]]
        keep = np.zeros_like(keep)
        keep[rows] = True
        first = int(np.arange(kept.shape[0])[pieces[segment - 1]][0])
        kept = kept[pieces[segment - 1]]
        if times.holes:
            name = f"{path} (segment {segment})"
            if kept.shape[0] < 3:
                raise SegmentTooShortError(f"{name}: {kept.shape[0]} sample(s) between holes (t = {kept[0]:.6g} s): "
                                           "too few for a time series; cut them from the file")
    grid = resampling_grid(kept, True, name, bridged=times.bridged, stacklevel=4)
    keep = None if keep.all() else keep
    clock = None if times.clock is None else (*times.clock, first)
    if on_clock and grid is not None:  # the kept rows on the regular clock of their stamps, none resampled
        line = regular_clock_line(kept)
        if line is None:
            raise NoRegularClockError(f"{name}: its stamps give no regular clock (a stamp half a step or more from "
                                      "it: a row dropped or a stall)")
        t0, step = line
        return TimeScan(t0, float(clock_instants(t0, step, kept.shape[0] - 1, 1)[0]), step, int(kept.shape[0]), keep,
                        clock=(t0, step, 0))
    if grid is None:
        return TimeScan(float(kept[0]), float(kept[-1]), float(np.median(np.diff(kept))), int(kept.shape[0]), keep,
                        clock=clock)
    step = float(kept[-1] - kept[0]) / (grid.shape[0] - 1)
    return TimeScan(float(kept[0]), float(kept[-1]), step, int(kept.shape[0]), keep, resampled=True)


def file_segments(frames, path: str | Path, model: IdentificationModel, *, max_gap: float = DEFAULT_MAX_GAP) -> int:
    """The segments the loader splits the file of ``frames`` into (its holes longer than ``max_gap``, one more);
    1 when its time column cannot be read (the per-chunk checks name the fault)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # said when each segment is read
        times = _cleaned(frames, path, model, max_gap=max_gap, split=True)
    return 1 if times is None else len(times.holes) + 1


def file_parts(frames, path: str | Path, model: IdentificationModel, *,
               max_gap: float = DEFAULT_MAX_GAP) -> HeldParts | None:
    """The parts of the file of ``frames`` between its holes and its holds longer than ``max_gap`` (the in-memory
    training record's segments, :func:`estimation.identification.prepared.training_without_holds`): one pass keeping
    the time and a 64-bit fingerprint of each row's positions (16 bytes a row, as the time scan's 9); ``None`` when
    its time column cannot be read or it holds no hold."""
    positions: list[NDArray[np.uint64]] = []
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # said when each part is read
        times = _cleaned(frames, path, model, max_gap=max_gap, split=True, positions=positions)
    return None if times is None else _held_parts(times, positions, max_gap)


def _held_parts(times, positions: list[NDArray[np.uint64]], max_gap: float) -> HeldParts | None:
    """The parts between the holes and holds of the rows ``times`` keeps (``positions``: their fingerprints, the
    one item :func:`_cleaned` appended); ``None`` without a hold (or without positions)."""
    if not positions or positions[0].shape[0] != times.t.shape[0]:
        return None
    prints, parts, held = positions[0], [], False
    for piece in split_rows(times.t.shape[0], times.holes):
        rows = np.arange(times.t.shape[0])[piece]
        same = np.r_[False, prints[rows][1:] == prints[rows][:-1]]
        found = held_runs(times.t[rows], same, max_gap)
        held = held or bool(found)
        parts.extend(rows[between] for between in between_holds(rows.shape[0], found))
    if not held:
        return None
    kept = sum(part.shape[0] for part in parts)
    return HeldParts(tuple(parts), times.t.shape[0], times.t.shape[0] - kept)


def _fingerprints(q: NDArray[np.float64]) -> NDArray[np.uint64]:
    """A 64-bit fingerprint of each row of positions: equal rows give equal fingerprints (``-0.0`` as ``0.0``),
    different ones differ but with probability about 2⁻⁶⁴ (the bits of each joint's value times an odd constant of
    its own, summed modulo 2⁶⁴)."""
    bits = np.ascontiguousarray(q + 0.0, dtype=np.float64).view(np.uint64)
    odd = (np.uint64(0x9E3779B97F4A7C15) * (2 * np.arange(1, q.shape[1] + 1, dtype=np.uint64) + np.uint64(1))
           | np.uint64(1))
    with np.errstate(over="ignore"):
        mixed = bits * odd
        return (mixed ^ (mixed >> np.uint64(29))).sum(axis=1, dtype=np.uint64)


def _cleaned(frames, path: str | Path, model: IdentificationModel, *, max_gap: float, split: bool,
             positions: list[NDArray[np.uint64]] | None = None, held_cells: list | None = None):
    """The rows the loader keeps of the file of ``frames`` (:func:`estimation.data.records.clean_time_base`), or
    ``None`` when its time column cannot be read. ``positions``: a list the fingerprints of the kept rows' positions
    are appended to (:func:`_fingerprints`; nothing when the file has no positions). ``held_cells``: a list the
    measured channels' held repeats are appended to (one ``{group: (rows,) bool}`` over the file's rows, when a
    measured channel repeats: masked in that channel, as in memory, their rows kept)."""
    prints: list[NDArray[np.uint64]] = []
    parts: list[NDArray[np.float64]] = []
    repeated: list[NDArray[np.bool_]] = []
    present: list[NDArray[np.bool_]] = []  # the rows not dropouts (:func:`estimation.data.records.dropouts`)
    first_blank: tuple[int, object] | None = None  # the first dropout's row and time stamp
    previous: NDArray[np.float64] | None = None
    steps: PositionSteps | None = None  # the position steps so far (encoder read errors: judged on the whole record)
    count, n_joints = 0, model.robot.n_joints
    blanks, repeats, holds, last_row = 0, 0, dict[str, int](), None  # dropouts, held repeats (:func:`held_rows`)
    masked_repeats, masked_count = {group: [] for group in MASKED_GROUPS}, 0  # a measured channel's repeats
    carry_q, carry_t, judged = np.zeros((0, n_joints)), np.zeros(0), 0  # the last rows read (a run's and the row
    # before it: GLITCH_RUN + 1); rows judged
    for frame in frames:
        frame = frame.rename(columns=lambda name: str(name).strip())
        if "t" not in frame.columns:
            return None
        blank = dropouts(frame, n_joints)
        if blank.any() and first_blank is None:  # said once for the file, after the scan
            first = int(np.flatnonzero(blank)[0])
            first_blank = (sum(part.shape[0] for part in present) + first, frame["t"].iloc[first])
        blanks += int(np.count_nonzero(blank))
        held = held_rows(frame, n_joints, before=last_row)  # a lower-rate channel's repeats: an input channel's rows
        # dropped, a measured channel's repeats masked in that channel only (their rows kept), as in memory
        last_row = frame.iloc[-1:] if len(frame) else last_row
        for group in MASKED_GROUPS:
            masked_repeats[group].append(held.group_rows((group,)) if held.holds else np.zeros(len(frame), bool))
        if held.holds:
            holds.update(held.holds)
            dropped = held.dropped_rows
            repeats += int(np.count_nonzero(dropped & ~blank))
            masked_count += int(np.count_nonzero(held.group_rows(MASKED_GROUPS) & ~blank & ~dropped))
            blank = blank | dropped
        present.append(~blank)
        frame = frame[~blank]
        t = column_floats(frame["t"])
        columns = [column for group in ("q", "dq", "ddq", "tau", "wrench")
                   for column in [_columns(group, n_joints)] if all(name in frame.columns for name in column)]
        data = np.column_stack([column_floats(frame[name]) for column in columns for name in column]) if columns \
            else np.zeros((len(frame), 0))
        count += t.shape[0]
        check_allocation(8.0 * (3 if positions is None else 5) * count, f"the time column of {path} ({count} samples)")
        parts.append(t)
        if columns and columns[0] == _columns("q", n_joints):
            if positions is not None:
                prints.append(_fingerprints(data[:, :n_joints]))
            block = position_steps(np.vstack([carry_q, data[:, :n_joints]]), np.concatenate([carry_t, t]),
                                   velocity_limits(model, n_joints), first_row=count - t.shape[0], carried=carry_t.shape[0])
            steps = block if steps is None else steps.merged(block)
            judged += t.shape[0]
            carry_q = np.vstack([carry_q, data[:, :n_joints]])[-(GLITCH_RUN + 1):]
            carry_t = np.concatenate([carry_t, t])[-(GLITCH_RUN + 1):]
            check_allocation(24.0 * steps.rows.shape[0], f"the steps of {path}'s positions")
        if previous is not None and previous.shape[1] == data.shape[1] and data.shape[0]:
            data = np.vstack([previous, data])
            repeated.append(repeated_rows(data)[1:])
        else:
            repeated.append(repeated_rows(data))
        previous = data[-1:] if data.shape[0] else previous
    if not parts:
        return None
    t = np.concatenate(parts)
    if t.shape[0] < 2 or not np.all(np.isfinite(t)):
        return None
    same = np.concatenate(repeated)
    if same.shape[0] != t.shape[0]:  # the channels change between blocks: the per-chunk checks name it
        return None
    rows = np.concatenate(present)
    if first_blank is not None:
        said_dropouts(blanks, *first_blank, str(path))
    if holds:
        said_held(HeldChannels(~rows, tuple(holds.items())), repeats, masked_count, rows.shape[0], str(path))
        if held_cells is not None and masked_count:
            held_cells.append({group: np.concatenate(parts) for group, parts in masked_repeats.items()
                               if parts and np.any([part.any() for part in parts])})
    found = glitch_rows(steps, model, n_joints) if steps is not None and judged == t.shape[0] else None
    glitched = None  # said once the time base holds, as in memory
    if found is not None and found[0].size:  # encoder read errors: dropouts, as in memory
        glitched = (np.flatnonzero(rows)[found[0]], found[1], t[found[0]])
        kept = np.ones(t.shape[0], dtype=bool)
        kept[found[0]] = False
        t, same = t[kept], same[kept]
        if positions is not None and prints and sum(part.shape[0] for part in prints) == kept.shape[0]:
            prints = [np.concatenate(prints)[kept]]
        rows[np.flatnonzero(rows)[found[0]]] = False
    times = clean_time_base(t, same, str(path), max_gap=max_gap, split=split)
    if glitched is not None:
        said_glitches(*glitched, model, str(path))
    if positions is not None and prints and sum(part.shape[0] for part in prints) == t.shape[0]:
        positions.append(np.concatenate(prints)[times.keep])
    if rows.all():
        return times
    keep = np.zeros(rows.shape[0], dtype=bool)
    keep[np.flatnonzero(rows)[times.keep]] = True
    return replace(times, keep=keep)


def _columns(group: str, n_joints: int) -> list[str]:
    return list(WRENCH_CHANNELS) if group == "wrench" else joint_columns(group, n_joints)


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
