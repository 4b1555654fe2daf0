"""Options shared by the verbs: which robot; the records, their derivatives and the streamed path (``oed identify``
and ``oed diagnose``); the checks and messages those verbs share; the output-file helpers, re-exported for the verbs."""

from __future__ import annotations

import argparse
import contextlib
import sys
import warnings
from collections.abc import Iterable, Iterator
from concurrent.futures import Executor, ProcessPoolExecutor
from pathlib import Path
from typing import Any

from dynamics.effects.linear import parse_effects
from dynamics.effects.shaped import is_shaped
from dynamics.models import IdentificationModel
from dynamics.robot import RobotModel
from dynamics.robots import BUILT_IN_ROBOTS, load_robot
from dynamics.runtime.output_files import (
    OutputFiles,
    atomic_output,
    check_figure_path,
    json_text,
)
from dynamics.transmission import Transmission
from estimation.data.log_cleaning import DEFAULT_MAX_GAP
from estimation.data.log_formats import DEFAULT_TOPIC, LogSource, is_log_file, parse_column_map
from estimation.estimators.effect_blocks import NoRowsError
from estimation.estimators.normal_equations import DEFAULT_CHUNK_SIZE
from estimation.preprocessing.differentiation import (
    ButterworthDifferentiation,
    Differentiation,
    FourierDifferentiation,
)
from estimation.identification.prepared import InMemoryBudget, PreparationSettings
from estimation.streaming.cluster import SCHEDULER_VARIABLE, connect, scheduler_address
from oed.cli.shared.options import check_hertz

__all__ = [
    "OutputFiles", "add_data_arguments", "add_log_arguments", "bind_log_options", "add_derivative_arguments", "add_jobs_argument", "add_robot_arguments", "add_streaming_arguments",
    "atomic_output", "check_csv_path", "check_figure_path", "check_json_path", "check_shaped_effects_kept",
    "differentiation", "executor_from_arguments", "json_text", "model_has_shapes", "preparation_settings",
    "print_warnings", "robot_from_arguments", "seed", "streaming_requested",
]

#: suffixes that promise another format than the CSV a verb writes
NOT_CSV_SUFFIXES = frozenset({".json", ".parquet", ".png", ".pdf", ".svg", ".npz", ".npy", ".mat", ".xlsx", ".md"})


def add_robot_arguments(parser: argparse.ArgumentParser, *, default: str | None = "puma560") -> None:
    """``--robot NAME``, ``--urdf FILE`` (which wins) and ``--joints N``."""
    group = parser.add_argument_group("robot")
    group.add_argument(
        "--robot", default=default, help=f"built-in robot: {', '.join(sorted(BUILT_IN_ROBOTS))} (default: {default})"
    )
    group.add_argument("--urdf", type=Path, help="URDF file of a serial chain (stands in for --robot)")
    group.add_argument("--joints", type=int, help="keep only the first N joints (the PUMA paper uses 3)")
    add_joint_selection_arguments(group)


def add_joint_selection_arguments(group: Any) -> None:
    """``--joint-names a,b,c`` and ``--locked-at name=value,...`` (the logged joints of any URDF)."""
    group.add_argument("--joint-names", type=joint_name_list, metavar="A,B,C",
                       help="with --urdf: the logged joints, base to tip (columns q1..qN and tau1..tauN follow this "
                            "order); every other joint of the URDF is locked")
    group.add_argument("--locked-at", type=locked_positions, default=None, metavar="NAME=VALUE,...",
                       help="with --joint-names: positions of locked joints, rad or m (default 0)")


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


def seed(text: str) -> int:
    """``--seed`` values: non-negative integers (what ``numpy.random`` accepts), checked by argparse."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be a non-negative integer, got {text!r}") from None
    if value < 0:
        raise argparse.ArgumentTypeError(f"must be a non-negative integer, got {value}")
    return value


def check_csv_path(path: str | Path, option: str = "--out") -> None:
    """Refuse, before any work, a CSV output named like another format (``--out u.json``)."""
    if Path(path).suffix.lower() in NOT_CSV_SUFFIXES:
        raise ValueError(f"{option} {path}: this verb writes CSV; give a .csv file name")


def check_json_path(path: str | Path, option: str = "--out") -> None:
    """Refuse, before any work, a JSON output named like another format (``--out t.csv``)."""
    suffix = Path(path).suffix.lower()
    if suffix in NOT_CSV_SUFFIXES - {".json"} or suffix == ".csv":
        raise ValueError(f"{option} {path}: this writes JSON; give a .json file name")


def robot_from_arguments(args: argparse.Namespace) -> RobotModel:
    return load_robot(args.robot, urdf=args.urdf, joints=args.joints, joint_names=getattr(args, "joint_names", None),
                      locked_at=getattr(args, "locked_at", None))


def add_log_arguments(parser: argparse.ArgumentParser) -> None:
    """``--topic`` and ``--columns``: how to read ROS bags, ``.npz`` and ``.mat`` files (bound to the data paths
    by :func:`bind_log_options`)."""
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


def bind_log_options(args: argparse.Namespace) -> None:
    """Each ``--data``, ``--validate`` and ``--test`` path that is a log file (a bag, ``.npz``, ``.mat``; any with
    ``--columns``) as a :class:`estimation.data.log_formats.LogSource` carrying ``--topic`` and ``--columns``."""
    if not hasattr(args, "topic"):
        return
    columns = getattr(args, "columns", None) or {}
    for option in ("data", "validate", "test"):
        paths = getattr(args, option, None)
        if paths:
            setattr(args, option, [LogSource(path, topic=args.topic, columns=columns)
                                   if columns or is_log_file(path) else path for path in paths])


def add_data_arguments(parser: argparse.ArgumentParser, *, validate_required: bool) -> None:
    """``--data`` and ``--validate`` (each repeatable: the segments of one record), ``--max-gap``, and the options
    of :func:`add_log_arguments`."""
    parser.add_argument("--data", type=Path, required=True, action="append",
                        help="identification data (.csv or .parquet; a ROS bag: .mcap, .db3, .bag or a rosbag2 "
                             "folder; .npz or .mat with --columns); repeat for several segments (files), each "
                             "preprocessed on its own and stacked")
    parser.add_argument("--validate", type=Path, required=validate_required, action="append",
                        help="validation data from another trajectory; repeatable like --data")
    parser.add_argument("--max-gap", type=float, default=DEFAULT_MAX_GAP, metavar="SECONDS",
                        help=f"longest logger stall bridged by interpolation (default {DEFAULT_MAX_GAP:g} s); a longer "
                             "hole splits a --data file into segments (and is an error in a --validate file)")
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
                           help="memory the in-memory path may take (2GB, 500MB, 1.5GiB or bytes; default a quarter of "
                                "the memory available): past it, estimated from the files' rows before reading them, "
                                "the files are streamed (the same choices; one line on stderr says so)")
    streaming.add_argument("--quiet", action="store_true", help="no progress lines on stderr")


def streaming_requested(args: argparse.Namespace) -> bool:
    """Whether ``--chunk-size``, ``--workers`` or a scheduler (``--scheduler``, ``$ROBOT_OED_SCHEDULER``) asks for the
    streamed path."""
    return args.chunk_size is not None or args.workers > 0 or scheduler_address(args.scheduler) is not None


@contextlib.contextmanager
def executor_from_arguments(args: argparse.Namespace) -> Iterator[Executor | None]:
    """A dask executor (``--scheduler`` or ``$ROBOT_OED_SCHEDULER``), a process pool (``--workers``) or ``None``."""
    if args.workers < 0:
        raise ValueError(f"--workers must be 0 (in this process) or a pool size, got {args.workers}")
    address = scheduler_address(args.scheduler)
    if address is not None and args.workers:
        raise ValueError("give --scheduler (a dask cluster) or --workers (a local pool), not both")
    if address is not None:
        with connect(address) as executor:
            yield executor
    elif args.workers:
        with ProcessPoolExecutor(args.workers) as executor:
            yield executor
    else:
        yield None


def differentiation(args: argparse.Namespace) -> Differentiation:
    """The differentiation the derivative options ask for (contradicting options are an error)."""
    check_hertz(args, "frequency", "cutoff")
    if args.frequency is not None and args.cutoff is not None:
        raise ValueError("give --frequency (Fourier fit of periodic data) or --cutoff (Butterworth filter), not both")
    if args.frequency is not None:
        return FourierDifferentiation(args.frequency, 5 if args.harmonics is None else args.harmonics,
                                      args.average_periods)
    return ButterworthDifferentiation(args.cutoff)


def preparation_settings(args: argparse.Namespace, transmission: Transmission | None,
                         memory: InMemoryBudget | None = None) -> PreparationSettings:
    """How ``--data`` and ``--validate`` are read and prepared (:func:`estimation.identification.prepared.prepare_records`):
    ``--max-gap``, the derivative options, ``--min-speed`` and ``--rest``."""
    return PreparationSettings(max_gap=args.max_gap, transmission=transmission, frequency_hz=args.frequency,
                               harmonics=args.harmonics, cutoff_hz=args.cutoff, average_periods=args.average_periods,
                               decimation=args.decimate, held_torques=args.held_torques, min_speed=args.min_speed,
                               rest=args.rest, memory=memory, jobs=args.jobs)


def check_shaped_effects_kept(effects: Iterable[Any], model: IdentificationModel) -> None:
    """A declared law with shape parameters that has no rows in this model is an error (a plain
    effect without rows is left out, as ``build_model`` does)."""
    for effect in parse_effects(effects):
        if is_shaped(effect, model.robot) and effect not in model.effects:
            raise NoRowsError(f"effect {getattr(effect, 'spec', effect.name)!r} has no rows in the {model.kind.value} model "
                              "(friction acts on the joint torques: use --model internal or combined)")


def model_has_shapes(model: IdentificationModel) -> bool:
    """Whether ``model`` holds a law with shape parameters (fitted by variable projection)."""
    return any(is_shaped(effect, model.robot) for effect in model.effects)


def print_warnings(verb: str, caught: Iterable[warnings.WarningMessage]) -> None:
    """Each warning caught once, in order, on stderr."""
    for message in dict.fromkeys(str(warning.message) for warning in caught):
        print(f"oed {verb}: warning: {message}", file=sys.stderr)
