"""The checks of measured data as they are read: columns, finiteness, time base, units, sample count.

The file format is that of :mod:`dynamics.measurements` (CSV or Parquet, SI units)::

    t, q1..qn [, dq1..dqn, ddq1..ddqn] [, tau1..taun] [, fx fy fz mx my mz]

The readers (:func:`estimation.data.records.read_measurements`, :func:`estimation.data.records.read_record`)
run these checks and say what is wrong with a file rather than failing later inside a
regressor: each problem raises a :class:`MeasurementError` subclass (a ``ValueError``) naming the
column (and row) at fault, or, when the data can be repaired, a :class:`MeasurementWarning`
subclass saying what was done (irregular sampling is resampled onto a uniform grid).
"""

from __future__ import annotations

import re
import warnings
from collections.abc import Sequence

import numpy as np
import pandas as pd
from numpy.typing import NDArray

from dynamics.models import IdentificationModel, ModelKind
from dynamics.robot import JointType
from estimation.data.log_cleaning import STALL_FACTOR, missing_samples
from dynamics.measurements import Measurements

#: groups of columns a caller may require besides those the model needs
COLUMN_GROUPS: tuple[str, ...] = ("q", "dq", "ddq", "tau", "wrench")

#: relative spread of the sampling interval above which the time base counts as irregular
IRREGULAR_TOLERANCE = 1e-3

#: a median sample time of this (s) or more is not seconds
MAX_SAMPLE_TIME = 1.0
#: a median sample time below this (s) is not seconds either: 1 MHz, beyond any robot's logger (a drive's current
#: loop logs at 10-40 kHz); a spreadsheet's date serial in days steps 4.6e-8 a sample at 250 Hz, hours 1.1e-6
MIN_SAMPLE_TIME = 1e-6
#: from this (s) on the time unit is questioned with a warning (10 Hz)
SLOW_SAMPLE_TIME = 0.1
#: a step this many times the median, with as many samples missing around it, is a gap in the record
GAP_FACTOR = 5.0
#: a revolute joint whose |q| exceeds this (rad) most likely holds degrees (2π plus a margin)
DEGREES_THRESHOLD = 2 * np.pi + 0.5
#: how far (rad) a revolute angle may pass the limit its description gives and still be radians (a controller's
#: soft limits, the margin :data:`DEGREES_THRESHOLD` allows beyond a turn)
DEGREES_LIMIT_MARGIN = 0.5
#: a prismatic joint whose |q| exceeds this many times the largest |limit| its description gives most likely holds
#: millimetres (1000 times the metres; a controller's soft limits narrower than the motion leave it within a few)
LENGTH_UNIT_FACTOR = 20.0
#: read as degrees, a |q| beyond this is more than two turns: motor-side angles rather than degrees
MOTOR_SIDE_DEGREES = 720.0


class MeasurementError(ValueError):
    """The data cannot be used as they are."""


class MissingColumnError(MeasurementError):
    """A column the chosen model (or the caller) needs is absent."""


class NonFiniteError(MeasurementError):
    """A column holds NaN or inf."""


class JointCountError(MeasurementError):
    """The file holds joint columns beyond the robot's joints (data of another robot, or a wrong ``--joints``)."""


class TimeBaseError(MeasurementError):
    """The time column is not strictly increasing (duplicated or decreasing samples)."""


class AngleUnitError(MeasurementError):
    """Revolute joint angles look like degrees."""


class LengthUnitError(MeasurementError):
    """Prismatic joint positions far beyond the description's limits: millimetres for metres."""


class MotorSideAnglesError(AngleUnitError):
    """Revolute joint angles span more turns than the joint can, even read as degrees: motor-side angles."""


def _radians_reach(limit: float) -> float:
    """The largest |q| (rad) read as radians on a revolute joint whose description allows ``limit`` (its largest
    |bound|, ``inf`` without one): :data:`DEGREES_THRESHOLD` (a turn and a margin), or the limit and
    :data:`DEGREES_LIMIT_MARGIN` when the description allows more than a turn (a wrist of ±450°)."""
    return max(DEGREES_THRESHOLD, limit + DEGREES_LIMIT_MARGIN) if np.isfinite(limit) else DEGREES_THRESHOLD


def _motor_side(peak: float, limit: float) -> bool:
    """Whether ``peak`` (|q| at most, rad) is too large for degrees: beyond two turns in degrees
    (720), or beyond 1.5 times the joint's limit in degrees when the description gives one."""
    return peak > MOTOR_SIDE_DEGREES or (np.isfinite(limit) and peak > 1.5 * np.degrees(limit))


class TooFewSamplesError(MeasurementError):
    """Fewer equations than base parameters to estimate."""


class WrappedAngleError(MeasurementError):
    """A revolute joint's angle jumps by a whole turn between two rows: a logger that wraps it to ±π."""


class AbsurdValueError(MeasurementError):
    """A value no sensor gives in SI units (a corrupt cell, a wrong unit by many orders of magnitude)."""


class HoleError(TimeBaseError):
    """A hole longer than ``max_gap`` where one segment was asked for (split the record)."""


class SegmentTooShortError(MeasurementError):
    """A segment too short for a time series, or for the filter that derives its motion."""


class ParquetSupportError(MeasurementError, ImportError):
    """Reading Parquet needs pyarrow, which is not installed."""


class MeasurementWarning(UserWarning):
    """The data were repaired; the message says how."""


class ResampledWarning(MeasurementWarning):
    """Irregular sampling: the data were interpolated onto a uniform grid."""


class ReceiveTimesWarning(MeasurementWarning):
    """The positions of a resampled record follow a regular clock rather than its stamps: the stamps look like a
    logger's receive times, and resampling by them adds noise (:mod:`estimation.data.sampling_clock`)."""


class RepeatedRowsWarning(MeasurementWarning):
    """Rows repeating the previous one on every channel (a re-sent packet) were dropped."""


class DuplicatedTimesWarning(MeasurementWarning):
    """A few rows stamped with the previous row's time but new values (a logger's clock that did not tick) were
    dropped."""


class RepeatedHeaderWarning(MeasurementWarning):
    """Lines of a CSV file repeating its header (a logger restarted and appended to the file, writing the column
    names again) were dropped; the rows around them are read as written (a clock that starts again splits the
    record, :class:`SplitWarning`)."""


class BlankRowsWarning(MeasurementWarning):
    """Rows whose data cells are all empty (a logger's dropouts) were dropped; the time they leave without samples
    is a gap like any other."""


class UnstartedChannelsWarning(MeasurementWarning):
    """Rows at the start (or the end) of a record where some channels held no value yet (or no longer: a logger
    whose channels start and stop on their own) were dropped; the record is the rows where every channel holds one
    (:func:`estimation.data.log_cleaning.unstarted_rows`)."""


class EncoderGlitchWarning(MeasurementWarning):
    """Samples where one joint's position left and came back by more than the joint can travel in a sample period
    (an encoder's read error) were dropped as dropouts; the message names their rows and joints."""


class SaturatedTorqueWarning(MeasurementWarning):
    """A torque channel holds its extreme value on runs of samples while its joint moves (a sensor past its range):
    those samples are left out of the samples as recorded (the fit and every error)."""


class StillJointWarning(MeasurementWarning):
    """A joint whose position never changes in a record (a brake held it): the record does not determine its
    parameters; the message names the lock that leaves it out of the model."""


class StallWarning(MeasurementWarning):
    """Short stalls of the logger (samples missing) were bridged by interpolation."""


class QuantisedStampsWarning(MeasurementWarning):
    """A time column whose resolution is as coarse as the samples' step (whole milliseconds at 1 kHz): rows sharing
    a stamp are samples the clock does not tell apart, every row kept on the regular clock through the stamps
    (:func:`estimation.data.sampling_clock.quantised_clock`)."""


class CoarseStampsWarning(MeasurementWarning):
    """Time stamps stored as float32 so far from zero that their rounding reaches a good part of the sampling step:
    the samples' instants are lost."""


class HoldWarning(MeasurementWarning):
    """A training record's holds (every joint's position unchanged for longer than ``max_gap``: the robot stopped)
    were cut out of the fit: the record split there, as at a gap (:func:`estimation.data.rest.holds`)."""


class DelimiterWarning(MeasurementWarning):
    """A CSV file whose columns are separated by another delimiter than the comma (``;``, a tab, ``|``), its decimal
    mark perhaps a comma (a European spreadsheet's export), was read so: the message says how."""


class CommentLinesWarning(MeasurementWarning):
    """A CSV file's first lines were comments (``#`` first: a logger's notes above its header, or NumPy's
    ``savetxt`` header ``# t q1 …`` above the numbers): skipped (the last one read as the header where it names the
    columns), said with their count."""


class UnitsRowWarning(MeasurementWarning):
    """A CSV file's second line named each column's unit: it was skipped, and the columns in other units of the same
    quantity (``ms``, ``deg``, ``mN·m``) were turned into the format's SI units (the message says which, by what)."""


class UnwrappedAngleWarning(MeasurementWarning):
    """A revolute joint's angle logged wrapped to ±π (or to a turn) was unwrapped on reading: which joint, how many wraps."""


class NewestFirstWarning(MeasurementWarning):
    """A log written newest first (its time column decreasing on every row): read reversed, oldest sample first
    (:func:`newest_first`)."""


class HeldChannelWarning(MeasurementWarning):
    """A channel logged at a lower rate than the positions and merged into their table by repeating its last value
    (torques held on two rows at half the positions' rate): the repeats are no samples and were dropped as a
    lower-rate channel's blanks are (:func:`estimation.data.log_cleaning.held_samples`)."""


class SplitWarning(MeasurementWarning):
    """Holes longer than ``max_gap``: the record was split into segments there."""


#: a value beyond this in any channel (SI units) is corrupt, not a measurement
ABSURD_VALUE = 1e9


def required_groups(model: IdentificationModel | ModelKind | str | None) -> tuple[str, ...]:
    """Column groups a model needs: ``tau`` (internal), ``wrench`` (external) or both (combined)."""
    if model is None:
        return ()
    kind = model.kind if isinstance(model, IdentificationModel) else ModelKind(model)
    return {
        ModelKind.INTERNAL: ("tau",),
        ModelKind.EXTERNAL: ("wrench",),
        ModelKind.COMBINED: ("wrench", "tau"),
    }[kind]


def check_sample_count(measurements: Measurements | Sequence[Measurements], model: IdentificationModel) -> None:
    """At least as many samples (over all segments) as base parameters (each sample gives ``m``
    equations, but rows of one sample are strongly correlated: the count asked for is the one that
    makes every base parameter estimable from the joint rows alone)."""
    segments = [measurements] if isinstance(measurements, Measurements) else list(measurements)
    count = sum(segment.n_samples for segment in segments)
    if count <= model.n_base:
        raise TooFewSamplesError(
            f"{count} samples for {model.n_base} base parameters of the {model.kind.value} "
            f"model: need more than {model.n_base} samples (many more for useful estimates)"
        )


#: what each column group holds, for the messages that name a missing one
GROUP_MEANING = {
    "q": "joint positions",
    "dq": "joint velocities",
    "ddq": "joint accelerations",
    "tau": "joint torques (internal model)",
    "wrench": "base reaction wrench (external model)",
}


def count_joint_columns(frame: pd.DataFrame, prefix: str) -> int:
    """The number of joints the columns ``{prefix}1, {prefix}2…`` give (the highest index when one is missing)."""
    pattern = re.compile(rf"^{prefix}(\d+)$")
    indices = sorted(int(match.group(1)) for column in frame.columns if (match := pattern.match(column)))
    return len(indices) if indices == list(range(1, len(indices) + 1)) else (max(indices) if indices else 0)


def check_no_further_joints(frame: pd.DataFrame, n_joints: int, source: str) -> None:
    """A column ``q5`` (or ``dq5``, ``tau5``…) in the data of a 4-joint robot: the motion of the joints
    left out drives the others, so identifying without it would be silently wrong."""
    pattern = re.compile(r"^(q|dq|ddq|tau)(\d+)$")
    beyond = [column for column in frame.columns
              if (match := pattern.match(column)) and int(match.group(2)) > n_joints]
    if beyond:
        raise JointCountError(
            f"{source}: column(s) {', '.join(beyond)} beyond the robot's {n_joints} joint(s): "
            "the data are for a robot with more joints (check --robot/--urdf/--joints)"
        )


def require_columns(frame: pd.DataFrame, columns: list[str], meaning: str, source: str) -> None:
    """Raise :class:`MissingColumnError` naming the ``columns`` absent from ``frame`` and what they hold."""
    missing = [column for column in columns if column not in frame.columns]
    if missing:
        delimiter = other_delimiter(str(frame.columns[0])) if len(frame.columns) == 1 else None
        if delimiter is not None:
            raise MissingColumnError(
                f"{source}: the columns are separated by {delimiter!r}, not by commas (one column "
                f"{str(frame.columns[0])[:60]!r} was read): write the file comma-separated (a CSV file)")
        if str(frame.columns[0]).lstrip().startswith("#"):
            raise MissingColumnError(
                f"{source}: missing column(s) {', '.join(missing)} ({meaning}); the first line read as the header is "
                f"a comment ({str(frame.columns[0])[:60]!r}): remove the comment lines above the header")
        zero = sorted({match.group(1) for column in frame.columns
                       if (match := re.fullmatch(r"(q|dq|ddq|tau)0", str(column)))}, key=len)
        if zero and any(re.fullmatch(r"(q|dq|ddq|tau)\d+", column) for column in missing):
            mapped = ",".join(f"{group}={group}" for group in zero)
            raise MissingColumnError(
                f"{source}: missing column(s) {', '.join(missing)} ({meaning}); the file numbers its joints from 0 "
                f"({', '.join(f'{group}0' for group in zero)}), the format from 1: --columns {mapped} reads them as "
                "joints 1 to n (or rename the columns)")
        held = [str(column) for column in frame.columns] + list(frame.attrs.get("unmapped_arrays", ()))
        shown = ", ".join(held[:12]) + (f" and {len(held) - 12} more" if len(held) > 12 else "")
        raise MissingColumnError(
            f"{source}: missing column(s) {', '.join(missing)} ({meaning}); the file holds {shown}: name yours with "
            "--columns (t=NAME for the time, q=NAME, dq=NAME, tau=NAME for a group: an .npz's or .mat's array, or a "
            "table's columns NAME1..NAMEn; docs/guides/robots-and-logs.md)")


#: a cell holding a date and a time of day as ISO 8601 writes them (``YYYY-MM-DD`` then ``T`` or a space, ``hh:mm``):
#: its ``.`` or ``,`` before the fractions of a second is no decimal mark of the table's numbers
DATE_TIME = re.compile(r"^\s*\d{4}-\d{2}-\d{2}[T ]\d{2}:\d{2}")

#: delimiters of files written as "CSV" by spreadsheets and loggers of other locales
OTHER_DELIMITERS = (";", "\t", "|")
#: the delimiter of a table whose fields are separated by runs of spaces (NumPy's ``savetxt``, MATLAB's
#: ``writematrix`` of a ``.txt`` file, a column-aligned export), as ``pandas.read_csv`` takes it
WHITESPACE = r"\s+"


def other_delimiter(header: str) -> str | None:
    """The delimiter of a header line that holds no comma but another delimiter (:data:`OTHER_DELIMITERS`, else
    runs of spaces between two names or more: :data:`WHITESPACE`), or ``None``."""
    if "," in header:
        return None
    found = next((delimiter for delimiter in OTHER_DELIMITERS if delimiter in header), None)
    return WHITESPACE if found is None and len(header.split()) > 1 else found


def split_fields(line: str, delimiter: str) -> list[str]:
    """The fields of a table's ``line`` (its line end aside) split by ``delimiter`` (runs of spaces for
    :data:`WHITESPACE`, spaces at the ends aside)."""
    line = line.rstrip("\r\n")
    return line.split() if delimiter == WHITESPACE else line.split(delimiter)


def csv_dialect(header: str, rows: Sequence[str]) -> tuple[str, str] | None:
    """``(separator, decimal mark)`` of a CSV file whose header holds no comma but another delimiter
    (:func:`other_delimiter`) that also splits each of its first data ``rows`` into as many fields; the decimal mark is
    the comma where those rows' numbers hold one (it separates nothing else there; a date-time's cells,
    :data:`DATE_TIME`, are not looked at), else the point. ``None`` for a
    comma-separated file, or where the rows do not agree with the header (nothing is guessed)."""
    delimiter = other_delimiter(header)
    if delimiter is None:
        return None
    count = len(split_fields(header, delimiter))
    values = [value for row in rows if row.strip() for value in split_fields(row, delimiter)
              if not DATE_TIME.match(value)]  # a date-time's fraction of a second tells no decimal mark
    if count < 2 or any(len(split_fields(row, delimiter)) != count for row in rows if row.strip()):
        return None
    decimal = "," if any("," in value for value in values) else "."
    if decimal == "," and any(value.count(",") > 1 or "." in value for value in values):
        return None  # a thousands separator or both marks: ambiguous
    return delimiter, decimal


#: the SI units of each column group as a units row may write them (lower case, without spaces, brackets, ``·``, ``.``,
#: ``*`` and ``^``): a revolute joint's or a prismatic joint's
SI_UNITS = {"t": ("s", "sec", "secs", "second", "seconds"), "q": ("rad", "m"), "dq": ("rad/s", "m/s"),
            "ddq": ("rad/s2", "rad/s²", "m/s2", "m/s²"), "tau": ("nm", "n")}
#: other units of the same quantities a units row may name (written as :data:`SI_UNITS`), with the factor that turns a
#: value in them into the format's SI unit: a decimal prefix, or degrees for radians; a unit of another quantity (a
#: current, ``mA``) is not one (its factor to N m is the robot's, not the unit's)
CONVERTED_UNITS = {
    "t": {"ms": 1e-3, "msec": 1e-3, "us": 1e-6, "µs": 1e-6, "μs": 1e-6, "ns": 1e-9},
    "q": {"deg": np.pi / 180.0, "degree": np.pi / 180.0, "degrees": np.pi / 180.0, "°": np.pi / 180.0,
          "mrad": 1e-3, "mm": 1e-3, "cm": 1e-2},
    "dq": {"deg/s": np.pi / 180.0, "°/s": np.pi / 180.0, "mrad/s": 1e-3, "mm/s": 1e-3},
    "ddq": {"deg/s2": np.pi / 180.0, "deg/s²": np.pi / 180.0, "°/s2": np.pi / 180.0, "°/s²": np.pi / 180.0,
            "mm/s2": 1e-3, "mm/s²": 1e-3},
    "tau": {"mnm": 1e-3, "nmm": 1e-3, "ncm": 1e-2, "knm": 1e3, "mn": 1e-3, "kn": 1e3},
}
_COLUMN_GROUP = re.compile(r"^(t|q|dq|ddq|tau)\d*$")


def units_row_factors(names: Sequence[str], row: Sequence[str]) -> dict[str, float] | None:
    """The factors that turn each column named in ``row`` (the line beneath the header ``names``, split alike) into
    the format's SI unit, where ``row`` is a units row: no field a number, and every column of ``t, q.., dq.., ddq..,
    tau..`` in :data:`SI_UNITS` (``s``, ``[rad]``, ``(N m)``, ``N·m``...) or :data:`CONVERTED_UNITS` (``ms``,
    ``deg``, ``mN·m``, ``N·mm``...); other columns' fields are not looked at. ``{column: factor}`` for the columns
    not in SI units (``{}`` where all are), ``None`` where ``row`` is not such a units row (a unit of another
    quantity, ``mA``, is the user's to convert: the reader then refuses the text, as before)."""
    if len(row) != len(names):
        return None
    fields = [field.strip().strip('"\'') for field in row]
    if any(_is_number(field) for field in fields):
        return None
    known, factors = 0, {}
    for name, field in zip(names, fields):
        column = str(name).strip().strip('"\'')
        group = _COLUMN_GROUP.match(column)
        if group is None:
            continue
        unit = re.sub(r"[\s\[\]()·.*^]", "", field).lower()
        if unit in CONVERTED_UNITS[group.group(1)]:
            factors[column] = CONVERTED_UNITS[group.group(1)][unit]
        elif unit not in SI_UNITS[group.group(1)]:
            return None
        known += 1
    return factors if known > 0 else None


def si_units_row(names: Sequence[str], row: Sequence[str]) -> bool:
    """Whether ``row`` (the line beneath the header ``names``, split alike) is a units row naming the format's SI
    units only (:func:`units_row_factors` with nothing to convert)."""
    return units_row_factors(names, row) == {}


def in_si_units(frame: pd.DataFrame, factors: dict[str, float]) -> pd.DataFrame:
    """``frame`` with each column of ``factors`` multiplied by its factor (a units row's other units turned into
    the format's SI units); a column holding text is left as read (the reader's error names the text)."""
    if not factors:
        return frame
    frame = frame.copy() if any(str(name).strip() in factors for name in frame.columns) else frame
    for name in frame.columns:
        factor = factors.get(str(name).strip())
        if factor is not None and pd.api.types.is_numeric_dtype(frame[name]):
            frame[name] = frame[name] * factor
    return frame


def repeated_header_rows(frame: pd.DataFrame) -> NDArray[np.bool_]:
    """``(N,)`` the rows of ``frame`` that repeat its header: every named column's cell is that column's name (spaces
    and a byte-order mark aside; the unnamed columns a trailing separator makes may be empty), as a logger that
    restarts and appends to its file writes the names again. A column read as numbers holds no such row."""
    named = [name for name in frame.columns if not str(name).startswith("Unnamed:")]
    if not named or len(frame) == 0 or any(pd.api.types.is_numeric_dtype(frame[name]) for name in named):
        return np.zeros(len(frame), dtype=bool)
    found = np.ones(len(frame), dtype=bool)
    for name in named:
        cells = frame[name].astype(str).str.strip().str.lstrip("\ufeff").str.strip()
        found &= (cells == str(name).strip().lstrip("\ufeff").strip()).to_numpy()
    return found


def without_repeated_headers(frame: pd.DataFrame, source: str) -> pd.DataFrame:
    """``frame`` without the lines repeating its header (:func:`repeated_header_rows`), said in a
    :class:`RepeatedHeaderWarning` naming the first one's line in the file (the frame's index, which runs on across
    a streamed reader's chunks); the columns they turned into text read again as numbers where every other cell is
    one, so the rows read as they would without them. One rule for the in-memory reader and the streamed ones."""
    header = repeated_header_rows(frame)
    if not header.any():
        return frame
    line = int(frame.index[int(np.flatnonzero(header)[0])]) + 2  # the header is line 1
    warnings.warn(RepeatedHeaderWarning(
        f"{source}: {int(header.sum())} line(s) repeat the header, first at line {line} (a logger restarted and "
        "appended to the file): dropped; a clock that starts again there splits the record"), stacklevel=3)
    frame = frame[~header].copy()
    for name in frame.columns:
        if frame[name].dtype == object:
            try:
                frame[name] = pd.to_numeric(frame[name])
            except (ValueError, TypeError):
                pass  # text the column checks name
    return frame


def _is_number(text: str) -> bool:
    try:
        float(text.replace(",", "."))
    except ValueError:
        return False
    return True


def column_floats(column: pd.Series) -> NDArray[np.float64]:
    """``(N,)`` the column's values as floats, a cell that is not a number as NaN: ``pd.to_numeric(column,
    errors="coerce").to_numpy(dtype=float)``, bit for bit. A column NumPy already holds as floats or integers is
    converted directly (``pd.to_numeric`` returns such a column unchanged; its call costs a Series a call, and the
    streamed reader converts every data column of every block in each pass)."""
    if isinstance(column.dtype, np.dtype) and column.dtype.kind in "fiu":
        return column.to_numpy(dtype=float)
    return pd.to_numeric(column, errors="coerce").to_numpy(dtype=float)


def numeric_columns(frame: pd.DataFrame, columns: list[str], source: str) -> NDArray[np.float64]:
    """``(N, len(columns))`` floats of ``frame``'s ``columns``; :class:`NonFiniteError` naming the first
    NaN, inf or non-numeric cell."""
    values = np.empty((len(frame), len(columns)))
    for index, column in enumerate(columns):
        numbers = pd.to_numeric(frame[column], errors="coerce").to_numpy(dtype=float)
        bad = ~np.isfinite(numbers)
        if bad.any():
            row = int(np.flatnonzero(bad)[0])
            if row == 0 and all(isinstance(frame[name].iloc[0], str) and pd.isna(pd.to_numeric(frame[name].iloc[0],
                                                                                                  errors="coerce"))
                                for name in columns):
                raise NonFiniteError(
                    f"{source}: row 0 holds text in every column ({', '.join(repr(frame[name].iloc[0]) for name in columns[:4])}"
                    "…): a second header line (units?) beneath the names; remove it (the format is SI: s, rad, m, N m)")
            raise NonFiniteError(
                f"{source}: column {column} holds {int(bad.sum())} NaN/inf or non-numeric value(s), "
                f"first at row {row} ({_shown(frame[column].iloc[row])})"
            )
        values[:, index] = numbers
    return values


def _shown(value: object) -> str:
    """A cell for a message: strings quoted, numbers plain (``nan``, not ``np.float64(nan)``)."""
    return repr(value) if isinstance(value, str) else str(value)


#: float32 stamps whose rounding reaches this share of the sampling step are said (:class:`CoarseStampsWarning`)
COARSE_STAMPS = 0.25


def newest_first(frame: pd.DataFrame, source: str) -> pd.DataFrame:
    """``frame`` in the order of its time column ``t``: reversed, said in a :class:`NewestFirstWarning`, where the
    log was written newest first (no step of its stamps forward, and more steps back than repeated stamps: a ring
    buffer dumped from its latest entry, a database query ordered by time descending); as it is otherwise (rows out of
    order stay :func:`check_time`'s error, naming them). Blank and non-numeric stamps are left out of the test."""
    if "t" not in frame.columns or len(frame) < 3:
        return frame
    column = frame["t"]
    t = (column.to_numpy(dtype=float) if pd.api.types.is_numeric_dtype(column)
         else pd.to_numeric(column, errors="coerce").to_numpy(dtype=float))
    t = t[np.isfinite(t)]
    if not written_newest_first(t):
        return frame
    warnings.warn(f"{source}: column t decreases on every row ({t[0]:.6g} s first, {t[-1]:.6g} s last): a log "
                  f"written newest first, read reversed ({len(frame)} rows, oldest first); the rows named in other "
                  "messages count from the oldest", NewestFirstWarning, stacklevel=4)
    return frame.iloc[::-1].reset_index(drop=True)


def written_newest_first(t: NDArray[np.float64]) -> bool:
    """Whether the finite stamps ``t`` (in the order written) are a newest-first log's: no step forward, and more
    steps back than repeated stamps (:func:`newest_first`; the streamed reader asks it of a file's first block)."""
    steps = np.diff(t)
    return not (steps.size < 2 or np.any(steps > 0) or np.count_nonzero(steps < 0) <= np.count_nonzero(steps == 0))


def check_time(t: NDArray[np.float64], source: str) -> float:
    """The median sampling step of ``t`` (s), after checking that ``t`` is a time series in seconds.

    Raises :class:`TooFewSamplesError` (fewer than two samples) or :class:`TimeBaseError` (duplicated
    or decreasing times, steps of a second or more, or under a microsecond: :data:`MIN_SAMPLE_TIME`); warns (:class:`MeasurementWarning`) for slow
    sampling and for stalls followed by a burst (receive times rather than sampling times).
    """
    if t.shape[0] < 2:
        raise TooFewSamplesError(f"{source}: {t.shape[0]} sample(s); need a time series")
    steps = np.diff(t)
    duplicated = np.flatnonzero(steps == 0)
    if duplicated.size:
        row = int(duplicated[0])
        raise TimeBaseError(f"{source}: column t has {duplicated.size} duplicated time(s), first t={t[row]} at rows {row} and {row + 1}")
    decreasing = np.flatnonzero(steps < 0)
    if decreasing.size:
        row = int(decreasing[0])
        if decreasing.size == 1:  # one step back, the rows either side in order: a logger that restarted its clock
            raise TimeBaseError(f"{source}: column t decreases at row {row + 1} ({t[row]} -> {t[row + 1]}) and only "
                                "there: a logger whose clock restarted? Split the file at that row and give each part "
                                "as a segment (--data or --validate repeated); rows out of order: sort them")
        if decreasing.size == steps.size:  # every step back: written newest first (the streamed reader's case)
            raise TimeBaseError(f"{source}: column t decreases on every row ({t[0]} -> {t[-1]}): a log written newest "
                                "first; the in-memory reader reads it reversed (without --chunk-size), or reverse "
                                "its rows")
        shown = ", ".join(f"{int(index) + 1} ({t[index]} -> {t[index + 1]})" for index in decreasing[1:6])
        more = f" and {decreasing.size - 6} more" if decreasing.size > 6 else ""
        raise TimeBaseError(f"{source}: column t decreases at row {row + 1} ({t[row]} -> {t[row + 1]}) and at "
                            f"{decreasing.size - 1} other row(s): {shown}{more}, of its {steps.size + 1}: rows out of "
                            "order (neither oldest nor newest first); sort the samples by time")
    step = float(np.median(steps))
    peak = float(np.max(np.abs(t)))
    rounding = float(np.spacing(np.float32(peak)))
    if step > 0 and rounding >= COARSE_STAMPS * step and np.array_equal(t, t.astype(np.float32)):
        warnings.warn(f"{source}: the time stamps are float32 values (each exactly one): at t = {peak:.6g} s they are "
                      f"rounded to {rounding * 1e3:.3g} ms, {rounding / step:.0%} of the sampling step, so the "
                      "samples' instants are lost and the derivatives and errors with them; log the time as float64, "
                      "or from the record's start", CoarseStampsWarning, stacklevel=4)
    if 0 < step < MIN_SAMPLE_TIME:
        raise TimeBaseError(f"{source}: column t advances by {step:.4g} a sample ({1 / step:.3g} samples a second "
                            "if these were seconds): the format wants seconds, and these look like days (a "
                            "spreadsheet's date serial: read as --columns t=86400*t, or multiply t by 86400) or hours "
                            "(--columns t=3600*t)")
    if step >= MAX_SAMPLE_TIME:
        raise TimeBaseError(f"{source}: column t advances by {step:.4g} a sample: the format wants seconds, "
                            "and these look like milliseconds or nanoseconds (divide t by 1e3 or 1e9)")
    if step >= SLOW_SAMPLE_TIME:
        warnings.warn(f"{source}: column t advances by {step:.4g} s a sample ({1 / step:.3g} Hz), slow for robot "
                      "dynamics: is t in seconds?", MeasurementWarning, stacklevel=4)
    long_steps = [int(row) for row in np.flatnonzero(steps > GAP_FACTOR * step)]
    late = [row for row in long_steps if missing_samples(t, row, step) < 0.5]
    if late:
        warnings.warn(
            f"{source}: column t stalls for {steps[late[0]]:.4g} s after row {late[0]} and the following samples come "
            f"in a burst ({len(late)} such stall(s)): receive times rather than sampling times? Resampling places "
            "those samples by their stamps", MeasurementWarning, stacklevel=5)
    return step


def check_angles(q: NDArray[np.float64], model, source: str) -> None:
    """Raise :class:`AngleUnitError` for revolute angles beyond ±2π (degrees), :class:`MotorSideAnglesError`
    for more turns than the joint makes even in degrees (``model``'s robot tells the joint types and limits;
    without one every joint counts as revolute), :class:`LengthUnitError` for a prismatic joint's positions beyond
    :data:`LENGTH_UNIT_FACTOR` times the largest position its description allows (millimetres: the message names
    the column map that reads the log as it is)."""
    revolute = [True] * q.shape[1]
    limits = [np.inf] * q.shape[1]
    if isinstance(model, IdentificationModel):
        revolute = [joint.joint_type is JointType.REVOLUTE for joint in model.robot.joints]
        limits = [max(abs(joint.lower), abs(joint.upper)) for joint in model.robot.joints]
    for index in range(q.shape[1]):
        peak = float(np.max(np.abs(q[:, index])))
        if not revolute[index] and isinstance(model, IdentificationModel) \
                and 0 < limits[index] < np.inf and peak > LENGTH_UNIT_FACTOR * limits[index]:
            column = f"q{index + 1}"
            raise LengthUnitError(
                f"{source}: column {column} reaches {peak:.4g}, {peak / limits[index]:.3g} x the largest position the "
                f"description allows its prismatic joint ({limits[index]:.4g} m): millimetres? (the format is SI: "
                f"divide by 1000, or read the log as it is: --columns {column}=0.001*{column}, a logged d{column} and "
                f"dd{column} alike)")
        reach = _radians_reach(limits[index])
        if revolute[index] and peak > reach and _motor_side(peak, limits[index]):
            raise MotorSideAnglesError(
                f"{source}: column q{index + 1} reaches {peak:.4g} rad and spans {np.ptp(q[:, index]) / (2 * np.pi):.3g} "
                "turns, more than this joint turns even in degrees: motor-side angles? gear ratio? (divide by the gear "
                "ratio, or give them as qm1..qmn with the transmission: --transmission FILE)"
            )
        if revolute[index] and peak > reach:
            raise AngleUnitError(
                f"{source}: column q{index + 1} reaches {peak:.4g}, beyond ±{reach - DEGREES_LIMIT_MARGIN:.4g} rad "
                f"({'its limits' if reach > DEGREES_THRESHOLD else '2π'}): the angles look like degrees "
                f"(the format is SI: convert with numpy.deg2rad{degrees_option(revolute)})"
            )


def degrees_option(revolute: Sequence[bool]) -> str:
    """The command line's way to read angles logged in degrees as they are, for the :class:`AngleUnitError`
    message: the column map's factor on the ``q`` group (``--columns q=0.0174...*q``, which scales every joint's
    column alike, :func:`estimation.data.log_formats.apply_column_map`), named only when every joint is revolute
    (a prismatic joint's metres would be scaled too); empty otherwise."""
    if not all(revolute):
        return ""
    factor = repr(float(np.pi / 180.0))
    return f", or read the log as it is: --columns q={factor}*q, a logged dq and ddq alike"


def resampling_grid(t, resample: bool, source: str, *, bridged: bool = False, stacklevel: int = 5):
    """The uniform grid the samples at ``t`` are interpolated onto, ``None`` when they are regular (a
    :class:`ResampledWarning` says what was done, :class:`TimeBaseError` if not ``resample``): one rule for the
    in-memory reader (:func:`uniform_grid`) and the streamed one (:mod:`estimation.streaming.time_base`).

    The grid's step is the median step corrected so that a whole number of steps spans the record:
    float32 or jittered stamps make the median one of a few rounded values (1 kHz at t ≈ 10 s in
    float32: 0.99976 ms), which would otherwise misstate the rate by up to 0.05 %."""
    steps = np.diff(t)
    step = float(np.median(steps))
    spread = float(np.max(np.abs(steps - step))) / step
    if spread <= IRREGULAR_TOLERANCE:
        return None
    if not resample:
        raise TimeBaseError(f"{source}: irregular sampling in column t (step varies by {100 * spread:.3g}% of {step:.4g} s)")
    intervals = max(int(round((t[-1] - t[0]) / step)), 1)
    step = (t[-1] - t[0]) / intervals
    grid = t[0] + step * np.arange(intervals + 1)
    grid[-1] = min(grid[-1], t[-1])
    regular = steps[steps <= STALL_FACTOR * float(np.median(steps))]
    jitter = float(np.max(np.abs(regular - np.median(steps)))) / float(np.median(steps)) if regular.size else 0.0
    reason = "stalls bridged, and " if bridged else ""
    if jitter > IRREGULAR_TOLERANCE or not bridged:  # stalls alone: their warning already says what was done
        warnings.warn(
            f"{source}: irregular sampling in column t ({reason}step varies by {100 * spread:.3g}% of the median "
            f"{float(np.median(steps)):.4g} s): resampled by linear interpolation onto {grid.shape[0]} uniform "
            f"samples of {step:.6g} s", ResampledWarning, stacklevel=stacklevel)
    return grid


def uniform_grid(t, arrays, resample: bool, source: str, metadata: dict, *, bridged: bool = False):
    """Data on a uniform grid: as they are when regular, else interpolated (a :class:`ResampledWarning` says
    so, ``metadata["resampled_from"]`` keeps the sample count; :class:`TimeBaseError` if not ``resample``).

    The grid is :func:`resampling_grid`'s."""
    grid = resampling_grid(t, resample, source, bridged=bridged)
    if grid is None:
        return t, arrays
    metadata["resampled_from"] = int(t.shape[0])
    resampled = {
        name: None if values is None else np.column_stack([np.interp(grid, t, column) for column in values.T])
        for name, values in arrays.items()
    }
    return grid, resampled
