"""A channel logged at a lower rate than the positions and merged into their table by holding its last value.

A drive's torque channel sampled at half the positions' rate (or a third, a quarter), written into one table
row by row, repeats its last value on the rows between two of its samples (a zero-order hold) rather than leaving
them blank. The repeats are no measurement of their instants: read as samples they lag the channel by half a
hold on average, which the fit and the diagnosis then explain (a delay, shaped friction laws: h-unseen16 measured
the diagnosis's test error at 3.6x identify's on such a log). A blank cell is already read as a lower-rate
channel's missing sample (:func:`estimation.data.records.dropouts`); a held one is read the same once the hold is
told apart from a quantised channel that repeats by chance:

* the channel's values (every column of the group at once: ``tau1..taun``, or the wrench) repeat the previous
  row's exactly on at least :data:`HELD_SHARE` of the rows where the positions moved (a hold of ``k`` rows: a
  share ``(k-1)/k``, a half or more; a quantised channel of several joints repeats on every joint at once only at
  rest);
* its new values come at a regular sub-rate: the rows between two new values are the same count ``k >= 2`` on at
  least :data:`HELD_REGULAR` of them (a quantised channel's repeats come as the signal crosses its levels:
  irregular), over at least :data:`HELD_LEAST` new values.

Then each repeat is a blank cell of that channel, and the first row of each hold, where the value is new, is its
sample. A measured channel's repeats (``tau``, the wrench) are masked in that channel only
(:mod:`estimation.data.channel_mask`: NaN there, their equations dropped), the row kept for the positions and the
other channels at their full rate; an input channel's (``dq``, ``ddq``: no per-channel mask holds them) drop their
rows, as a lower-rate channel's blank cells do (the time without a sample bridged as any gap). The streamed reader
drops every held repeat's row (its fits hold no per-channel mask yet).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd
from numpy.typing import NDArray

from dynamics.channels import WRENCH_CHANNELS
from dynamics.measurements import joint_columns

#: the least share of the rows where the positions moved on which a held channel repeats its previous value
HELD_SHARE = 0.4
#: the least share of the intervals between a held channel's new values equal to its hold (the most common one)
HELD_REGULAR = 0.8
#: the fewest new values of a channel that make its hold judged
HELD_LEAST = 20
#: the groups judged (the positions are the clock every other channel is held against)
HELD_GROUPS = ("dq", "ddq", "tau", "wrench")
#: the groups whose repeats are masked in their own channel (the measured ones); the others' drop their rows
MASKED_GROUPS = ("tau", "wrench")


@dataclass(frozen=True)
class HeldChannels:
    """What :func:`held_rows` found in a table.

    Attributes
    ----------
    rows
        ``(N,)`` the rows where a held channel repeats its previous value (read as that channel's blanks).
    holds
        ``(group, k)`` for each held group: its new values every ``k`` rows.
    repeats
        ``(N,)`` for each group of ``holds`` (in its order), the rows where that group repeats its previous value.
    """

    rows: NDArray[np.bool_]
    holds: tuple[tuple[str, int], ...]
    repeats: tuple[NDArray[np.bool_], ...] = ()

    def group_rows(self, groups: tuple[str, ...]) -> NDArray[np.bool_]:
        """``(N,)`` the rows where any of ``groups`` that is held repeats its value (none when none is)."""
        found = np.zeros(self.rows.shape[0], dtype=bool)
        for (group, _), rows in zip(self.holds, self.repeats):
            if group in groups:
                found |= rows
        return found

    @property
    def dropped_rows(self) -> NDArray[np.bool_]:
        """``(N,)`` the rows an input channel's repeats drop (those outside :data:`MASKED_GROUPS`)."""
        return self.group_rows(tuple(group for group in HELD_GROUPS if group not in MASKED_GROUPS))


def held_samples(values: NDArray[np.float64], moved: NDArray[np.bool_]) -> tuple[NDArray[np.bool_], int]:
    """``(repeats (N,), k)``: the rows of ``values (N, m)`` (a channel's columns; the first row may be the block
    before's last, as context) that repeat the previous row on every column, and the hold ``k`` (rows a value
    stays), where the channel is held (module docstring); no rows and ``k = 0`` otherwise. ``moved (N,)``: the rows
    where the positions changed since the row before."""
    none = np.zeros(values.shape[0], dtype=bool)
    if values.shape[0] < 3 or values.shape[1] == 0:
        return none, 0
    finite = np.all(np.isfinite(values), axis=1)
    repeated = np.zeros(values.shape[0], dtype=bool)
    repeated[1:] = np.all(values[1:] == values[:-1], axis=1) & finite[1:] & finite[:-1]
    judged = moved & finite
    judged[0] = False
    if np.count_nonzero(judged) < HELD_LEAST or np.count_nonzero(repeated & judged) < HELD_SHARE * np.count_nonzero(judged):
        return none, 0
    fresh = np.flatnonzero(finite & ~repeated)
    intervals = np.diff(fresh)
    if intervals.size < HELD_LEAST:
        return none, 0
    hold = int(np.argmax(np.bincount(intervals)))
    if hold < 2 or np.count_nonzero(intervals == hold) < HELD_REGULAR * intervals.size:
        return none, 0
    return repeated, hold


def _numbers(frame: pd.DataFrame, columns: list[str]) -> NDArray[np.float64]:
    return np.column_stack([frame[column].to_numpy(dtype=float) if pd.api.types.is_numeric_dtype(frame[column])
                            else pd.to_numeric(frame[column], errors="coerce").to_numpy(dtype=float)
                            for column in columns])


def held_rows(frame: pd.DataFrame, n_joints: int, before: pd.DataFrame | None = None) -> HeldChannels:
    """The rows of ``frame`` where a channel held at a lower rate than the positions repeats its value
    (:func:`held_samples` on each group of :data:`HELD_GROUPS` present whole, against the positions ``q1..qn``);
    ``before``: the rows read before ``frame`` (the streamed reader's previous block; its last row is the context of
    the first row's repeat). None without positions."""
    none = HeldChannels(np.zeros(len(frame), dtype=bool), ())
    positions = joint_columns("q", n_joints)
    if len(frame) < 3 or not all(column in frame.columns for column in positions):
        return none
    context = before is not None and len(before) > 0 and all(column in before.columns for column in positions)
    joined = pd.concat([before.iloc[-1:], frame]) if context else frame
    candidates = []
    for group in HELD_GROUPS:  # a group's first column must repeat often enough first (one column read: cheap)
        columns = list(WRENCH_CHANNELS) if group == "wrench" else joint_columns(group, n_joints)
        if all(column in joined.columns for column in columns):
            first = _numbers(joined, columns[:1])[:, 0]
            if np.count_nonzero(first[1:] == first[:-1]) >= HELD_SHARE * HELD_LEAST:
                candidates.append((group, columns))
    if not candidates:
        return none
    q = _numbers(joined, positions)
    moved = np.zeros(q.shape[0], dtype=bool)
    moved[1:] = np.any(q[1:] != q[:-1], axis=1)
    rows = np.zeros(len(joined), dtype=bool)
    holds, found = [], []
    for group, columns in candidates:
        repeats, hold = held_samples(_numbers(joined, columns), moved)
        if hold:
            rows |= repeats
            holds.append((group, hold))
            found.append(repeats[1:] if context else repeats)
    return HeldChannels(rows[1:] if context else rows, tuple(holds), tuple(found))
