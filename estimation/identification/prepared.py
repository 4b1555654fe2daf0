"""The records of an identification, read once and prepared alike: one call from file names to estimator input.

:func:`prepare_records` reads the training, validation and test files (a hole longer than ``max_gap`` splits a
file into segments, :func:`estimation.data.records.read_record`, as ``oed predict`` reads a record), motor-side columns converted by the transmission
(:func:`estimation.data.motor_side.read_record_with_transmission`). It refuses a validation or test file that
is a training file, and a channel that holds one value throughout a record. It chooses one preprocessing on the
training segments, by held-out evidence (:func:`estimation.identification.preprocessing_choice.choose_by_evidence`,
the default) or by the fixed rule (:func:`estimation.preprocessing.plan.choose_preprocessing`), when asked
(``validation_fits``) chooses again among the same candidates on a validation record of another motion
(:func:`estimation.identification.preprocessing_on_validation.on_validation`), prepares every record
with it (:func:`estimation.preprocessing.plan.prepare`), optionally refuses records too large for an
in-memory estimation (:class:`InMemoryBudget`), and drops the rows at rest
(:func:`estimation.data.rest.drop_rest`, ``--min-speed V --rest drop``).

The records as read stay in the result, file by file (:attr:`PreparedRecord.files`): what a noise floor
is estimated on (:mod:`estimation.uncertainty.noise_floor`), before any differentiation, averaging or
filtering, without reading the files again.
"""

from __future__ import annotations

import os

import warnings
from collections.abc import Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Literal

import numpy as np

from dynamics.channels import WRENCH_CHANNELS
from dynamics.measurements import Measurements
from dynamics.models import IdentificationModel
from dynamics.runtime.memory import check_allocation
from dynamics.runtime.progress import step
from dynamics.transmission import JointDirections, Transmission
from estimation.data.channel_mask import channel_counts
from estimation.data.input_findings import reading_findings
from estimation.data.loading import HoldWarning
from estimation.data.log_cleaning import DEFAULT_MAX_GAP
from estimation.data.motor_side import read_record_with_transmission
from estimation.data.passive import passive_channels
from estimation.data.segments import check_varying_channels
from estimation.data.rest import (
    RestHandling,
    RestSelection,
    coulomb_combinations,
    drop_rest,
    without_holds,
)
from estimation.identification.preprocessing_choice import PreprocessingChoice, choose_by_evidence, scored_window
from estimation.identification.preprocessing_on_validation import FITS, another_motion, on_validation, window
from estimation.identification.repeated_motion import still_spans_note
from estimation.identification.time_base_choice import choose_time_base, receive_times_evidence, regular_segments
from estimation.preprocessing.differentiation import AverageChoice
from estimation.uncertainty.noise_floor import NoiseFloor, NoiseFloorError, noise_floor, pooled_floor
from estimation.preprocessing.plan import (
    Preprocessing,
    best_filter,
    check_frequency,
    choose_preprocessing,
    prepare,
    prepare_unseen,
)

#: how the preprocessing is chosen: by held-out error among candidates, or by the fixed rule
Selection = Literal["held-out", "rule"]

__all__ = ["InMemoryBudget", "PreparationSettings", "PreparedRecord", "PreparedRecords", "RecordedFile",
           "prepare_records", "read_files"]


@dataclass(frozen=True)
class InMemoryBudget:
    """What the in-memory estimation that follows holds at its peak, to refuse records too large for it.

    Attributes
    ----------
    bytes_per_value
        Bytes a sample, channel and base parameter (the stacked regressor and its companions).
    task
        What the estimation does, for the message (``"identifying"``).
    hint
        What to do instead, for the message (``"use --chunk-size to stream them in bounded memory"``).
    """

    bytes_per_value: float
    task: str
    hint: str = ""

    def check(self, model: IdentificationModel, records: Sequence[Measurements]) -> None:
        """Raise :class:`dynamics.runtime.memory.InsufficientMemoryError` when ``records`` need more than the
        machine can give."""
        samples = sum(record.n_samples for record in records)
        hint = f" ({self.hint})" if self.hint else ""
        check_allocation(self.bytes_per_value * samples * model.n_channels * model.n_base,
                         f"{self.task} {samples} samples in memory{hint}")


@dataclass(frozen=True)
class PreparationSettings:
    """How the records are read and prepared (the options of ``oed identify`` and ``oed diagnose``).

    Attributes
    ----------
    max_gap
        Longest logger stall bridged by interpolation, s; a longer hole splits a file (training,
        validation or test) into segments.
    transmission
        Converts motor-side columns (``qm``, ``taum``, ``im``…) to joint-side ones; ``None``: none may appear.
    frequency_hz, harmonics, cutoff_hz, average_periods, decimation, held_torques
        As :func:`estimation.preprocessing.plan.choose_preprocessing`.
    min_speed, rest
        With ``rest="drop"``, rows where a joint (or a coupled motor) moves slower than ``min_speed`` are
        dropped from every prepared record; ``"smooth"`` changes the model, not the records.
    memory
        Refuse prepared records too large for the estimation that follows (before rows at rest are dropped).
    selection
        ``held-out`` (default): the derivative method chosen among candidates by held-out error
        (:mod:`estimation.identification.preprocessing_choice`); ``rule``: the fixed rule of
        :func:`~estimation.preprocessing.plan.choose_preprocessing`.
    plan
        A preprocessing chosen beforehand on the same training data (by held-out error on their
        :class:`~estimation.identification.preprocessing_choice.ChoiceWindow`, read before the records were):
        used as it is, nothing is chosen again.
    jobs
        Processes that score the derivative candidates side by side (``None``: the cores available, at
        most 4; :func:`~estimation.identification.preprocessing_choice.choose_by_evidence`).
    validation_fits
        The unconstrained fits (``ols``, ``wls``) that score the derivative candidates on the validation record
        when it holds another motion (:mod:`estimation.identification.preprocessing_on_validation`: the candidate
        whose fitted model predicts it best is chosen); empty (default): the training record's choice is kept.
        Not with rows at rest dropped (they depend on each candidate's ``dq``: the candidates would not be
        scored on the same samples).
    validation_model
        The model those fits fit (its channels those of the model the records are read for); ``None``: that
        model. ``oed diagnose`` gives the plain model (its declared effects plus Coulomb friction and an offset on
        every joint): the effects the declared model lacks must not choose the derivatives that will reveal them.
    joint_offsets
        Added to the joint positions of every record read (rad, or m; one a joint): encoders zeroed elsewhere than
        the robot description (``--joint-offsets``); ``None``: none.
    joint_directions
        The joints' directions against the description's axes (``--joint-offsets``' ``signs`` and
        ``torque_signs``), applied to every record read before the offsets; ``None``: as recorded.
    """

    max_gap: float = DEFAULT_MAX_GAP
    transmission: Transmission | None = None
    frequency_hz: float | None = None
    harmonics: int | None = None
    cutoff_hz: float | None = None
    average_periods: AverageChoice = "auto"
    decimation: int = 1
    held_torques: bool | None = False
    min_speed: float | None = None
    rest: RestHandling = "drop"
    memory: InMemoryBudget | None = None
    selection: Selection = "held-out"
    plan: Preprocessing | None = None
    jobs: int | None = None
    validation_fits: tuple[str, ...] = ()
    validation_model: IdentificationModel | None = None
    joint_offsets: tuple[float, ...] | None = None
    joint_directions: JointDirections | None = None

    def __post_init__(self) -> None:
        if self.selection not in ("held-out", "rule"):
            raise ValueError(f"selection must be 'held-out' or 'rule', got {self.selection!r}")
        if any(fit not in FITS for fit in self.validation_fits):
            raise ValueError(f"validation_fits must be among {FITS}, got {self.validation_fits!r}")
        if not (self.max_gap > 0 and self.max_gap < float("inf")):
            raise ValueError(f"--max-gap must be a positive number of seconds, got {self.max_gap}")
        if self.rest not in ("drop", "smooth"):
            raise ValueError(f"rest must be 'drop' or 'smooth', got {self.rest!r}")

    def drops_rest(self) -> bool:
        """Whether rows at rest are dropped from the records."""
        return self.min_speed is not None and self.rest == "drop" and self.min_speed != 0


@dataclass(frozen=True)
class RecordedFile:
    """One file and its segments as read (joint side, before any preprocessing)."""

    path: Path
    segments: tuple[Measurements, ...]


@dataclass(frozen=True)
class PreparedRecord:
    """One record (training, validation or test), as read and as prepared.

    Attributes
    ----------
    files
        The files as read, in the order given.
    measurements
        The segments prepared and stacked, rows at rest dropped when asked.
    rest
        What was dropped as at rest, or ``None`` when nothing was asked.
    """

    files: tuple[RecordedFile, ...]
    measurements: Measurements
    rest: RestSelection | None = None

    @property
    def segments(self) -> tuple[Measurements, ...]:
        """Every segment as read, file after file."""
        return tuple(segment for file in self.files for segment in file.segments)

    def noise_floor(self, channels: Sequence[str], frequency_hz: float | None = None) -> NoiseFloor | None:
        """The noise floor of the record as read, before any differentiation, averaging or filtering
        (:func:`estimation.uncertainty.noise_floor.noise_floor`: period-to-period at ``frequency_hz``, given or
        detected, or the file's frequency, else differences), pooled over the segments that can give one;
        ``None`` with a warning when none can. On the samples as recorded: a resampled log's own (interpolated
        onto a grid, a log jittered by ±30 % of a step showed 0.012 for the 0.04 simulated)."""
        floors, failures = [], []
        for file in self.files:
            for segment in file.segments:
                try:
                    floors.append(noise_floor(segment.as_recorded, tuple(channels), frequency_hz=frequency_hz))
                except NoiseFloorError as error:
                    failures.append(f"{file.path}: {error}")
        if failures:
            warnings.warn("no noise floor from " + "; ".join(failures)
                          + ("" if floors else " (the floor is then estimated from the prepared validation data, if "
                             "they can give one)"), stacklevel=2)
        return pooled_floor(floors)


@dataclass(frozen=True)
class PreparedRecords:
    """The result of :func:`prepare_records`: the records and the preprocessing chosen on the training data."""

    preprocessing: Preprocessing
    train: PreparedRecord
    validation: PreparedRecord | None = None
    test: PreparedRecord | None = None


def saturated_sample_counts(records: PreparedRecords | None) -> dict[str, list[dict]] | None:
    """``result.json``'s ``saturated_samples``: for each record (``train``, ``validation``, ``test``) the segments
    whose torque sensor was clipped (:func:`estimation.data.records.clipped_torques`) with the samples left out of
    the fit and of the errors, per channel; ``None`` when no record holds any (or the records were streamed)."""
    if records is None:
        return None
    found = {role: [{"file": str(file.path), "segment": int(segment.metadata.get("segment", 1)),
                     "samples": dict(segment.metadata["saturated_samples"])}
                    for file in record.files for segment in file.segments
                    if segment.metadata.get("saturated_samples")]
             for role, record in (("train", records.train), ("validation", records.validation),
                                  ("test", records.test)) if record is not None}
    return {role: entries for role, entries in found.items() if entries} or None


def channel_sample_counts(records: PreparedRecords | None) -> dict[str, dict] | None:
    """``result.json``'s ``channel_samples``: for each record (``train``, ``validation``, ``test``) whose channels'
    errors are taken over different samples (a channel's masked samples left out of its error only,
    :mod:`estimation.data.channel_mask`), the samples as recorded (``samples``) and each channel's valid ones
    (``channels``); ``None`` when every channel's error is over every sample (or the records were streamed)."""
    if records is None:
        return None
    found = {}
    for role, record in (("train", records.train), ("validation", records.validation), ("test", records.test)):
        if record is None:
            continue
        recorded = record.measurements.as_recorded
        names = ([f"tau{j + 1}" for j in range(recorded.n_joints)] if recorded.tau is not None else []) + (
            list(WRENCH_CHANNELS) if recorded.wrench is not None else [])
        values = [part for part in (recorded.tau, recorded.wrench) if part is not None]
        if not values:
            continue
        counts = channel_counts(np.hstack(values))
        if np.all(counts == recorded.n_samples):
            continue
        found[role] = {"samples": int(recorded.n_samples),
                       "channels": {name: int(count) for name, count in zip(names, counts)}}
    return found or None


def channel_sample_line(counts: dict[str, dict] | None) -> str | None:
    """The summary's line for :func:`channel_sample_counts`: the channels whose errors are over fewer samples."""
    if not counts:
        return None
    parts = [f"{role} " + ", ".join(f"{name} {count} of {entry['samples']}"
                                    for name, count in entry["channels"].items() if count < entry["samples"])
             for role, entry in counts.items()]
    return ("errors per channel over its valid samples (a clipped sensor's samples, a held channel's "
            "repeats, masked in that channel only, the other channels' kept): " + "; ".join(parts))


def read_files(paths: Sequence[str | Path], model: IdentificationModel, *, split: bool,
               max_gap: float = DEFAULT_MAX_GAP, transmission: Transmission | None = None,
               joint_offsets: tuple[float, ...] | None = None,
               joint_directions: JointDirections | None = None) -> tuple[RecordedFile, ...]:
    """The segments of every file (a hole splits a file when ``split``, else it is an error); motor-side
    columns converted by ``transmission``, ``joint_offsets`` added to the joint positions. A file given twice is an
    error: each file is one segment."""
    seen: dict[Path, Path] = {}
    for path in map(Path, paths):
        resolved = path.expanduser().resolve()
        if resolved in seen:
            raise ValueError(f"{path} given twice (as {seen[resolved]} too): each file is one segment of the record")
        seen[resolved] = path
    return tuple(RecordedFile(Path(os.fspath(source)), tuple(read_record_with_transmission(
        source, model=model, transmission=transmission, max_gap=max_gap, split=split, joint_offsets=joint_offsets,
        joint_directions=joint_directions)))
        for source in paths)  # a path, or a LogSource (a topic, a column map) read as it says


def prepare_records(model: IdentificationModel, train: Sequence[str | Path], validation: Sequence[str | Path] = (),
                    test: Sequence[str | Path] = (), settings: PreparationSettings | None = None) -> PreparedRecords:
    """Read the training, validation and test files once, choose one preprocessing on the training data,
    prepare every record with it and drop the rows at rest (module docstring).

    Parameters
    ----------
    model
        The model identified (its channels and joints say which columns are read).
    train, validation, test
        Files (``.csv``, ``.parquet``) of each record; ``validation`` and ``test`` may be empty.
    settings
        How to read and prepare them; default :class:`PreparationSettings`.

    Returns
    -------
    PreparedRecords
        The preprocessing chosen, and each record as read and as prepared.

    Raises
    ------
    ValueError
        A file given twice for one record; the errors of reading (:mod:`estimation.data.records`), of
        preparing (:mod:`estimation.preprocessing.plan`) and of dropping rows at rest
        (:func:`estimation.data.rest.drop_rest`: nearly every row at rest).
    dynamics.runtime.memory.InsufficientMemoryError
        The prepared records exceed ``settings.memory``.

    Warns
    -----
    UserWarning
        ``held_torques`` with measured ``dq``, ``ddq`` (nothing to align); and the warnings of reading
        and of :func:`~estimation.preprocessing.plan.choose_preprocessing`.
    """
    settings = PreparationSettings() if settings is None else settings
    check_distinct_records({"--data": train, "--validate": validation, "--test": test})
    with step(f"read {len(train) + len(validation) + len(test)} file(s)"), \
            reading_findings([*train, *validation, *test]):  # each finding said once, at once
        train_files = read_files(train, model, split=True, max_gap=settings.max_gap, transmission=settings.transmission,
                                 joint_offsets=settings.joint_offsets, joint_directions=settings.joint_directions)
        # a hole splits a held-out file too, as it does a training file and as ``oed predict`` reads one: each
        # segment is scored on its own samples as recorded (refusing it made the defaults exit where the user's
        # own split of the file into two --validate files works)
        held_out = {role: read_files(paths, model, split=True, max_gap=settings.max_gap,
                                     transmission=settings.transmission, joint_offsets=settings.joint_offsets,
                                     joint_directions=settings.joint_directions)
                    if paths else None
                    for role, paths in (("validation", validation), ("test", test))}
    check_no_shared_samples({"training": train_files, **held_out})
    train_files, held_out = logged_derivatives_alike(train_files, held_out)
    if settings.min_speed is None:  # rows at rest not handled by the user: the holds cut out of the fit
        train_files = training_without_holds(train_files, settings.max_gap)
    for role, files in (("training", train_files), *held_out.items()):
        if files is not None:
            check_varying_channels([segment for file in files for segment in file.segments],
                                   [channel for channel in model.channels if channel not in passive_channels(model)],
                                   f"{role} data")  # a passive joint's zero torque is a measurement of zero
    if held_out["validation"]:
        note = still_record_note(train_files, held_out["validation"])
        if note is not None:
            warnings.warn(note, stacklevel=2)
    with step("preprocessing chosen"):
        chooser = None
        if settings.validation_fits and held_out["validation"] and settings.plan is None and not settings.drops_rest():
            chooser = model if settings.validation_model is None else settings.validation_model
            if tuple(chooser.channels) != tuple(model.channels):
                raise ValueError(f"validation_model has channels {chooser.channels}, the records {model.channels}")
        preprocessing = chosen_preprocessing(model, train_files, held_out, settings, chooser)
        ratio = None if chooser is None else receive_times_evidence(
            [segment for files in (train_files, held_out["validation"]) for file in files or ()
             for segment in file.segments])
        if ratio is not None and preprocessing.evidence is not None \
                and preprocessing.evidence.selection == "validation":  # the stamps may be receive times
            on_clock = {role: on_regular_clock_files(files) for role, files in
                        (("training", train_files), *held_out.items())}
            if all(on_clock[role] is not None for role, files in
                   (("training", train_files), *held_out.items()) if files is not None):
                clock_plan = chosen_preprocessing(model, on_clock["training"] or (), {
                    role: on_clock[role] for role in held_out}, settings, chooser)
                preprocessing = choose_time_base(preprocessing, clock_plan, chooser.channels, ratio)
                if preprocessing.time_base == "regular":
                    train_files = on_clock["training"] or ()
                    held_out = {role: on_clock[role] for role in held_out}
    if preprocessing.method == "measured" and settings.held_torques:
        warnings.warn("held torques: nothing to align, the data hold measured dq and ddq", stacklevel=2)
    with step("records prepared"):
        prepared = {"train": _prepared(train_files, preprocessing, "training data", check=False)}
        for role, files in held_out.items():
            prepared[role] = None if files is None else _prepared(files, preprocessing, f"{role} data", check=True)
    if settings.memory is not None:
        settings.memory.check(model, [record.measurements for record in prepared.values() if record is not None])
    records = {role: None if record is None else _without_rest(record, model, settings, role)
               for role, record in prepared.items()}
    return PreparedRecords(preprocessing, records["train"], records["validation"], records["test"])


def chosen_preprocessing(model: IdentificationModel, train_files: Sequence[RecordedFile],
                         held_out: dict[str, Sequence[RecordedFile] | None], settings: PreparationSettings,
                         chooser: IdentificationModel | None) -> Preprocessing:
    """The preprocessing of the training files (:func:`choose_plan`), chosen again on the validation record by
    ``chooser``'s fits when it is given (:func:`~estimation.identification.preprocessing_on_validation.on_validation`)."""
    train_segments = [segment for file in train_files for segment in file.segments]
    validation_segments = [segment for file in held_out["validation"] or () for segment in file.segments]
    choice = choose_plan(model, train_segments, settings,
                         [segment for files in held_out.values() if files for file in files
                          for segment in file.segments],
                         sums_model=chooser if chooser is not None and shares_training_sums(
                             settings, train_segments, validation_segments) else None)
    if chooser is None:
        return choice.chosen
    return on_validation(choice.chosen, chooser, train_segments, validation_segments, fits=settings.validation_fits,
                         jobs=settings.jobs, training_sums=choice.training_sums)


def on_regular_clock_files(files: Sequence[RecordedFile] | None) -> tuple[RecordedFile, ...] | None:
    """``files`` with every segment on its regular clock
    (:func:`~estimation.identification.time_base_choice.regular_segments`); ``None`` when one segment gives none
    (or no files)."""
    if files is None:
        return None
    moved = [(file, regular_segments(file.segments)) for file in files]
    if any(segments is None for _, segments in moved):
        return None
    return tuple(RecordedFile(file.path, segments) for file, segments in moved if segments is not None)


def training_without_holds(files: Sequence[RecordedFile], max_gap: float) -> tuple[RecordedFile, ...]:
    """The training files with each hold longer than ``max_gap`` cut out, the segment split there as at a gap
    (:func:`estimation.data.rest.without_holds`: at a hold static friction or a brake takes any share of the
    torque, and the derived velocity's sign is noise), said in a :class:`~estimation.data.loading.HoldWarning`.
    Validation and test records are scored as recorded."""
    out = []
    for file in files:
        parts, dropped = [], 0
        for segment in file.segments:
            kept, left = without_holds(segment, max_gap)
            parts.extend(kept)
            dropped += left
        if dropped and parts:  # a record held still throughout is left to the checks that name it
            total = sum(segment.n_samples for segment in file.segments)
            warnings.warn(HoldWarning(
                f"{file.path}: the robot is held still (every joint's position unchanged for more than {max_gap:g} "
                f"s) on {dropped} of {total} rows: left out of the fit, the record split there (at rest the torque "
                "holds any share of the static friction, and the sign of the derived velocity is noise); "
                "--min-speed V drops rows slower than V instead"), stacklevel=3)
            file = replace(file, segments=tuple(parts))
        out.append(file)
    return tuple(out)


def logged_derivatives_alike(train: Sequence[RecordedFile], held_out: dict[str, Sequence[RecordedFile] | None]
                             ) -> tuple[tuple[RecordedFile, ...], dict[str, tuple[RecordedFile, ...] | None]]:
    """The records with the logged derivatives (``ddq``, ``dq``) that every record holds, a warning naming those
    dropped: a training record logged with ``dq`` and ``ddq`` beside a validation or test record logged without
    (another logger) is prepared as they are, by a filter every record takes, so that every candidate is chosen
    and scored on the same kind of samples (the logged derivatives cannot apply to the held-out record: no
    candidate; they made the defaults exit, "validation data lacks the measured dq/ddq the training data hold")."""
    records = [*train, *(file for files in held_out.values() if files for file in files)]
    segments = [segment for file in records for segment in file.segments]
    dropped = [name for name in ("ddq", "dq") if any(getattr(segment, name) is not None for segment in segments)
               and any(getattr(segment, name) is None for segment in segments)]
    if "dq" in dropped and "ddq" not in dropped and any(segment.ddq is not None for segment in segments):
        dropped.insert(0, "ddq")
    if not dropped:
        return tuple(train), held_out
    lacking = sorted({str(file.path) for file in records for segment in file.segments
                      if any(getattr(segment, name) is None for name in dropped)})
    warnings.warn(f"{', '.join(lacking)} logged without {' and '.join(dropped)}: the {' and '.join(dropped)} the "
                  "other records log are left out, every record's derivatives taken alike from what all of them hold",
                  stacklevel=3)
    gone = {name: None for name in dropped}

    def without(file: RecordedFile) -> RecordedFile:
        return RecordedFile(file.path, tuple(
            replace(segment, **gone, recorded=None if segment.recorded is None else replace(segment.recorded, **gone))
            for segment in file.segments))

    return (tuple(without(file) for file in train),
            {role: None if files is None else tuple(without(file) for file in files) for role, files in held_out.items()})


def still_record_note(train: Sequence[RecordedFile], validation: Sequence[RecordedFile]) -> str | None:
    """A warning when every joint of the validation record spans less than :data:`STILL_SHARE` of its range in the
    training record (a robot holding its pose: what is chosen on it measures little of the dynamics), else ``None``.
    """
    def span(files: Sequence[RecordedFile]) -> np.ndarray:
        q = np.concatenate([segment.q for file in files for segment in file.segments], axis=0)
        return np.ptp(q, axis=0)

    return still_spans_note(span(train), span(validation))


def check_distinct_records(records: dict[str, Sequence[str | Path]]) -> None:
    """No file in two roles: a model validated or tested on what trained it would look better than it is."""
    seen: dict[Path, tuple[str, Path]] = {}
    for option, paths in records.items():
        for path in map(Path, paths):
            resolved = path.expanduser().resolve()
            if resolved in seen and seen[resolved][0] != option:
                first_option, first_path = seen[resolved]
                instead = ("; or leave out --validate: the choices are then made on held-out blocks of the training "
                           "record" if option == "--validate" and first_option == "--data" else "")
                raise ValueError(f"{option} {path} is also a {first_option} file ({first_path}): each record must come "
                                 f"from another experiment (another run or seed){instead}")
            seen.setdefault(resolved, (option, path))


def check_no_shared_samples(records: dict[str, tuple[RecordedFile, ...] | None], probes: int = 64) -> None:
    """No record holds samples of another: a test or validation file cut from the training record (most of its
    rows, probed at ``probes`` instants, with the same time stamp, positions and torques or wrench in the other) is
    refused, naming the files and the time. A repeated experiment replays the same motion with other noise, and two
    experiments may start from the same state: neither is one record."""
    pieces = [(role, file.path, segment) for role, files in records.items() if files
              for file in files for segment in file.segments]
    for index, (role, path, segment) in enumerate(pieces):
        rows = np.unique(np.linspace(0, segment.n_samples - 1, min(probes, segment.n_samples)).astype(int))
        for other_role, other_path, other in pieces[:index]:
            if other_role == role:
                continue
            at = np.clip(np.searchsorted(other.t, segment.t[rows]), 0, other.n_samples - 1)
            same = other.t[at] == segment.t[rows]
            for name in ("q", "tau", "wrench"):  # a repeated experiment has the same motion, not the same noise
                mine, theirs = getattr(segment, name), getattr(other, name)
                if mine is not None and theirs is not None:
                    same &= np.all(theirs[at] == mine[rows], axis=1)
            if np.mean(same) >= 0.5:
                first = float(segment.t[rows][same][0])
                raise ValueError(f"{role} file {path} shares samples with {other_role} file {other_path} (the same "
                                 f"time stamps and readings, from t = {first:.6g} s): each record must come from "
                                 "another experiment")


def choose_plan(model: IdentificationModel, train: Sequence[Measurements], settings: PreparationSettings,
                held_out: Sequence[Measurements] = (), *,
                sums_model: IdentificationModel | None = None) -> PreprocessingChoice:
    """The preprocessing of the training segments: ``settings.plan``, else chosen as ``settings.selection`` says,
    among plans that also apply to the ``held_out`` segments (validation, test). ``sums_model``: each candidate's
    training window also summed for it, for the choice on the validation record
    (:attr:`~estimation.identification.preprocessing_choice.PreprocessingChoice.training_sums`)."""
    if settings.plan is not None:
        return PreprocessingChoice(settings.plan, settings.plan)
    options = {"frequency_hz": settings.frequency_hz, "harmonics": settings.harmonics, "cutoff_hz": settings.cutoff_hz,
               "average_periods": settings.average_periods, "decimation": settings.decimation,
               "held_torques": settings.held_torques}
    if settings.selection == "rule":
        rule = choose_preprocessing(train, **{**options, "held_torques": bool(settings.held_torques)})
        return PreprocessingChoice(rule, rule)
    return choose_by_evidence(model, train, **options, jobs=settings.jobs, held_out=held_out, sums_model=sums_model)


def shares_training_sums(settings: PreparationSettings, train: Sequence[Measurements],
                         validation: Sequence[Measurements]) -> bool:
    """Whether the derivative candidates will be chosen again on the validation record
    (:func:`~estimation.identification.preprocessing_on_validation.chooses_on_validation`: chosen among candidates,
    not given by the user, and the validation record another motion), so that the blocked cross-validation, which
    prepares each candidate's training window, also sums it for the fits of that choice: the window is then prepared
    once a candidate, not twice (issue 34's cost)."""
    return (settings.selection != "rule" and settings.frequency_hz is None and settings.harmonics is None
            and settings.cutoff_hz is None and bool(validation)
            and another_motion(scored_window(train), [window(segment) for segment in validation]))


def _prepared(files: tuple[RecordedFile, ...], preprocessing: Preprocessing, role: str, *,
              check: bool) -> PreparedRecord:
    """``files`` prepared by ``preprocessing``; a held-out record (``check``) as ``oed predict`` prepares one
    (:func:`estimation.preprocessing.plan.prepare_unseen`: by the plan where it applies, else by the rule's filter,
    said), its frequency checked against the Fourier fit's."""
    segments = [segment for file in files for segment in file.segments]
    if not check:
        return PreparedRecord(files, prepare(segments, preprocessing, role=role))
    if preprocessing.method == "fourier":
        check_frequency(segments, preprocessing.frequency_hz)
    return PreparedRecord(files, prepare_unseen(segments, preprocessing, role=role,
                                                fallback=best_filter(preprocessing.to_dict())))


def _without_rest(record: PreparedRecord, model: IdentificationModel, settings: PreparationSettings,
                  label: str) -> PreparedRecord:
    """``record`` with its rows at rest dropped, when the settings ask for it."""
    if not settings.drops_rest():
        return record
    selection = drop_rest(record.measurements, settings.min_speed, combinations=coulomb_combinations(model.effects),
                          source=label)
    return PreparedRecord(record.files, selection.measurements, selection)
