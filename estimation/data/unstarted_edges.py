"""A record's unstarted edges: the rows a logger wrote before every channel had reported, and after one had stopped
(a drive per joint, a topic per sensor, tables merged by time), left out by every reader, whole or block by block.

The in-memory reader (:func:`estimation.data.records.segments_from_frame`) takes the rows before the first row that
holds every data channel and after the last (:func:`estimation.data.log_cleaning.unstarted_rows`) out of the record;
:func:`started_blocks` does the same to a file's blocks as they are read, so the streamed path reads the rows memory
reads: the head is dropped until the first complete row; after it, the rows past a block's last complete row are
held back until a later block holds a complete row (they are then inner rows, handed on: blanks between complete
rows stay the readers' error, dropouts their dropouts) or the file ends (the tail, dropped). Memory: one block and
the rows held back, at most :data:`HELD_BACK_ROWS` (past them the streamed path refuses the file, naming the
in-memory route). Both say what they dropped in one :class:`~estimation.data.loading.UnstartedChannelsWarning`.
"""

from __future__ import annotations

import warnings
from collections.abc import Callable, Iterator

import numpy as np
import pandas as pd

from dynamics.channels import WRENCH_CHANNELS
from dynamics.measurements import joint_columns
from estimation.data.loading import COLUMN_GROUPS, MeasurementError, UnstartedChannelsWarning

#: the most rows after a block's last complete row the streamed reader holds back before it knows whether they are
#: inner rows or the record's tail (a channel stopped this long before the end: read the file in memory)
HELD_BACK_ROWS = 1_000_000


def data_cells(frame: pd.DataFrame, n_joints: int) -> list[str]:
    """The data columns of ``frame`` (``q, dq, ddq, tau``, wrench: those present), as the dropouts' rule reads them."""
    return [column for group in COLUMN_GROUPS
            for column in (list(WRENCH_CHANNELS) if group == "wrench" else joint_columns(group, n_joints))
            if column in frame.columns]


def span(stamps: np.ndarray) -> str:
    """`` (t = a to b)`` of the finite ``stamps`` of rows dropped, ``""`` without one."""
    finite = stamps[np.isfinite(stamps)]
    return f" (t = {np.min(finite):.6g} to {np.max(finite):.6g})" if finite.size else ""


def said_unstarted(head: int, tail: int, head_span: str, tail_span: str, lacking: list[str], source: str, *,
                   stacklevel: int) -> None:
    """The :class:`~estimation.data.loading.UnstartedChannelsWarning` of ``head`` rows dropped at a record's start
    and ``tail`` at its end (``…_span``: :func:`span` of their stamps), ``lacking`` the channels they lacked."""
    said = [f"{head} row(s) at its start{head_span}"] if head else []
    said += [f"{tail} row(s) at its end{tail_span}"] if tail else []
    warnings.warn(
        f"{source}: dropped {' and '.join(said)} where some channels hold no value yet or no longer "
        f"({', '.join(lacking[:8])}{' …' if len(lacking) > 8 else ''}: a logger whose channels start and stop on "
        "their own); the record is the rows where every channel holds a value", UnstartedChannelsWarning,
        stacklevel=stacklevel + 1)


def _stamps(frame: pd.DataFrame) -> np.ndarray:
    if "t" not in frame.columns:
        return np.zeros(0)
    return pd.to_numeric(frame["t"], errors="coerce").to_numpy(dtype=float)


def started_blocks(frames: Iterator[pd.DataFrame], n_joints: int, source: str, *, say: bool = True,
                   dropouts: Callable[[pd.DataFrame], np.ndarray] | None = None) -> Iterator[pd.DataFrame]:
    """``frames`` (a file's blocks in the format's columns) without the record's unstarted edges (the module's
    note), said once at the end when ``say``; blocks without data columns as they are. ``dropouts``: the rows of a
    block the reader drops as dropouts before it looks at the edges (memory's order): handed on, never an edge.

    Raises
    ------
    MeasurementError
        More than :data:`HELD_BACK_ROWS` rows lacking a channel after the last complete row read so far."""
    started, head, tail = False, 0, 0
    head_stamps: list[np.ndarray] = []
    lacking: dict[str, None] = {}
    held: list[pd.DataFrame] = []
    complete_row: pd.DataFrame | None = None  # the last complete row read
    lost_head: list[pd.DataFrame] = []  # dropouts before the first complete row, handed on with it
    ready: pd.DataFrame | None = None  # the last block made, handed on with the next (the tail's dropouts join it)
    for frame in frames:
        cells = data_cells(frame, n_joints)
        if not cells or not len(frame):
            if ready is not None:
                yield ready
                ready = None
            yield frame
            continue
        empty = frame[cells].isna().to_numpy()
        complete = ~empty.any(axis=1)
        if not started:
            first = int(np.argmax(complete)) if complete.any() else len(frame)
            lost = np.zeros(first, dtype=bool) if dropouts is None or not first else \
                np.asarray(dropouts(frame.iloc[:first + 1]))[:first]  # judged beside a complete row, as in memory
            edge = ~lost
            if edge.any():
                head += int(np.count_nonzero(edge))
                head_stamps.append(_stamps(frame.iloc[:first])[edge])
                lacking.update(dict.fromkeys(column for column, missing in zip(cells, empty[:first][edge]
                                                                                .any(axis=0)) if missing))
            if lost.any():
                lost_head.append(frame.iloc[:first][lost])  # dropouts: the reader's
            if first == len(frame):
                continue
            frame, empty, complete, started = frame.iloc[first:], empty[first:], complete[first:], True
            if lost_head:
                frame = pd.concat([*lost_head, frame])
                empty = np.vstack([np.ones((len(frame) - len(complete), len(cells)), dtype=bool), empty])
                complete = np.concatenate([np.zeros(len(frame) - len(complete), dtype=bool), complete])
        if not complete.any():
            held.append(frame)
        else:
            last = int(np.flatnonzero(complete)[-1]) + 1
            out = frame.iloc[:last]
            complete_row = frame.iloc[last - 1:last]
            if ready is not None:
                yield ready
            ready = pd.concat([*held, out]) if held else out
            held = [frame.iloc[last:]] if last < len(frame) else []
        if sum(len(part) for part in held) > HELD_BACK_ROWS:
            raise MeasurementError(
                f"{source}: more than {HELD_BACK_ROWS} rows after its last complete row so far lack a channel's value: "
                "whether they are the record's end (dropped) or inner blanks (an error) is known at the file's end "
                "only; read it in memory (drop the streaming options)")
    if held:
        rest = pd.concat(held)
        lost = np.zeros(len(rest), dtype=bool) if dropouts is None or complete_row is None else \
            np.asarray(dropouts(pd.concat([complete_row, rest])))[1:]  # judged beside a complete row, as in memory
        if lost.any():  # dropouts: the reader's, in the last block as in memory's table
            ready = rest[lost] if ready is None else pd.concat([ready, rest[lost]])
        rest = rest[~lost]
        tail = len(rest)
        cells = data_cells(rest, n_joints)
        lacking.update(dict.fromkeys(column for column, missing in zip(cells, rest[cells].isna().to_numpy()
                                                                        .any(axis=0)) if missing))
    if ready is not None:
        yield ready
    if say and started and (head or tail):
        said_unstarted(head, tail, span(np.concatenate(head_stamps)) if head_stamps else "",
                       span(_stamps(rest)) if tail else "", list(lacking), source, stacklevel=2)
