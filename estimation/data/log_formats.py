"""Logs as they come: ROS bags, ``.npz`` and ``.mat`` files, and tables with other column names, read into the
table of :mod:`dynamics.measurements` (``t, q1..qn [, dq1..dqn] [, tau1..taun]``).

* **ROS bags** (the ``ros`` extra, ``pip install 'robot-oed[ros]'``: the pure-Python ``rosbags`` reader, no ROS
  install): a ROS 2 bag (a rosbag2 folder with SQLite or MCAP storage, or a single ``.mcap`` or ``.db3`` file)
  or a ROS 1 ``.bag``. The ``sensor_msgs/JointState`` messages on the topic (default ``/joint_states``) give, by
  joint name: header stamp → ``t`` (seconds since the first stamp; the time the bag logged the message when
  the publisher left every stamp at zero), position → ``q``, velocity → ``dq`` when every message carries it,
  effort → ``tau`` when every message carries it. The joints are matched by name to the robot's (the logged
  joints named, :func:`dynamics.urdf.robot_from_urdf`), in the robot's order; other joints in the messages are
  ignored; messages of one stamp (split publishers) are merged; a stamp missing a joint is dropped (warned).
* **.npz / .mat** (MATLAB 5 to 7.2, SciPy's reader): arrays by name, taken as the columns they are named
  after (``t``, ``q1``…), a 2-D array named ``q``, ``dq``, ``ddq``, ``tau`` or ``wrench`` giving one column per
  joint (or ``fx..mz``), or mapped by a column map.
* **A column map** (``--columns t=times,q=positions,tau=35.15*vir``): each entry says which array (or table
  column) is the column or group on the left, optionally scaled by a factor; for a table, a group whose
  columns carry another prefix (``q=Pos`` for ``Pos1..Posn``) is renamed column by column (numbered from 0,
  ``Pos0..Pos{n-1}``, as joints 1 to n).
"""

from __future__ import annotations

import os
import re
import warnings
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from dynamics.channels import WRENCH_CHANNELS
from estimation.data.loading import MeasurementError, MeasurementWarning, MissingColumnError, without_repeated_headers

__all__ = ["BAG_SUFFIXES", "DEFAULT_TOPIC", "DroppedStampsWarning", "LogSource", "RosSupportError", "UnknownTopicError",
           "DescribedColumns", "DescriptionOrderWarning",
           "JointStateTableWarning", "JointNamedColumnsWarning", "description_numbered", "TimeColumnWarning", "apply_column_map", "is_log_file", "joint_state_echo", "logged_joints", "parse_column_map", "read_log_frame",
           "split_stamps", "header_milliseconds"]

#: the topic of ``sensor_msgs/JointState`` read by default
DEFAULT_TOPIC = "/joint_states"
#: suffixes of bag files (a rosbag2 folder is recognised by its ``metadata.yaml``)
BAG_SUFFIXES = (".bag", ".mcap", ".db3")
#: suffixes of arrays by name
ARRAY_SUFFIXES = (".npz", ".mat")
#: column groups a map may name, with one column per joint
JOINT_GROUPS = ("q", "dq", "ddq", "tau")
_FACTOR = re.compile(r"^\s*([+-]?(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?)\s*\*\s*(.+?)\s*$")


class RosSupportError(MeasurementError, ImportError):
    """Reading a ROS bag needs the ``ros`` extra (the ``rosbags`` package), which is not installed."""


class UnknownTopicError(MeasurementError):
    """The bag holds no ``sensor_msgs/JointState`` messages on the topic asked for."""


class DroppedStampsWarning(MeasurementWarning):
    """Stamps at which a named joint was missing from every message were dropped."""


class JointStateTableWarning(MeasurementWarning):
    """A table with no ``t, q1..`` columns was read as ``rostopic echo -p`` of ``JointState`` messages; the message
    gives the column map that reads it so."""


#: the columns of ``rostopic echo -p`` of ``sensor_msgs/JointState`` messages, by group: index k of each array
JOINT_STATE_ECHO = {"q": "field.position", "dq": "field.velocity", "tau": "field.effort"}


def joint_state_echo(frame: pd.DataFrame) -> dict[str, str] | None:
    """The column map of a table of ``JointState`` messages as ``rostopic echo -p`` writes them (``%time`` and
    ``field.header.stamp`` in ns, ``field.name0..``, ``field.position0..`` [, ``field.velocity0..``,
    ``field.effort0..``]), for a table without ``t`` and ``q1``: ``t`` from the messages' stamps (the time the
    topic was logged, ``%time``, where every stamp is 0), each array present as its group; ``None`` otherwise.
    The joints are matched by the names (:func:`logged_joints`)."""
    if {"t", "q1"} & set(frame.columns) or not {"field.position0", "field.name0"} <= set(frame.columns):
        return None
    stamps = "field.header.stamp"
    if stamps not in frame.columns or not (pd.to_numeric(frame[stamps], errors="coerce").fillna(0) != 0).any():
        stamps = "%time"
    if stamps not in frame.columns:
        return None
    groups = {group: prefix for group, prefix in JOINT_STATE_ECHO.items()
              if f"{prefix}0" in frame.columns and pd.to_numeric(frame[f"{prefix}0"], errors="coerce").notna().all()}
    return {"t": f"1e-9*{stamps}", **groups}


class JointNamedColumnsWarning(MeasurementWarning):
    """A table whose joint columns are named by the robot's joint names (``shoulder_pan_joint_effort``) rather than
    numbered (``tau1``) was read by those names; the message gives the column map that reads it so."""


#: the words that name a joint column's quantity beside the joint's name, by group (lower case)
JOINT_COLUMN_WORDS = {"q": ("position", "pos", "angle", "q"), "dq": ("velocity", "vel", "dq"),
                      "ddq": ("acceleration", "acc", "ddq"), "tau": ("effort", "torque", "tau", "trq")}
_JOINT_COLUMN_SEPARATORS = ("_", ".", "/", ":", " ")


def joint_named_columns(frame: pd.DataFrame, joint_names: Sequence[str] | None) -> dict[str, str] | None:
    """The column map of a table whose joint columns are named by the robot's joints: for each group without its
    numbered columns (no ``tau1``), the column ``<joint><sep><word>`` or ``<word><sep><joint>`` of each joint of
    ``joint_names`` (in the robot's order; ``sep`` one of ``_ . / :`` or a space, ``word`` one of
    :data:`JOINT_COLUMN_WORDS`, case ignored), as ``{"tau1": "shoulder_pan_joint_effort", ...}``. A group is mapped
    only when every joint has exactly one such column (otherwise nothing is guessed and the numbered columns are
    missing as before); ``None`` when no group is mapped or the robot's joint names are not known."""
    if not joint_names:
        return None
    columns = {str(column).strip().lower(): str(column) for column in frame.columns}
    found: dict[str, str] = {}
    for group, words in JOINT_COLUMN_WORDS.items():
        if f"{group}1" in frame.columns:
            continue
        mapped = {}
        for index, joint in enumerate(joint_names, start=1):
            name = str(joint).strip().lower()
            matches = {columns[candidate] for word in words for sep in _JOINT_COLUMN_SEPARATORS
                       for candidate in (f"{name}{sep}{word}", f"{word}{sep}{name}") if candidate in columns}
            if len(matches) != 1:
                break
            mapped[f"{group}{index}"] = matches.pop()
        else:
            if len(set(mapped.values())) == len(mapped):
                found.update(mapped)
    return found or None


class LongTableWarning(MeasurementWarning):
    """A long table (one row per joint and time stamp, a column naming the joint: a database's or a time-series
    store's export) was read as one row per time stamp (:func:`long_table`)."""


class LongTableError(MeasurementError):
    """A long table names one joint twice at one time stamp: its rows cannot be put side by side."""


@dataclass(frozen=True)
class LongTable:
    """A long table turned into one row per time stamp: ``frame`` (the time column as it was, each value column
    ``<value>.<joint>`` per joint, as :func:`joint_named_columns` reads them), ``message`` saying what was read."""

    frame: pd.DataFrame
    message: str
    layout: LongLayout | None = None


def long_table(frame: pd.DataFrame, joint_names: Sequence[str] | None, source: str) -> LongTable | None:
    """A table of one row per joint and time stamp (a "long" table: ``t, joint, position, effort``) as one row per
    time stamp, or ``None`` when ``frame`` is not one: it has no numbered joint columns (``q1``, ``qm1``), a time
    column (``t``, or the one :func:`time_column` finds) and exactly one column of text whose values name every
    one of the robot's joints (``joint_names``, two or more; rows of other joints, a gripper's, are left out and
    said). Its
    other columns become ``<column>.<joint>`` for each joint, in the order the time stamps first appear (a time
    that goes back stays where it was written); a joint missing at a stamp leaves its cells empty (the loader's
    rules for blank cells apply). :class:`LongTableError` when a joint is written twice at one stamp."""
    if not joint_names or len(joint_names) < 2 or {"q1", "qm1"} & {str(column) for column in frame.columns}:
        return None  # one joint: a column naming it on every row is a label (a JointState export's name[0])
    names = [str(name) for name in joint_names]
    keys = []
    for column in frame.columns:
        values = frame[column]
        if pd.api.types.is_numeric_dtype(values):
            continue
        found = set(values.dropna().astype(str).str.strip().unique())
        if set(names) <= found:
            keys.append(str(column))
    time = "t" if "t" in frame.columns else time_column(frame)
    if len(keys) != 1 or time is None:
        return None
    key, time = keys[0], _scaled(time)[1]
    values = [str(column) for column in frame.columns if str(column) not in (key, time)]
    if not values:
        return None
    out, rows, others = side_by_side(frame, LongLayout(key, time, tuple(names), tuple(values)), source)
    return LongTable(out, long_table_message(source, key, values, rows, len(out), others),
                     LongLayout(key, time, tuple(names), tuple(values)))


@dataclass(frozen=True)
class LongLayout:
    """How a long table is laid out: its column naming the joints (``key``), its time column, the robot's joint
    names and the value columns (``position``, ``effort``…)."""

    key: str
    time: str
    names: tuple[str, ...]
    values: tuple[str, ...]


def side_by_side(frame: pd.DataFrame, layout: LongLayout, source: str) -> tuple[pd.DataFrame, int, list[str]]:
    """``(wide, rows, others)``: the rows of ``frame`` (a long table laid out as ``layout`` says, or a block of one
    holding whole time stamps) one row per time stamp, in the order the stamps first appear, every column
    ``<value>.<joint>`` of the layout (a joint missing at a stamp leaves its cells empty); the rows of the robot's
    joints put side by side and the other names left out. :class:`LongTableError` when a joint is written twice at
    one stamp."""
    key, time, names = layout.key, layout.time, list(layout.names)
    joint = frame[key].astype(str).str.strip()
    own = joint.isin(names)
    others = sorted(set(joint[~own].dropna()) - {"nan"})
    rows = frame[own].assign(**{key: joint[own]})
    twice = rows.duplicated(subset=[time, key])
    if twice.any():
        first = rows[twice].iloc[0]
        raise LongTableError(
            f"{source}: read as a long table (one row per joint and time stamp, column {key!r} naming the joints), "
            f"but {int(twice.sum())} row(s) name a joint again at the same time stamp, first {first[key]!r} at "
            f"{time} = {first[time]!r}: the rows cannot be put side by side")
    values = list(layout.values)
    wide = rows.pivot(index=time, columns=key, values=values)
    wide = wide.reindex(pd.unique(rows[time]))
    wide.columns = [f"{value}.{name}" for value, name in wide.columns]
    ordered = [f"{value}.{name}" for value in values for name in names]
    return wide.reindex(columns=ordered).reset_index(names=time), len(rows), others


def long_table_message(source: str, key: str, values: Sequence[str], rows: int, stamps: int,
                       others: Sequence[str]) -> str:
    """What a :class:`LongTableWarning` says of a long table read: the column naming the joints, the value columns,
    the rows put side by side as how many stamps, the other names' rows left out."""
    left = f"; rows of {', '.join(repr(name) for name in list(others)[:6])} left out (not the robot's joints)" \
        if others else ""
    return (f"{source}: read as a long table, one row per joint and time stamp (column {key!r} naming the joints, "
            f"{', '.join(repr(value) for value in values)} per joint): {rows} rows put side by side as {stamps} time "
            f"stamps{left}")


class DescriptionOrderWarning(MeasurementWarning):
    """A table numbering every joint of the description the robot's chain was read from (``q1..q6`` of a dual arm,
    in the file's order) was read for the chain's joints alone: which columns, and which were left out (joints on
    other branches, whose motion moves nothing of the chain)."""


@dataclass(frozen=True)
class DescribedColumns:
    """What :func:`description_numbered` read: ``renamed`` the table's columns under the chain's numbers
    (``{"q1": "q4", ...}``), ``left_out`` the other joints' columns, ``message`` what the warning says."""

    renamed: dict[str, str]
    left_out: tuple[str, ...]
    message: str


def description_numbered(frame: pd.DataFrame, robot: Any, source: str) -> DescribedColumns | None:
    """For a robot read as one chain of a larger description (:attr:`~dynamics.robot.RobotModel.description_joints`:
    another arm of a dual-arm robot beside it), a table whose joint columns number every joint of the description
    in its order (``q1..qN``, ``tau1..tauN``, N the description's movable joints, more than the chain's): the
    chain's joints read from their own numbers, the others' columns left out where every one of them is apart from
    the chain (:attr:`~dynamics.robot.RobotModel.apart_joints`: on another branch of a fixed base, its motion moves
    and loads nothing of the chain). ``None`` otherwise: a table of the chain's joints, or one whose other joints
    drive or load the chain (the reader's :class:`~estimation.data.loading.JointCountError` then)."""
    described = tuple(getattr(robot, "description_joints", ()) or ())
    if not described or len(described) <= robot.n_joints:
        return None
    columns = {str(column) for column in frame.columns}
    numbered = sorted(int(found.group(1)) for column in columns if (found := re.fullmatch(r"q(\d+)", column)))
    if numbered != list(range(1, len(described) + 1)):
        return None
    others = [name for name in described if name not in robot.joint_names]
    if not set(others) <= set(robot.apart_joints):
        return None
    places = [described.index(name) + 1 for name in robot.joint_names]
    renamed: dict[str, str] = {}
    left_out: list[str] = []
    for group in JOINT_GROUPS:
        held = [index for index in range(1, len(described) + 1) if f"{group}{index}" in columns]
        if not held:
            continue
        renamed.update({f"{group}{joint}": f"{group}{place}" for joint, place in enumerate(places, start=1)
                        if f"{group}{place}" in columns})
        left_out.extend(f"{group}{index}" for index in held if index not in places)
    read = ", ".join(f"{key}={value}" for key, value in renamed.items() if key != value) or "their own numbers"
    message = (f"{source}: the joint columns number the description's {len(described)} joints in its order "
               f"({', '.join(described)}): the chain's {', '.join(robot.joint_names)} read as {read}; "
               f"{', '.join(left_out)} left out (the joints {', '.join(others)}, on other branches from the base: "
               "their motion moves nothing of the chain's)")
    return DescribedColumns(renamed, tuple(left_out), message)


class TimeColumnWarning(MeasurementWarning):
    """A table without a ``t`` column was read with its time column under another name (``time``, ``timestamp``,
    ``time_ms``...); the message gives the column map that reads it so."""


#: a time column's name without its unit (lower case, spaces, brackets and ``_`` removed) and the units a name may
#: carry, with their factor to seconds
TIME_NAMES = ("time", "timestamp", "stamp", "times", "t")  # "t" with a unit: ``t [s]``, ``t (ms)``
TIME_UNITS = {"": 1.0, "s": 1.0, "sec": 1.0, "ms": 1e-3, "us": 1e-6, "µs": 1e-6, "ns": 1e-9}
#: the sampling steps (s) a robot's log plausibly has: a name without a unit is read as seconds only within them
PLAUSIBLE_STEP = (1e-5, 0.5)


def time_column(frame: pd.DataFrame) -> str | None:
    """For a table without a ``t`` column, its time column as a column map's entry (``"time"``, ``"0.001*time_ms"``):
    the one column named ``time``, ``timestamp``, ``stamp`` (case, spaces, brackets and ``_`` ignored), perhaps with
    a unit (``time_ms``, ``time [s]``, ``timestamp_ns``: :data:`TIME_UNITS`), whose median step in seconds is that of
    a robot's log (:data:`PLAUSIBLE_STEP`: a name without a unit is read as seconds only then; ns since 1970 are
    not); ``None`` otherwise (the missing ``t`` refused as before)."""
    if "t" in frame.columns:
        return None
    found = []
    for column in frame.columns:
        plain = re.sub(r"[\s\[\]()_]", "", str(column).lower())
        for name in TIME_NAMES:
            unit = plain[len(name):] if plain.startswith(name) else None
            if unit is not None and unit in TIME_UNITS:
                found.append((str(column), TIME_UNITS[unit]))
                break
    if len(found) != 1:
        return None
    column, factor = found[0]
    values = pd.to_numeric(frame[column], errors="coerce").to_numpy(dtype=float) * factor
    steps = np.diff(values[np.isfinite(values)])
    steps = steps[steps > 0]
    if steps.size == 0 or not PLAUSIBLE_STEP[0] <= float(np.median(steps)) < PLAUSIBLE_STEP[1]:
        return None
    return column if factor == 1.0 else f"{factor:g}*{column}"


#: the second's column of a stamp split in two, by its name's last word, and the fraction's columns beside it with
#: their factor to seconds: ROS 2's ``builtin_interfaces/Time`` (``sec``, ``nanosec``), ROS 1's ``time``
#: (``secs``, ``nsecs``), ABB EGM's ``EgmClock`` (``sec``, ``usec``: egm.proto)
STAMP_SECONDS = ("sec", "secs")
STAMP_FRACTIONS = {"nanosec": 1e-9, "nanosecs": 1e-9, "nsec": 1e-9, "nsecs": 1e-9, "usec": 1e-6, "usecs": 1e-6}
#: the words of a split stamp's name that make it the time of a command (EGM's ``planned.time``), not of the sample
_COMMAND_STAMP_WORDS = frozenset({"planned", "target", "command", "commanded", "cmd", "desired", "goal", "ref"})
_STAMP_PART = re.compile(r"^(?P<prefix>.*?)(?P<word>[A-Za-z]+)\s*$")


def split_stamps(frame: pd.DataFrame) -> list[str]:
    """The time stamps of ``frame`` split into a seconds column and a fraction column beside it (ROS 2's
    ``header.stamp.sec`` and ``header.stamp.nanosec``, or ``sec`` and ``nanosec``; ROS 1's ``secs``/``nsecs``; ABB
    EGM's ``feedBack.time.sec``/``usec``: :data:`STAMP_FRACTIONS`), each as the column map's entry that joins it
    (``"header.stamp.sec+1e-09*header.stamp.nanosec"``, :func:`apply_column_map`); stamps of a command
    (``planned.time``) left out, and pairs whose fraction is not below one second or whose joined steps are not a
    robot log's (:data:`PLAUSIBLE_STEP`)."""
    columns = [str(column) for column in frame.columns]
    found = []
    for column in columns:
        part = _STAMP_PART.match(column)
        if part is None or part.group("word").lower() not in STAMP_SECONDS:
            continue
        prefix = part.group("prefix")
        if set(re.findall(r"[a-z]+", prefix.lower())) & _COMMAND_STAMP_WORDS:
            continue
        for fraction_column in columns:
            fraction = _STAMP_PART.match(fraction_column)
            if fraction is None or fraction.group("prefix") != prefix:
                continue
            factor = STAMP_FRACTIONS.get(fraction.group("word").lower())
            if factor is None:
                continue
            seconds = pd.to_numeric(frame[column], errors="coerce").to_numpy(dtype=float)
            parts = pd.to_numeric(frame[fraction_column], errors="coerce").to_numpy(dtype=float)
            kept = np.isfinite(seconds) & np.isfinite(parts)
            if not kept.any() or np.any(parts[kept] < 0) or np.any(parts[kept] * factor >= 1.0):
                continue
            joined = (seconds[kept] - seconds[kept][0]) + factor * parts[kept]
            steps = np.diff(joined)
            steps = steps[steps > 0]
            if steps.size and PLAUSIBLE_STEP[0] <= float(np.median(steps)) < PLAUSIBLE_STEP[1]:
                found.append(f"{column}+{factor:g}*{fraction_column}")
    return found


#: ABB EGM's message header's time (egm.proto, ``EgmHeader``: ``optional uint32 tm = 2; // Timestamp in
#: milliseconds``): a column whose name's last word is ``tm`` after a ``header`` word, read in milliseconds
EGM_HEADER_TIME = ("header", "tm")


def header_milliseconds(frame: pd.DataFrame) -> str | None:
    """For a table without a ``t`` column nor a split stamp, ABB EGM's header stamp as the column map's entry that
    reads it in seconds (``"0.001*header.tm"``, :data:`EGM_HEADER_TIME`): the one column named ``…header.tm`` (case
    and separators ignored; a command's header, ``planned…``, left out) whose steps, in milliseconds, are a robot
    log's (:data:`PLAUSIBLE_STEP`); ``None`` otherwise."""
    if "t" in frame.columns:
        return None
    found = []
    for column in frame.columns:
        words = re.findall(r"[a-z]+", str(column).lower())
        if len(words) >= 2 and tuple(words[-2:]) == EGM_HEADER_TIME and not set(words) & _COMMAND_STAMP_WORDS:
            found.append(str(column))
    if len(found) != 1:
        return None
    values = pd.to_numeric(frame[found[0]], errors="coerce").to_numpy(dtype=float) * 1e-3
    steps = np.diff(values[np.isfinite(values)])
    steps = steps[steps > 0]
    if steps.size == 0 or not PLAUSIBLE_STEP[0] <= float(np.median(steps)) < PLAUSIBLE_STEP[1]:
        return None
    return f"0.001*{found[0]}"


@dataclass(frozen=True)
class LogSource(os.PathLike):
    """A log file (or rosbag2 folder) with how to read it: the ROS topic and a column map.

    Anywhere a data path is taken, a :class:`LogSource` may stand in for it (it is path-like).

    Parameters
    ----------
    path
        The file or rosbag2 folder.
    topic
        The topic of the ``sensor_msgs/JointState`` messages in a bag.
    columns
        Column map ``{column or group: name in the file}`` (:func:`parse_column_map`); empty: names as they are.
    joint_names
        The joints of a bag's messages to read, in this order; default the robot's.
    """

    path: Path
    topic: str = DEFAULT_TOPIC
    columns: Mapping[str, str] = field(default_factory=dict)
    joint_names: tuple[str, ...] | None = None

    def __post_init__(self) -> None:
        object.__setattr__(self, "path", Path(self.path))
        object.__setattr__(self, "columns", dict(self.columns))

    def __fspath__(self) -> str:
        return os.fspath(self.path)

    def __str__(self) -> str:
        return str(self.path)

    def __getattr__(self, name: str) -> Any:  # the path's own (suffix, exists, expanduser…): it stands in for one
        if name.startswith("__") or name == "path":
            raise AttributeError(name)
        return getattr(self.path, name)


def parse_column_map(text: str | Mapping[str, str] | None) -> dict[str, str]:
    """``"t=times,q=positions,tau=35.15*vir"`` as ``{"t": "times", "q": "positions", "tau": "35.15*vir"}``.

    Raises
    ------
    ValueError
        An entry that is not ``column=name``, or a column named twice.
    """
    if text is None:
        return {}
    if isinstance(text, Mapping):
        return {str(key).strip(): str(value).strip() for key, value in text.items()}
    columns: dict[str, str] = {}
    for item in filter(None, (part.strip() for part in str(text).split(","))):
        key, sign, value = item.partition("=")
        if not sign or not key.strip() or not value.strip():
            raise ValueError(f"column map entry {item!r}: expected COLUMN=NAME (e.g. t=times,q=positions)")
        if key.strip() in columns:
            raise ValueError(f"column map: {key.strip()!r} mapped twice")
        columns[key.strip()] = value.strip()
    return columns


def _path(source: str | os.PathLike[str]) -> Path:
    return Path(os.fspath(source))


def is_log_file(source: str | os.PathLike[str]) -> bool:
    """Whether ``source`` is read here rather than as a CSV or Parquet table: a bag, a rosbag2 folder, an
    ``.npz`` or ``.mat`` file, or a :class:`LogSource` with a column map."""
    path = _path(source)
    if isinstance(source, LogSource) and source.columns:
        return True
    return path.suffix.lower() in BAG_SUFFIXES + ARRAY_SUFFIXES or (path.is_dir() and (path / "metadata.yaml").is_file())


def read_log_frame(source: str | os.PathLike[str], *, joint_names: Sequence[str] | None = None,
                   n_joints: int | None = None) -> pd.DataFrame:
    """The log as a table of :mod:`dynamics.measurements` (module docstring).

    Parameters
    ----------
    source
        A path or :class:`LogSource`.
    joint_names
        The robot's joints, in its order (a bag's messages are matched to them by name); ``source.joint_names``
        wins when given.
    n_joints
        The robot's number of joints (a 2-D array's columns are checked against it).

    Raises
    ------
    RosSupportError
        A bag without the ``ros`` extra installed.
    UnknownTopicError
        No ``JointState`` messages on the topic: the message names the topics and types the bag holds.
    MissingColumnError
        A named joint absent from the messages, or a mapped name absent from the file.
    MeasurementError
        A file that cannot be read.
    """
    path = _path(source)
    log = source if isinstance(source, LogSource) else LogSource(path)
    if not path.exists():
        raise FileNotFoundError(f"data file not found: {path}")
    suffix = path.suffix.lower()
    if suffix in BAG_SUFFIXES or path.is_dir():
        names = log.joint_names if log.joint_names is not None else joint_names
        if names is None:
            raise MeasurementError(f"{path}: a ROS bag is read by joint name: name the joints (--joint-names with "
                                   "--urdf, or a robot)")
        frame = _bag_frame(path, log.topic, list(names))
        return apply_column_map(frame, log.columns, str(path)) if log.columns else frame
    if suffix in ARRAY_SUFFIXES:
        return _array_frame(_arrays(path), log.columns, str(path), n_joints)
    try:
        frame = pd.read_parquet(path) if suffix == ".parquet" \
            else without_repeated_headers(pd.read_csv(path), str(path))
    except (ValueError, OSError, ImportError, pd.errors.ParserError) as error:
        raise MeasurementError(f"cannot read {path}: {str(error).strip()}") from None
    return apply_column_map(frame, log.columns, str(path), joint_names=joint_names)


def _scaled(value: str) -> tuple[float, str]:
    """``"35.15*vir"`` as ``(35.15, "vir")``; ``"vir"`` as ``(1.0, "vir")``."""
    found = _FACTOR.match(value)
    return (float(found.group(1)), found.group(2)) if found else (1.0, value)


def apply_column_map(frame: pd.DataFrame, columns: Mapping[str, str], source: str, *,
                     joint_names: Sequence[str] | None = None) -> pd.DataFrame:
    """``frame`` with the mapped columns under the names of :mod:`dynamics.measurements` (module docstring).

    A group mapped by its prefix (``q=field.position``) beside columns that name the joint of each index
    (``field.name0..``, as ``rostopic echo -p`` writes a ``JointState``) is matched to ``joint_names`` (the robot's,
    in its order) by those names, as a bag's messages are (:func:`logged_joints`)."""
    if not columns:
        return frame
    renamed: dict[str, Any] = {}
    used: set[str] = set()
    for key, value in columns.items():
        factor, name = _scaled(value)
        if key == "t" and name not in frame.columns and value not in frame.columns and "+" in value:
            renamed[key] = _summed_time(frame, value, source)  # a stamp split in two: sec+1e-09*nanosec
            used.update(_scaled(term)[1] for term in value.split("+"))
            continue
        if name in frame.columns:
            renamed[f"{key}1" if key in JOINT_GROUPS else key] = factor * pd.to_numeric(frame[name], errors="coerce") if factor != 1.0 else frame[name]
            used.add(name)
            continue
        prefixed = sorted((column for column in frame.columns if re.fullmatch(re.escape(name) + r"\d+", str(column))),
                          key=lambda column: int(str(column)[len(name):]))
        if key in JOINT_GROUPS and prefixed:
            first = int(str(prefixed[0])[len(name):])  # numbered from 0 (a ROS array, Python): joint 1 is name0
            named = logged_joints(frame, name, prefixed, joint_names, source)
            for column in prefixed:
                index = int(str(column)[len(name):])
                joint = index + (1 if first == 0 else 0) if named is None else named.get(index)
                if joint is not None:  # a joint the robot does not have (a gripper's finger) is left out
                    renamed[f"{key}{joint}"] = factor * frame[column] if factor != 1.0 else frame[column]
            used.update(prefixed)
            continue
        raise MissingColumnError(f"{source}: column map {key}={value}: no column {name!r} (columns: "
                                 + ", ".join(map(str, frame.columns)) + ")")
    kept = frame[[column for column in frame.columns if column not in used and column not in renamed]]
    return pd.concat([pd.DataFrame(renamed, index=frame.index), kept], axis=1)


def _summed_time(frame: pd.DataFrame, value: str, source: str) -> pd.Series:
    """The time of a column map's sum ``t=SECONDS+FACTOR*FRACTION`` (a stamp split in two, :func:`split_stamps`),
    counted from the first row's value of its first term: seconds since 1970 (1.7e9) and their nanoseconds do not
    both fit in a double (its step there is 2.4e-7 s), their differences do."""
    total = None
    for index, term in enumerate(value.split("+")):
        factor, name = _scaled(term)
        if name not in frame.columns:
            raise MissingColumnError(f"{source}: column map t={value}: no column {name!r} (columns: "
                                     + ", ".join(map(str, frame.columns)) + ")")
        values = pd.to_numeric(frame[name], errors="coerce").astype(float)
        if index == 0:
            finite = values[np.isfinite(values)]
            values = values - (float(finite.iloc[0]) if len(finite) else 0.0)
        total = factor * values if total is None else total + factor * values
    return total


def logged_joints(frame: pd.DataFrame, prefix: str, prefixed: Sequence[str], joint_names: Sequence[str] | None,
                  source: str) -> dict[int, int] | None:
    """For a group ``prefix0..`` whose table also holds the joints' names by index (``field.name0..`` beside
    ``field.position0..``: the prefix's last word replaced by ``name``), the robot's joint (1-based, in
    ``joint_names``) of each index the names give; ``None`` without such names or without ``joint_names``.

    A ``JointState`` lists its joints in the publisher's order (a UR driver's: elbow first), not the
    description's: taking index ``k`` as joint ``k + 1`` would fit one joint's torque with another's motion.

    Raises
    ------
    MissingColumnError
        A joint of the robot that no index names, or names that change from row to row."""
    names_prefix = re.sub(r"[A-Za-z]+(_?)$", r"name\1", prefix)
    indices = [int(str(column)[len(prefix):]) for column in prefixed]
    name_columns = [f"{names_prefix}{index}" for index in indices]
    if joint_names is None or names_prefix == prefix or not all(column in frame.columns for column in name_columns):
        return None
    names = frame[name_columns].astype(str)
    if len(names) and not (names == names.iloc[0]).all().all():
        changing = [column for column in name_columns if names[column].nunique() > 1]
        raise MissingColumnError(f"{source}: the joint names {', '.join(changing)} change from row to row: the "
                                 "joints cannot be matched to the robot's by name (write one joint order per file)")
    logged = [str(value).strip() for value in names.iloc[0]] if len(names) else []
    missing = [name for name in joint_names if name not in logged]
    if missing:
        raise MissingColumnError(f"{source}: the robot's joint(s) {', '.join(missing)} are not among the joints "
                                 f"{names_prefix}0.. name ({', '.join(logged)})")
    return {index: list(joint_names).index(name) + 1 for index, name in zip(indices, logged) if name in joint_names}


def _arrays(path: Path) -> dict[str, np.ndarray]:
    """The arrays of an ``.npz`` or ``.mat`` file by name (MATLAB's own variables ``__header__``… left out)."""
    try:
        if path.suffix.lower() == ".npz":
            with np.load(path, allow_pickle=False) as archive:
                return {name: np.asarray(archive[name]) for name in archive.files}
        from scipy.io import loadmat

        return {name: np.asarray(value) for name, value in loadmat(path).items() if not name.startswith("__")}
    except NotImplementedError:
        raise MeasurementError(f"cannot read {path}: a MATLAB 7.3 (HDF5) file; save it with save(..., '-v7')") from None
    except (ValueError, OSError, TypeError) as error:
        raise MeasurementError(f"cannot read {path}: {str(error).strip()}") from None


def _array_frame(arrays: Mapping[str, np.ndarray], columns: Mapping[str, str], source: str,
                 n_joints: int | None) -> pd.DataFrame:
    """The table of named arrays: each mapped (or, without a map, each array) as its column or group."""
    wanted = dict(columns) if columns else {name: name for name in arrays}
    table: dict[str, np.ndarray] = {}
    unmapped: list[str] = []  # arrays without a map that are no column (2-D, not named as a group)
    for key, value in wanted.items():
        factor, name = _scaled(value)
        if name not in arrays:
            raise MissingColumnError(f"{source}: column map {key}={value}: no array {name!r} (arrays: "
                                     + ", ".join(sorted(arrays)) + ")")
        array = np.asarray(arrays[name])
        if array.dtype.kind not in "biuf":
            if columns:
                raise MeasurementError(f"{source}: array {name!r} holds {array.dtype} values, not numbers")
            continue  # an unmapped array of text or objects: not a column
        array = factor * array.astype(float)
        if array.ndim == 2 and 1 in array.shape:
            array = array.reshape(-1)
        if array.ndim == 1:
            table[f"{key}1" if key in JOINT_GROUPS else key] = array  # a group of one joint
        elif array.ndim == 2 and key in JOINT_GROUPS + ("wrench",):
            if array.shape[1] > array.shape[0]:
                array = array.T  # joints x samples, as MATLAB users often store them
            if key == "wrench":
                table.update({channel: array[:, index] for index, channel in enumerate(WRENCH_CHANNELS)})
                continue
            if n_joints is not None and array.shape[1] < n_joints:
                raise MissingColumnError(f"{source}: array {name!r} ({key}) has {array.shape[1]} columns for "
                                         f"{n_joints} joints")
            table.update({f"{key}{index + 1}": array[:, index] for index in range(array.shape[1])})
        elif columns:
            raise MeasurementError(f"{source}: array {name!r} has shape {array.shape}: map a 1-D array to a column "
                                   f"or a 2-D one (samples x joints) to a group ({', '.join(JOINT_GROUPS)})")
        else:
            unmapped.append(f"{name} ({' x '.join(str(size) for size in array.shape)})")
    lengths = {name: len(values) for name, values in table.items()}
    if len(set(lengths.values())) > 1:
        raise MeasurementError(f"{source}: the arrays have different lengths ({lengths}); map the ones of one record "
                               "(--columns t=...,q=...)")
    frame = pd.DataFrame(table)
    if unmapped:  # named by a missing column's message (estimation.data.loading.require_columns)
        frame.attrs["unmapped_arrays"] = tuple(unmapped)
    return frame


def _ros_reader() -> tuple[Any, Any, Any]:
    try:
        from rosbags.highlevel import AnyReader
        from rosbags.typesys import Stores, get_typestore
    except ImportError:
        raise RosSupportError("reading ROS bags needs the ros extra: pip install 'robot-oed[ros]' (the pure-Python "
                              "rosbags package, no ROS install)") from None
    return AnyReader, Stores, get_typestore


def _bag_frame(path: Path, topic: str, joint_names: list[str]) -> pd.DataFrame:
    """The ``JointState`` messages of ``topic`` as a table (module docstring)."""
    any_reader, stores, get_typestore = _ros_reader()
    typestore = get_typestore(stores.ROS1_NOETIC if path.suffix.lower() == ".bag" else stores.ROS2_HUMBLE)
    messages: list[tuple[int, int, list[str], list[float], list[float], list[float]]] = []
    try:
        with any_reader([path], default_typestore=typestore) as reader:
            connections = [connection for connection in reader.connections if connection.topic == topic]
            if not connections or not all(connection.msgtype.endswith("JointState") for connection in connections):
                held = sorted({(connection.topic, connection.msgtype) for connection in reader.connections})
                raise UnknownTopicError(
                    f"{path}: no sensor_msgs/JointState messages on topic {topic!r}; the bag holds "
                    + (", ".join(f"{name} ({kind})" for name, kind in held) if held else "no messages")
                    + " (choose one with --topic)")
            for connection, timestamp, data in reader.messages(connections=connections):
                message = reader.deserialize(data, connection.msgtype)
                stamp = int(message.header.stamp.sec) * 1_000_000_000 + int(message.header.stamp.nanosec)
                messages.append((stamp, int(timestamp), list(message.name), list(message.position),
                                 list(message.velocity), list(message.effort)))
    except (UnknownTopicError, RosSupportError):
        raise
    except Exception as error:  # the reader's own errors (a corrupt or unknown bag) name no common base
        if isinstance(error, (KeyboardInterrupt, MemoryError)):
            raise
        raise MeasurementError(f"cannot read the ROS bag {path}: {error.__class__.__name__}: {error}") from None
    by_header = any(message[0] != 0 for message in messages)  # else the publisher left the header empty
    stamps: dict[int, dict[str, list[float | None]]] = {}  # stamp (ns) -> joint -> [position, velocity, effort]
    for stamp, logged, names, position, velocity, effort in messages:
        row = stamps.setdefault(stamp if by_header else logged, {})
        for index, name in enumerate(names):
            row[name] = [float(values[index]) if index < len(values) else None
                         for values in (position, velocity, effort)]
    seen = {name for row in stamps.values() for name in row}
    missing = [name for name in joint_names if name not in seen]
    if missing:
        raise MissingColumnError(f"{path}: joint(s) {', '.join(missing)} in no JointState message on {topic}; the "
                                 "messages name " + (", ".join(sorted(seen)) or "no joint"))
    return _joint_table(path, stamps, joint_names)


def _joint_table(path: Path, stamps: Mapping[int, Mapping[str, list[float | None]]],
                 joint_names: list[str]) -> pd.DataFrame:
    """The rows of the stamps at which every named joint has a position, in time order."""
    order = sorted(stamps)
    complete = [stamp for stamp in order if all(name in stamps[stamp] and stamps[stamp][name][0] is not None
                                               for name in joint_names)]
    if not complete:
        raise MissingColumnError(f"{path}: the joints {', '.join(joint_names)} never appear at one stamp together")
    if len(complete) < len(order):
        warnings.warn(DroppedStampsWarning(f"{path}: {len(order) - len(complete)} of {len(order)} stamps lack the "
                                           "position of a named joint in every message: dropped"), stacklevel=3)
    times = np.array(complete, dtype=np.int64)
    table: dict[str, np.ndarray] = {"t": (times - times[0]).astype(float) * 1e-9}
    for field_index, prefix in ((0, "q"), (1, "dq"), (2, "tau")):
        values = [[stamps[stamp][name][field_index] for name in joint_names] for stamp in complete]
        if field_index and any(value is None for row in values for value in row):
            continue  # velocity or effort not in every message: not read
        array = np.array(values, dtype=float)
        table.update({f"{prefix}{index + 1}": array[:, index] for index in range(len(joint_names))})
    return pd.DataFrame(table)
