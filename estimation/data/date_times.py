"""Time columns written as date-times, or as integer counts of milli-, micro- or nanoseconds, read as seconds.

A database's, a spreadsheet's or pandas' export writes a log's time as ISO 8601 date-times
(``2026-11-28 10:00:00.004``, ``2026-11-28T10:00:00.004+01:00``) and a Parquet file as a timestamp type. The
format wants seconds as numbers: such a column is read as the seconds elapsed since its first stamp (the
record's own clock from zero; stamps with UTC offsets on the same time line, so a change of offset inside the
record moves no sample), each stamp to the nanosecond. The absolute date matters to no model. One rule for the
in-memory readers (:func:`estimation.data.records.read_csv_frame`, ``read_parquet_frame``) and the streamed one
(:mod:`estimation.streaming.chunks`), which carries the first chunk's first stamp as the origin of the others.

A logger that stamps its samples with an integer count written as one (``t`` = 1732000000004000000, nanoseconds since 1970, as a
ROS or a Linux clock gives them; or microseconds since the controller started) writes a time the format's seconds
would step by a million a sample. Its unit is the one of milli-, micro- and nanoseconds that puts the first stamp
between 2000 and 2100 since 1970 (an epoch count), else the only one that puts the median step within a robot log's
(:data:`INTEGER_STEP`); such a column is read as the seconds since its first stamp, subtracted as integers (no
rounding of a nanosecond count near 2e18 by float64), said in an :class:`IntegerStampsWarning`. Where two units fit
(a step of 100: 0.1 s in milliseconds or 100 µs), nothing is guessed: the reader's refusal names the maps.

Such a count with a blank cell (a row the logger left empty) is parsed by pandas as floats, rounded past 2**53 (a
nanosecond count since 1970 to 256 ns) and no longer an integer column: the readers look at the time column as read
(:func:`counted_time`: integers, or floats with a blank whose other values are whole numbers a unit fits) and read it
again as text, each cell an integer exactly (:func:`integers_of_text`; the blank stays blank: a dropout row, or a
missing stamp the column checks refuse, as for a time in seconds). The in-memory reader reads the file again so when
its column came out as floats; the streamed one starts again from its first block whenever that block's time is
counted in integers, so that no later block with a blank is rounded: both read the same stamps.
"""

from __future__ import annotations

import re
import warnings
from dataclasses import dataclass

import numpy as np
import pandas as pd

from estimation.data.loading import DATE_TIME, MeasurementWarning
from estimation.data.log_formats import TIME_NAMES

#: a comma before the fractions of a second (ISO 8601 allows it; Python's ``logging`` writes ``10:00:00,004``)
DECIMAL_COMMA = r"(?<=\d{2}:\d{2}:\d{2}),(?=\d)"


#: a cell of an integer count written as text: an integer written as one (a sign, digits; spaces around)
INTEGER_CELL = r"\s*[+-]?\d+\s*"

#: the origin of durations (a timedelta type): their seconds as they are
EPOCH = pd.Timestamp(0, tz="UTC")
#: the units an integer time count may be in, with their factor to seconds
INTEGER_UNITS = {"ms": 1e-3, "us": 1e-6, "ns": 1e-9}
#: an integer count's first stamp read in a unit as seconds since 1970 within these (2000 to 2100): an epoch count
EPOCH_SPAN = (946_684_800.0, 4_102_444_800.0)
#: the sampling steps (s) a robot's log has, for an integer count's unit: 40 kHz (a drive's current loop) to 2 Hz
INTEGER_STEP = (2.5e-5, 0.5)


@dataclass(frozen=True)
class IntegerOrigin:
    """The first stamp of an integer time count and its unit, the origin its seconds count from (a streamed reader
    carries it from the first chunk to the others)."""

    first: int
    unit: str

    @property
    def factor(self) -> float:
        return INTEGER_UNITS[self.unit]


class DateTimeStampsWarning(MeasurementWarning):
    """A time column of date-times (ISO 8601 text, or a timestamp type) was read as seconds since its first stamp."""


class IntegerStampsWarning(MeasurementWarning):
    """A time column of integer counts of milli-, micro- or nanoseconds was read as seconds since its first stamp."""


def integer_unit(values: np.ndarray) -> str | None:
    """The unit of a time column holding integer counts (``values``, finite, in the order written): ``"ms"``,
    ``"us"`` or ``"ns"``, by the epoch rule then the step rule (the module's note); ``None`` where the values are not
    integers stepping by one or more (seconds, the common case), or where no unit or two fit."""
    if values.size < 2 or not np.all(np.mod(values[:64], 1.0) == 0) or not np.all(np.mod(values, 1.0) == 0):
        return None  # seconds (the common case: told by the first values)
    steps = np.diff(values)
    steps = steps[steps > 0]
    if steps.size == 0 or float(np.median(steps)) < 1.0:
        return None
    step = float(np.median(steps))
    epoch = [unit for unit, factor in INTEGER_UNITS.items() if EPOCH_SPAN[0] <= abs(float(values[0])) * factor
             <= EPOCH_SPAN[1] and INTEGER_STEP[0] <= step * factor < INTEGER_STEP[1]]
    if len(epoch) == 1:
        return epoch[0]
    fits = [unit for unit, factor in INTEGER_UNITS.items() if INTEGER_STEP[0] <= step * factor < INTEGER_STEP[1]]
    return fits[0] if len(fits) == 1 else None


def counted_time(frame: pd.DataFrame) -> str | None:
    """The name of the time column (:func:`time_column_name`) of a table as pandas parsed it, where its cells may be
    integer counts the parser did not keep as integers, or may not in a later block: integers, or floats with a
    blank cell whose other values are whole numbers :func:`integer_unit` reads in a unit; ``None`` otherwise (seconds
    written as floats, the common case: one look at the dtype, and one for blanks). The readers read that column
    again as text (:func:`integers_of_text`)."""
    name = time_column_name(frame)
    column = None if name is None else frame[name]
    if not isinstance(column, pd.Series) or pd.api.types.is_bool_dtype(column.dtype):
        return None
    if pd.api.types.is_integer_dtype(column.dtype):
        return name
    if not pd.api.types.is_float_dtype(column.dtype):
        return None
    values = column.to_numpy(dtype=float)
    blank = np.isnan(values)
    if not blank.any() or blank.all():
        return None
    return name if integer_unit(values[~blank]) is not None else None


def integers_of_text(column: pd.Series) -> pd.Series | None:
    """``column``, read as text, as integers exactly (a nullable ``Int64`` column, a blank cell missing) where every
    cell not blank is an integer written as one (:data:`INTEGER_CELL`); ``None`` otherwise (a decimal point, a
    number written ``1.0``: not a count)."""
    cells = column.astype("string").str.strip()
    present = cells.notna() & (cells != "")
    if not cells[present].str.fullmatch(INTEGER_CELL).all():
        return None
    return cells.where(present).astype("Int64")


def seconds_of_integer_stamps(frame: pd.DataFrame, name: str, source: str, origin: IntegerOrigin | None
                              ) -> tuple[pd.DataFrame, IntegerOrigin | None]:
    """``frame`` with its time column ``name`` in seconds since ``origin`` (else its first stamp, said) where it
    holds integer counts of a unit :func:`integer_unit` tells; as it is otherwise."""
    column = frame[name]
    if not pd.api.types.is_numeric_dtype(column.dtype) or pd.api.types.is_bool_dtype(column.dtype) \
            or origin is None and not pd.api.types.is_integer_dtype(column.dtype):
        return frame, origin  # written as integers only (seconds as floats: the common case, nothing read twice)
    values = column.to_numpy(dtype=float, na_value=np.nan)  # a nullable column's blanks as NaN
    present = np.isfinite(values)
    if origin is None:
        unit = integer_unit(values[present])
        if unit is None:
            return frame, origin
        first = column[present].iloc[0]  # as written (a float's rounding of a count past 2**53 left out)
        origin = IntegerOrigin(int(first), unit)
        warnings.warn(IntegerStampsWarning(
            f"{source}: column {name} holds integer counts stepping by {float(np.median(np.diff(values[present]))):.6g}"
            f" a sample: read as {unit} (" + ("since 1970, " if EPOCH_SPAN[0] <= abs(float(first)) * origin.factor
                                               <= EPOCH_SPAN[1] else "")
            + f"x{origin.factor:g} s), the seconds since the first stamp {int(first)}"), stacklevel=4)
    if pd.api.types.is_integer_dtype(column.dtype) and not column.hasnans:  # exact: the difference of two integers
        seconds = (column.to_numpy(dtype=np.int64) - np.int64(origin.first)).astype(float) * origin.factor
    elif pd.api.types.is_integer_dtype(column.dtype):  # read as text (integers_of_text): a blank cell stays blank
        seconds = (column - origin.first).to_numpy(dtype=float, na_value=np.nan) * origin.factor
    else:  # a count with blank cells, read as floats
        seconds = (column.to_numpy(dtype=float) - float(origin.first)) * origin.factor
    return frame.assign(**{name: seconds}), origin


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
    is an ISO 8601 date and time of day that pandas reads (a comma before the fractions of a second read as a
    point); ``None`` otherwise (numbers, other text: read as before)."""
    if pd.api.types.is_datetime64_any_dtype(column):
        return pd.to_datetime(column, utc=True)
    if pd.api.types.is_numeric_dtype(column.dtype) or pd.api.types.is_bool_dtype(column.dtype):
        return None
    cells = column.astype("string").str.strip()
    present = cells.notna() & (cells != "")
    if not present.any() or not cells[present].str.match(DATE_TIME).all():
        return None
    if cells[present].str.contains(",", regex=False).any():  # 10:00:00,004: the fraction's comma as ISO allows it
        cells = cells.str.replace(DECIMAL_COMMA, ".", regex=True)
    instants = pd.to_datetime(cells.where(present), format="ISO8601", utc=True, errors="coerce")
    if instants[present].isna().any():
        return None
    return instants


def seconds_of_date_times(frame: pd.DataFrame, source: str, origin: pd.Timestamp | IntegerOrigin | None = None
                          ) -> tuple[pd.DataFrame, pd.Timestamp | IntegerOrigin | None]:
    """``frame`` with its time column (:func:`time_column_name`) in seconds where it holds date-times
    (:func:`as_instants`) or durations (a timedelta type: their seconds as they are), and the origin its seconds
    count from (``origin``, else the column's first stamp: said in a :class:`DateTimeStampsWarning`); ``frame`` as
    it is and ``origin`` otherwise. A blank cell stays blank (a dropout, as the readers take it)."""
    name = time_column_name(frame)
    column = None if name is None else frame[name]
    if isinstance(column, pd.Series) and (isinstance(origin, IntegerOrigin) or origin is None
                                          and pd.api.types.is_numeric_dtype(column.dtype)):
        return seconds_of_integer_stamps(frame, name, source, origin)  # counts of ms, us or ns (or seconds: as is)
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
