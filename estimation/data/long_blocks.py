"""A long table (one row per joint and time stamp: ``t, joint, position, effort``) read block by block, as the
in-memory reader reads it whole (:func:`estimation.data.log_formats.long_table`).

The first block tells the layout (the column naming the joints, the time column, the value columns); each block is
then cut after its last whole time stamp, the rows of that stamp carried into the next block (a block may split a
stamp's rows), put side by side with the whole table's columns
(:func:`~estimation.data.log_formats.side_by_side`) and handed on ``chunk_size`` stamps at a time. Memory: a
block of rows, one stamp's rows and ``chunk_size`` stamps. In memory the stamps keep
the order they first appear in; block by block that order is known only where a stamp's rows are written together,
so the streamed path reads a long table whose stamps never go back (written oldest first, each stamp's rows
together) and refuses another, naming the in-memory route. The table's reading is said once, at its end, with the
whole file's counts (:class:`~estimation.data.log_formats.LongTableWarning`).
"""

from __future__ import annotations

import warnings
from collections.abc import Iterator, Sequence

import numpy as np
import pandas as pd

from estimation.data.loading import MeasurementError
from estimation.data.log_formats import LongLayout, LongTableWarning, long_table, long_table_message, side_by_side


class LongTableOrderError(MeasurementError):
    """A long table whose time stamps go back, read block by block: the in-memory reader reads it."""


def _stamps(frame: pd.DataFrame, layout: LongLayout) -> np.ndarray:
    return pd.to_numeric(frame[layout.time], errors="coerce").to_numpy(dtype=float)


def _names_some_joints(frame: pd.DataFrame, joint_names: Sequence[str] | None) -> bool:
    """Whether ``frame`` (a first block that is no long table) has a text column naming some of the robot's joints and
    no numbered joint columns: a long table whose first block does not name them all (written joint by joint)."""
    if not joint_names or len(joint_names) < 2 or {"q1", "qm1"} & {str(column) for column in frame.columns}:
        return False
    names = {str(name) for name in joint_names}
    return any(not pd.api.types.is_numeric_dtype(frame[column])
               and names & set(frame[column].dropna().astype(str).str.strip().unique()) for column in frame.columns)


def long_blocks(frames: Iterator[pd.DataFrame], joint_names: Sequence[str] | None, source: str, *,
                chunk_size: int, say: bool = True) -> Iterator[pd.DataFrame]:
    """``frames`` (a file's blocks) put side by side where the first block is a long table (the module's note; said
    once at the end when ``say``), ``chunk_size`` time stamps a block (the last fewer); as they are otherwise.

    Raises
    ------
    LongTableOrderError
        A stamp before the one before it (written newest first, sorted by joint, or out of order).
    LongTableError
        A joint written twice at one stamp (:func:`~estimation.data.log_formats.side_by_side`)."""
    layout: LongLayout | None = None
    carry: pd.DataFrame | None = None
    rows, stamps, others, last = 0, 0, dict[str, None](), -np.inf
    made: list[pd.DataFrame] = []  # stamps put side by side, handed on ``chunk_size`` at a time
    for index, frame in enumerate(frames):
        if index == 0:
            found = long_table(frame, joint_names, source)
            if (found is None or found.layout is None) and _names_some_joints(frame, joint_names):
                raise LongTableOrderError(
                    f"{source}: a long table whose first {len(frame)} rows do not name every joint (written joint by "
                    "joint?): the streamed path reads a long table whose stamps never go back, each stamp's rows "
                    "together; read it in memory (drop the streaming options)")
            if found is None or found.layout is None:
                yield frame
                yield from frames
                return
            layout = found.layout
        if carry is not None:
            frame = pd.concat([carry, frame])
        times = _stamps(frame, layout)
        finite = times[np.isfinite(times)]
        steps = np.diff(np.concatenate([[last], finite]))
        if np.any(steps < 0):
            row = int(np.flatnonzero(steps < 0)[0])
            raise LongTableOrderError(
                f"{source}: a long table whose time stamps go back ({finite[row - 1] if row else last:.6g} then "
                f"{finite[row]:.6g}: written newest first, by joint, or out of order): the streamed path reads a long "
                "table whose stamps never go back, each stamp's rows together; read it in memory (drop the streaming "
                "options)")
        last = float(finite[-1]) if finite.size else last
        whole = times != times[-1] if len(frame) else np.zeros(0, dtype=bool)
        carry = frame[~whole]
        if whole.any():
            wide, count, left = side_by_side(frame[whole], layout, source)
            rows, stamps = rows + count, stamps + len(wide)
            others.update(dict.fromkeys(left))
            made.append(wide)
            if sum(len(part) for part in made) >= chunk_size:
                joined = pd.concat(made, ignore_index=True)
                yield joined.iloc[:chunk_size]
                made = [joined.iloc[chunk_size:]] if len(joined) > chunk_size else []
    if carry is not None and len(carry):
        wide, count, left = side_by_side(carry, layout, source)
        rows, stamps = rows + count, stamps + len(wide)
        others.update(dict.fromkeys(left))
        made.append(wide)
    if made:
        yield pd.concat(made, ignore_index=True)
    if say and layout is not None:
        warnings.warn(LongTableWarning(long_table_message(source, layout.key, layout.values, rows, stamps,
                                                          sorted(others))), stacklevel=2)
