"""The options the ``oed`` verbs share, as frozen dataclasses whose field names are the command line's option
names (``--min-speed`` -> ``min_speed``), and the settings derived from them: the robot, the derivatives, the
preparation of the records, the streamed path and its executor.

A verb function (``oed.identify(**options)``) builds its option set from its keywords (an unknown keyword is a
``TypeError``); paths may be given as strings, repeated options (``--data a --data b``) as lists.
"""

from __future__ import annotations

import contextlib
import dataclasses
import math
import os
import warnings
from collections.abc import Iterable, Iterator
from concurrent.futures import Executor, ProcessPoolExecutor
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pandas as pd

from dynamics.effects.linear import parse_effects
from dynamics.effects.shaped import is_shaped
from dynamics.models import IdentificationModel, ModelKind
from dynamics.robot import RobotModel
from dynamics.robot import passive_joint_indices
from dynamics.robots import described_unactuated, load_robot
from dynamics.mjcf import is_mjcf, mjcf_logged_chain
from dynamics.urdf import logged_chain
from dynamics.transmission import Transmission
from dynamics.runtime.report_document import HTML_SUFFIXES, MARKDOWN_SUFFIXES
from estimation.data.log_cleaning import DEFAULT_MAX_GAP
from estimation.data.compressed_logs import csv_input
from estimation.data.records import csv_options
from estimation.data.loading import count_joint_columns
from estimation.data.passive import PassiveJointWarning
from estimation.data.log_formats import BAG_SUFFIXES, DEFAULT_TOPIC, LogSource, apply_column_map, is_log_file, read_log_frame
from estimation.estimators.effect_blocks import NoRowsError
from estimation.identification.prepared import InMemoryBudget, PreparationSettings
from estimation.preprocessing.differentiation import (
    ButterworthDifferentiation,
    Differentiation,
    FourierDifferentiation,
)
from estimation.streaming.settings import scheduler_address

__all__ = [
    "NOT_CSV_SUFFIXES", "OutputPathError", "RecordOptions", "RobotOptions", "caught_messages", "check_choice",
    "check_csv_path", "check_hertz", "check_json_path", "check_markdown_path", "check_mjcf_path", "check_report_path",
    "check_urdf_path", "check_shaped_effects_kept", "differentiation", "executor_for", "LoggedChainWarning",
    "with_logged_chain", "with_passive_joints",
    "model_has_shapes", "paths", "preparation_settings", "robot_of", "streaming_requested",
]

class OutputPathError(ValueError):
    """An output path named like another format than the one written there (``--out t.csv`` for JSON,
    ``write("model.txt")`` for a URDF): refused before anything is written."""


#: suffixes that promise another format than the CSV a verb writes
NOT_CSV_SUFFIXES = frozenset({".json", ".parquet", ".png", ".pdf", ".svg", ".npz", ".npy", ".mat", ".xlsx", ".md"})


def paths(value: Any) -> tuple[Path, ...]:
    """A repeatable path option as a tuple of paths: ``None`` -> ``()``, one path -> a 1-tuple; a
    :class:`~estimation.data.log_formats.LogSource` stays one."""
    if value is None:
        return ()
    if isinstance(value, (str, os.PathLike)):
        value = (value,)
    return tuple(item if isinstance(item, LogSource) else Path(item) for item in value)


def log_sources(value: tuple[Path, ...], topic: str, columns: Any) -> tuple[Path, ...]:
    """Each path of ``value`` that is a log file (a ROS bag, ``.npz``, ``.mat``; any with a column map) as a
    :class:`~estimation.data.log_formats.LogSource` carrying ``topic`` and ``columns`` (``--topic``, ``--columns``)."""
    columns = dict(columns or {})
    return tuple(item if isinstance(item, LogSource) or not (columns or is_log_file(item))
                 else LogSource(item, topic=topic, columns=columns) for item in value)


def optional_path(value: Any) -> Path | None:
    """A path option: ``None`` or a :class:`~pathlib.Path`."""
    return None if value is None else Path(value)


def check_choice(option: str, value: Any, choices: Iterable[Any]) -> None:
    """Refuse ``value`` outside ``choices``, naming the option as typed (``--rest``)."""
    choices = tuple(choices)
    if value not in choices:
        raise ValueError(f"--{option.replace('_', '-')} must be one of {', '.join(map(str, choices))}, got {value!r}")


def check_hertz(options: Any, *names: str) -> None:
    """Refuse a ``names`` value (``"frequency"``, ``"cutoff"``) that is given and not a positive, finite number of
    hertz, naming the option as typed (``--frequency``)."""
    for name in names:
        value = getattr(options, name, None)
        if value is not None and not (math.isfinite(value) and value > 0):
            raise ValueError(f"--{name.replace('_', '-')} must be a positive, finite number of hertz, got {value:g}")


def check_csv_path(path: str | Path, option: str = "--out") -> None:
    """Refuse, before any work, a CSV output named like another format (``--out u.json``)."""
    if Path(path).suffix.lower() in NOT_CSV_SUFFIXES:
        raise OutputPathError(f"{option} {path}: this verb writes CSV; give a .csv file name")


def check_json_path(path: str | Path, option: str = "--out") -> None:
    """Refuse, before any work, a JSON output named like another format (``--out t.csv``)."""
    suffix = Path(path).suffix.lower()
    if suffix in NOT_CSV_SUFFIXES - {".json"} or suffix == ".csv":
        raise OutputPathError(f"{option} {path}: this writes JSON; give a .json file name")


def check_urdf_path(path: str | Path | None, option: str = "--urdf") -> None:
    """Refuse, before any work, a URDF output without the ``.urdf`` suffix (``--urdf model.txt``)."""
    if path is not None and Path(path).suffix.lower() != ".urdf":
        raise OutputPathError(f"{option} {path}: this writes a URDF; give a .urdf file name")


def check_mjcf_path(path: str | Path | None, option: str = "--mjcf") -> None:
    """Refuse, before any work, a MuJoCo MJCF output without the ``.xml`` suffix (``--mjcf model.urdf``)."""
    if path is not None and Path(path).suffix.lower() != ".xml":
        raise OutputPathError(f"{option} {path}: this writes MuJoCo's MJCF; give an .xml file name")


def check_markdown_path(path: str | Path | None, option: str = "--report") -> None:
    """Refuse, before any work, a Markdown output named like another format (``--report r.pdf``)."""
    if path is not None and Path(path).suffix.lower() not in MARKDOWN_SUFFIXES:
        raise OutputPathError(f"{option} {path}: this writes Markdown; give a .md file name")


def check_report_path(path: str | Path | None, option: str = "--report") -> None:
    """Refuse, before any work, a report named like neither Markdown nor HTML (``--report r.pdf``)."""
    if path is not None and Path(path).suffix.lower() not in MARKDOWN_SUFFIXES | HTML_SUFFIXES:
        raise OutputPathError(f"{option} {path}: this writes Markdown (.md, figures beside it) or a self-contained "
                         "HTML page (.html); give one of these suffixes")


@dataclass(frozen=True, kw_only=True)
class RobotOptions:
    """``--robot NAME``, ``--urdf FILE`` (which wins), ``--joints N``, and with ``--urdf`` the logged joints
    ``--joint-names A,B,C`` (every other joint locked at ``--locked-at NAME=VALUE,...``, default 0); ``--passive
    JOINT,...`` the passive (unactuated) joints, by name or number (their torque zero by physics)."""

    robot: str | None = "puma560"
    urdf: Path | None = None
    joints: int | None = None
    joint_names: tuple[str, ...] | None = None
    locked_at: dict[str, float] | None = None
    passive: tuple[str, ...] | None = None

    def __post_init__(self) -> None:
        object.__setattr__(self, "urdf", optional_path(self.urdf))
        if self.joint_names is not None:
            object.__setattr__(self, "joint_names", tuple(self.joint_names))
        if self.passive is not None:
            object.__setattr__(self, "passive", tuple(self.passive))


def robot_of(options: RobotOptions) -> RobotModel:
    """The robot the options name."""
    return load_robot(options.robot, urdf=options.urdf, joints=options.joints, joint_names=options.joint_names,
                      locked_at=options.locked_at, passive=options.passive)


class LoggedChainWarning(UserWarning):
    """A URDF that branches or holds ``<mimic>`` joints read as the chain of the log's joints, the others held fixed."""


def logged_joint_count(source: Path) -> int | None:
    """The number of joints a record's columns ``q1..qn`` give (after its column map); ``None`` when its header
    does not say (a ROS bag: read by joint name; a file that cannot be read: the reader names the problem)."""
    frame = logged_frame_head(source)
    if frame is None:
        return None
    count = count_joint_columns(frame, "q")
    return count or None


def with_logged_chain(args: Any) -> tuple[Any, dict[str, Any] | None]:
    """``args`` with ``joint_names`` set to the chain the records' joint columns determine when ``--urdf`` names
    a file that branches or holds ``<mimic>`` joints and neither ``--joint-names`` nor ``--joints`` is given
    (:func:`dynamics.urdf.logged_chain`: the one path of the logged number of joints from the base; the other
    joints held fixed at 0, their bodies merged), said in a :class:`LoggedChainWarning`; with it the document's
    ``logged_chain`` (``{joint_names, held_fixed, reason}``). Otherwise ``args`` unchanged and ``None``; a tree the
    columns do not determine one chain of is the error naming ``--joint-names``."""
    if (args.urdf is None or args.joint_names is not None or args.joints is not None or args.locked_at
            or not args.data):
        return args, None
    n_logged = logged_joint_count(args.data[0])
    if n_logged is None:
        return args, None
    mjcf = is_mjcf(args.urdf)
    found = (mjcf_logged_chain if mjcf else logged_chain)(args.urdf, n_logged)
    if found is None:
        return args, None
    chain, held = found
    reason = ((f"MJCF {args.urdf} branches or holds coupled joints" if mjcf else
               f"URDF {args.urdf} branches or holds <mimic> joints")
              + f" and the log holds {n_logged} joint(s): read as "
              f"the chain {','.join(chain)} (--joint-names {','.join(chain)}), "
              + (f"{', '.join(held)} held fixed at 0 "
                 + ("" if mjcf else "(a <mimic> joint, if any, following its driver) ")
                 + "and the bodies they carry merged into the link they hang from" if held else "no joint held fixed"))
    warnings.warn(reason, LoggedChainWarning, stacklevel=2)
    return dataclasses.replace(args, joint_names=chain), {"joint_names": list(chain), "held_fixed": list(held),
                                                          "reason": reason}


def logged_frame_head(source: Path) -> pd.DataFrame | None:
    """The first rows of a record's table (after its column map), or ``None`` when its header does not say (a ROS
    bag: read by joint name; a file that cannot be read: the reader names the problem)."""
    log = source if isinstance(source, LogSource) else LogSource(source)
    suffix = log.path.suffix.lower()
    try:
        if suffix in BAG_SUFFIXES or log.path.is_dir():
            return None
        if suffix in (".npz", ".mat", ".parquet"):
            return read_log_frame(log)
        with warnings.catch_warnings():  # said by the reader
            warnings.simplefilter("ignore")
            options = csv_options(log.path)  # another delimiter, comment lines above the header, a units row
        with csv_input(log.path) as stream:  # a packed CSV file's first rows, decompressed
            return apply_column_map(pd.read_csv(stream, nrows=2, **options), log.columns, str(log.path))
    except (ValueError, OSError, ImportError, KeyError):
        return None


def with_passive_joints(args: Any) -> tuple[Any, dict[str, Any] | None]:
    """``args`` with ``passive`` (the passive joints, :mod:`estimation.data.passive`) completed by the description
    where the log is silent, and the document's ``passive_joints`` (``{joints, named, described, statement}``;
    ``None`` when no joint is passive).

    A joint is passive when the user names it (``--passive``), or when the training log has no torque column for it
    (the other joints' torques logged) and the robot's description declares motors on other joints and none on it
    (:func:`dynamics.robots.described_unactuated`: a URDF's ``<transmission>``, an MJCF's ``<actuator>``); the latter
    said in a :class:`~estimation.data.passive.PassiveJointWarning`. A missing torque column the description does
    not explain stays the reader's error, which names ``--passive`` (a driven joint whose torque was not logged is
    not passive: its torque is unknown, not zero)."""
    named = tuple(args.passive or ())
    described: tuple[str, ...] = ()
    frame = logged_frame_head(args.data[0]) if args.urdf is not None and getattr(args, "data", None) else None
    n_logged = 0 if frame is None else count_joint_columns(frame, "q")
    missing = [j for j in range(n_logged) if f"tau{j + 1}" not in frame.columns]
    if missing and len(missing) < n_logged:  # some torques logged, not all: the description is read (no cost else)
        robot = robot_of(dataclasses.replace(args, passive=None))
        chosen = {robot.joint_names[j] for j in passive_joint_indices(robot, named)} if named else set()
        unactuated = set(described_unactuated(args.urdf, robot))
        described = tuple(robot.joint_names[j] for j in missing if j < robot.n_joints
                          and robot.joint_names[j] in unactuated and robot.joint_names[j] not in chosen)
    if described:
        warnings.warn(
            f"{', '.join(described)}: read as passive (unactuated; torque zero by physics, its friction in the model): "
            f"{args.urdf} declares motors on other joints (<transmission> or <actuator>) and none on "
            f"{'it' if len(described) == 1 else 'them'}, and the log has no torque column for "
            f"{'it' if len(described) == 1 else 'them'}; say so with --passive {','.join(described)}",
            PassiveJointWarning, stacklevel=2)
    if not named and not described:
        return args, None
    args = dataclasses.replace(args, passive=named + described)
    robot = robot_of(args)
    statement = (f"passive joint(s): {', '.join(robot.passive_joints)} (unactuated: torque zero by physics, "
                 "0 = Y_j theta with the joint's own friction an equation of the fit; "
                 + ("named with --passive" if named else "")
                 + (" and " if named and described else "")
                 + (f"{', '.join(described)} from the description (no motor, no torque column)" if described else "")
                 + ")")
    return args, {"joints": list(robot.passive_joints), "named": list(named), "described": list(described),
                  "statement": statement}


@dataclass(frozen=True, kw_only=True)
class RecordOptions(RobotOptions):
    """What ``oed identify`` and ``oed diagnose`` share: the model, the robot as built, the records and their
    derivatives, the processes and the streamed path (the options of the same names)."""

    model: str = "internal"
    friction: str = "viscous"
    transmission: str | None = None
    joint_offsets: str | None = None
    min_speed: float | None = None
    rest: str = "drop"
    data: tuple[Path, ...] = ()
    validate: tuple[Path, ...] = ()
    max_gap: float = DEFAULT_MAX_GAP
    frequency: float | None = None
    average_periods: str = "auto"
    harmonics: int | None = None
    cutoff: float | None = None
    decimate: int = 1
    held_torques: bool | None = None
    jobs: int | None = None
    chunk_size: int | None = None
    scheduler: str | None = None
    workers: int = 0
    memory_budget: str | None = None
    topic: str = DEFAULT_TOPIC
    columns: dict[str, str] | None = None

    def __post_init__(self) -> None:
        super().__post_init__()
        object.__setattr__(self, "data", self.sources(self.data))
        object.__setattr__(self, "validate", self.sources(self.validate))
        if not self.data:
            raise ValueError("give the training record: data=... (--data FILE)")
        check_choice("model", self.model, [kind.value for kind in ModelKind])
        check_choice("rest", self.rest, ("drop", "smooth"))
        check_choice("average_periods", self.average_periods, ("auto", "yes", "no"))
        if self.transmission is not None:
            object.__setattr__(self, "transmission", str(self.transmission))
        if self.joint_offsets is not None:
            object.__setattr__(self, "joint_offsets", str(self.joint_offsets))

    def sources(self, value: Any) -> tuple[Path, ...]:
        """A record option's paths, the log files among them read with ``topic`` and ``columns``."""
        return log_sources(paths(value), self.topic, self.columns)

    def replace(self, **changes: Any) -> RecordOptions:
        """A copy with ``changes``."""
        return dataclasses.replace(self, **changes)


def streaming_requested(options: RecordOptions) -> bool:
    """Whether ``chunk_size``, ``workers`` or a scheduler (``scheduler``, ``$ROBOT_OED_SCHEDULER``) asks for the
    streamed path."""
    return options.chunk_size is not None or options.workers > 0 or scheduler_address(options.scheduler) is not None


@contextlib.contextmanager
def executor_for(options: RecordOptions) -> Iterator[Executor | None]:
    """A dask executor (``scheduler`` or ``$ROBOT_OED_SCHEDULER``), a process pool (``workers``) or ``None``."""
    if options.workers < 0:
        raise ValueError(f"--workers must be 0 (in this process) or a pool size, got {options.workers}")
    address = scheduler_address(options.scheduler)
    if address is not None and options.workers:
        raise ValueError("give --scheduler (a dask cluster) or --workers (a local pool), not both")
    if address is not None:
        from estimation.streaming.cluster import connect  # the streamed path's modules: imported when it runs

        with connect(address) as executor:
            yield executor
    elif options.workers:
        with ProcessPoolExecutor(options.workers) as executor:
            yield executor
    else:
        yield None


def differentiation(options: RecordOptions) -> Differentiation:
    """The differentiation the derivative options ask for (contradicting options are an error)."""
    check_hertz(options, "frequency", "cutoff")
    if options.frequency is not None and options.cutoff is not None:
        raise ValueError("give --frequency (Fourier fit of periodic data) or --cutoff (Butterworth filter), not both")
    if options.frequency is not None:
        return FourierDifferentiation(options.frequency, 5 if options.harmonics is None else options.harmonics,
                                      options.average_periods)
    return ButterworthDifferentiation(options.cutoff)


def preparation_settings(options: RecordOptions, transmission: Transmission | None,
                         memory: InMemoryBudget | None = None) -> PreparationSettings:
    """How ``data`` and ``validate`` are read and prepared
    (:func:`estimation.identification.prepared.prepare_records`): ``max_gap``, the derivative options,
    ``min_speed`` and ``rest``."""
    return PreparationSettings(max_gap=options.max_gap, transmission=transmission, frequency_hz=options.frequency,
                               harmonics=options.harmonics, cutoff_hz=options.cutoff,
                               average_periods=options.average_periods, decimation=options.decimate,
                               held_torques=options.held_torques, min_speed=options.min_speed, rest=options.rest,
                               memory=memory, jobs=options.jobs)


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


def caught_messages(caught: Iterable[warnings.WarningMessage]) -> list[str]:
    """The messages of the warnings caught, each once, in order."""
    return list(dict.fromkeys(str(warning.message) for warning in caught))
