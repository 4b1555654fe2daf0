"""Reading a log as it comes: one or more segments, with re-sent rows dropped and stalls bridged.

:func:`read_measurements` reads a file as one segment (a hole in it is an error), :func:`read_record`
as one or more. :func:`read_record` reads a CSV or Parquet file with the checks of :mod:`estimation.data.loading`
(columns, finiteness, time base, units, sample count) plus those of a real logger's record
(:mod:`estimation.data.log_cleaning`): values no sensor gives, rows re-sent by the logger (dropped,
counted: :class:`~estimation.data.loading.RepeatedRowsWarning`), stalls up to ``max_gap`` seconds
(bridged by interpolation: :class:`~estimation.data.loading.StallWarning`) and longer holes (the record
split into segments there: :class:`~estimation.data.loading.SplitWarning`, or a
:class:`~estimation.data.loading.HoleError` when one segment is asked for).
"""

from __future__ import annotations

import os
import shlex
import warnings
from dataclasses import dataclass
from collections.abc import Callable, Iterable
from pathlib import Path

import numpy as np
import pandas as pd
from numpy.typing import NDArray

from dynamics.channels import WRENCH_CHANNELS
from dynamics.models import IdentificationModel, ModelKind
from dynamics.robot import JointType
from dynamics.servos import ServoLaws
from estimation.data.loading import (
    ABSURD_VALUE,
    AbsurdValueError,
    BlankRowsWarning,
    COLUMN_GROUPS,
    EncoderGlitchWarning,
    HeldChannelWarning,
    SaturatedTorqueWarning,
    CommentLinesWarning,
    DelimiterWarning,
    DuplicatedTimesWarning,
    QuantisedStampsWarning,
    UnitsRowWarning,
    without_repeated_headers,
    GROUP_MEANING,
    HoleError,
    MeasurementError,
    MissingColumnError,
    ParquetSupportError,
    RepeatedRowsWarning,
    SegmentTooShortError,
    SplitWarning,
    StallWarning,
    StillJointWarning,
    TooFewSamplesError,
    UnwrappedAngleWarning,
    WrappedAngleError,
    check_angles,
    check_no_further_joints,
    check_sample_count,
    check_time,
    count_joint_columns,
    newest_first,
    csv_dialect,
    in_si_units,
    units_row_factors,
    numeric_columns,
    require_columns,
    WHITESPACE,
    other_delimiter,
    split_fields,
    required_groups,
    uniform_grid,
)
from estimation.data.unstarted_edges import data_cells, said_unstarted, span
from estimation.data.compressed_logs import COMPRESSIONS, TEXT_TABLES, csv_input, open_text, packed_format, packer_named
from estimation.data.date_times import counted_time, integers_of_text, seconds_of_date_times
from estimation.data.passive import with_passive_torques
from estimation.data.log_formats import (
    DescriptionOrderWarning,
    LongTableError,
    LongTableWarning,
    long_table,
    JointNamedColumnsWarning,
    JointStateTableWarning,
    TimeColumnWarning,
    apply_column_map,
    description_numbered,
    is_log_file,
    joint_named_columns,
    joint_state_echo,
    read_log_frame,
    split_stamps,
    header_milliseconds,
    time_column,
)
from estimation.data.vendor_logs import (AmbiguousColumnsError, ServoForcesWarning, VendorColumnsWarning, array_cells,
                                        vendor_columns, with_servo_torques)
from estimation.data.sampling_clock import clock_instants, clock_roughness, quantised_clock, said_receive_times
from estimation.data.held_channels import MASKED_GROUPS, HeldChannels, held_rows
from estimation.data.channel_mask import channel_only_parameters, masked_channels
from estimation.data.log_cleaning import (DEFAULT_MAX_GAP, ZERO_ROW_JOINTS, Gap, PositionSteps, blank_rows, describe,
                                          unstarted_rows,
                                          GLITCH_RUN, encoder_glitches, find_gaps, position_steps, repeated_rows,
                                          saturated_samples, saturated_wrench, split_rows, time_stamps_jump,
                                          zero_rows)
from dynamics.measurements import Measurements, joint_columns


def read_measurements(
    path: str | Path,
    *,
    n_joints: int | None = None,
    model: IdentificationModel | ModelKind | str | None = None,
    require: Iterable[str] = ("q",),
    resample: bool = True,
    max_gap: float = DEFAULT_MAX_GAP,
) -> Measurements:
    """Read a CSV or Parquet file of measurements and check it: one segment.

    Parameters
    ----------
    path
        ``.csv`` or ``.parquet`` file with the columns of :mod:`dynamics.measurements`.
    n_joints
        Number of joints; default: the model's robot, else the number of ``q`` columns.
    model
        The identification model the data are for (or its kind): its channels must be present
        (``tau1..taun`` internal, ``fx..mz`` external, both combined), the samples must give more
        equations than base parameters, and revolute angles are checked for degrees.
    require
        Further column groups that must be present, among ``q dq ddq tau wrench``.
    resample
        Interpolate irregularly sampled data onto a uniform grid (with a
        :class:`~estimation.data.loading.ResampledWarning`); if false, irregular sampling is an error.
    max_gap
        Longest time without samples (s) bridged by interpolation
        (:class:`~estimation.data.loading.StallWarning`); a longer hole is a
        :class:`~estimation.data.loading.HoleError` here (:func:`read_record` splits the record there).

    Raises
    ------
    MissingColumnError, NonFiniteError, TimeBaseError, AngleUnitError, TooFewSamplesError, JointCountError
        (:mod:`estimation.data.loading`, each a :class:`~estimation.data.loading.MeasurementError`) Each naming the column, row or count at fault (``JointCountError``: columns such as ``q4``
        beyond the given or the model's number of joints).
    HoleError, AbsurdValueError, ParquetSupportError
        A hole in the record, a value no sensor gives, Parquet without pyarrow.
    """
    segments = read_record(path, n_joints=n_joints, model=model, require=require, resample=resample,
                           max_gap=max_gap, split=False)
    return segments[0]


def measurements_from_frame(
    frame: pd.DataFrame,
    *,
    n_joints: int | None = None,
    model: IdentificationModel | ModelKind | str | None = None,
    require: Iterable[str] = ("q",),
    resample: bool = True,
    source: str = "data",
    max_gap: float = DEFAULT_MAX_GAP,
    glitches: bool = True,
) -> Measurements:
    """The checks of :func:`read_measurements` on a ``DataFrame`` already in memory (``glitches`` false: its
    encoder read errors and clipped torques not judged, as for a chunk of a streamed file, which holds part of the
    record only)."""
    return segments_from_frame(frame, n_joints=n_joints, model=model, require=require, resample=resample,
                               source=source, max_gap=max_gap, split=False, glitches=glitches)[0]


def read_record(
    path: str | os.PathLike[str],
    *,
    n_joints: int | None = None,
    model: IdentificationModel | ModelKind | str | None = None,
    require: Iterable[str] = ("q",),
    resample: bool = True,
    max_gap: float = DEFAULT_MAX_GAP,
    split: bool = True,
) -> tuple[Measurements, ...]:
    """Read a file as one or more segments: :func:`read_measurements`, but a hole longer than
    ``max_gap`` seconds splits the record (a :class:`SplitWarning`) instead of failing.

    ``path`` may also be a ROS bag, an ``.npz`` or ``.mat`` file, or a
    :class:`~estimation.data.log_formats.LogSource` (a topic, a column map): :mod:`estimation.data.log_formats`
    reads it into the table first, matching a bag's joints by name to the model's robot.

    Rows repeating the previous row on every channel are dropped (:class:`RepeatedRowsWarning`,
    :mod:`estimation.data.log_cleaning`), and a few rows stamped with the previous row's time but new values
    (:class:`DuplicatedTimesWarning`; many are a :class:`TimeBaseError`), stalls up to ``max_gap`` bridged
    (:class:`StallWarning`). Each segment's ``metadata`` holds ``source``, ``segment`` (1-based),
    ``repeated_rows_dropped`` and ``duplicated_times_dropped``.
    """
    source, path = path, Path(os.fspath(path))
    suffix = path.suffix.lower()
    if suffix in COMPRESSIONS or suffix in TEXT_TABLES:  # a CSV file packed whole, a .tsv or .txt table: read as CSV
        suffix = packed_format(path)
    if is_log_file(source):  # a ROS bag, .npz, .mat, or a column map (estimation.data.log_formats)
        robot = model.robot if isinstance(model, IdentificationModel) else None
        frame = read_log_frame(source, joint_names=None if robot is None else robot.joint_names,
                               n_joints=n_joints if robot is None else robot.n_joints)
        return segments_from_frame(frame, n_joints=n_joints, model=model, require=require, resample=resample,
                                   source=str(path), max_gap=max_gap, split=split)
    if path.is_dir():
        raise IsADirectoryError(f"data file {path} is a folder")
    if suffix not in (".csv", ".parquet"):
        raise MeasurementError(f"unknown data format {path.suffix!r} for {path}: use .csv or .parquet (a .tsv or "
                               ".txt table read as .csv; either packed by gzip, bzip2, xz, zstd or in a one-file ZIP "
                               "archive), a ROS bag (.mcap, .db3, .bag or a rosbag2 folder), .npz or .mat"
                               + packer_named(path))
    if not path.is_file():
        raise FileNotFoundError(f"data file not found: {path}")
    try:
        frame = read_parquet_frame(path) if suffix == ".parquet" else read_csv_frame(path)
    except ParquetSupportError:
        raise
    except (ValueError, OSError, pd.errors.ParserError) as error:
        raise MeasurementError(f"cannot read {path}: {str(error).strip()}{_delimiter_note(path)}") from None
    frame = in_the_format(frame, path, model, require=require)
    return segments_from_frame(frame, n_joints=n_joints, model=model, require=require, resample=resample,
                               source=str(path), max_gap=max_gap, split=split)


def in_the_format(frame: pd.DataFrame, path: Path, model: IdentificationModel | ModelKind | str | None, *,
                  require: Iterable[str] = ("q",), servos: ServoLaws | None = None,
                  streamed: bool = False) -> pd.DataFrame:
    """A CSV or Parquet table with its columns under the format's names where it names them otherwise, each said
    in a warning giving the ``--columns`` map that reads it so: a long table, one row per joint and time stamp, put
    side by side first (:func:`~estimation.data.log_formats.long_table`), ``rostopic echo -p`` of ``JointState`` messages
    (:func:`~estimation.data.log_formats.joint_state_echo`), the time under another name
    (:func:`~estimation.data.log_formats.time_column`), joint columns named by the robot's joints
    (:func:`~estimation.data.log_formats.joint_named_columns`), then a controller's or driver's log
    (:func:`~estimation.data.vendor_logs.vendor_columns`: ``actual_q_0``, ``q[0]``, ``measured_torque``…, cells
    holding arrays split). One rule for the in-memory reader and the motor-side one (``streamed``: a block of a
    streamed file, where a long table is refused). ``servos``: the MJCF's actuator laws (a transmission's,
    :func:`dynamics.mjcf.mjcf_servos`): a MuJoCo log of the servos' controls without a force is read through them
    (:func:`~estimation.data.vendor_logs.with_servo_torques`), else refused."""
    robot = model.robot if isinstance(model, IdentificationModel) else None
    long = None if robot is None else long_table(frame, robot.joint_names, str(path))
    if long is not None and streamed:  # a block of a long table may split a time stamp's rows
        raise LongTableError(f"{path}: a long table (one row per joint and time stamp) is read in memory only: drop "
                             "the streaming options")
    if long is not None:  # one row per joint and time stamp: put side by side, then read by the joints' names
        frame = long.frame
        warnings.warn(LongTableWarning(long.message), stacklevel=2)
    echo = joint_state_echo(frame)
    if echo is not None:  # rostopic echo -p of JointState messages: read as the column map that reads it
        frame = apply_column_map(frame, echo, str(path), joint_names=None if robot is None else robot.joint_names)
        warnings.warn(JointStateTableWarning(
            f"{path}: read as `rostopic echo -p` of JointState messages, the joints matched by field.name0.. "
            f"(--columns {','.join(f'{key}={value}' for key, value in echo.items())})"), stacklevel=2)
    time = None if echo is not None else time_column(frame)
    if time is not None:  # the time under another name (time, timestamp_ns, time [ms]), not t
        frame = apply_column_map(frame, {"t": time}, str(path))
        warnings.warn(TimeColumnWarning(f"{path}: no column t; the time read as --columns {shlex.quote('t=' + time)}"),
                      stacklevel=2)
    elif echo is None and "t" not in frame.columns:
        time = split_stamp(frame, path)
        if time is not None:  # a stamp split in two: header.stamp.sec and header.stamp.nanosec
            first = pd.to_numeric(frame[time.split("+")[0]], errors="coerce").dropna()
            frame = apply_column_map(frame, {"t": time}, str(path))
            warnings.warn(TimeColumnWarning(
                f"{path}: no column t; the time joined from its stamp split in two, counted from the first row's "
                f"{first.iloc[0]:.0f} s (--columns {shlex.quote('t=' + time)})"), stacklevel=2)
        else:
            time = header_milliseconds(frame)
            if time is not None:  # ABB EGM's header.tm alone: milliseconds by its protocol
                frame = apply_column_map(frame, {"t": time}, str(path))
                warnings.warn(TimeColumnWarning(
                    f"{path}: no column t; the time read from ABB EGM's header stamp {time.split('*', 1)[1]}, "
                    f"milliseconds by its protocol (--columns {shlex.quote('t=' + time)})"), stacklevel=2)
    described = None if robot is None else description_numbered(frame, robot, str(path))
    if described is not None:  # q1..q6 of a dual arm's log, the description's order: one arm's own columns read
        frame = frame.drop(columns=list(described.left_out)).rename(
            columns={value: key for key, value in described.renamed.items()})
        warnings.warn(DescriptionOrderWarning(described.message), stacklevel=2)
    named = None if echo is not None or robot is None else joint_named_columns(frame, robot.joint_names)
    if named is not None:  # joint columns named by the robot's joints (shoulder_pan_joint_effort), not tau1..
        frame = apply_column_map(frame, named, str(path))
        warnings.warn(JointNamedColumnsWarning(
            f"{path}: the joint columns read by the robot's joint names "
            f"(--columns {shlex.quote(','.join(f'{key}={value}' for key, value in named.items()))})"), stacklevel=2)
    if robot is not None and echo is None and not {"q1", "qm1"} & {str(column) for column in frame.columns}:
        frame = array_cells(frame)
        torque = "tau" in set(require) | set(required_groups(model))
        reading = vendor_columns(frame, robot.joint_names, robot.n_joints, str(path), torque=torque, time=time,
                                 controls=servos is not None)
        if reading is not None:  # a controller's log: actual_q_0.., tau_J[0].., measured_torque..
            frame = apply_column_map(frame, reading.columns, str(path))
            warnings.warn(VendorColumnsWarning(reading.message), stacklevel=2)
            if servos is not None and "ctrl1" in frame.columns:  # a servo's setpoint: its force by the MJCF's law
                frame, said = with_servo_torques(frame, servos, robot.n_joints, str(path))
                warnings.warn(ServoForcesWarning(said), stacklevel=2)
    return frame


def split_stamp(frame: pd.DataFrame, path: Path) -> str | None:
    """The column map's entry of a table's time stamped in two columns (:func:`~estimation.data.log_formats.
    split_stamps`: ``header.stamp.sec`` and ``header.stamp.nanosec``), or ``None`` without one.

    Raises
    ------
    AmbiguousColumnsError
        Two such stamps (a message's header and another clock's): the message names the map that reads each."""
    stamps = split_stamps(frame)
    if len(stamps) > 1:
        raise AmbiguousColumnsError(
            f"{path}: the split stamps " + " and ".join(stamp.replace("+", " with ") for stamp in stamps[:2])
            + " could each be the time of the samples, and no rule chooses between them: name yours, "
            + " or ".join(f"--columns {shlex.quote('t=' + stamp)}" for stamp in stamps[:2]))
    return stamps[0] if stamps else None


#: the data rows read to tell a CSV file's separator and decimal mark
DIALECT_ROWS = 20


def read_csv_frame(path: Path) -> pd.DataFrame:
    """The CSV file as a table: comma-separated with ``.`` decimals, or as :func:`csv_options` says, lines repeating
    its header dropped (:func:`without_repeated_headers`), its columns in the format's SI units (:func:`csv_units`)."""
    options = csv_options(path)
    with csv_input(path) as source:
        frame = pd.read_csv(source, **options)
    counted = counted_time(frame)
    if counted is not None and not pd.api.types.is_integer_dtype(frame[counted].dtype):  # integer counts with a
        with csv_input(path) as source:  # blank cell, parsed as floats (rounded past 2**53): read again as text
            text = pd.read_csv(source, **options, dtype={counted: str})
        integers = integers_of_text(text[counted])
        if integers is not None:  # else written as floats (1.0): as parsed
            frame = text.assign(**{counted: integers})
    frame = in_si_units(without_repeated_headers(frame, str(path)), csv_units(path))
    return seconds_of_date_times(frame, str(path))[0]


#: the comment lines (``#`` first) read at most at the head of a CSV file before its header: a logger's notes
COMMENT_LINES = 1000


def _comment(line: str) -> bool:
    return line.lstrip("\ufeff \t").startswith("#")


def _is_number(field: str) -> bool:
    try:
        float(field.strip().replace(",", "."))
    except ValueError:
        return False
    return True


@dataclass(frozen=True)
class CsvHead:
    """The head of a CSV file: the comment lines (``#`` first: a logger's notes, the date, the rate) before its
    header, the header line, the lines after it (up to ``rows``), and whether the header is the last comment line
    (NumPy's ``savetxt(header=...)`` writes ``# t q1 q2 …`` above the numbers)."""

    comments: int
    header: str
    rows: list[str]
    commented_header: bool = False

    @property
    def header_line(self) -> int:
        """The header's line (0-based)."""
        return self.comments - 1 if self.commented_header else self.comments

    def names(self, delimiter: str) -> list[str]:
        """The header's fields (a commented header's ``#`` left out)."""
        header = self.header.lstrip("\ufeff \t")[1:] if self.commented_header else self.header
        return split_fields(header.strip() if delimiter == WHITESPACE else header, delimiter)


def csv_head(path: Path, rows: int = 1) -> CsvHead:
    """The head of the CSV file ``path`` (:class:`CsvHead`): its comment lines (at most :data:`COMMENT_LINES`), its
    header line and the ``rows`` lines after it; the header is the last comment line where the first line after the
    comments is numbers only and that comment holds as many fields, names (NumPy's ``savetxt``).

    Raises
    ------
    OSError
        The file cannot be read."""
    comments = 0
    with open_text(path) as stream:
        line = stream.readline()
        last = ""
        while line and _comment(line) and comments < COMMENT_LINES:
            comments, last = comments + 1, line
            line = stream.readline()
        following = [stream.readline() for _ in range(rows)]
    if comments and line.strip():
        delimiter = other_delimiter(line) or ","
        fields = split_fields(line.strip() if delimiter == WHITESPACE else line, delimiter)
        named = last.lstrip("\ufeff \t")[1:].strip()
        names = split_fields(named, delimiter) if delimiter == WHITESPACE or delimiter in named else []
        if all(_is_number(field) for field in fields) and len(names) == len(fields) \
                and not any(_is_number(name) for name in names):
            return CsvHead(comments, last, [line, *following[:-1]] if rows else [], commented_header=True)
    return CsvHead(comments, line, following)


def _units_row(path: Path) -> tuple[str, list[str], list[str]] | None:
    """``(delimiter, header fields, second line's fields)`` of a CSV file (``None`` where it cannot be read)."""
    try:
        head = csv_head(path)
    except OSError:
        return None
    if head.commented_header:
        return None  # numbers right beneath
    delimiter = other_delimiter(head.header) or ","
    return delimiter, head.names(delimiter), split_fields(head.rows[0], delimiter)


def csv_units(path: Path) -> dict[str, float]:
    """The factors that turn a CSV file's columns into the format's SI units, as its units row names them
    (:func:`~estimation.data.loading.units_row_factors`: ``{"tau1": 0.001}`` for ``mN·m``); ``{}`` without a units
    row or where it names SI units only. Every reader of a CSV file (in memory, streamed, motor side) multiplies
    by them (:func:`~estimation.data.loading.in_si_units`)."""
    read = _units_row(path)
    if read is None:
        return {}
    return units_row_factors(read[1], read[2]) or {}


def csv_options(path: Path) -> dict[str, object]:
    """``pandas.read_csv``'s ``sep`` and ``decimal`` for a CSV file whose header and first rows agree on another
    delimiter than the comma (:func:`~estimation.data.loading.csv_dialect`: ``;`` with ``,`` decimals, a
    spreadsheet's European export), said in a :class:`DelimiterWarning`, and ``skiprows`` for a units row beneath
    the header naming each column's unit (:func:`~estimation.data.loading.units_row_factors`; other units than
    the format's are converted by the reader, :func:`csv_units`), said in a :class:`UnitsRowWarning`; ``{}`` for a plain file or where nothing can be told (the reader's error then names
    the separator, or the text beneath the names)."""
    try:
        head = csv_head(path, DIALECT_ROWS + 1)
    except OSError:
        return {}
    header = head.header.lstrip("\ufeff \t")[1:] if head.commented_header else head.header
    rows = head.rows
    options: dict[str, object] = {}
    delimiter = other_delimiter(header) or ","
    if head.comments:  # a logger's notes above the header (# rate: 250 Hz), or the header commented (savetxt)
        options["skiprows"] = list(range(head.comments))
        warnings.warn(CommentLinesWarning(
            f"{path}: its first {head.comments} line(s) are comments (# first): skipped"
            + (f", the last one read as the header ({head.header.strip()[:80]})" if head.commented_header else "")),
            stacklevel=3)
    if head.commented_header:
        options.update(header=None, names=[name.strip() for name in head.names(delimiter)])
    factors = None if head.commented_header or not rows else \
        units_row_factors(split_fields(header, delimiter), split_fields(rows[0], delimiter))
    if factors is not None:
        options["skiprows"] = [*options.get("skiprows", []), head.header_line + 1]
        converted = "".join(f"; {name} read as SI units (x{factor:g})" for name, factor in factors.items())
        line = f"line {head.header_line + 2}" if head.comments else "second line"
        warnings.warn(UnitsRowWarning(f"{path}: its {line} names the columns' units ({rows[0].strip()})"
                                      + (converted if factors else ", the format's SI units") + ": skipped"),
                      stacklevel=3)
        rows = rows[1:]
    dialect = csv_dialect(header, rows[:DIALECT_ROWS])
    if dialect is None:
        return options
    separator, decimal = dialect
    warnings.warn(DelimiterWarning(
        f"{path}: columns separated by {'spaces' if separator == WHITESPACE else repr(separator)}"
        + (", ',' the decimal mark" if decimal == "," else "")
        + ": read so"), stacklevel=3)
    return {**options, "sep": separator, "decimal": decimal}


def _delimiter_note(path: Path) -> str:
    """``" (…separated by ';'…)"`` when the file's header is not separated by commas, else ``""``."""
    try:
        header = csv_head(path).header
    except OSError:
        return ""
    delimiter = other_delimiter(header)
    if delimiter is None:
        return ""
    return (f" (its columns are separated by {'spaces' if delimiter == WHITESPACE else repr(delimiter)}, not by "
            "commas: write the file comma-separated, "
            "with '.' as the decimal mark)")


def read_parquet_frame(path: Path) -> pd.DataFrame:
    try:
        import pyarrow  # noqa: F401  (pandas' Parquet engine)
    except ImportError:
        raise ParquetSupportError(
            f"cannot read {path}: Parquet needs the pyarrow package (pip install pyarrow); or save the data as CSV"
        ) from None
    return seconds_of_date_times(pd.read_parquet(path), str(path))[0]


def segments_from_frame(
    frame: pd.DataFrame,
    *,
    n_joints: int | None = None,
    model: IdentificationModel | ModelKind | str | None = None,
    require: Iterable[str] = ("q",),
    resample: bool = True,
    source: str = "data",
    max_gap: float = DEFAULT_MAX_GAP,
    split: bool = True,
    glitches: bool = True,
) -> tuple[Measurements, ...]:
    """The checks of :func:`read_record` on a ``DataFrame`` already in memory; with ``glitches``, its encoder read
    errors dropped as dropouts (:func:`glitch_rows`, said in an :class:`EncoderGlitchWarning`), a torque sensor's
    clipped samples left out of the samples as recorded (:func:`clipped_torques`) and the rows before every channel
    has reported or after one has stopped left out (:func:`_started`)."""
    if isinstance(max_gap, bool) or not isinstance(max_gap, (int, float, np.floating)) or not max_gap > 0 \
            or not np.isfinite(max_gap):
        raise ValueError(f"max_gap must be a positive number of seconds, got {max_gap!r}")
    frame = newest_first(frame.rename(columns=lambda name: str(name).strip()), source)
    n_joints = _joint_count(frame, n_joints, model, source)
    frame = with_passive_torques(frame, model, source)  # a passive joint's torque: zero by physics
    blank = dropouts(frame, n_joints)
    if len(frame) and blank.all():
        raise TooFewSamplesError(
            f"{source}: every one of its {len(frame)} row(s) is a dropout (its data cells all empty, or all exactly 0 "
            "beside the torques: a lost frame written as zeros): no measured sample is left")
    if blank.any():
        first = int(np.flatnonzero(blank)[0])
        said_dropouts(int(blank.sum()), first, frame["t"].iloc[first] if "t" in frame.columns else None, source)
    held = held_rows(frame, n_joints)
    repeats = None  # a measured channel's held repeats, masked in that channel only: (N,) per group of MASKED_GROUPS
    if held.holds:  # a channel at a lower rate, its value repeated between its samples: the repeats are blanks
        dropped_rows = held.dropped_rows
        said_held(held, int(np.count_nonzero(held.dropped_rows & ~blank)),
                  int(np.count_nonzero(held.group_rows(MASKED_GROUPS) & ~blank & ~dropped_rows)), len(frame), source)
        blank = blank | dropped_rows
        repeats = {group: held.group_rows((group,)) for group in MASKED_GROUPS}
    if blank.any():
        frame = frame[~blank].reset_index(drop=True)
        repeats = None if repeats is None else {group: rows[~blank] for group, rows in repeats.items()}
    if glitches:  # the whole record's edges (a streamed file's chunk holds part of it: its reader refuses them)
        frame, started = _started(frame, n_joints, source)
        if started is not None and repeats is not None:
            repeats = {group: rows[started] for group, rows in repeats.items()}
    groups = set(require) | set(required_groups(model)) | {"q"}
    unknown = groups - set(COLUMN_GROUPS)
    if unknown:
        raise ValueError(f"unknown column groups {sorted(unknown)}; expected some of {COLUMN_GROUPS}")

    require_columns(frame, ["t"], "the time", source)
    arrays = _group_arrays(frame, groups, n_joints, source, model)
    frame = seconds_of_date_times(frame, source)[0]  # a table handed over as it is: its date-times read alike
    t = numeric_columns(frame, ["t"], source)[:, 0]
    _check_absurd(t, arrays, n_joints, source)
    _said_still_joints(arrays["q"], model, source)
    data = np.hstack([values for values in arrays.values() if values is not None])
    repeated = repeated_rows(data)
    found = glitch_rows(position_steps(arrays["q"], t, velocity_limits(model, n_joints)), model, n_joints) if glitches else None
    glitched = None  # said once the time base holds (a shuffled file is an error, not read errors)
    if found is not None and found[0].size:
        glitched = (np.flatnonzero(~blank)[found[0]], found[1], t[found[0]])
        kept = np.ones(t.shape[0], dtype=bool)
        kept[found[0]] = False
        t, repeated = t[kept], repeated[kept]
        arrays = {key: None if values is None else values[kept] for key, values in arrays.items()}
        repeats = None if repeats is None else {group: rows[kept] for group, rows in repeats.items()}
    times = clean_time_base(t, repeated, source, max_gap=max_gap, split=split,
                            check=lambda keep: check_angles(arrays["q"][keep], model, source))
    if glitched is not None:
        said_glitches(*glitched, model, source)
    t, holes = times.t, times.holes
    dropped, duplicated = times.repeated_rows_dropped, times.duplicated_times_dropped
    if dropped or duplicated:
        arrays = {key: None if values is None else values[times.keep] for key, values in arrays.items()}
        repeats = None if repeats is None else {group: rows[times.keep] for group, rows in repeats.items()}
    if repeats is not None:  # the held repeats masked in their channel (NaN), the rows kept for the other channels
        arrays = masked_channels(arrays, held_cells(arrays, repeats))
    clipped = clipped_torques(arrays, t, model, source) if glitches else None
    segments = []
    for index, rows in enumerate(split_rows(t.shape[0], holes), start=1):
        name = source if len(holes) == 0 else f"{source} (segment {index})"
        piece = {key: None if values is None else values[rows] for key, values in arrays.items()}
        piece["q"], _, wraps = unwrap_angles(piece["q"], model, name)
        said_unwrapped(wraps, model, name)
        if t[rows].shape[0] < 3:
            raise SegmentTooShortError(f"{name}: {t[rows].shape[0]} sample(s) between holes (t = {t[rows][0]:.6g} s): "
                                       "too few for a time series; cut them from the file")
        metadata: dict[str, object] = {"source": source, "segment": index, "segments_in_file": len(holes) + 1,
                                       "repeated_rows_dropped": dropped, "duplicated_times_dropped": duplicated}
        if clipped is not None and clipped[rows].any():  # a clipped channel's samples masked, that channel's only
            metadata["saturated_samples"] = {name: int(count) for name, count in
                                             zip(clipped_channels(arrays), clipped[rows].sum(axis=0)) if count}
            piece = masked_channels(piece, clipped[rows])
        stamps = t[rows]
        segment_t, grid = uniform_grid(stamps, piece, resample, name, metadata, bridged=times.bridged)
        if "resampled_from" in metadata:  # resampled by its stamps: were they the samples' instants?
            said_receive_times(clock_roughness(stamps, piece["q"], (stamps[-1] - stamps[0]) / (segment_t.shape[0] - 1)),
                               float(stamps[0]), float(stamps[-1]), stamps.shape[0], name)
        segments.append(Measurements(segment_t, grid["q"], grid["dq"], grid["ddq"], grid["tau"], grid["wrench"],
                                     metadata, *_as_recorded(stamps, piece, segment_t, metadata)))
    if isinstance(model, IdentificationModel):
        check_sample_count(segments, model)
    return tuple(segments)


def dropouts(frame: pd.DataFrame, n_joints: int) -> NDArray[np.bool_]:
    """``(N,)`` the rows of ``frame`` whose data cells (``q, dq, ddq, tau``, wrench: those present) are all empty:
    a logger's dropouts (:func:`estimation.data.log_cleaning.blank_rows`; a cell holding text is not empty); and the
    rows where one group's cells are all empty while other rows of the frame hold that group: a channel logged at a
    lower rate than the others (torques at 125 Hz beside positions at 250 Hz, merged into one table with blanks),
    its rows without a sample of it dropped as dropouts. A group empty on every row is not a dropout (the column
    checks name it). One rule for the in-memory reader and the streamed one (:mod:`estimation.streaming.time_base`,
    which applies it to each chunk). Rows whose every data cell is exactly zero are dropouts too, where the row holds
    measured torques or a wrench (a planned trajectory's positions may start at the zero pose): a lost frame written
    as zeros (:func:`lost_frames`)."""
    groups = [[column for column in (list(WRENCH_CHANNELS) if group == "wrench" else joint_columns(group, n_joints))
               if column in frame.columns] for group in COLUMN_GROUPS]
    groups = [columns for columns in groups if columns]
    if not groups:
        return np.zeros(len(frame), dtype=bool)
    cells = [column for columns in groups for column in columns]
    empty_cells = _empty_cells(frame)
    blank = blank_rows(empty_cells(cells))
    blank |= lost_frames(frame, n_joints, cells)
    for columns in groups:
        unlogged = blank_rows(empty_cells(columns))
        if not unlogged.all():
            blank |= unlogged
    return blank


def held_cells(arrays: dict, repeats: dict[str, NDArray[np.bool_]]) -> NDArray[np.bool_]:
    """``(N, k)`` the cells of the measured channels of ``arrays`` (``tau`` then ``wrench``, those present: the
    columns :func:`estimation.data.channel_mask.masked_channels` takes) that repeat a held value, every column of a
    group at its rows of ``repeats`` (:func:`estimation.data.held_channels.held_rows`, one ``(N,)`` per group)."""
    return np.hstack([np.repeat(repeats[key][:, None], arrays[key].shape[1], axis=1)
                      for key in ("tau", "wrench") if arrays.get(key) is not None]
                     or [np.zeros((len(next(iter(repeats.values()))), 0), dtype=bool)])


def _started(frame: pd.DataFrame, n_joints: int, source: str) -> tuple[pd.DataFrame, NDArray[np.bool_] | None]:
    """``(frame, kept)``: ``frame`` without the rows before every data channel has reported and after one has stopped
    (:func:`estimation.data.log_cleaning.unstarted_rows`), said in an :class:`UnstartedChannelsWarning` naming how
    many, the time they span and the channels that lacked a value, and the mask of the rows kept; ``frame`` itself
    and ``None`` when there are none (the streamed reader drops the same rows block by block:
    :func:`estimation.data.unstarted_edges.started_blocks`)."""
    cells = data_cells(frame, n_joints)
    if not cells or not len(frame):
        return frame, None
    empty = _empty_cells(frame)(cells)
    edges = unstarted_rows(empty)
    if not edges.any():
        return frame, None
    lacking = [column for column, missing in zip(cells, empty[edges].any(axis=0)) if missing]
    head = int(np.argmax(~edges))
    tail = int(edges.sum()) - head
    stamps = pd.to_numeric(frame["t"], errors="coerce").to_numpy(dtype=float) if "t" in frame.columns else \
        np.zeros(len(frame))
    said_unstarted(head, tail, span(stamps[:head]) if "t" in frame.columns else "",
                   span(stamps[len(frame) - tail:]) if "t" in frame.columns else "", lacking, source, stacklevel=5)
    return frame[~edges].reset_index(drop=True), ~edges


def _empty_cells(frame: pd.DataFrame) -> Callable[[list[str]], NDArray[np.bool_]]:
    """``columns -> (N, len(columns))`` whether each cell of those columns of ``frame`` is empty: the frame's cells
    tested once and taken by position (a table selected by labels costs about 1 ms a call, and the streamed reader
    applies :func:`dropouts` to every block of every pass); by label where a label is repeated."""
    if frame.columns.has_duplicates:
        return lambda columns: frame[columns].isna().to_numpy()
    empty = frame.isna().to_numpy()
    position = {name: index for index, name in enumerate(frame.columns)}
    return lambda columns: empty[:, [position[column] for column in columns]]


def lost_frames(frame: pd.DataFrame, n_joints: int, cells: list[str]) -> NDArray[np.bool_]:
    """``(N,)`` the rows of ``frame`` whose data ``cells`` are all exactly zero, where they hold measured torques or
    a wrench, on a robot of :data:`~estimation.data.log_cleaning.ZERO_ROW_JOINTS` joints or more
    (:func:`estimation.data.log_cleaning.zero_rows`)."""
    measured = set(joint_columns("tau", n_joints)) | set(WRENCH_CHANNELS)
    if n_joints < ZERO_ROW_JOINTS or not len(frame) or not measured & set(cells):
        return np.zeros(len(frame), dtype=bool)
    return zero_rows(np.column_stack([
        frame[column].to_numpy(dtype=float) if pd.api.types.is_numeric_dtype(frame[column])
        else pd.to_numeric(frame[column], errors="coerce").to_numpy(dtype=float) for column in cells]), n_joints)


def velocity_limits(model, n_joints: int) -> NDArray[np.float64]:
    """``(n,)`` the velocity limits of the model's robot (``inf`` without a model or a limit: the record's own fast
    speed then bounds the steps, :func:`estimation.data.log_cleaning.fast_speeds`)."""
    return (np.asarray(model.robot.velocity_limit, dtype=float) if isinstance(model, IdentificationModel)
            else np.full(n_joints, np.inf))


def glitch_rows(steps: PositionSteps, model, n_joints: int) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """The rows and joints of ``steps``' encoder read errors (:func:`estimation.data.log_cleaning.encoder_glitches`),
    judged by the velocity limits of the model's robot (:func:`velocity_limits`)."""
    return encoder_glitches(steps, velocity_limits(model, n_joints))


def said_glitches(rows: NDArray[np.int64], joints: NDArray[np.int64], stamps: NDArray[np.float64], model,
                  source: str, limit: int = 6) -> None:
    """The :class:`EncoderGlitchWarning` naming the rows of the file (``rows``, as :func:`said_dropouts` counts
    them), their joints and time stamps."""
    names = ([joint.name for joint in model.robot.joints] if isinstance(model, IdentificationModel)
             else [f"q{j + 1}" for j in range(int(joints.max()) + 1)])
    unique = np.unique(rows)
    shown = ", ".join(f"row {int(row)} (t = {float(stamp):.6g} s, "
                      + "/".join(f"q{int(j) + 1}" + ("" if names[j] == f"q{int(j) + 1}" else f" {names[j]!r}")
                                 for j in joints[rows == row]) + ")"
                      for row, stamp in zip(unique[:limit], [stamps[np.flatnonzero(rows == row)[0]]
                                                             for row in unique[:limit]]))
    more = f" and {unique.size - limit} more" if unique.size > limit else ""
    warnings.warn(
        f"{source}: dropped {unique.size} row(s) where a joint's position leaves and comes back within a few samples "
        f"(up to {GLITCH_RUN}) by more than the joint can travel in that time (an encoder's read error: twice its "
        "velocity limit, or without one four times the record's fast speed, and more than four of its counts): "
        f"{shown}{more}; read as dropouts, the "
        "time they leave bridged by interpolation as any gap", EncoderGlitchWarning, stacklevel=5)


def said_held(held: HeldChannels, count: int, masked: int, rows: int, source: str) -> None:
    """The :class:`HeldChannelWarning` for the channels of ``held`` (:func:`estimation.data.held_channels.held_rows`),
    ``count`` of the file's ``rows`` rows dropped as their repeats and ``masked`` more whose measured channel's
    repeat is masked in that channel only."""
    groups = "; ".join(f"{GROUP_MEANING.get(group, group).split(' (')[0]} ({group}) new every {every} rows, repeated between"
                       for group, every in held.holds)
    dropped = f"the {count} row(s) of {rows} where it repeats are read as that channel's blanks (dropped, as a " \
              "lower-rate channel's empty cells are)" if count else ""
    kept = f"{'; ' if count else 'the '}{masked} row(s) of {rows} where a measured channel repeats keep their " \
           "positions and other channels, that channel's repeat masked (no sample of it there)" if masked else ""
    warnings.warn(
        f"{source}: a channel logged at a lower rate than the positions, its last value repeated on the rows between "
        f"its samples (a hold, not a measurement of those instants): {groups}; {dropped}{kept}, each hold's "
        "first row its sample", HeldChannelWarning, stacklevel=5)


def said_dropouts(count: int, first_row: int, first_stamp: object, source: str) -> None:
    """The :class:`BlankRowsWarning` for ``count`` rows dropped as dropouts, the first at row ``first_row`` of the
    file, stamped ``first_stamp`` (as written)."""
    stamp = pd.to_numeric(pd.Series([first_stamp]), errors="coerce").iloc[0]
    warnings.warn(
        f"{source}: dropped {count} row(s) whose data cells are all empty (a logger's dropouts; or all exactly 0: "
        "a lost frame written as zeros), or those of a "
        "channel (joint positions, velocities, torques: one logged at a lower rate), first at row "
        f"{first_row}" + ("" if not np.isfinite(stamp) else f" (t = {stamp:.6g} s)") + "; the time they leave "
        "without samples is bridged by interpolation up to --max-gap and split beyond, as any gap",
        BlankRowsWarning, stacklevel=5)


def _as_recorded(t: NDArray[np.float64], piece: dict, grid: NDArray[np.float64], metadata: dict
                 ) -> tuple[Measurements | None, NDArray[np.int_] | None]:
    """The samples as recorded beside a resampled segment (``Measurements.recorded``, each beside its nearest grid
    sample: ``recorded_rows``), or ``(None, None)`` when the segment was not resampled. Errors are taken on them:
    the torques are never interpolated (the motion derived on the grid is, at their time stamps,
    :func:`estimation.preprocessing.plan.prepare`). A clipped sensor's samples are masked in ``piece`` (NaN in that
    channel, :mod:`estimation.data.channel_mask`), here as in the grid."""
    if grid is t:
        return None, None
    step = (grid[-1] - grid[0]) / max(grid.shape[0] - 1, 1)
    rows = np.clip(np.rint((t - grid[0]) / step), 0, grid.shape[0] - 1).astype(np.int_)
    recorded = Measurements(t, *(piece[key] for key in ("q", "dq", "ddq", "tau", "wrench")),
                            dict(metadata, recorded_stamps=True))
    return recorded, rows


def clipped_torques(arrays: dict, t: NDArray[np.float64], model, source: str) -> NDArray[np.bool_] | None:
    """``(N, k)`` the samples of each torque channel and then each wrench channel (those present, in
    :func:`clipped_channels`' order) held at a sensor's limit (:func:`estimation.data.log_cleaning.saturated_samples`,
    :func:`~estimation.data.log_cleaning.saturated_wrench`), said in a :class:`SaturatedTorqueWarning` naming the
    channels; ``None`` when there are none (or no torques nor wrench)."""
    if arrays.get("q") is None or (arrays.get("tau") is None and arrays.get("wrench") is None):
        return None
    parts = ([saturated_samples(arrays["tau"], arrays["q"])] if arrays.get("tau") is not None else []) + (
        [saturated_wrench(arrays["wrench"], arrays["q"])] if arrays.get("wrench") is not None else [])
    found = np.hstack(parts)
    if not found.any():
        return None
    values = np.hstack([arrays[key] for key in ("tau", "wrench") if arrays.get(key) is not None])
    names = clipped_channels(arrays)
    said = []
    for j in np.flatnonzero(found.any(axis=0)):
        rows = np.flatnonzero(found[:, j])
        said.append((names[j], float(values[rows[0], j]), int(rows.size), float(t[rows[0]]), float(t[rows[-1]])))
    said_clipped(said, model, source)
    return found


def said_clipped(said: list[tuple[str, float, int, float, float]], model, source: str) -> None:
    """The :class:`SaturatedTorqueWarning` naming each clipped channel: ``(name, value, samples, first and last time
    stamp)``; its samples are left out of the fit and the errors (in memory and streamed, masked in that channel)."""
    joint_names = [joint.name for joint in model.robot.joints] if isinstance(model, IdentificationModel) else []
    parts = []
    for name, value, count, first, last in said:
        joint = int(name[3:]) - 1 if name.startswith("tau") else None
        named = "" if joint is None or joint >= len(joint_names) or joint_names[joint] == name else \
            f" ({joint_names[joint]})"
        parts.append(f"{name}{named} at {value:.6g} on {count} sample(s) from t = {first:.6g} s to {last:.6g} s")
    torques = all(name.startswith("tau") for name, *_ in said)
    what = ("these samples are left out of the fit and of every error (taken against what was recorded where the "
            "recording is valid), the positions kept for the derivatives")
    warnings.warn(
        f"{source}: a {'torque' if torques else 'force/torque'} sensor past its range: {'; '.join(parts)}, its extreme "
        f"value held while {'the joint moves' if torques else 'the robot moves'} (and held far more often than its "
        f"other values): clipped, not measured; {what}", SaturatedTorqueWarning, stacklevel=6)


def clipped_channels(arrays: dict) -> list[str]:
    """The channels :func:`clipped_torques` judges, in its columns' order: ``tau1 … taun`` then ``fx … mz``, those
    present in ``arrays``."""
    return ([f"tau{j + 1}" for j in range(arrays["tau"].shape[1])] if arrays.get("tau") is not None else []) + (
        list(WRENCH_CHANNELS) if arrays.get("wrench") is not None else [])


def _joint_count(frame: pd.DataFrame, n_joints: int | None, model: IdentificationModel | ModelKind | str | None,
                 source: str) -> int:
    """The joints of the record: the model's robot's, ``n_joints`` (no further ``q`` column then), or
    counted from the ``q`` columns."""
    if isinstance(model, IdentificationModel):
        robot_joints = model.robot.n_joints
        if n_joints is not None and n_joints != robot_joints:
            raise ValueError(f"n_joints={n_joints} but the model's robot has {robot_joints} joints")
        n_joints = robot_joints
    if n_joints is None:
        n_joints = count_joint_columns(frame, "q")
        if n_joints == 0:
            raise MissingColumnError(f"{source}: no joint position columns q1..qn")
    else:
        check_no_further_joints(frame, n_joints, source)
    return n_joints


def _group_arrays(frame: pd.DataFrame, groups: set[str], n_joints: int, source: str, model=None
                  ) -> dict[str, NDArray[np.float64] | None]:
    """The numeric columns of each group (``q, dq, ddq, tau, wrench``), ``None`` for a group absent;
    the ``groups`` required, and a group present in part, are errors naming the columns (a torque column missing:
    with ``model``, the base parameters that only its equations hold, :func:`unlogged_torque_parameters`)."""
    arrays: dict[str, NDArray[np.float64] | None] = {}
    for group in ("q", "dq", "ddq", "tau", "wrench"):
        columns = list(WRENCH_CHANNELS) if group == "wrench" else joint_columns(group, n_joints)
        present = [column for column in columns if column in frame.columns]
        if group == "tau" and present and len(present) != len(columns):  # before the group's own message
            missing = [column for column in columns if column not in frame.columns]
            raise MissingColumnError(
                f"{source}: no torque column {', '.join(missing)} (the other joints' torques are logged): a passive "
                "(unactuated) joint's torque is zero by physics, and --passive JOINT reads it so (name or number; "
                "or a description that declares motors on the other joints only); a driven joint whose torque was "
                "not logged is not passive (its torque is unknown, not zero): give its column "
                f"(docs/guides/robots-and-logs.md){unlogged_torque_parameters(model, missing)}")
        if group in groups:
            require_columns(frame, columns, GROUP_MEANING[group], source)
        elif present and len(present) != len(columns):
            missing = [column for column in columns if column not in frame.columns]
            raise MissingColumnError(f"{source}: column(s) {', '.join(missing)} missing (the others of {group} are present)")
        arrays[group] = numeric_columns(frame, columns, source) if len(present) == len(columns) else None
    return arrays


def unlogged_torque_parameters(model, missing: list[str]) -> str:
    """The sentence of the missing-torque error naming the base parameters that only the ``missing`` torques'
    equations hold (:func:`estimation.data.channel_mask.channel_only_parameters`): without those columns they
    cannot be identified, so the fit is not run on the others' equations alone; empty without a model (or when
    none is only theirs)."""
    if not isinstance(model, IdentificationModel) or not all(name in model.channels for name in missing):
        return ""
    alone = channel_only_parameters(model, missing)
    if not alone:
        return ""
    return (f"; without {', '.join(missing)} no other joint's equation holds {', '.join(alone)} (the base parameters "
            "only its torque sees: its friction and offset among them), so they cannot be identified from the "
            "others' torques")


def _holes_and_stalls(t: NDArray[np.float64], step: float, max_gap: float, split: bool, source: str,
                      t_recorded: NDArray[np.float64] | None = None) -> tuple[list, list]:
    """The gaps in ``t`` longer than ``max_gap`` (holes: the record is split there, or with ``split``
    false a :class:`HoleError`) and the shorter ones (stalls: bridged); each kind warned about (for
    the caller of :func:`segments_from_frame`). Gaps are judged on the time stamps alone: with rows dropped
    as repeated, ``t_recorded`` (the time column before) must jump there too (a robot at rest leaves none)."""
    gaps = [gap for gap in find_gaps(t, step)
            if t_recorded is None or time_stamps_jump(t_recorded, t[gap.row], t[gap.row + 1], step)]
    holes = [gap for gap in gaps if gap.duration > max_gap]
    stalls = [gap for gap in gaps if gap.duration <= max_gap]
    if holes and not split:
        gap = holes[0]
        raise HoleError(
            f"{source}: column t jumps by {gap.duration:.4g} s between rows {gap.row} and {gap.row + 1} (t = {gap.t:.6g} s), "
            f"{gap.duration / step:.3g} times the median step {step:.4g} s, and the samples do not catch up: a gap "
            f"in the record longer than max_gap = {max_gap:g} s, which interpolation would fill with a straight line "
            f"({len(holes)} such gap(s)); split the record there (several files, or read_record), or raise --max-gap"
        )
    if stalls:
        warnings.warn(
            f"{source}: the logger stalled {len(stalls)} time(s) for at most {max_gap:g} s (--max-gap), longest at "
            f"{describe(sorted(stalls, key=lambda gap: -gap.duration))}; bridged by linear interpolation (resampled "
            "onto a uniform grid)", StallWarning, stacklevel=5)
    if holes:
        warnings.warn(
            f"{source}: {len(holes)} hole(s) longer than --max-gap {max_gap:g} s at {describe(holes)}: the record is "
            f"split into {len(holes) + 1} segments there, each preprocessed on its own", SplitWarning, stacklevel=5)
    return holes, stalls


@dataclass(frozen=True)
class CleanedTimes:
    """What a record's time stamps and re-sent rows say, before its channels are read into segments: one rule for
    the in-memory reader (:func:`segments_from_frame`) and the streamed one
    (:func:`estimation.streaming.time_base.scan_records`, which holds the time column and this mask only).

    Attributes
    ----------
    keep
        ``(N,)`` the rows of the file kept (re-sent rows and duplicated time stamps dropped).
    t
        Their time stamps.
    step
        The median step of ``t``.
    holes, stalls
        The gaps longer than ``max_gap`` (the record is split there) and the shorter ones (bridged), by row of ``t``.
    repeated_rows_dropped, duplicated_times_dropped
        Rows dropped of each kind.
    clock
        ``(t0, step)``: the rows kept were placed on the regular clock ``t0 + step * k`` (``k`` the kept row's index),
        their time column as coarse as the samples' step (:func:`_on_quantised_clock`); ``None``: at their stamps.
    """

    keep: NDArray[np.bool_]
    t: NDArray[np.float64]
    step: float
    holes: list
    stalls: list
    repeated_rows_dropped: int
    duplicated_times_dropped: int
    clock: tuple[float, float] | None = None

    @property
    def bridged(self) -> bool:
        """Whether samples are interpolated where the logger left none (stalls, rows dropped)."""
        return bool(self.stalls) or self.repeated_rows_dropped + self.duplicated_times_dropped > 0


def clean_time_base(t: NDArray[np.float64], repeated: NDArray[np.bool_], source: str, *, max_gap: float, split: bool,
                    check=None) -> CleanedTimes:
    """The rows kept of a record whose time column is ``t`` and whose rows repeating the previous one on every
    channel are ``repeated`` (:func:`estimation.data.log_cleaning.repeated_rows`), with the loader's warnings and
    errors: re-sent rows dropped (:class:`RepeatedRowsWarning`), then a few rows stamped with the previous row's
    time (:class:`DuplicatedTimesWarning`), the time base checked (:func:`check_time`), ``check`` called with the
    mask of the rows kept (the units of the angles), and the gaps found (:func:`_holes_and_stalls`); with ``split``,
    a clock that starts again (:func:`clock_restarts`) splits the record there as a hole does (a
    :class:`SplitWarning`). Before the repeated stamps are looked at, a time column as coarse as the samples' step
    whose rows share stamps puts the rows kept on the regular clock through it, every row kept
    (:func:`_on_quantised_clock`; :attr:`CleanedTimes.clock`, which the streamed reader's blocks take their
    instants from)."""
    recorded = t
    keep = _unrepeated(t, repeated, source)
    dropped = int(t.shape[0] - np.count_nonzero(keep))
    kept_rows = np.flatnonzero(keep)
    t, clock = _on_quantised_clock(t, kept_rows, source)
    later = _duplicated_times(t[kept_rows], source, max_gap if split else None)
    keep[kept_rows[later]] = False
    t = t[keep]
    restarts = clock_restarts(t, max_gap) if split else []
    step = check_time(_continued(t, restarts), source)
    if check is not None:
        check(keep)
    holes, stalls = _holes_and_stalls(t, step, max_gap, split, source,
                                      recorded if (dropped or later.size) and not restarts else None)
    if restarts:
        rows = [gap.row for gap in restarts]
        warnings.warn(
            f"{source}: the clock starts again at row(s) {', '.join(str(row + 1) for row in rows)} "
            f"({'; '.join(f't = {gap.t:.6g} -> {gap.t + gap.duration:.6g} s' for gap in restarts)}): sessions logged "
            f"one after the other into one file, read as {len(restarts) + 1} segments (split there, each preprocessed "
            "on its own and each keeping its own time stamps)", SplitWarning, stacklevel=4)
        holes = sorted([*holes, *restarts], key=lambda gap: gap.row)
    return CleanedTimes(keep, t, step, holes, stalls, dropped, int(later.size), clock)


def _on_quantised_clock(t: NDArray[np.float64], kept_rows: NDArray[np.int_], source: str
                        ) -> tuple[NDArray[np.float64], tuple[float, float] | None]:
    """``t`` with the stamps of ``kept_rows`` on the regular clock through them where they are as coarse as the
    samples' step and some share a stamp (:func:`~estimation.data.sampling_clock.quantised_clock`), said in a
    :class:`QuantisedStampsWarning`, and the clock's ``(t0, step)``; ``(t, None)`` elsewhere."""
    found = quantised_clock(t[kept_rows])
    if found is None:
        return t, None
    t0, step, resolution = found
    clock = clock_instants(t0, step, 0, kept_rows.shape[0])
    shared = int(np.count_nonzero(np.diff(t[kept_rows]) == 0))
    warnings.warn(
        f"{source}: the stamps of column t advance by ticks of {resolution:.6g} s, as coarse as the samples' step "
        f"({step:.6g} s): {shared} row(s) share their stamp with the row before (new values: samples the clock "
        "does not tell apart, not a clock that did not tick); read on the regular clock through the stamps "
        f"(t = {clock[0]:.6g} + k * {step:.6g} s, every stamp within its resolution of it), every row kept",
        QuantisedStampsWarning, stacklevel=5)
    out = t.copy()
    out[kept_rows] = clock
    return out, (t0, step)


def clock_restarts(t: NDArray[np.float64], max_gap: float) -> list[Gap]:
    """The rows after which the time stamps ``t`` step back by more than ``max_gap`` seconds while every other step
    goes forward: a logger whose clock started again (sessions logged one after the other into one file, the clock
    from zero or from another origin each time); each a :class:`~estimation.data.log_cleaning.Gap` of negative
    duration (no sample missing), where the record is split as at a hole. A step back of less than ``max_gap``, or
    any other step back, is rows out of order: none (:func:`~estimation.data.loading.check_time` names them)."""
    steps = np.diff(t)
    back = np.flatnonzero(steps < 0)
    if back.size == 0 or np.any(steps[back] >= -max_gap):
        return []
    return [Gap(int(row), float(t[row]), float(steps[row]), 0.0) for row in back]


def _continued(t: NDArray[np.float64], restarts: list[Gap]) -> NDArray[np.float64]:
    """``t`` with each part after a clock restart moved to follow the part before it by that part's median step:
    one time base to check (:func:`~estimation.data.loading.check_time`); the stamps read stay ``t``."""
    if not restarts:
        return t
    out = t.copy()
    for gap in restarts:
        before = out[: gap.row + 1]
        step = float(np.median(np.diff(before))) if before.shape[0] > 1 else 0.0
        out[gap.row + 1:] += out[gap.row] + step - out[gap.row + 1]
    return out


def _unrepeated(t, repeated, source: str):
    """The mask of the rows kept once those repeating the previous one on every channel are dropped, with one
    warning counting them."""
    repeated = repeated & np.concatenate([[False], np.diff(t) >= 0])
    count = int(repeated.sum())
    if count == 0:
        return np.ones(t.shape[0], dtype=bool)
    rows = np.flatnonzero(repeated)
    same_time = int(np.sum(np.diff(t)[rows - 1] == 0))
    warnings.warn(
        f"{source}: dropped {count} row(s) that repeat the previous row on every channel (a logger re-sending its "
        f"last packet; {same_time} with the same time stamp, {count - same_time} with an advanced one), first at "
        f"row {int(rows[0])} (t = {t[rows[0]]:.6g} s); the samples they stood for are interpolated",
        RepeatedRowsWarning, stacklevel=5)
    return ~repeated


#: at most this share of the rows may repeat the previous row's time stamp with new values to be dropped (a logger's
#: clock that did not tick now and then); more is a time base that cannot be trusted (a coarse clock, t in whole
#: seconds, rows out of order): :class:`~estimation.data.loading.TimeBaseError`
MAX_DUPLICATED_TIMES = 0.01


def _duplicated_times(t, source: str, max_gap: float | None = None):
    """Rows stamped with the previous row's time but holding new values: a few (at most :data:`MAX_DUPLICATED_TIMES`
    of the rows, and the time base otherwise increasing) are dropped, the first row at each time stamp kept, with
    one warning counting them (their instant is unknown: placing them would invent a time; the errors are taken on
    the rows kept); their rows. More are left to :func:`~estimation.data.loading.check_time`, which refuses them."""
    steps = np.diff(t)
    later = np.flatnonzero(steps == 0) + 1
    back = steps < 0 if max_gap is None else (steps < 0) & (steps >= -max_gap)  # not a clock restart
    if later.size == 0 or later.size > MAX_DUPLICATED_TIMES * t.shape[0] or np.any(back):
        return np.zeros(0, dtype=np.int_)
    warnings.warn(
        f"{source}: dropped {later.size} row(s) stamped with the previous row's time but holding new values (a "
        f"logger's clock that did not tick), first at row {int(later[0])} (t = {t[later[0]]:.6g} s); the first row "
        "at each time stamp is kept", DuplicatedTimesWarning, stacklevel=5)
    return later


#: a jump between two rows this close to a whole turn (rad), and more than half a turn: a wrapped angle
WRAP_TOLERANCE = 0.5
#: how far (rad) an unwrapped angle may pass the joint's limits in the description before the jump is not a wrap
WRAP_LIMIT_MARGIN = 0.1


@dataclass(frozen=True)
class AngleTurns:
    """Where the unwrap of a record stands after a block of rows: the last finite row's angles as logged (``(n,)``,
    ``None`` before the first row) and the whole turns added to them (``(n,)`` integers); a streamed reader passes it
    from one chunk of a file (or segment) to the next, so that the chunks are unwrapped as the whole record is."""

    last: NDArray[np.float64] | None = None
    turns: NDArray[np.int_] | None = None


def unwrap_angles(q: NDArray[np.float64], model, source: str, before: AngleTurns = AngleTurns(), *, first_row: int = 0
                  ) -> tuple[NDArray[np.float64], AngleTurns, NDArray[np.int_]]:
    """``q`` with the whole turns of a logger that wraps a revolute joint's angle (to ±π, or to one turn) undone;
    the state for the next block (:class:`AngleTurns`); the wraps per joint.

    A wrap is a jump between two rows (rows with a non-finite angle skipped) by more than half a turn and within
    :data:`WRAP_TOLERANCE` of whole turns (no joint turns half a turn in one sample), on a revolute joint (every joint
    without a robot) that is continuous in the description (no position limits), or with both rows within
    :data:`WRAP_TOLERANCE` of ±π (the logged range touches ±π there). Each row gets ``q + 2π k`` with ``k`` the integer
    turns counted so far (the same arithmetic in memory and streamed: the chunks are identical to the last bit).
    Refused (:class:`WrappedAngleError`, naming ``numpy.unwrap``): a whole-turn jump on a limited joint away from ±π,
    or one whose unwrapped angle leaves the joint's limits by more than :data:`WRAP_LIMIT_MARGIN` (a motion the joint
    could not make). Rows with no wrap before them are returned as logged."""
    n = q.shape[1]
    robot = model.robot if isinstance(model, IdentificationModel) else None
    revolute = np.array([joint.joint_type is JointType.REVOLUTE for joint in robot.joints] if robot else [True] * n)
    lower = np.array([joint.lower for joint in robot.joints] if robot else [-np.inf] * n, dtype=float)
    upper = np.array([joint.upper for joint in robot.joints] if robot else [np.inf] * n, dtype=float)
    finite = np.flatnonzero(np.all(np.isfinite(q), axis=1))
    turns0 = np.zeros(n, dtype=np.int_) if before.turns is None else before.turns
    rows = q[finite]
    if rows.shape[0] == 0:
        return q, before, np.zeros(n, dtype=np.int_)
    extended = rows if before.last is None else np.vstack([before.last, rows])
    steps = np.diff(extended, axis=0)
    whole = np.round(steps / (2 * np.pi))
    wrapped = (np.abs(steps) > np.pi) & (np.abs(steps - 2 * np.pi * whole) < WRAP_TOLERANCE) & revolute
    state = AngleTurns(rows[-1].copy(), turns0)
    if not wrapped.any() and not turns0.any():
        return q, state, np.zeros(n, dtype=np.int_)
    at_half_turn = (np.abs(extended[:-1]) > np.pi - WRAP_TOLERANCE) & (np.abs(extended[1:]) > np.pi - WRAP_TOLERANCE)
    continuous = ~np.isfinite(lower) & ~np.isfinite(upper)
    offset = 0 if before.last is None else 1  # the step into row i of ``rows`` is steps[i - 1 + offset]

    def refused(step: int, column: int, why: str) -> WrappedAngleError:
        row = int(finite[step + 1 - offset])
        was = extended[step, column]
        return WrappedAngleError(
            f"{source}: column q{column + 1} jumps from {was:.4g} to {extended[step + 1, column]:.4g} rad at row "
            f"{first_row + row} ({int(wrapped[:, column].sum())} such jump(s)): a whole turn, {why}; if the logger "
            "wraps the angle, unwrap it before identifying (numpy.unwrap on the column)")

    away = wrapped & ~(continuous | at_half_turn)
    if away.any():
        step, column = (int(index) for index in np.argwhere(away)[0])
        raise refused(step, column, "on a joint with limits, away from ±π: not a wrap of its angle")
    counted = np.cumsum(-(whole * wrapped).astype(np.int_), axis=0) + turns0
    turns = counted if before.last is not None else np.vstack([turns0, counted])
    unwrapped = q.copy()
    unwrapped[finite] = np.where(turns != 0, rows + 2 * np.pi * turns, rows)
    beyond = (turns != 0) & ((unwrapped[finite] < lower - WRAP_LIMIT_MARGIN) | (unwrapped[finite] > upper
                                                                               + WRAP_LIMIT_MARGIN))
    if beyond.any():
        row, column = (int(index) for index in np.argwhere(beyond)[0])
        step = int(np.flatnonzero(wrapped[:, column])[0])
        raise refused(step, column, f"unwrapped it would leave the joint's limits [{lower[column]:.4g}, "
                                    f"{upper[column]:.4g}] rad: a motion the joint could not make")
    return unwrapped, AngleTurns(rows[-1].copy(), turns[-1].copy()), wrapped.sum(axis=0).astype(np.int_)


def said_unwrapped(wraps: NDArray[np.int_], model, source: str) -> None:
    """One :class:`UnwrappedAngleWarning` naming each joint whose angle was unwrapped and how many wraps."""
    if not wraps.any():
        return
    names = (list(model.robot.joint_names) if isinstance(model, IdentificationModel)
             else [f"q{j + 1}" for j in range(wraps.shape[0])])
    said = ", ".join(f"{names[j]} (q{j + 1}): {int(wraps[j])} wrap(s)" for j in np.flatnonzero(wraps))
    warnings.warn(f"{source}: unwrapped the angle a logger wrapped by whole turns: {said}; the record is read with "
                  "the turns added (numpy.unwrap's result)", UnwrappedAngleWarning, stacklevel=4)


def _said_still_joints(q: NDArray[np.float64], model, source: str) -> None:
    """A :class:`StillJointWarning` for each joint whose position is the same on every row of the record (two rows
    or more; read for a model, whose robot names the joints): a joint held still, whose parameters the record does not determine (the fit's rank-deficiency error
    follows when no other record moves it); the message names ``--joint-names`` and ``--locked-at`` that lock it."""
    if q.shape[0] < 2 or not isinstance(model, IdentificationModel):  # the lock names the robot's joints
        return
    still = np.flatnonzero(np.all(q == q[0], axis=0))
    if still.size == 0:
        return
    names = list(model.robot.joint_names)
    moving = [name for j, name in enumerate(names) if j not in set(still.tolist())]
    for j in still:
        warnings.warn(
            f"{source}: joint {names[j]} does not move (q{j + 1} = {q[0, j]:.6g} on every row): this record does "
            f"not determine its parameters; a joint held still in every record is locked by --joint-names "
            f"{','.join(moving)} --locked-at {names[j]}={q[0, j]:.6g} (with --urdf; the log's columns q1.., tau1.. then "
            "those joints' in that order)",
            StillJointWarning, stacklevel=4)


def _check_absurd(t, arrays, n_joints: int, source: str) -> None:
    """A value beyond :data:`ABSURD_VALUE` is named as such (before the unit checks misread it)."""
    if np.any(np.abs(t) > 1e20):
        row = int(np.flatnonzero(np.abs(t) > 1e20)[0])
        raise AbsurdValueError(f"{source}: column t holds {t[row]:.4g} at row {row}: not a time stamp in any unit; "
                               "a corrupt log? Remove or repair those rows")
    columns = {}
    for group, values in arrays.items():
        if values is not None:
            columns[group] = values
    for group, values in columns.items():
        beyond = np.abs(values) > ABSURD_VALUE
        if beyond.any():
            row, column = (int(index) for index in np.argwhere(beyond)[0])
            names = (["t"] if group == "t" else list(WRENCH_CHANNELS) if group == "wrench"
                     else joint_columns(group, n_joints))
            raise AbsurdValueError(
                f"{source}: column {names[column]} holds {values[row, column]:.4g} at row {row} ({int(beyond.sum())} "
                f"value(s) beyond ±{ABSURD_VALUE:.0e} in {group}): no measurement in SI units is that large; "
                "a corrupt log? Remove or repair those rows")
