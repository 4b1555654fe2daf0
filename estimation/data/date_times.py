"""Time columns written as date-times, read as seconds.

A database's, a spreadsheet's or pandas' export writes a log's time as ISO 8601 date-times
(``2026-11-28 10:00:00.004``, ``2026-11-28T10:00:00.004+01:00``) and a Parquet file as a timestamp type. The
format wants seconds as numbers: such a column is read as the seconds elapsed since its first stamp (the
record's own clock from zero; stamps with UTC offsets on the same time line, so a change of offset inside the
record moves no sample), each stamp to the nanosecond. The absolute date matters to no model. One rule for the
in-memory readers (:func:`estimation.data.records.read_csv_frame`, ``read_parquet_frame``) and the streamed one
(:mod:`estimation.streaming.chunks`), which carries the first chunk's first stamp as the origin of the others.
"""

from __future__ import annotations

import re
import warnings

import pandas as pd

from estimation.data.loading import MeasurementWarning
from estimation.data.log_formats import TIME_NAMES

#: a cell holding a date and a time of day as ISO 8601 writes them (``YYYY-MM-DD`` then ``T`` or a space, ``hh:mm``)
DATE_TIME = re.compile(r"^\s*\d{4}-\d{2}-\d{2}[T ]\d{2}:\d{2}")


#: the origin of durations (a timedelta type): their seconds as they are
EPOCH = pd.Timestamp(0, tz="UTC")


class DateTimeStampsWarning(MeasurementWarning):
    """A time column of date-times (ISO 8601 text, or a timestamp type) was read as seconds since its first stamp."""


def time_column_name(frame: pd.DataFrame) -> str | None:
    """The column of ``frame`` that holds its time: ``t``, else the one column named ``time``, ``timestamp``,
    ``stamp`` or ``times`` (case, spaces, brackets and ``_`` ignored, no unit: a date-time has none)."""
    if "t" in frame.columns:
        return "t"
    names = [str(column) for column in frame.columns]
    if "t" in [name.strip() for name in names]:
        return next(name for name in names if name.strip() == "t")
    found = [name for name in names if re.sub(r"[\s\[\]()_]", "", name.lower()) in TIME_NAMES]
    return found[0] if len(found) == 1 else None


def as_instants(column: pd.Series) -> pd.Series | None:
    """``column`` as UTC instants where it holds date-times: a timestamp type, or text whose every non-blank cell
    is an ISO 8601 date and time of day that pandas reads; ``None`` otherwise (numbers, other text: read as
    before)."""
    if pd.api.types.is_datetime64_any_dtype(column):
        return pd.to_datetime(column, utc=True)
    if pd.api.types.is_numeric_dtype(column.dtype) or pd.api.types.is_bool_dtype(column.dtype):
        return None
    cells = column.astype("string").str.strip()
    present = cells.notna() & (cells != "")
    if not present.any() or not cells[present].str.match(DATE_TIME).all():
        return None
    instants = pd.to_datetime(cells.where(present), format="ISO8601", utc=True, errors="coerce")
    if instants[present].isna().any():
        return None
    return instants


def seconds_of_date_times(frame: pd.DataFrame, source: str, origin: pd.Timestamp | None = None
                          ) -> tuple[pd.DataFrame, pd.Timestamp | None]:
    """``frame`` with its time column (:func:`time_column_name`) in seconds where it holds date-times
    (:func:`as_instants`) or durations (a timedelta type: their seconds as they are), and the origin its seconds
    count from (``origin``, else the column's first stamp: said in a :class:`DateTimeStampsWarning`); ``frame`` as
    it is and ``origin`` otherwise. A blank cell stays blank (a dropout, as the readers take it)."""
    name = time_column_name(frame)
    column = None if name is None else frame[name]
    if not isinstance(column, pd.Series) or pd.api.types.is_float_dtype(column.dtype):  # none, a name twice, or
        return frame, origin  # seconds already (the common case)
    if pd.api.types.is_timedelta64_dtype(column):
        if origin is None:  # said once: the epoch stands for the origin durations count from
            warnings.warn(DateTimeStampsWarning(f"{source}: column {name} holds durations: read as their seconds"),
                          stacklevel=3)
        return frame.assign(**{name: column.dt.total_seconds()}), EPOCH
    instants = as_instants(column)
    if instants is None:
        return frame, origin
    if origin is None:
        valid = instants.dropna()
        if valid.empty:
            return frame, origin
        origin = valid.iloc[0]
        first = column[instants.notna()].iloc[0]
        warnings.warn(DateTimeStampsWarning(
            f"{source}: column {name} holds date-times (first {first}): read as the seconds since that stamp"),
            stacklevel=3)
    return frame.assign(**{name: (instants - origin).dt.total_seconds()}), origin
