"""Options shared by the verbs: which robot; the records, their derivatives and the streamed path (``oed identify``
and ``oed diagnose``); and how a verb hands its options to its library function (:func:`verb_keywords`) and prints
what it returns (:func:`print_warnings`, :func:`stderr_say`)."""

from __future__ import annotations

import argparse
import dataclasses
import sys
from collections.abc import Callable, Iterable
from pathlib import Path
from typing import Any

from dynamics.mjcf import is_mjcf
from dynamics.robots import BUILT_IN_ROBOTS
from estimation.data.log_cleaning import DEFAULT_MAX_GAP
from estimation.data.log_formats import DEFAULT_TOPIC, parse_column_map
from estimation.estimators.normal_equations import DEFAULT_CHUNK_SIZE
from estimation.streaming.settings import SCHEDULER_VARIABLE

__all__ = [
    "add_data_arguments", "add_derivative_arguments", "add_jobs_argument", "add_log_arguments", "add_robot_arguments",
    "add_streaming_arguments", "print_lines", "print_warnings", "seed", "stderr_say", "verb_keywords",
]


def add_robot_arguments(parser: argparse.ArgumentParser, *, default: str | None = "puma560") -> None:
    """``--robot NAME``, ``--urdf FILE`` or ``--mjcf FILE`` (which win) and ``--joints N``.

    ``--mjcf`` fills the same option as ``--urdf`` (the robot's description file: the verbs, the model file and
    ``oed predict`` read either by its root element, :func:`dynamics.robots.load_robot`); the two exclude each other.
    """
    group = parser.add_argument_group("robot")
    group.add_argument(
        "--robot", default=default, help=f"built-in robot: {', '.join(sorted(BUILT_IN_ROBOTS))} (default: {default})"
    )
    files = group.add_mutually_exclusive_group()
    files.add_argument("--urdf", type=Path, help="URDF file of a serial chain (stands in for --robot)")
    files.add_argument("--mjcf", dest="urdf", type=mjcf_file, metavar="MJCF",
                       help="MuJoCo MJCF model (<mujoco> file, e.g. from MuJoCo Menagerie) of a serial chain, read as "
                            "--urdf is (stands in for --robot)")
    group.add_argument("--joints", type=int, help="keep only the first N joints (the PUMA paper uses 3)")
    add_joint_selection_arguments(group)


def mjcf_file(text: str) -> Path:
    """``--mjcf`` values: a file that exists and is not MJCF (a URDF) is refused by argparse, naming ``--urdf``
    (one that is missing or unreadable is named by the reader)."""
    path = Path(text)
    if path.is_file() and not is_mjcf(path):
        raise argparse.ArgumentTypeError(f"{text} is not a MuJoCo MJCF model (its root element is not <mujoco>)"
                                         + ("; a URDF goes to --urdf" if path.suffix.lower() == ".urdf" else ""))
    return path


def add_joint_selection_arguments(group: Any) -> None:
    """``--joint-names a,b,c`` and ``--locked-at name=value,...`` (the logged joints of any URDF)."""
    group.add_argument("--joint-names", type=joint_name_list, metavar="A,B,C",
                       help="with --urdf or --mjcf: the logged joints, base to tip (columns q1..qN and tau1..tauN follow this "
                            "order); every other joint of the file is locked")
    group.add_argument("--locked-at", type=locked_positions, default=None, metavar="NAME=VALUE,...",
                       help="with --joint-names: positions of locked joints, rad or m (default 0)")
    group.add_argument("--passive", type=joint_name_list, default=None, metavar="JOINT,...",
                       help="passive (unactuated) joints, by name or number from 1: no motor drives them, their torque "
                            "is zero by physics (0 = Y_j theta, their own friction in the model), a measurement of zero "
                            "that the fit uses; the log needs no torque column for them (docs/guides/robots-and-logs.md)")


def joint_name_list(text: str) -> tuple[str, ...]:
    """``--joint-names`` values: comma-separated names, checked by argparse."""
    names = tuple(name.strip() for name in text.split(","))
    if not all(names):
        raise argparse.ArgumentTypeError(f"expected comma-separated joint names, got {text!r}")
    return names


def locked_positions(text: str) -> dict[str, float]:
    """``--locked-at`` values: ``name=value`` pairs separated by commas, checked by argparse."""
    positions: dict[str, float] = {}
    for item in filter(None, (part.strip() for part in text.split(","))):
        name, _, value = item.partition("=")
        try:
            positions[name.strip()] = float(value)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected NAME=VALUE pairs, got {item!r}") from None
        if not name.strip():
            raise argparse.ArgumentTypeError(f"expected NAME=VALUE pairs, got {item!r}")
    return positions


def add_log_arguments(parser: argparse.ArgumentParser) -> None:
    """``--topic`` and ``--columns``: how to read ROS bags, ``.npz`` and ``.mat`` files (the library wraps such data
    paths as :class:`estimation.data.log_formats.LogSource`)."""
    group = parser.add_argument_group("logs (ROS bags, .npz, .mat, other column names)")
    group.add_argument("--topic", default=DEFAULT_TOPIC,
                       help=f"topic of the sensor_msgs/JointState messages in a ROS bag (default {DEFAULT_TOPIC}); "
                            "joints matched by name to --joint-names or the URDF's joints")
    group.add_argument("--columns", type=column_map, default=None, metavar="COLUMN=NAME,...",
                       help="column map, e.g. t=times,q=positions,dq=velocities,tau=torques (an .npz's or .mat's "
                            "arrays, a table's columns; a factor scales: tau=35.15*vir)")


def column_map(text: str) -> dict[str, str]:
    """``--columns`` values, checked by argparse."""
    try:
        return parse_column_map(text)
    except ValueError as error:
        raise argparse.ArgumentTypeError(str(error)) from None


def seed(text: str) -> int:
    """``--seed`` values: non-negative integers (what ``numpy.random`` accepts), checked by argparse."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be a non-negative integer, got {text!r}") from None
    if value < 0:
        raise argparse.ArgumentTypeError(f"must be a non-negative integer, got {value}")
    return value


def add_data_arguments(parser: argparse.ArgumentParser, *, validate_required: bool) -> None:
    """``--data`` and ``--validate`` (each repeatable: the segments of one record), ``--max-gap``, and the options
    of :func:`add_log_arguments`."""
    parser.add_argument("--data", type=Path, required=True, action="append",
                        help="identification data (.csv or .parquet, a .csv packed as .gz, .bz2, .xz or a one-file .zip; a ROS bag: .mcap, .db3, .bag or a rosbag2 "
                             "folder; .npz or .mat with --columns); repeat for several segments (files), each "
                             "preprocessed on its own and stacked")
    parser.add_argument("--validate", type=Path, required=validate_required, action="append",
                        help="validation data from another trajectory; repeatable like --data")
    parser.add_argument("--max-gap", type=float, default=DEFAULT_MAX_GAP, metavar="SECONDS",
                        help=f"longest logger stall bridged by interpolation (default {DEFAULT_MAX_GAP:g} s); a longer "
                             "hole splits a --data or --validate file into segments")
    add_log_arguments(parser)


def jobs_count(text: str) -> int | None:
    """``--jobs``: ``auto`` (``None``: the cores available, at most 4) or a positive number of processes."""
    if text == "auto":
        return None
    try:
        jobs = int(text)
    except ValueError:
        jobs = 0
    if jobs < 1:
        raise argparse.ArgumentTypeError(f"must be 'auto' or a positive number of processes, got {text!r}")
    return jobs


def add_jobs_argument(parser: argparse.ArgumentParser, work: str) -> None:
    """``--jobs N``: processes that run ``work`` side by side (forks of this one; the results are the same)."""
    parser.add_argument("--jobs", type=jobs_count, default=None, metavar="N",
                        help=f"processes that run {work} side by side (default auto: the cores available, at most "
                             "4; 1: in turn); the results are the same whatever N")


def add_derivative_arguments(parser: argparse.ArgumentParser) -> None:
    """``--frequency/--harmonics`` (Fourier fit) or ``--cutoff`` (Butterworth), and ``--decimate``."""
    derivatives = parser.add_argument_group("derivatives (only when dq/ddq columns are absent)")
    derivatives.add_argument("--frequency", type=float, help="periodic excitation: fundamental frequency, Hz, any "
                             "value (Fourier fit of the positions on their time stamps; checked against the period "
                             "the data show). Default: detected when the positions repeat, else a filter")
    derivatives.add_argument("--average-periods", choices=("auto", "yes", "no"), default="auto",
                             help="average whole periods before the Fourier fit: auto (default) when there are two or "
                                  "more and a period is a whole number of samples, else fit every sample")
    derivatives.add_argument("--harmonics", type=int, help="harmonics of the Fourier fit (default: 5, the paper's, with "
                             "--frequency; 15 for a detected frequency; records of a robot under feedback want about "
                             "three times the reference's)")
    derivatives.add_argument("--cutoff", type=float, help="otherwise: Butterworth cut-off, Hz (default: automatic)")
    derivatives.add_argument("--decimate", type=int, default=1, help="keep one sample in K after low-pass filtering")
    derivatives.add_argument("--held-torques", action=argparse.BooleanOptionalAction, default=None,
                             help="joint torques were held over each sample (zero-order hold, as `oed simulate` "
                                  "and digital current commands): take the derived motion half a sample later; "
                                  "--no-held-torques: they were not; default: chosen by held-out error")


def add_streaming_arguments(parser: argparse.ArgumentParser) -> None:
    """``--chunk-size``, ``--scheduler``, ``--workers``: the bounded-memory, distributed path."""
    streaming = parser.add_argument_group(
        "bounded memory and clusters (estimation.streaming.identification)",
        "read and sum the files chunk by chunk (peak memory set by the chunk, not the record), in this process, "
        "a process pool or on a dask cluster; any of these options selects this path")
    streaming.add_argument("--chunk-size", type=int, help=f"samples a chunk (default {DEFAULT_CHUNK_SIZE} when "
                           "streaming)")
    streaming.add_argument("--scheduler", help=f"dask scheduler address (tcp://host:8786) to sum the files on a "
                           f"cluster (default: ${SCHEDULER_VARIABLE}); needs pip install 'robot-oed[cluster]'")
    streaming.add_argument("--workers", type=int, default=0, help="sum the files in a local process pool of this size")
    streaming.add_argument("--memory-budget", metavar="SIZE",
                           help="memory the in-memory path may take (2GB, 500MB, 1.5GiB or bytes; default 1GB, the "
                                "same on every machine): past it, estimated from the files' rows before reading them, "
                                "the files are streamed (the same choices; one line on stderr says so)")
    streaming.add_argument("--quiet", action="store_true", help="no progress lines on stderr")


def verb_keywords(args: argparse.Namespace, options: type, **overrides: Any) -> dict[str, Any]:
    """The keywords of a verb's library function: the parsed options whose names are fields of the dataclass
    ``options`` (:class:`oed.workflows.options.RecordOptions` and its kin), with ``overrides``."""
    names = {field.name for field in dataclasses.fields(options)}
    keywords = {name: value for name, value in vars(args).items() if name in names}
    keywords.update(overrides)
    return keywords


def stderr_say(verb: str) -> Callable[[str], None]:
    """A ``say`` for a library call: each line on stderr as ``oed VERB: line``."""
    def say(line: str) -> None:
        print(f"oed {verb}: {line}", file=sys.stderr)
    return say


def print_warnings(verb: str, messages: Iterable[str]) -> None:
    """Each warning on stderr as ``oed VERB: warning: message``."""
    for message in messages:
        print(f"oed {verb}: warning: {message}", file=sys.stderr)


def print_lines(lines: Iterable[str], *, file: Any = None) -> None:
    """The lines of a run's ``summary()``."""
    for line in lines:
        print(line, file=file)
