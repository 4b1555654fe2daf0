"""The keys ``model_file`` and ``plausibility`` of ``result.json`` and ``report.json`` (one call from each verb)."""

from __future__ import annotations

import json
import warnings
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from estimation.consistent.identification import ConsistentResult
from estimation.consistent.model_selection import selection_file, selection_model_file
from estimation.identification.fit import IdentificationResult
from estimation.identification.identified_model import IdentifiedModel
from estimation.identification.model_file import (
    ModelFile,
    RobotSource,
    model_file_document,
    summed_model_file_document,
)
from estimation.identification.training_range import RangeCheck, TrainingRange
from estimation.identification.preprocessing_on_validation import block_mse
from estimation.identification.validation import ChannelErrors, Comparison, channel_mse
from estimation.identification.plausibility import assess_plausibility, link_findings
from estimation.preprocessing.delay import delayed
from oed.workflows.asbuilt import resolve_joint_directions, resolve_joint_offsets
from oed.workflows.chosen_model import ChosenModel
from oed.workflows.consistent import prior_source_scale
from oed.workflows.options import RecordOptions


def add_training_range(document: dict[str, Any], training_range: TrainingRange | None,
                       checks: Mapping[str, RangeCheck | None]) -> list[str]:
    """Put each joint's training range (:mod:`estimation.identification.training_range`) into the model files of
    ``document`` (``model_file``, the runner-up's), and each held-out record's check against it
    (``checks``: by the document's key, ``validation`` or ``test``) as ``outside_training_range`` under that key, in
    place; return the warnings: a test record that leaves the range (the errors measured on it measure
    extrapolation), the same words on both paths (the fraction of the samples, which the streamed path does not
    count, in ``outside_training_range`` and the summary). A validation record that leaves it is no fault of the
    user's records (the choices then measured some extrapolation): said in the summary and the document, not warned."""
    if training_range is None:
        return []
    for model_file in (document.get("model_file"), (document.get("runner_up") or {}).get("model_file")):
        if isinstance(model_file, dict):
            model_file["training_range"] = training_range.to_dict()
    messages: list[str] = []
    for key, check in checks.items():
        if check is None or not isinstance(document.get(key), dict):
            continue
        document[key]["outside_training_range"] = check.to_dict()
        if key != "validation":
            messages += check.messages(f"the {key} record", fraction=False)
    return messages


def range_lines(checks: Mapping[str, RangeCheck | None]) -> list[str]:
    """The summary's line per held-out record against the training range (none when there is no check)."""
    lines = []
    for key, check in checks.items():
        if check is None:
            continue
        if not check.outside:
            lines.append(f"training range: the {key} record stays within every joint's training positions and speeds")
        else:
            lines.append(f"training range: the {key} record leaves it on "
                         + "; ".join(joint.statement() for joint in check.outside))
    return lines


def robot_source(robot: Any, args: RecordOptions) -> RobotSource:
    """Where the robot of ``args`` came from (``--robot``, ``--urdf``, ``--joints``)."""
    return RobotSource.from_description(robot, builtin=None if args.urdf is not None else args.robot, urdf=args.urdf,
                                        joints=args.joints, joint_names=getattr(args, "joint_names", None),
                                        locked_at=getattr(args, "locked_at", None))


def rest_document(args: RecordOptions) -> dict[str, Any] | None:
    """The model file's ``rest``: ``{min_speed, rest}`` when rows at rest were dropped or Coulomb laws smoothed."""
    return None if args.min_speed is None or args.min_speed == 0 else {"min_speed": args.min_speed, "rest": args.rest}


def add_runner_up_model_file(document: dict[str, Any], runner_up: Any, args: RecordOptions, preprocessing: Any,
                             transmission: Any) -> None:
    """Put the runner-up's ``model_file`` (:mod:`estimation.diagnosis.runner_up`; the format of the chosen model's,
    what ``oed design --discriminate`` reads) into ``document["runner_up"]``, in place; nothing without one."""
    if runner_up is None or document.get("runner_up") is None:
        return
    document["runner_up"]["model_file"] = model_file_document(
        runner_up.fit, robot=robot_source(runner_up.model.robot, args), preprocessing=preprocessing.to_dict(),
        transmission=transmission, rest=rest_document(args), max_gap=args.max_gap)
    offsets = resolve_joint_offsets(args, runner_up.model.robot)
    if offsets is not None:
        document["runner_up"]["model_file"]["joint_offsets"] = list(offsets)
    directions = resolve_joint_directions(args, runner_up.model.robot)
    if directions is not None:
        document["runner_up"]["model_file"]["joint_directions"] = directions.to_dict()


def add_model_file(document: dict[str, Any], result: IdentificationResult, args: RecordOptions, preprocessing: Any,
                   transmission: Any, *, consistent: Any = None, selection: Any = None) -> tuple[str, ...]:
    """Put ``model_file`` (what ``oed predict`` and ``oed export`` read) and ``plausibility`` into
    ``document``, in place; return the plausibility warnings.

    ``preprocessing``: the :class:`estimation.preprocessing.plan.Preprocessing` chosen on the training data;
    ``consistent``: the :class:`estimation.consistent.identification.ConsistentResult` of a consistent fit, or
    ``None``; ``selection``: the :class:`estimation.consistent.model_selection.ModelSelection` whose chosen model
    the file holds (its other candidates as alternatives), or ``None`` (``result`` is the model).
    """
    robot = robot_source(result.model.robot, args)
    rest = rest_document(args)
    if selection is not None:
        document["model_file"] = selection_model_file(selection, robot=robot, preprocessing=preprocessing.to_dict(),
                                                      transmission=transmission, rest=rest, max_gap=args.max_gap)
    else:
        document["model_file"] = model_file_document(
            result, robot=robot, preprocessing=preprocessing.to_dict(), transmission=transmission, rest=rest,
            max_gap=args.max_gap, consistent=None if consistent is None else consistent.estimate,
            consistent_validation_mse=None if consistent is None or consistent.validation is None
            else consistent.validation.mse)
    offsets = resolve_joint_offsets(args, result.model.robot)
    if offsets is not None:  # added to the joint positions of every record oed predict reads with this file
        document["model_file"]["joint_offsets"] = list(offsets)
    directions = resolve_joint_directions(args, result.model.robot)
    if directions is not None:  # the joints' directions of every record oed predict reads with this file
        document["model_file"]["joint_directions"] = directions.to_dict()
    validation = document.get("validation") or {}
    answer = ChosenModel(result.estimate.method, result) if selection is None else ChosenModel.of(selection)
    plausibility = assess_plausibility(result.model, answer.records(),  # of the model the file holds
                                       validation_mse=None if answer.validation is None else answer.validation.mse,
                                       nominal_mse=validation.get("nominal_mse"), zero_mse=validation.get("zero_mse"))
    document["plausibility"] = plausibility.to_dict()
    links = () if consistent is None else consistent_link_findings(result.model.robot, consistent)
    document["plausibility"]["consistent_links"] = list(links)
    return tuple(plausibility.messages()) + tuple(links)


def add_summed_runner_up_model_file(document: dict[str, Any], runner_up: Any, args: RecordOptions,
                                   preprocessing: dict[str, Any], validation_mse: dict[str, float] | None,
                                   transmission: Any = None, shape: dict[str, float] | None = None) -> None:
    """The streamed path's :func:`add_runner_up_model_file`: the runner-up's estimate from the sums at its fixed
    shapes (``validation_mse``: its validation MSE as ``oed predict`` measures it, or ``None``; ``shape``: its
    shapes and the delay its sums were moved by, :meth:`~estimation.diagnosis.results.Diagnosis.runner_up_shape`,
    ``None``: its own shapes alone), the transmission and ``--joint-offsets``' zeros and directions as in memory."""
    if runner_up is None or document.get("runner_up") is None:
        return
    document["runner_up"]["model_file"] = summed_model_file_document(
        runner_up.model, runner_up.fit, robot=robot_source(runner_up.model.robot, args), preprocessing=preprocessing,
        shape=runner_up.shape() if shape is None else shape, recorded_mse=runner_up.train_mse,
        validation_mse=validation_mse)
    as_read(document["runner_up"]["model_file"], args, runner_up.model.robot, transmission)


def as_read(model_file: dict[str, Any], args: RecordOptions, robot: Any, transmission: Any) -> None:
    """``model_file`` (in place) with what every record ``oed predict`` reads with it goes through, as read here:
    the transmission (motor-side columns, motor laws), ``--joint-offsets``' zeros and directions."""
    if transmission is not None:
        model_file["transmission"] = transmission.to_dict()
    offsets = resolve_joint_offsets(args, robot)
    if offsets is not None:  # added to the joint positions of every record oed predict reads with this file
        model_file["joint_offsets"] = list(offsets)
    directions = resolve_joint_directions(args, robot)
    if directions is not None:  # the joints' directions of every record oed predict reads with this file
        model_file["joint_directions"] = directions.to_dict()


def add_summed_model_file(document: dict[str, Any], model: Any, estimate: Any, args: RecordOptions,
                          preprocessing: dict[str, Any], *, shape: dict[str, float] | None = None,
                          recorded_mse: dict[str, float] | None = None,
                          validation_mse: dict[str, float] | None = None, selection: Any = None,
                          transmission: Any = None) -> tuple[str, ...]:
    """``model_file`` and ``plausibility`` of the streamed path, in place (its estimate from sums,
    :func:`estimation.identification.model_file.summed_model_file_document`; ``transmission``, ``--joint-offsets``'
    zeros and directions written as in memory); return the plausibility warnings.
    ``selection``: the :class:`estimation.consistent.model_selection.ModelSelection` made from sums
    (:mod:`estimation.streaming.model_selection`), whose chosen model the file holds, the other candidates as
    alternatives (``estimate``, ``recorded_mse`` and ``validation_mse`` are then its candidates')."""
    robot = robot_source(model.robot, args)
    if selection is not None:
        consistent = selection.consistent
        extra = {} if consistent is None else {
            "consistent": consistent.estimate,
            "consistent_validation_mse": None if consistent.validation is None else consistent.validation.mse}
        documents = {candidate.name: summed_model_file_document(
            model, candidate.fit.estimate, robot=robot, preprocessing=preprocessing, shape=shape,
            recorded_mse=candidate.fit.train.mse,
            validation_mse=None if candidate.fit.validation is None else candidate.fit.validation.mse, **extra)
            for candidate in selection.candidates  # the unconstrained fits (a streamed diagnosis's: SummedFit)
            if candidate.fit is not None and not isinstance(candidate.fit, ConsistentResult)}
        document["model_file"] = selection_file(selection, documents)
        answer = ChosenModel.of(selection)
        records = answer.records()
        validation_mse = None if answer.validation is None else answer.validation.mse
    else:
        document["model_file"] = summed_model_file_document(model, estimate, robot=robot, preprocessing=preprocessing,
                                                            shape=shape, recorded_mse=recorded_mse,
                                                            validation_mse=validation_mse)
        document["model_file"]["chosen"] = estimate.method  # the only model: named, as predict and the summary name it
        records, consistent = estimate.records(), None
    as_read(document["model_file"], args, model.robot, transmission)  # as in memory
    validation = document.get("validation") or {}
    plausibility = assess_plausibility(model, records, validation_mse=validation_mse,
                                       nominal_mse=validation.get("nominal_mse"), zero_mse=validation.get("zero_mse"))
    document["plausibility"] = plausibility.to_dict()
    links = () if consistent is None else consistent_link_findings(model.robot, consistent)
    document["plausibility"]["consistent_links"] = list(links)
    return tuple(plausibility.messages()) + tuple(links)


def consistent_link_findings(robot: Any, consistent: Any) -> tuple[str, ...]:
    """The link checks of a consistent estimate (:func:`~estimation.identification.plausibility.link_findings`),
    against the description's bodies at the scale its prior took them (a description in grams read at the recorded
    torques' scale: :func:`oed.workflows.consistent.prior_source_scale`), as ``oed export`` judges them."""
    scale = prior_source_scale(getattr(consistent, "prior_source", None))
    reference = robot if scale is None else robot.with_parameters(scale * robot.standard_parameters)
    return link_findings(reference, consistent.estimate.link_parameters())


def recorded_validation_mse(model_file: dict[str, Any], validate: Sequence[str | Path]) -> dict[str, float] | None:
    """The validation MSE of the model of ``model_file`` (a ``model_file`` document) on the records ``validate``,
    as ``oed predict`` measures it (:meth:`estimation.identification.identified_model.IdentifiedModel.evaluate`: at
    the recorded time stamps, against the torques as recorded), when the loader cleaned or resampled a record
    (jittered stamps, rows a logger re-sent, stalls): the streamed chunks score such a record on the uniform grid,
    against torques interpolated onto it. ``None`` when every record is read as it was recorded (the streamed
    pass measured that error already). Reads the validation records in memory, as ``oed predict`` does."""
    counted = recorded_validation_counted(model_file, validate)
    return None if counted is None else counted[0]


def recorded_validation_counted(model_file: dict[str, Any], validate: Sequence[str | Path]
                                ) -> tuple[dict[str, float], int] | None:
    """:func:`recorded_validation_mse` with the number of recorded samples it is measured on (those ``oed predict``
    measures: the validation errors' sample count, not the uniform grid's)."""
    return recorded_validations_counted([model_file], validate)[0]


#: the keys of a model file that hold its model, not how a record is read and prepared for it
#: (:meth:`~estimation.identification.identified_model.IdentifiedModel.read`, ``prepare``; its delay moves the
#: prepared record at prediction): files alike in every other key read a record alike
_MODEL_ONLY_KEYS = frozenset({"effects", "effect_values", "shape", "shape_std", "smoothing", "delay", "base", "theta",
                              "cov", "channel_variance", "weights", "method", "recorded_variance", "reported",
                              "consistent", "chosen", "alternatives"})


def _reading_key(model_file: dict[str, Any]) -> str:
    """What the record as read and prepared for ``model_file`` depends on, as one string (its effects too when rows at
    rest are dropped: by its Coulomb laws' joint combinations)."""
    kept = {key: value for key, value in model_file.items()
            if key not in _MODEL_ONLY_KEYS or (key == "effects" and model_file.get("rest"))}
    return json.dumps(kept, sort_keys=True, default=str)


def recorded_validations_counted(model_files: Sequence[dict[str, Any]], validate: Sequence[str | Path]
                                 ) -> list[tuple[dict[str, float], int] | None]:
    """:func:`recorded_validation_counted` of each of ``model_files``, the records read and prepared once for the files
    that read them alike (:func:`_reading_key`: the same robot, preprocessing, transmission, joint zeros...)."""
    prepared: dict[str, Any] = {}
    counted: list[tuple[dict[str, float], int] | None] = []
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the records' findings were said when the verb read them
        for model_file in model_files:
            model = IdentifiedModel(ModelFile.from_dict(model_file))
            key = _reading_key(model_file)
            if key not in prepared:
                segments = model.read(list(validate))
                prepared[key] = None if all(segment.recorded is None for segment in segments) else \
                    model.prepare(segments)
            if prepared[key] is None:
                counted.append(None)
                continue
            prediction = model.predict_record(prepared[key])
            counted.append((dict(prediction.mse), int(np.asarray(prediction.t).shape[0])))
    return counted


def recorded_validation_errors(model_file: dict[str, Any], thetas: Mapping[Any, Any],
                               validate: Sequence[str | Path]) -> dict[Any, dict[str, float]] | None:
    """:func:`recorded_validation_mse` of several base-parameter vectors of the model of ``model_file`` (by key, in
    the file's base order), on the same samples: at the recorded time stamps, against the torques as recorded, as
    ``oed predict`` measures each (shaped laws at the file's shapes, the motion moved by its delay); ``None`` when every record is read as it was
    recorded."""
    scored = recorded_validation_scores(model_file, thetas, validate)
    return None if scored is None else {key: errors.mse for key, errors in scored.items()}


def recorded_validation_scores(model_file: dict[str, Any], thetas: Mapping[Any, Any],
                               validate: Sequence[str | Path]) -> dict[Any, ChannelErrors] | None:
    """:func:`recorded_validation_errors` as :class:`~estimation.identification.validation.ChannelErrors`: each
    vector's MSE, the recorded samples counted, and its MSE on each contiguous block of them as memory cuts the
    samples it holds (:func:`~estimation.identification.preprocessing_on_validation.block_mse`, for the paired
    difference of two candidates' scores); ``None`` when every record is read as it was recorded."""
    model = IdentifiedModel(ModelFile.from_dict(model_file))
    if model.payload_link is not None:
        raise ValueError("the errors of other parameter vectors are measured for a model without payload")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the records' findings were said when the verb read them
        segments = model.read(list(validate))
        if all(segment.recorded is None for segment in segments):
            return None
        prepared = model.prepare(segments)
        record = (prepared if model.delay is None else delayed(prepared, model.delay)).as_recorded  # as predict
    measured = record.channels(model.channels)
    shaped = any(model.shape.values())
    Y = model.regressor(record.q, record.dq, record.ddq) if shaped else None  # at the file's shapes, as predict

    def scored(theta: Any) -> ChannelErrors:
        theta = np.asarray(theta, dtype=float)
        predicted = Y @ theta if Y is not None else model.model.predict(theta, record.q, record.dq, record.ddq)
        blocks = block_mse(Comparison(record.t, measured, predicted, tuple(model.channels)))
        return ChannelErrors(channel_mse(measured, predicted, model.channels), int(measured.shape[0]),
                             block_mse=blocks or None)
    return {key: scored(theta) for key, theta in thetas.items()}


def resampled_validation(document: dict[str, Any]) -> bool:
    """Whether the streamed run of ``document`` (``result.json`` or ``report.json``) resampled a validation file
    onto a uniform grid (``streaming.validation_files[].resampled_from``: jittered stamps, stalls): its errors there
    are then measured again at the recorded samples (:func:`recorded_validation_mse`). Reading the validation files
    in memory only then keeps the streamed path's memory bounded on regular records."""
    files = (document.get("streaming") or {}).get("validation_files") or ()
    return any(entry.get("resampled_from") is not None for entry in files)
