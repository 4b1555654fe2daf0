"""``oed identify`` as a library call: base parameters from measured data, with uncertainties and validation.

:func:`identify` takes the verb's options as keywords (:class:`IdentifyOptions`) and runs one workflow
(:func:`run_identify`): the path is decided by the records (:func:`~oed.workflows.memory_path.decide_path`), the data
are read whole (:func:`identification_in_memory`) or in blocks (:func:`identification_streamed`,
:mod:`estimation.streaming.identification`), both give one
:class:`~estimation.identification.fit.IdentificationResult` (what the streamed path cannot compute is ``None``, its
reason in ``not_computed``) in an :class:`Identified`, and one builder makes the document
(:func:`identify_document`) and the summary (:func:`summary_lines`) from it. It returns an :class:`IdentifyRun`: ``to_dict()`` is ``result.json``, ``write(out, plot=...)`` writes it (and the figure),
``summary()`` the lines ``oed identify`` prints, ``warnings`` the warnings it prints on stderr.
"""

from __future__ import annotations

import copy
import time
import warnings
from collections.abc import Callable, Mapping
from contextlib import ExitStack
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from dynamics.channels import is_joint_torque
from dynamics.effects.specs import effect_spec
from dynamics.measurements import Measurements
from dynamics.models import IdentificationModel, build_model
from dynamics.robot import RobotModel
from dynamics.runtime.output_files import OutputFiles, check_figure_path, json_text
from dynamics.runtime.progress import step
from dynamics.runtime.report_document import Report
from dynamics.transmission import Transmission
from estimation.data.passive import passive_channels
from estimation.data.input_findings import FindingsSaid, grouped_messages
from estimation.data.log_cleaning import DEFAULT_MAX_GAP
from estimation.data.rest import smooth_coulomb
from estimation.diagnosis.statistics import FLOOR_ALPHA, ResidualReport, residual_report
from estimation.uncertainty.floor_comparison import compare_with_floor
from estimation.uncertainty.noise_floor import NoiseFloor
from estimation.estimators.least_squares import IdentifiabilityError
from estimation.estimators.normal_equations import DEFAULT_CHUNK_SIZE, NormalEquations
from estimation.identification.fit import IdentificationResult
from estimation.identification.prepared import (InMemoryBudget, PreparedRecords, channel_sample_counts,
                                                channel_sample_line, prepare_records, saturated_sample_counts)
from estimation.identification.preprocessing_choice import ChoiceWindow
from estimation.identification.repeated_motion import repeat_note, repeated_motion_note
from estimation.identification.model_file import summed_model_file_document
from estimation.identification.mount import MountCheck
from estimation.identification.subtracted_load import SubtractedLoad, added_back_records, load_channels
from estimation.identification.report import identification_report
from estimation.identification.friction_drift import FrictionDrift, check_friction_drift
from estimation.consistent.training_halves import PARTS, TrainingHalves, gains_halves, parts_compared, training_part
from estimation.identification.time_base_choice import STREAMED_TIME_BASE
from estimation.identification.training_range import RangeCheck, TrainingRange, merged_ranges
from estimation.identification.trivial_predictors import trivial_warnings
from estimation.identification.undetermined import fitted_without_undetermined, left_out_unexcited
from estimation.identification.validation import ChannelErrors, plot_comparison
from estimation.identification.weighting_choice import choose_weighting, weighting_samples
from estimation.preprocessing.delay import DelayBounds, split_delay
from estimation.preprocessing.plan import Preprocessing
from estimation.streaming.chunks import FileScans, source_files
from estimation.streaming.masked_counts import streamed_mask_counts
from estimation.streaming.cutoff_choice import streamed_window
from estimation.streaming.identification import (SummedFits, identify_files_candidates, prepared_chunks,
                                                streamed_channel_counts)
from estimation.streaming.model_selection import streamed_repeated_motion, summed_selection, warned_still_motion
from estimation.streaming.torque_gains import GainsScorer, divided_sums, streamed_gains_check
from estimation.streaming.periods import plan_options
from estimation.streaming.diagnosis_passes import window_floor
from estimation.streaming.block_errors import BlockSquares, block_channel_mse, block_normal_equations
from estimation.streaming.recorded_errors import (
    counted_errors_at_stamps,
    counted_predicted_errors,
    less_load,
    recorded_training_errors,
    streamed_plan,
    streamed_recorded_errors,
    theta_predictors,
)
from oed.workflows.asbuilt import (
    finish_document,
    description_checks,
    description_notes,
    streamed_description_findings,
    streamed_description_notes,
    model_effects,
    resolve_joint_directions,
    resolve_joint_offsets,
    resolve_transmission,
    rest_message,
    rest_records,
    trivial_predictors,
)
from estimation.consistent.identification import ConsistentResult, Scorer
from estimation.consistent.model_selection import ConsistentSettings, ModelSelection, select_model
from estimation.consistent.motor_friction import motor_friction_answer, motor_friction_laws
from estimation.consistent.armature import armature_answer, armature_laws
from estimation.consistent.mounted_gravity import gravity_answer, subtracted_answer, turned_model
from estimation.consistent.torque_gains import (
    TorqueGains,
    divided_torques,
    gains_on_validation,
    in_recorded_units,
    other_scale,
    scale_notes,
    torque_gains_answer,
)
from oed.workflows.consistent import check_consistent_arguments, consistent_lines, consistent_settings
from oed.workflows.chosen_model import ChosenModel, answer_identification, chosen_messages, mse_line
from oed.workflows.joint_side import named_as_given, records_to_read
from oed.workflows.memory_path import (IN_MEMORY_ROUTE, decide_path, on_time_base, stamps_kept, streamed_choice,
                                      streamed_records, with_time_base)
from oed.workflows.model_files import (
    add_model_file,
    add_summed_model_file,
    add_training_range,
    range_lines,
    recorded_validation_errors,
    recorded_validation_counted,
    resampled_validation,
    robot_source,
)
from oed.workflows.options import (
    RecordOptions,
    caught_messages,
    check_choice,
    check_json_path,
    check_report_path,
    check_shaped_effects_kept,
    differentiation,
    executor_for,
    model_has_shapes,
    preparation_settings,
    robot_of,
    with_logged_chain,
    with_passive_joints,
    streaming_requested,
)

__all__ = ["IN_MEMORY", "IdentifyOptions", "IdentifyRun", "identify"]

STREAMED = "the streamed path (--chunk-size, --scheduler or --workers)"

#: what the in-memory identification holds at its peak: bytes a sample, channel and base parameter (the
#: stacked regressor and the prediction's; measured 3.5 KB a sample for the 7-joint KUKA, m r = 350)
IN_MEMORY = InMemoryBudget(2 * 8, "identifying", "use --chunk-size to stream them in bounded memory")


@dataclass(frozen=True, kw_only=True)
class IdentifyOptions(RecordOptions):
    """The options of ``oed identify`` (:class:`~oed.workflows.options.RecordOptions` and these): ``method``
    (``auto``, ``wls``, ``ols``), ``plot`` (whether a figure, which draws every sample, will be written: it keeps
    the run in memory), ``report`` (whether the report will be written: on the streamed path it has no figures and
    says what the path did not compute), ``consistent``, ``prior_weight`` (a number or ``"auto"``), ``prior``, ``link_bounds``."""

    method: str = "auto"
    plot: bool = False
    report: bool = False
    consistent: bool = False
    prior_weight: float | str | None = None
    prior: str | None = None
    link_bounds: str | None = None
    #: not an option: the description's bodies times this as the consistent candidate's prior, set by the verb when
    #: the fitted torque gains say the recorded torques are in other units (a description in grams: 0.001;
    #: :func:`oed.workflows.consistent.consistent_settings`)
    prior_scale: float | None = None

    def __post_init__(self) -> None:
        super().__post_init__()
        check_choice("method", self.method, ("auto", "wls", "ols"))


@dataclass(frozen=True)
class IdentifyRun:
    """What ``oed identify`` computed: the document it writes, the lines it prints, and the objects behind them.

    Attributes
    ----------
    document
        ``result.json`` (:meth:`to_dict` returns a copy).
    lines
        The lines ``oed identify`` prints on stdout (:meth:`summary`).
    warnings
        The warnings it prints on stderr, in order.
    result
        The :class:`~estimation.identification.fit.IdentificationResult`, in memory or streamed (``result.path``;
        :attr:`streamed`).
    title
        The figure's title.
    """

    document: dict[str, Any] = field(repr=False)
    lines: tuple[str, ...]
    warnings: tuple[str, ...]
    result: IdentificationResult = field(repr=False)
    title: str = ""
    #: the preprocessing chosen, in one line (the report's choices)
    preprocessing: str = ""
    #: the model the result holds (:class:`oed.workflows.chosen_model.ChosenModel`; in memory): what the figure
    #: and the report draw
    answer: ChosenModel | None = field(default=None, repr=False)

    @property
    def streamed(self) -> bool:
        """Whether the files were read in blocks (no figure nor report then: no samples held)."""
        return self.result.path == "streamed"

    def to_dict(self) -> dict[str, Any]:
        """``result.json``, as ``oed identify`` writes it."""
        return copy.deepcopy(self.document)

    def summary(self) -> list[str]:
        """The lines ``oed identify`` prints (the preprocessing, the estimate, the errors)."""
        return list(self.lines)

    def plot(self, path: str | Path) -> None:
        """The figure of measured against predicted channels (training and validation), saved at ``path``."""
        if self.streamed:
            raise ValueError(f"--plot draws every sample: not with {STREAMED}")
        fit = self.result if self.answer is None else self.answer
        comparisons = [fit.train] + ([fit.validation] if fit.validation is not None else [])
        plot_comparison(comparisons, path, title=self.title)

    def report(self) -> Report:
        """The report a person reads (:func:`estimation.identification.report.identification_report`): the choices,
        every warning, the parameters with their standard deviations, the errors beside the floor, measured
        against predicted per channel. Written as Markdown or HTML (:meth:`write`). A streamed run's report has no
        figure (no samples held) and says what its path did not compute."""
        return identification_report(self.result, self.document, preprocessing=self.preprocessing,
                                     warnings=self.warnings, title=self.title, chosen=self.answer)

    def write(self, out: str | Path, *, plot: str | Path | None = None, report: str | Path | None = None) -> None:
        """The result JSON at ``out``, with ``plot`` the figure, with ``report`` the report (HTML with its figures
        inline, or Markdown with them beside it, by the suffix): all files or none."""
        check_json_path(out)
        check_figure_path(plot)
        check_report_path(report)
        if plot is not None and self.streamed:
            raise ValueError(f"--plot draws every sample: not with {STREAMED}")
        document = None if report is None else self.report()
        with OutputFiles() as outputs:
            with outputs.open(out) as stream:
                stream.write(json_text(self.document))
            if plot is not None:
                self.plot(outputs.stage_figure(plot))
            if document is not None:
                document.write(report, outputs)


def identify(*, say: Callable[[str], None] | None = None, **options: Any) -> IdentifyRun:
    """``oed identify``: the base parameters of ``data``, validated on ``validate``.

    Parameters
    ----------
    say
        Called with each line said as the run goes (the path decision); default: nothing.
    **options
        The verb's options by their names (:class:`IdentifyOptions`): ``data`` and ``validate`` (a path or a
        list of paths), ``robot`` or ``urdf``, ``joints``, ``model``, ``friction``, ``method``, the derivative
        options (``frequency``, ``harmonics``, ``cutoff``, ``average_periods``, ``decimate``, ``held_torques``),
        ``consistent``… as ``oed identify --help`` lists them.

    Returns
    -------
    IdentifyRun
        ``to_dict()`` is ``result.json``; ``write(out, plot=None)``.
    """
    settings = IdentifyOptions(**options)
    return run_identify(settings, say=say or (lambda line: None))


def run_identify(args: IdentifyOptions, *, say: Callable[[str], None]) -> IdentifyRun:
    """:func:`identify` of checked options: the path decided by the records (:func:`decide_path`: their rows against
    the memory budget, or the streamed path asked for), the data read whole or in blocks
    (:func:`identification_in_memory`, :func:`identification_streamed`), one :class:`Identified` either way, and
    from it the one document (:func:`identify_document`) and summary (:func:`summary_lines`)."""
    differentiation(args)  # contradicting derivative options are an error even when the data hold dq, ddq
    check_consistent_arguments(args)
    args, chain = with_logged_chain(args)  # a branching or mimic URDF read as the log's chain
    args, passive = with_passive_joints(args)  # named, or the description's joints without a motor the log lacks
    robot = robot_of(args)
    transmission = resolve_transmission(args, robot)
    friction, delay = split_delay(args.friction)  # the delay moves the motion: not a column effect
    effects = model_effects(args, friction, robot, transmission)
    model = build_model(robot, args.model, effects)
    check_shaped_effects_kept(effects, model)
    check_model_request(args, model, delay)
    if streaming_requested(args):
        check_streamed_request(args, model)
    with ExitStack() as copies:
        with warnings.catch_warnings(record=True) as copying:  # what the copies' reading said (a controller's log)
            warnings.simplefilter("always")
            read, names = copies.enter_context(records_to_read(  # joint-side copies of motor-side, zeroed records
                args, model, transmission, bytes_per_value=IN_MEMORY.bytes_per_value,
                in_memory_only=lambda: in_memory_only(args, model, delay)))
        # a Coulomb column the record cannot tell from the offset merged, a still joint's left out: said
        identified, merged = fitted_without_undetermined(
            lambda effects, model, merged: identification_by_path(read, robot, model, transmission, delay, say),
            effects, model, lambda effects: build_model(robot, args.model, effects))
        if merged:
            said = tuple(column.statement() for column in merged)
            identified = replace(identified, messages=(*said, *identified.messages), notes=(*said, *identified.notes))
        copied = tuple(dict.fromkeys(str(item.message) for item in copying))
        if copied:
            identified = replace(identified, messages=(*copied, *identified.messages))  # said as the reader says it
        document, messages = identify_document(args, identified)
        if identified.records is None and _masked_sums(identified.result.streaming):
            # streamed with masked samples in its sums: the clipped ones counted as memory counts them, from the
            # files read (one more pass each; none on a record without a masked sample)
            document["saturated_samples"] = streamed_mask_counts(
                {role: paths for role, paths in (("train", read.data), ("validation", read.validate)) if paths},
                identified.result.model,
                chunk_size=DEFAULT_CHUNK_SIZE if identified.chunk_size is None else identified.chunk_size)[0]
            (document.get("not_computed") or {}).pop("saturated_samples", None)
        if merged:
            document["not_determined"] = [column.to_dict() for column in merged]
        if chain is not None:
            document["logged_chain"] = chain
        if passive is not None:
            document["passive_joints"] = passive
        summary = tuple(summary_lines(args, identified)) + (() if passive is None else (passive["statement"],))
    if names:  # the files as given, not their joint-side copies
        document, messages, summary = (named_as_given(value, names) for value in (document, messages, summary))
        identified = replace(identified, result=replace(identified.result, streaming=named_as_given(
            identified.result.streaming, names)))
    chosen = identified.chosen
    return IdentifyRun(document, summary, messages, identified.result,
                       title=f"{robot.name}: {model.kind.value} model ({chosen.name})",
                       preprocessing=identified.describe, answer=chosen)


def identification_by_path(read: IdentifyOptions, robot: RobotModel, model: IdentificationModel,
                           transmission: Transmission | None, delay: DelayBounds | None,
                           say: Callable[[str], None]) -> Identified:
    """The identification of the records ``read``, streamed when asked for or when they exceed the memory budget
    (:func:`decide_path`), else in memory."""
    if streaming_requested(read):
        return identification_streamed(read, model, transmission)
    decision = decide_path(read, model, task="identifying", bytes_per_value=IN_MEMORY.bytes_per_value,
                           in_memory_only=lambda: in_memory_only(read, model, delay), say=say,
                           validation_fits=validation_fits(read, model, delay))
    return (identification_streamed(read, model, transmission, decision.plan, decision.findings)
            if decision.stream
            else identification_in_memory(read, robot, model, transmission, delay, decision.plan))


@dataclass(frozen=True)
class Identified:
    """An identification, in memory or streamed, and what its document and summary need besides it.

    Attributes
    ----------
    result
        The :class:`~estimation.identification.fit.IdentificationResult` (``result.path``: which path made it);
        streamed, its validation errors are against the recording where the sums hold filtered channels
        (measured again: :class:`ValidationScores`, on the Fourier path :func:`recorded_validation`).
    chosen
        The model the result holds (:class:`~oed.workflows.chosen_model.ChosenModel`): the one the comparison of
        candidates chose (streamed from sums, :mod:`estimation.streaming.model_selection`; on the streamed Fourier
        path the weighting fitted).
    preprocessing
        How the motion was derived: the document's ``preprocessing``.
    describe
        The preprocessing in one line (the summary's first).
    messages
        The warnings said, in order (the model files' come after them: :func:`identify_document`).
    notes
        The run's own warnings, into the document's ``warnings``.
    trivial
        The validation MSE of the trivial predictors (``zero_mse``, ``nominal_mse``), or ``None``.
    floor, floor_note
        The validation record's noise floor and how it was had (``None``: no validation record, or none found).
    not_computed
        What this run could not compute, by the document's key, and why (the result's and the run's own).
    records, selection, consistent, floor_report
        The prepared records and the floor's comparison of the validation error (in memory; ``None`` when
        streamed), the comparison of candidate models and the consistent refit (both paths; ``None`` on the
        streamed Fourier path).
    weighting
        The weighting chosen on held-out blocks (``--method auto``), or ``None``.
    transmission
        The robot's transmission (``--transmission``, the URDF's or the built-in robot's), or ``None``.
    chunk_size
        Streamed: the rows a block; ``None`` in memory.
    model_file
        Streamed: what the summed model file is written with (its plan and validation error).
    n_samples
        The training samples fitted (in memory after averaging periods or decimating; ``None``: the result's).
    """

    result: IdentificationResult
    chosen: ChosenModel
    preprocessing: dict[str, Any]
    describe: str
    messages: tuple[str, ...]
    notes: tuple[str, ...] = ()
    trivial: dict[str, dict[str, float]] | None = None
    floor: NoiseFloor | None = None
    floor_note: str | None = None
    not_computed: dict[str, str] = field(default_factory=dict)
    records: PreparedRecords | None = None
    selection: ModelSelection | None = None
    consistent: ConsistentResult | None = None
    floor_report: ResidualReport | None = None
    weighting: Any = None
    transmission: Transmission | None = None
    chunk_size: int | None = None
    model_file: tuple[dict[str, Any], dict[str, float] | None] | None = None
    n_samples: int | None = None
    #: the per-joint torque gains fitted (:func:`torque_gains_selection`) and whether the answer holds them
    torque_gains: tuple[TorqueGains, bool, str] | None = None
    #: each joint's range on the samples fitted (:mod:`estimation.identification.training_range`), and the held-out
    #: records against it by the document's key (``validation``)
    training_range: TrainingRange | None = None
    range_checks: dict[str, RangeCheck | None] = field(default_factory=dict)
    #: each joint's friction on the validation record against the training record's
    #: (:mod:`estimation.identification.friction_drift`; ``None``: not checked)
    friction_drift: FrictionDrift | None = None
    #: in memory: the torque gains the check took, fitted on each half of the training record
    #: (:mod:`estimation.consistent.training_halves`; ``None``: not checked)
    training_stationarity: TrainingHalves | None = None
    #: the load the logged torques lack, when the answer is the model of such a log (:func:`subtracted_selection`;
    #: the result file's ``model_file.subtracted``), else ``None``
    subtracted: SubtractedLoad | None = None

    @property
    def rest(self) -> dict[str, dict | None]:
        """What was dropped as at rest (``--min-speed``, in memory only: the streamed path drops nothing)."""
        if self.records is None:
            return {"train": None, "validation": None}
        return rest_records(self.records)


def _masked_sums(streaming: dict[str, Any] | None) -> bool:
    """Whether a streamed fit's sums left a masked sample out (a file's ``channel_samples``)."""
    return bool(streaming) and any(entry.get("channel_samples") for key in ("files", "validation_files")
                                   for entry in streaming.get(key) or [])


def identify_document(args: IdentifyOptions, identified: Identified) -> tuple[dict[str, Any], tuple[str, ...]]:
    """``result.json`` (the same keys on both paths: :meth:`IdentificationResult.to_dict`, the preprocessing, the
    trivial predictors, the model's parameters, the weighting and model choices, the model file, the noise floor,
    the chosen model's answer at the top level) and the warnings said, the model file's after the run's."""
    result = identified.result
    messages = list(identified.messages)
    document = finish_document(result.to_dict(), result, trivial=identified.trivial, warnings=identified.notes,
                               rest=identified.rest, transmission=identified.transmission)
    document["not_computed"] = dict(identified.not_computed)
    for key in ("zero_mse", "nominal_mse"):  # not computed: null, as the other keys the path says why it lacks
        if f"validation.{key}" in identified.not_computed and document.get("validation") is not None:
            document["validation"][key] = None
    if result.path == "streamed":
        document["preprocessing"] = dict(identified.preprocessing)
    if identified.consistent is not None:
        document.update(identified.consistent.to_dict())
    else:  # not fitted: null, as the streamed path says why (not_computed)
        document.update({key: None for key in ("consistent", "links") if key in identified.not_computed})
    if identified.weighting is not None:
        document["method_selection"] = identified.weighting.to_dict()
    selection = identified.selection
    document["model_selection"] = None if selection is None else selection.to_dict()
    # a torque sensor past its range: the samples left out of the fit and of the errors (said when read)
    document["saturated_samples"] = saturated_sample_counts(identified.records)
    # each channel's errors over its valid samples where they differ by channel (its masked samples out)
    document["channel_samples"] = channel_sample_counts(identified.records) if identified.records is not None else \
        streamed_channel_counts(result.streaming)  # streamed: the sums' counts
    if identified.records is not None:
        messages += add_model_file(document, result, args, identified.records.preprocessing, identified.transmission,
                                   consistent=identified.consistent, selection=selection)
    else:
        model_plan, validation_mse = identified.model_file
        messages += add_summed_model_file(document, result.model, result.estimate, args, model_plan,
                                          recorded_mse=document["train"]["mse"], validation_mse=validation_mse,
                                          selection=selection, transmission=identified.transmission)
    gains = identified.torque_gains
    document["torque_gains"] = None if gains is None else {**gains[0].to_dict(), "taken": gains[1], "reason": gains[2]}
    if gains is not None and gains[1]:  # oed predict multiplies the model's torques by them
        document["model_file"]["torque_gains"] = gains[0].to_dict()
    if identified.subtracted is not None:  # oed predict subtracts it from the model's torques, as the log did
        document["model_file"]["subtracted"] = identified.subtracted.to_dict()
    floor, floor_report = identified.floor, identified.floor_report
    if document.get("validation") is not None:
        if floor_report is not None:
            document["validation"]["mse_over_floor"] = floor_report.ratios("after") or None
        document["noise_floor"] = None if floor is None else {
            "mse": floor.mse(), "method": floor.method, "note": identified.floor_note}
    answered = identified.chosen.validation is None or identified.chosen.validation.mse is not None
    answer_identification(document, identified.chosen, floor=floor if answered else None, fitted=result)
    if document.get("validation") is not None and "mse_over_floor" not in document["validation"]:
        document["validation"]["mse_over_floor"] = None  # no floor, or no error against the recording
    drift = identified.friction_drift
    document["friction_drift"] = None if drift is None else drift.to_dict()
    halves = identified.training_stationarity
    document["training_stationarity"] = None if halves is None else halves.to_dict()
    said = add_training_range(document, identified.training_range, identified.range_checks)
    if said:  # a validation record beyond the training range: the choice measured some extrapolation
        messages += said
        document["warnings"] = [*document.get("warnings", []), *said]
    return document, tuple(messages)


def identification_streamed(args: IdentifyOptions, model: IdentificationModel, transmission: Transmission | None,
                            plan: Preprocessing | None = None, findings: FindingsSaid | None = None) -> Identified:
    """Identify from the files read in blocks (:func:`estimation.streaming.identification.identify_files_candidates`),
    their derivatives chosen as in memory (``plan``: already chosen), and choose the answer as in memory among the
    unconstrained fits and the consistent refit (:func:`estimation.streaming.model_selection.summed_selection`: from
    the sums, every candidate scored on the same validation samples against the channels as recorded,
    :class:`ValidationScores`; on the Fourier path, whose sums hold averaged periods, every sample of the validation
    files' recorded samples scored); on the validation files,
    the errors against the channels as recorded, the trivial predictors' and the noise floor of their first rows
    (:func:`recorded_validation`). ``findings``: what the path decision said of the files (not said again)."""
    chunk_size = DEFAULT_CHUNK_SIZE if args.chunk_size is None else args.chunk_size
    selection, gains, subtracted = None, None, None
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        args = streamed_records(args, model)  # a file with holes: its segments, each on its own as in memory
        if plan is None:
            plan = streamed_choice(args, model, validation_fits=validation_fits(args, model, None)).chosen
        args = on_time_base(args, plan)  # the regular clock chosen: every pass reads the sources on it, as memory
        options = plan_options(plan)
        weighting = choose_weighting(model, weighting_samples(streamed_window(args.data, model), plan)) \
            if args.method == "auto" else None  # on the samples the in-memory path chooses it on
        base = args.method if weighting is None else weighting.method
        methods = (base,) if args.method != "auto" else (base, "ols" if base == "wls" else "wls")
        with executor_for(args) as executor:
            sums = identify_files_candidates(model, args.data, args.validate or [], methods=methods,
                                             chunk_size=chunk_size, cutoff_hz=options["cutoff_hz"],
                                             frequency_hz=options["frequency_hz"], harmonics=options["harmonics"],
                                             decimation=options["decimation"], held_torques=options["held_torques"],
                                             executor=executor)
        result = sums.fits[base]
        cutoff_hz, frequency_hz = result.streaming["cutoff_hz"], result.streaming["frequency_hz"]
        scores, ratio, checked, gravity_taken = None, None, None, False
        reading_options = {"chunk_size": chunk_size, "cutoff_hz": options["cutoff_hz"],
                           "frequency_hz": options["frequency_hz"], "harmonics": options["harmonics"],
                           "decimation": options["decimation"], "held_torques": options["held_torques"]}
        # the answer chosen as in memory (on the Fourier path scored on every sample of the validation files' whole
        # periods, ValidationScores)
        scores = None if result.validation is None else ValidationScores(args, sums, result, chunk_size, options)
        ratio = None if not args.validate else streamed_repeated_motion(model, args.data, args.validate,
                                                                        chunk_size=chunk_size)
        still = bool(args.validate) and warned_still_motion(model, args.data, args.validate,
                                                            chunk_size=chunk_size)
        with step("identified (the candidate models fitted and compared)"):
            selection = summed_selection(sums, base=base, given=None if args.method == "auto" else args.method,
                                         consistent=consistent_settings(args, model.robot), score=scores,
                                         ratio=ratio, still=still)
        motor = streamed_motor_friction_selection(
            args, selection, model, transmission, base=base, methods=methods, chunk_size=chunk_size,
            options=options, ratio=ratio, still=still, sums=sums, scores=scores)
        if motor is not None:  # the selection with the candidate compared, and the sums of the model it holds
            selection, sums, scores = motor
        selection, sums, scores = streamed_armature_selection(
            args, selection, base=base, methods=methods, chunk_size=chunk_size, options=options, ratio=ratio,
            still=still, sums=sums, scores=scores)
        # the candidates of a found mount, of a subtracted load and of torque gains, on either path (on the Fourier
        # path the sums hold averaged periods and the checks read every recorded sample with the fit's motion); the
        # joints' zeros and gravity's direction against the description's; a mount found is a candidate
        checked = streamed_description_findings(
            model, args.data, int(sums.train.n_samples), args.validate or [],
            0 if sums.validation is None else int(sums.validation.n_samples), options=reading_options)
        declared = selection.unconstrained.model  # the answer's model with the description's gravity
        selection, sums, scores, gravity_taken = streamed_gravity_selection(
            args, selection, checked.said_mount, base=base, methods=methods, chunk_size=chunk_size,
            options=options, ratio=ratio, still=still, sums=sums, scores=scores)
        selection, sums, scores, subtracted = streamed_subtracted_selection(
            args, selection, declared, checked.said_mount, base=base, methods=methods, chunk_size=chunk_size,
            options=options, ratio=ratio, still=still, sums=sums, scores=scores)
        if subtracted is not None:  # every pass after reads the torques with the load added back, as memory's
            options, gravity_taken = {**options, "load": subtracted}, False
            reading_options = {**reading_options, "load": subtracted}
        else:  # one known load at a time: the gains are not tried on a log that lacks one
            selection, gains = streamed_torque_gains_selection(
                args, selection, base=base, methods=methods, chunk_size=chunk_size, options=options,
                ratio=ratio, still=still, sums=sums, scores=scores)
        result = selection.unconstrained
    # a line per finding across files; those said when the path was decided (``findings``) not again
    messages = grouped_messages(caught, source_files([*args.data, *(args.validate or ())])) if findings is None \
        else findings.mark(caught)
    not_computed = dict(result.not_computed)
    if args.method != "auto":  # in memory too, the consistent refit is a candidate of the default choice only
        for key in ("consistent", "links"):
            not_computed.pop(key, None)
    if selection is not None:
        not_computed.pop("model_selection", None)
        not_computed.pop("gravity", None)  # a mount found is a candidate, as in memory
        not_computed.pop("subtracted", None)  # and the log less the description's gravity torque
        if selection.consistent is not None or args.method != "auto":
            not_computed.pop("consistent", None)
            not_computed.pop("links", None)
        else:
            reason = next((c.unavailable for c in selection.candidates if c.name == "consistent"), None)
            not_computed.update({key: reason for key in ("consistent", "links") if reason})
        result = replace(result, not_computed={key: value for key, value in result.not_computed.items()
                                               if key in not_computed})  # what the selection computed
    if frequency_hz is not None:  # a Fourier fit of averaged periods: `oed predict` fits a record's periods alike
        model_plan = fourier_plan(args, frequency_hz, options["harmonics"])
    else:
        model_plan = streamed_plan(args.data[0], model, cutoff_hz=cutoff_hz, decimation=options["decimation"],
                                   held_torques=bool(options["held_torques"]), chunk_size=chunk_size)  # as summed
    model_plan = with_time_base(model_plan, plan)  # oed predict reads a record on the clock the fit read
    if args.validate and stamps_kept(args.data):  # a training file cut at its holds: the stamps kept
        not_computed["time_base"] = STREAMED_TIME_BASE
    chosen = ChosenModel(result.estimate.method, result) if selection is None else ChosenModel.of(selection)
    trivial, floor, floor_note, notes = None, None, None, ()
    if result.validation is not None:
        if scores is not None:  # every candidate's and the trivial predictors' errors, scored on the same samples
            trivial = scores.trivial
        else:
            result, trivial, reasons = recorded_validation(args, result, chunk_size, harmonics=options["harmonics"])
            not_computed.update(reasons)
            chosen = ChosenModel(result.estimate.method, result)
        frequency = plan.frequency_hz if plan.method == "fourier" else args.frequency
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # the files' findings were said on the first pass
            floor, floor_note = window_floor(args.validate, model, frequency_hz=frequency, load=subtracted)
        if floor is None:
            not_computed["noise_floor"] = floor_note
        mse = chosen.validation.mse
        if trivial is not None and mse is not None:
            notes += trivial_warnings(mse, trivial)
        if floor is not None and mse is not None:
            comparisons = compare_with_floor(mse, floor, result.validation.n_samples, alpha=FLOOR_ALPHA)
            notes += tuple(f"{comparison.statement()}: the model lacks something there; `oed diagnose` searches for it"
                           for comparison in comparisons.values() if comparison.above)
    repeat = None if ratio is None else repeat_note(ratio)  # the notes said in memory after the floor's
    notes = notes if repeat is None else (*notes, repeat)
    # the joint zeros, the mount and the friction drift checked as in memory, on the samples memory checks
    said, drift = streamed_description_notes(
        model, args.data, int(sums.train.n_samples), args.validate or [],
        0 if sums.validation is None else int(sums.validation.n_samples), options=reading_options,
        findings=checked, gravity_taken=gravity_taken, subtracted=subtracted is not None)
    notes = (*notes, *said, *scale_notes(None if gains is None else gains[0]))
    result, chosen, selection = recorded_training(args, result, chosen, selection, chunk_size, options)
    validation_mse = None if result.validation is None else result.validation.mse
    ranges = merged_ranges([part.joint_range for part in sums.files])  # taken in the sums pass
    validation_range = merged_ranges([part.joint_range for part in sums.validation_files])
    return Identified(result, chosen, plan.to_dict(), plan.describe(),
                      (*messages, *notes), notes, trivial, floor, floor_note, not_computed, selection=selection,
                      consistent=None if selection is None else selection.consistent, weighting=weighting,
                      transmission=transmission, chunk_size=chunk_size, model_file=(model_plan, validation_mse),
                      torque_gains=gains, training_range=ranges,
                      range_checks={"validation": None if ranges is None or validation_range is None
                                    else ranges.check_range(validation_range)}, friction_drift=drift,
                      subtracted=subtracted)


def streamed_torque_gains_selection(args: IdentifyOptions, selection: ModelSelection, *, base: str,
                                    methods: tuple[str, ...], chunk_size: int, options: Mapping[str, Any],
                                    ratio: float | None, still: bool, sums: SummedFits,
                                    scores: Scorer | None = None
                                    ) -> tuple[ModelSelection, tuple[TorqueGains, bool, str] | None]:
    """:func:`torque_gains_selection` of files read in blocks, under the same conditions: the gains fitted from the
    training sums and checked on the validation files in one pass
    (:func:`estimation.streaming.torque_gains.streamed_gains_check`, the in-memory rule); when the check takes them,
    the answer's candidates chosen again from the sums of the torques divided by them
    (:func:`~estimation.streaming.torque_gains.divided_sums`, no pass) and scored in the log's units
    (:class:`~estimation.streaming.torque_gains.GainsScorer`), then compared with the declared model's answer by
    :func:`~estimation.consistent.torque_gains.torque_gains_answer`. ``sums``: those of the model ``selection``
    holds."""
    model = selection.unconstrained.model
    channels = model.channels
    if args.method != "auto" or args.consistent or model_has_shapes(model) or not args.validate \
            or sums.validation is None or selection.selection != "validation" or len(channels) < 2 \
            or not all(map(is_joint_torque, channels)):
        return selection, None
    reading = {"chunk_size": chunk_size, "cutoff_hz": options["cutoff_hz"], "decimation": options["decimation"],
               "held_torques": options["held_torques"]}
    recorded = int(sums.validation.n_samples)  # the validation samples as recorded the check's pass reads
    if options["frequency_hz"] is not None:  # the Fourier path: every recorded row, the fit's motion there
        reading.update(frequency_hz=options["frequency_hz"], harmonics=options["harmonics"])
        recorded = sum(int(part.rows) for part in sums.validation_files)
    with step("an unknown gain on each joint's torque fitted and checked on the validation record"):
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")  # the files' findings were said on the first pass
                checked = streamed_gains_check(model, sums.train, args.validate, recorded, reading)
        except (ValueError, np.linalg.LinAlgError):
            return selection, None
    if checked is None:
        return selection, None
    gains, promising, sentence = checked
    scale = other_scale(gains)
    if scale is not None and args.prior is None:  # as in memory (torque_gains_selection): the prior at that scale
        with step("the answer's candidates fitted again with the description's bodies at the torques' scale"):
            selection = carried_reasons(selection, summed_selection(
                sums, base=base, consistent=prior_at_scale(args, model, scale), score=scores, ratio=ratio,
                still=still))
    if not promising:
        return selection, (gains, False, sentence)
    with step("the answer's candidates fitted to the torques divided by the gains and compared"):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            other = summed_selection(divided_sums(sums, gains, methods), base=base,
                                     consistent=consistent_settings(args, model.robot),
                                     score=GainsScorer(model, gains, args.validate, reading, n_samples=recorded),
                                     ratio=ratio, still=still)
    answer, taken, compared = torque_gains_answer(selection, carried_reasons(selection, other), gains)
    return answer, (gains, taken, f"{sentence}; then {compared}" if compared else sentence)


def streamed_motor_friction_selection(args: IdentifyOptions, selection: ModelSelection, model: IdentificationModel,
                                      transmission: Transmission | None, *, base: str, methods: tuple[str, ...],
                                      chunk_size: int, options: Mapping[str, Any], ratio: float | None, still: bool,
                                      sums: SummedFits, scores: ValidationScores | None
                                      ) -> tuple[ModelSelection, SummedFits, ValidationScores | None] | None:
    """:func:`motor_friction_selection` of files read in blocks: the declared model with motor-side viscous and
    Coulomb friction on the coupled motors added, summed over the same files with the same derivatives, weightings
    and options, chosen among its candidates from its sums as the declared model's were
    (:func:`estimation.streaming.model_selection.summed_selection`, scored on the same validation samples), and
    compared with the declared model's answer by the same rule
    (:func:`estimation.consistent.motor_friction.motor_friction_answer`). ``None`` when the in-memory path would not
    try it (the same conditions), else the selection made, the sums and the scorer of the model it holds (``sums``,
    ``scores``: the declared model's)."""
    laws = motor_friction_laws(model, transmission)
    if not laws or args.method != "auto" or args.consistent or not args.validate or model_has_shapes(model) \
            or selection.selection != "validation":
        return None
    other_model = build_model(model.robot, model.kind, (*model.effects, *laws))
    with step("motor-side friction on the coupled motors fitted and compared"):
        other, other_sums, other_scores = summed_candidate(args, other_model, base=base, methods=methods,
                                                           chunk_size=chunk_size, options=options, ratio=ratio,
                                                           still=still)
    answer = motor_friction_answer(selection, other, ",".join(effect_spec(effect) for effect in laws))
    return (answer, other_sums, other_scores) if answer.unconstrained.model is other_model else (answer, sums, scores)


def summed_candidate(args: IdentifyOptions, other_model: IdentificationModel, *, base: str, methods: tuple[str, ...],
                     chunk_size: int, options: Mapping[str, Any], ratio: float | None, still: bool
                     ) -> tuple[ModelSelection, SummedFits, ValidationScores]:
    """A candidate model of the streamed default answer (motor-side friction, armature) summed over the same files
    with the same derivatives, weightings and options as the declared model, and chosen among its candidates from
    its sums as the declared model's were (scored on the same validation samples): ``(selection, sums, scores)``."""
    with executor_for(args) as executor:
        other_sums = identify_files_candidates(
            other_model, args.data, args.validate, methods=methods, chunk_size=chunk_size,
            cutoff_hz=options["cutoff_hz"], frequency_hz=options["frequency_hz"], harmonics=options["harmonics"],
            decimation=options["decimation"], held_torques=options["held_torques"], executor=executor,
            load=options.get("load"))
    other_scores = ValidationScores(args, other_sums, other_sums.fits[base], chunk_size, dict(options))
    other = summed_selection(other_sums, base=base, consistent=consistent_settings(args, other_model.robot),
                             score=other_scores, ratio=ratio, still=still)
    return other, other_sums, other_scores


def streamed_armature_selection(args: IdentifyOptions, selection: ModelSelection, *, base: str,
                                methods: tuple[str, ...], chunk_size: int, options: Mapping[str, Any],
                                ratio: float | None, still: bool, sums: SummedFits, scores: ValidationScores | None
                                ) -> tuple[ModelSelection, SummedFits, ValidationScores | None]:
    """:func:`armature_selection` of files read in blocks: the model ``selection`` holds with ``armature`` added,
    summed and chosen among its candidates as the declared model's were (:func:`summed_candidate`) and compared by
    the same rule (:func:`estimation.consistent.armature.armature_answer`); ``(selection, sums, scores)`` unchanged
    when the in-memory path would not try it (the same conditions), else those of the answer."""
    model = selection.unconstrained.model
    laws = armature_laws(model)
    if not laws or args.method != "auto" or args.consistent or not args.validate or model_has_shapes(model) \
            or selection.selection != "validation":
        return selection, sums, scores
    with step("the rotors' reflected inertia (armature) fitted and compared"):
        fitted = armature_candidate(model, laws, lambda candidate: summed_candidate(
            args, candidate, base=base, methods=methods, chunk_size=chunk_size, options=options, ratio=ratio,
            still=still))
    if fitted is None:
        return selection, sums, scores
    other_model, (other, other_sums, other_scores) = fitted
    answer = armature_answer(selection, other)
    return (answer, other_sums, other_scores) if answer.unconstrained.model is other_model else (answer, sums, scores)


def streamed_gravity_selection(args: IdentifyOptions, selection: ModelSelection, mount: MountCheck | None, *,
                               base: str, methods: tuple[str, ...], chunk_size: int, options: Mapping[str, Any],
                               ratio: float | None, still: bool, sums: SummedFits, scores: ValidationScores | None
                               ) -> tuple[ModelSelection, SummedFits, ValidationScores | None, bool]:
    """:func:`gravity_selection` of files read in blocks: the model ``selection`` holds with the gravity the mount
    check found (:func:`~estimation.consistent.mounted_gravity.turned_model`), summed over the same files with the
    same derivatives (a pass of its own: the regressor changes with gravity), chosen among its candidates from its
    sums as the declared model's were (:func:`summed_candidate`, scored on the same validation samples) and compared
    by the same rule (:func:`~estimation.consistent.mounted_gravity.gravity_answer`); ``(selection, sums, scores,
    taken)``, unchanged (``taken`` false) under the conditions memory tries nothing (no mount said, the estimator
    given, shaped laws, no validation record of another motion)."""
    model = selection.unconstrained.model
    if mount is None or args.method != "auto" or args.consistent or not args.validate or model_has_shapes(model) \
            or selection.selection != "validation":
        return selection, sums, scores, False
    turned = turned_model(model, mount.gravity)
    with step("the model with the gravity the mount check found fitted and compared"):
        other, other_sums, other_scores = summed_candidate(args, turned, base=base, methods=methods,
                                                           chunk_size=chunk_size, options=options, ratio=ratio,
                                                           still=still)
    answer, taken = gravity_answer(selection, other, mount.gravity)
    if answer.unconstrained.model is turned:
        return answer, other_sums, other_scores, taken
    return answer, sums, scores, taken


def streamed_subtracted_selection(args: IdentifyOptions, selection: ModelSelection, declared: IdentificationModel,
                                  mount: MountCheck | None, *, base: str, methods: tuple[str, ...], chunk_size: int,
                                  options: Mapping[str, Any], ratio: float | None, still: bool, sums: SummedFits,
                                  scores: ValidationScores | None
                                  ) -> tuple[ModelSelection, SummedFits, ValidationScores | None,
                                             SubtractedLoad | None]:
    """:func:`subtracted_selection` of files read in blocks: where the mount check says the torques hold no gravity
    load, ``declared`` (the answer's model with the description's gravity) summed over the same files with the same
    derivatives, the description's gravity torque added back to every prepared chunk of every pass
    (:func:`estimation.streaming.chunks.loaded_chunk`, as memory adds it to the prepared records), chosen among its
    candidates from its sums as the declared model's were (:func:`summed_candidate`; scored on the same validation
    samples, each prediction less the load against the torques as recorded, what ``oed predict`` measures) and
    compared by the same rule (:func:`~estimation.consistent.mounted_gravity.subtracted_answer`); ``(selection, sums,
    scores, the load)`` of the answer when taken, else ``(selection, sums, scores, None)`` unchanged, under the
    conditions memory tries nothing (:func:`streamed_gravity_selection`'s, and a model of the joint torques)."""
    if mount is None or not mount.absent or args.method != "auto" or args.consistent or not args.validate \
            or model_has_shapes(declared) or selection.selection != "validation" or not load_channels(declared):
        return selection, sums, scores, None
    load = SubtractedLoad()
    with step("the model of a log less the description's gravity torque fitted and compared"):
        other, other_sums, other_scores = summed_candidate(args, declared, base=base, methods=methods,
                                                           chunk_size=chunk_size, options={**options, "load": load},
                                                           ratio=ratio, still=still)
    answer, taken = subtracted_answer(selection, other)
    return (answer, other_sums, other_scores, load) if taken else (answer, sums, scores, None)


def recorded_training(args: IdentifyOptions, result: IdentificationResult, chosen: ChosenModel,
                      selection: ModelSelection | None, chunk_size: int, options: Mapping[str, Any]
                      ) -> tuple[IdentificationResult, ChosenModel, ModelSelection | None]:
    """The streamed fits with their training errors against the channels as recorded, on the samples the in-memory
    path measures them on (``n_samples``: the recorded samples, as in memory), from one more pass over the training
    files (:func:`estimation.streaming.recorded_errors.recorded_training_errors`): where the sums hold filtered or
    period-averaged channels (their errors kept as ``mse_filtered``) or a file was resampled onto a uniform grid
    (the sums' errors, against interpolated channels, kept as ``mse_filtered``). Every fitted candidate's, the
    unconstrained result's and the chosen model's, in the one pass. Unchanged where the sums hold the recording
    of files read as logged, or where the loader drops rows the grid interpolates (then measured on the grid)."""
    streaming = result.streaming or {}
    files = streaming.get("files") or []
    resampled = any(record.get("resampled_from") is not None for record in files)
    if result.train.mse is not None and not resampled:
        return result, chosen, selection
    fits: dict[str, Any] = {"result": result, "chosen": chosen.fit}
    if selection is not None:
        fits.update({candidate.name: candidate.fit for candidate in selection.candidates if candidate.fit is not None})
    clock = time.perf_counter()
    with step(f"training errors against the recording: a pass over {len(args.data)} training file(s)"), \
            warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the files' findings were said on the first pass
        counted = recorded_training_errors(
            result.model, less_load(result.model, theta_predictors(
                result.model, {key: fit.estimate.values for key, fit in fits.items()}), options.get("load")),
            args.data, files,
            chunk_size=chunk_size, cutoff_hz=streaming.get("cutoff_hz"), decimation=int(options["decimation"]),
            held_torques=bool(options["held_torques"]), frequency_hz=streaming.get("frequency_hz"),
            harmonics=int(options["harmonics"]))
    if counted is None:
        return result, chosen, selection
    errors, count = counted
    seconds = {**streaming.get("seconds", {}), "training_errors_pass": round(time.perf_counter() - clock, 3)}

    def measured(key: str) -> Any:
        fit = fits[key]
        summed = fit.train
        against = summed.mse_filtered if summed.mse_filtered is not None else summed.mse
        return replace(fit, train=ChannelErrors(dict(errors[key]), count, mse_filtered=against))

    result = replace(measured("result"), streaming={**streaming, "seconds": seconds})
    chosen = ChosenModel(chosen.name, measured("chosen"))
    if selection is not None:
        selection = replace(selection, candidates=tuple(
            candidate if candidate.fit is None else replace(candidate, fit=measured(candidate.name))
            for candidate in selection.candidates))
    return result, chosen, selection


class ValidationScores:
    """The validation errors of several base-parameter vectors of a streamed run, all on the same samples and
    against the channels as recorded (:data:`estimation.consistent.identification.Scorer`): from the validation
    sums when they hold the recording, else from one pass over the validation files' blocks
    (:func:`estimation.streaming.recorded_errors.streamed_recorded_errors`; the sums give the errors against the
    filtered channels beside them), and on a file resampled onto a uniform grid at the recorded samples
    (:func:`~oed.workflows.model_files.recorded_validation_mse`'s measurement, what ``oed predict`` measures). The
    first call scores the trivial predictors too (:attr:`trivial`: zero and nominal parameters).

    Each error carries the MSE of each validation block (``ChannelErrors.block_mse``: the blocks memory cuts its
    samples into, :mod:`estimation.streaming.block_errors`), for the paired difference of the default answer's
    candidates (:func:`estimation.consistent.model_selection.paired_difference`): summed on the pass against the
    recording, or, where the sums hold the recording, from each block's normal equations summed once on a pass
    of their own (:meth:`block_sums`); on a file resampled onto a uniform grid at its recorded stamps, once their
    count is known (:meth:`at_stamps`). Not where the loader drops rows the grid interpolates (the files measured
    whole): ``None`` there. On the Fourier path (the sums hold one averaged period a file) every sample of the
    validation files' whole periods is scored with the fit of their averaged period at its instant, as memory scores
    its validation record, ``n_samples`` those samples; no blocks, as memory holds none there."""

    def __init__(self, args: IdentifyOptions, sums: SummedFits, result: IdentificationResult, chunk_size: int,
                 options: dict[str, Any]) -> None:
        self.args, self.sums, self.result, self.chunk_size = args, sums, result, chunk_size
        #: the derivatives as the files were summed (:func:`estimation.streaming.periods.plan_options`)
        self.decimation, self.held_torques = int(options["decimation"]), bool(options["held_torques"])
        self.harmonics = int(options.get("harmonics") or 5)  # the Fourier fit's, on the Fourier path
        #: a load the logged torques lack (the subtracted load's candidate): added back to every chunk the sums and
        #: the blocks read, subtracted from every prediction scored against the torques as recorded
        self.load: SubtractedLoad | None = options.get("load")
        self.trivial: dict[str, dict[str, float]] | None = None
        self._block_sums: list[NormalEquations] | None = None
        self._block_sums_made = False
        self._stamp_count: int | None = None  # the recorded samples of a resampled validation file
        #: each validation file scanned once for the scorer's passes (every one under an ignoring warnings filter:
        #: the files' findings were said on the sums pass), the scan handed to the later ones
        self.scans = FileScans()

    def block_sums(self) -> list[NormalEquations] | None:
        """Each validation block's normal equations, summed on one pass the first time they are asked for
        (:func:`estimation.streaming.block_errors.block_normal_equations`, the chunks as the sums took them)."""
        if not self._block_sums_made:
            self._block_sums_made = True
            model, streaming = self.result.model, self.result.streaming
            options = {"chunk_size": self.chunk_size, "cutoff_hz": streaming["cutoff_hz"],
                       "decimation": self.decimation, "held_torques": self.held_torques, "load": self.load}
            chunks = (chunk for path in self.args.validate
                      for chunk in prepared_chunks(str(path), model, scans=self.scans, **options))
            with step("the validation record's blocks summed (the paired difference of the candidates)"):
                self._block_sums = block_normal_equations(model, chunks, int(self.sums.validation.n_samples))
        return self._block_sums

    def __call__(self, thetas: Mapping[Any, np.ndarray]) -> dict[Any, ChannelErrors]:
        model, args, streaming = self.result.model, self.args, self.result.streaming
        vectors = {("theta", key): np.asarray(theta, dtype=float) for key, theta in thetas.items()}
        if self.trivial is None:
            vectors.update({("trivial", "zero_mse"): np.zeros(model.n_base),
                            ("trivial", "nominal_mse"): model.base.K @ model.nominal_parameters()})
        summed = {key: self.sums.validation_errors(theta) for key, theta in vectors.items()}
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # the files' findings were said on the first pass
            recorded = None
            blocks: dict[Any, dict[str, tuple[float, ...]] | None] = {}
            block_samples = None
            fourier = streaming.get("frequency_hz") is not None
            if resampled_validation({"streaming": streaming}):  # jittered or cleaned: at the recorded samples
                recorded, blocks, block_samples = self.at_stamps(vectors, thetas)  # block by block
                if fourier and recorded is not None:  # the recorded samples counted (no blocks: none in memory there)
                    summed = {key: replace(errors, n_samples=block_samples) for key, errors in summed.items()}
                    block_samples = None
            if recorded is None and resampled_validation({"streaming": streaming}):  # rows the loader drops: whole
                plan = fourier_plan(args, streaming["frequency_hz"], self.harmonics) if fourier else \
                    streamed_plan(args.data[0], model, cutoff_hz=streaming["cutoff_hz"], decimation=self.decimation,
                                  held_torques=self.held_torques, chunk_size=self.chunk_size)
                document = summed_model_file_document(model, self.result.estimate,
                                                      robot=robot_source(model.robot, args), preprocessing=plan)
                if self.load is not None:  # oed predict subtracts it from the model's torques
                    document["subtracted"] = self.load.to_dict()
                recorded = recorded_validation_errors(document, vectors, source_files(args.validate))  # None: as recorded
            if recorded is not None:
                pass
            elif next(iter(summed.values())).mse is not None:  # the sums hold the recording
                recorded = {key: errors.mse for key, errors in summed.items()}
                block_sums = self.block_sums()
                if block_sums is not None:
                    blocks = {("theta", key): block_channel_mse(block_sums, np.asarray(theta, dtype=float))
                              for key, theta in thetas.items()}
            elif fourier:  # averaged periods summed: every recorded sample, the fit's motion there
                # each block of those samples too, as memory cuts the samples it compares (every row is scored: the
                # blocks of the rows the validation files' sums read; none when the pass gives another count)
                rows = sum(int(part.rows) for part in self.sums.validation_files)
                squares = {("theta", key): BlockSquares(rows, model.n_channels) for key in thetas}
                recorded, counted = counted_predicted_errors(
                    model, less_load(model, theta_predictors(model, vectors), self.load), args.validate,
                    chunk_size=self.chunk_size, decimation=self.decimation, held_torques=self.held_torques,
                    frequency_hz=streaming["frequency_hz"], harmonics=self.harmonics, blocks=squares,
                    scans=self.scans)
                # the samples scored, as memory counts its validation record
                summed = {key: replace(errors, n_samples=counted) for key, errors in summed.items()}
                blocks = {key: accumulated.block_mse(model.channels) for key, accumulated in squares.items()}
            else:
                count = int(self.sums.validation.n_samples)
                squares = {("theta", key): BlockSquares(count, model.n_channels) for key in thetas}
                recorded, _ = counted_predicted_errors(
                    model, less_load(model, theta_predictors(model, vectors), self.load), args.validate,
                    chunk_size=self.chunk_size, cutoff_hz=streaming["cutoff_hz"], decimation=self.decimation,
                    held_torques=self.held_torques, blocks=squares, scans=self.scans)
                blocks = {key: accumulated.block_mse(model.channels) for key, accumulated in squares.items()}
        if self.trivial is None:
            self.trivial = {name: dict(recorded[("trivial", name)]) for name in ("zero_mse", "nominal_mse")}
        return {key: ChannelErrors(dict(recorded[("theta", key)]), summed[("theta", key)].n_samples,
                                   mse_filtered=summed[("theta", key)].mse_filtered,
                                   block_mse=blocks.get(("theta", key)), block_samples=block_samples)
                for key in thetas}

    def at_stamps(self, vectors: Mapping[Any, np.ndarray], thetas: Mapping[Any, np.ndarray]
                  ) -> tuple[dict[Any, dict[str, float]] | None, dict[Any, Any], int | None]:
        """The errors of ``vectors`` at the recorded stamps of a validation file resampled onto a grid
        (:func:`~estimation.streaming.recorded_errors.counted_errors_at_stamps`), each block's of the ``thetas``
        among them, and how many samples the blocks cut: the first call learns that count, then scores the
        ``thetas`` once more with the blocks (one more pass, once a scorer); ``(None, {}, None)`` when the loader
        drops rows the grid interpolates."""
        model, streaming = self.result.model, self.result.streaming
        reading = {"chunk_size": self.chunk_size, "cutoff_hz": streaming["cutoff_hz"], "decimation": self.decimation,
                   "held_torques": self.held_torques, "frequency_hz": streaming.get("frequency_hz"),
                   "harmonics": self.harmonics}
        keys = [("theta", key) for key in thetas]

        def squares(count: int | None) -> dict[Any, BlockSquares] | None:
            return None if count is None else {key: BlockSquares(count, model.n_channels) for key in keys}

        accumulated = squares(self._stamp_count)
        predictors = less_load(model, theta_predictors(model, vectors), self.load)
        counted = counted_errors_at_stamps(model, {}, self.args.validate, blocks=accumulated, predictors=predictors,
                                           scans=self.scans, **reading)
        if counted is None:
            return None, {}, None
        recorded, count = counted
        if reading["frequency_hz"] is not None:  # the Fourier path: no blocks (memory holds none there)
            return recorded, {}, count
        if accumulated is None:  # the count learnt: the blocks of the thetas from one more pass
            self._stamp_count = count
            accumulated = squares(count)
            again = counted_errors_at_stamps(model, {}, self.args.validate, blocks=accumulated,
                                             predictors={key: predictors[key] for key in keys}, scans=self.scans,
                                             **reading)
            if again is None or accumulated is None:
                return recorded, {}, None
        return recorded, {key: item.block_mse(model.channels) for key, item in accumulated.items()}, count


def recorded_validation(args: IdentifyOptions, result: IdentificationResult, chunk_size: int, *, harmonics: int = 5
                        ) -> tuple[IdentificationResult, dict[str, dict[str, float]] | None, dict[str, str]]:
    """The streamed ``result`` with its validation error against the channels as recorded, on the samples the
    in-memory preprocessing keeps (what ``oed predict`` measures), and the trivial predictors' errors there, from
    one pass over the validation files (:func:`estimation.streaming.recorded_errors.streamed_recorded_errors`; the
    filter path's sums hold filtered channels; sums of the recording give both: ``result.trivial``); on a file resampled onto a uniform grid, the error at the recorded
    samples (:func:`~oed.workflows.model_files.recorded_validation_mse`). On the Fourier path (the sums hold
    averaged periods) the pass reads every sample of the validation files' whole periods with the fit's motion at
    their instants (``harmonics``: the fit's), as ``oed predict`` reads them."""
    streaming = result.streaming
    model = result.model
    if result.trivial is not None and result.validation.mse is not None:  # the sums hold the recording
        errors, mse = {key: dict(value) for key, value in result.trivial.items()}, result.validation.mse
    else:
        thetas = {"zero_mse": np.zeros(model.n_base), "nominal_mse": model.base.K @ model.nominal_parameters(),
                  "mse": result.estimate.values}
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # the files' findings were said on the first pass
            errors = streamed_recorded_errors(model, thetas, args.validate, chunk_size=chunk_size,
                                              cutoff_hz=streaming["cutoff_hz"], decimation=args.decimate,
                                              held_torques=bool(args.held_torques),
                                              frequency_hz=streaming["frequency_hz"], harmonics=harmonics)
        mse = errors.pop("mse")
    if resampled_validation({"streaming": streaming}):  # jittered or cleaned: its error at the recorded samples
        plan = fourier_plan(args, streaming["frequency_hz"], harmonics) if streaming["frequency_hz"] is not None \
            else streamed_plan(args.data[0], model, cutoff_hz=streaming["cutoff_hz"], decimation=args.decimate,
                               held_torques=bool(args.held_torques), chunk_size=chunk_size)
        recorded = recorded_validation_counted(summed_model_file_document(
            model, result.estimate, robot=robot_source(model.robot, args), preprocessing=plan),
            source_files(args.validate))
        if recorded is not None:  # and counted there, as in memory (not the grid's samples)
            mse, count = recorded
            return replace(result, validation=replace(result.validation, mse=mse, n_samples=count)), errors, {}
    return replace(result, validation=replace(result.validation, mse=mse)), errors, {}


def fourier_plan(args: IdentifyOptions, frequency_hz: float, harmonics: int) -> dict[str, Any]:
    """The model file's preprocessing of a streamed Fourier fit of averaged periods (``oed predict`` fits a record's
    periods alike)."""
    return {"method": "fourier", "frequency_hz": frequency_hz, "harmonics": harmonics, "frequency_source": "given",
            "average_periods": "auto", "decimation": args.decimate, "held_torques": bool(args.held_torques)}


def in_memory_only(args: IdentifyOptions, model: IdentificationModel, delay: DelayBounds | None) -> str | None:
    """The options given that the streamed identification lacks, in a few words, or ``None``."""
    if delay is not None:
        return "a delay is searched in memory"
    try:
        check_streamed_request(args, model)
    except ValueError as error:
        return str(error).split(":")[0] + " (not on the streamed path)"
    return None


def check_model_request(args: IdentifyOptions, model: IdentificationModel, delay: DelayBounds | None) -> None:
    """A delay only in memory (``--consistent`` holds it, and the shaped laws' shapes, at their fitted values)."""
    if delay is not None and streaming_requested(args):
        raise ValueError("a delay between torques and motion is searched in memory by the weighted least squares: "
                         "not with the streamed path (--chunk-size, --scheduler or --workers)")


def check_streamed_request(args: IdentifyOptions, model: IdentificationModel) -> None:
    """Options the streamed identification does not have: an error naming them, before anything is read."""
    if args.plot:  # the report is written on both paths (streamed: without figures, saying what it lacks)
        raise ValueError(f"--plot draws every sample: not with {STREAMED}")
    if args.min_speed is not None:
        raise ValueError(f"--min-speed drops rows of the whole record: not with {STREAMED}")
    if model_has_shapes(model):
        raise ValueError("laws with shape parameters (coulomb:tanh, sigmoid…) are fitted by variable projection "
                         f"in memory: not with {STREAMED}")
    if args.consistent:
        raise ValueError(f"--consistent refits in memory: not with {STREAMED}")
    unsupported = [option for option, given in (
        ("--average-periods", args.average_periods != "auto"),
        ("--max-gap", args.max_gap != DEFAULT_MAX_GAP)) if given]
    if unsupported:
        raise ValueError(f"{', '.join(unsupported)}: not with {STREAMED}, which reads whole files without holes "
                         f"and with --frequency averages periods or fits every sample as --average-periods auto says; "
                         f"{IN_MEMORY_ROUTE}")


def identification_in_memory(args: IdentifyOptions, robot: RobotModel, model: IdentificationModel,
                             transmission: Transmission | None, delay: DelayBounds | None,
                             plan: Preprocessing | None = None) -> Identified:
    """Read and prepare the records (:func:`estimation.identification.prepared.prepare_records`; ``plan``: the
    derivatives chosen before reading), identify, compare the candidate models, and measure the validation error
    against the trivial predictors and the noise floor."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        records = prepare_records(model, args.data, args.validate or (),  # reports its steps
                                  settings=replace(preparation_settings(args, transmission, IN_MEMORY), plan=plan,
                                                   validation_fits=validation_fits(args, model, delay),
                                                   joint_offsets=resolve_joint_offsets(args, robot),
                                                   joint_directions=resolve_joint_directions(args, robot)))
        train = records.train.measurements
        validation = None if records.validation is None else records.validation.measurements
        with step("weighting chosen on held-out blocks"):
            weighting = choose_weighting(model, weighting_samples(ChoiceWindow.of(records.train.segments),
                                                                  records.preprocessing, train)) \
                if args.method == "auto" and delay is None and not model_has_shapes(model) else None
        base = weighting.method if weighting is not None else "ols" if args.method == "ols" else "wls"
        given = "consistent" if args.consistent else None if args.method == "auto" else args.method
        with step("identified (the candidate models fitted and compared)"):
            selection = select_model(model, train, validation, base=base, given=given, delay=delay,
                                     consistent=consistent_settings(args, robot))
        selection = motor_friction_selection(args, selection, model, transmission, train, validation,
                                             base=base, given=given, delay=delay)
        selection = armature_selection(args, selection, train, validation, base=base, given=given, delay=delay)
        # the joints' zeros and gravity's direction against the description's; a mount found is a candidate
        checks = description_checks(model, train, validation, delay=delay)
        declared = selection.unconstrained.model  # the answer's model with the description's gravity
        selection, gravity_taken = gravity_selection(args, selection, checks[1], train, validation, base=base,
                                                     given=given, delay=delay)
        selection, subtracted = subtracted_selection(args, selection, declared, checks[1], records, base=base,
                                                     given=given, delay=delay)
        if subtracted is not None:  # the answer's records: the torques with the load added back (its errors alike)
            records, gravity_taken = subtracted, False
            train = records.train.measurements
            validation = None if records.validation is None else records.validation.measurements
            gains, halves = None, None  # one known load at a time: the gains are not tried on a log that lacks one
        else:
            selection, gains, halves = torque_gains_selection(args, selection, train, validation, base=base, given=given,
                                                      delay=delay)
            if halves is not None and halves.fitted_on in PARTS:  # the answer fitted on that half: its samples on
                records = replace(records, train=replace(records.train, measurements=training_part(train, halves.fitted_on)))
                train = records.train.measurements
        result, consistent = selection.unconstrained, selection.consistent
        chosen = ChosenModel.of(selection)  # the answer: what the summary, result.json, predict and export hold
        trivial, notes = trivial_predictors(result, validation, chosen.validation)
        with step("noise floor of the validation record"):
            floor_report = None if validation is None else floor_check(records, model, result, args.frequency)
        notes = (*notes, *above_floor_notes(floor_report, chosen, None if validation is None else validation.n_samples))
        repeat = None if validation is None else repeated_motion_note(train, validation)
        notes = notes if repeat is None else (*notes, repeat)
        notes = (*notes, *description_notes(model, checks, gravity_taken=gravity_taken,
                                            subtracted=subtracted is not None),
                 *scale_notes(None if gains is None else gains[0]))
        said = None if halves is None else halves.message()  # the plant changed during training
        notes = notes if said is None else (*notes, said)
        drift = None if delay is not None or model_has_shapes(model) else check_friction_drift(model, train, validation)
        notes = notes if drift is None or drift.message() is None else (*notes, drift.message())
    ranges = TrainingRange.of(train.q, train.dq, model.robot.joint_names)  # the samples fitted
    return Identified(result, chosen, records.preprocessing.to_dict(), records.preprocessing.describe(),
                      (*chosen_messages(caught_messages(caught), selection), *notes), notes, trivial,
                      None if floor_report is None else floor_report.floor,
                      None if floor_report is None else floor_report.floor_note, records=records, selection=selection,
                      consistent=consistent, floor_report=floor_report, weighting=weighting, transmission=transmission,
                      n_samples=train.n_samples, torque_gains=gains, training_range=ranges,
                      range_checks={"validation": None if validation is None else ranges.check(validation.q,
                                                                                               validation.dq)},
                      friction_drift=drift, subtracted=None if subtracted is None else SubtractedLoad(),
                      training_stationarity=halves)


def motor_friction_selection(args: IdentifyOptions, selection: ModelSelection, model: IdentificationModel,
                             transmission: Transmission | None, train: Measurements, validation: Measurements | None,
                             *, base: str, given: str | None, delay: DelayBounds | None) -> ModelSelection:
    """The default answer with motor-side friction on the coupled motors of the declared transmission a candidate
    (:mod:`estimation.consistent.motor_friction`): the model with the motor laws added chosen among its candidates
    as the declared model's were, on the same records, and taken when its answer validates better. ``selection``
    unchanged when the user chose the estimator (``--method``, ``--consistent``), with a delay search or shaped laws
    (fitted by a search each), without a validation record, or when no coupled motor lacks its laws."""
    laws = motor_friction_laws(model, transmission)
    if not laws or given is not None or delay is not None or model_has_shapes(model) or validation is None \
            or selection.selection != "validation":
        return selection
    if args.min_speed is not None and args.rest == "smooth":
        laws = smooth_coulomb(laws, args.min_speed)
    with step("motor-side friction on the coupled motors fitted and compared"):
        other = select_model(build_model(model.robot, model.kind, (*model.effects, *laws)), train, validation,
                             base=base, consistent=consistent_settings(args, model.robot))
    return motor_friction_answer(selection, other, ",".join(effect_spec(effect) for effect in laws))


def armature_selection(args: IdentifyOptions, selection: ModelSelection, train: Measurements,
                       validation: Measurements | None, *, base: str, given: str | None,
                       delay: DelayBounds | None) -> ModelSelection:
    """The default answer with the rotors' reflected inertia (armature on every joint) a candidate
    (:mod:`estimation.consistent.armature`): the model ``selection`` holds (the declared one, with the motor laws when
    they were taken) with ``armature`` added, chosen among its candidates as the declared model's were, on the same
    records, and taken when its answer validates better. ``selection`` unchanged when the user chose the estimator
    (``--method``, ``--consistent``), with a delay search or shaped laws, without a validation record of another
    motion, or when the model declares an armature or models no joint torque."""
    model = selection.unconstrained.model
    laws = armature_laws(model)
    if not laws or given is not None or delay is not None or model_has_shapes(model) or validation is None \
            or selection.selection != "validation":
        return selection
    with step("the rotors' reflected inertia (armature) fitted and compared"):
        fitted = armature_candidate(model, laws, lambda candidate: select_model(
            candidate, train, validation, base=base, consistent=consistent_settings(args, model.robot)))
    return selection if fitted is None else armature_answer(selection, fitted[1])


def armature_candidate(model: IdentificationModel, laws: tuple[Any, ...],
                       fit: Callable[[IdentificationModel], Any]) -> tuple[IdentificationModel, Any] | None:
    """``model`` with the armature ``laws`` added, and ``fit`` of it; where the records never accelerate a joint
    (its armature column zero on every training sample) that joint's armature is left out
    (:func:`~estimation.identification.undetermined.left_out_unexcited`) and the rest fitted; ``None`` when no
    joint's armature is determined (no candidate)."""
    candidate = build_model(model.robot, model.kind, (*model.effects, *laws))
    try:
        return candidate, fit(candidate)
    except IdentifiabilityError as error:
        change = left_out_unexcited(candidate, error.parameters) if error.unexcited else None
        if change is None or not any(getattr(effect, "name", "") == "armature" for effect in change[0]):
            return None
        candidate = build_model(model.robot, model.kind, change[0])
        return candidate, fit(candidate)


def gravity_selection(args: IdentifyOptions, selection: ModelSelection, mount: MountCheck | None,
                      train: Measurements, validation: Measurements | None, *, base: str, given: str | None,
                      delay: DelayBounds | None) -> tuple[ModelSelection, bool]:
    """The default answer with the gravity the mount check found a candidate
    (:mod:`estimation.consistent.mounted_gravity`): the model ``selection`` holds (with the motor laws or the
    armature when they were taken) with that gravity, chosen among its candidates as the declared model's were, on
    the same records, and taken when its answer validates better; ``(answer, taken)``. ``(selection, False)`` when no
    mount is said (``mount`` ``None``: not marked, or the joints' zeros said instead), when the user chose the
    estimator, with a delay search or shaped laws, or without a validation record of another motion."""
    model = selection.unconstrained.model
    if mount is None or given is not None or delay is not None or model_has_shapes(model) or validation is None \
            or selection.selection != "validation":
        return selection, False
    with step("the model with the gravity the mount check found fitted and compared"):
        turned = turned_model(model, mount.gravity)
        other = select_model(turned, train, validation, base=base, consistent=consistent_settings(args, turned.robot))
    return gravity_answer(selection, other, mount.gravity)


def subtracted_selection(args: IdentifyOptions, selection: ModelSelection, declared: IdentificationModel,
                         mount: MountCheck | None, records: PreparedRecords, *, base: str, given: str | None,
                         delay: DelayBounds | None) -> tuple[ModelSelection, PreparedRecords | None]:
    """The default answer with the description's gravity torque subtracted by the logger a candidate
    (:func:`estimation.consistent.mounted_gravity.subtracted_answer`): where the mount check says the torques hold no
    gravity load, ``declared`` (the answer's model with the description's gravity) chosen among its candidates on the
    records with that load added back (:func:`~estimation.identification.subtracted_load.added_back_records`), and
    taken when its answer validates better than ``selection``'s; ``(answer, the records added back)`` then, else
    ``(selection, None)``: under :func:`gravity_selection`'s conditions, and for a model of the joint torques only."""
    validation = records.validation
    if mount is None or not mount.absent or given is not None or delay is not None or model_has_shapes(declared) \
            or validation is None or selection.selection != "validation" or not load_channels(declared):
        return selection, None
    with step("the model of a log less the description's gravity torque fitted and compared"):
        added = added_back_records(records, SubtractedLoad(), declared.robot)
        other = select_model(declared, added.train.measurements, added.validation.measurements, base=base,
                             consistent=consistent_settings(args, declared.robot))
    answer, taken = subtracted_answer(selection, other)
    return answer, added if taken else None


def prior_at_scale(args: IdentifyOptions, model: IdentificationModel, scale: float) -> ConsistentSettings:
    """The consistent candidate's settings with the description's bodies times ``scale`` as its prior (the recorded
    torques' scale, :func:`~estimation.consistent.torque_gains.other_scale`: a description in grams gives 0.001),
    ``prior_source`` saying so; the same for the in-memory and the streamed ``oed identify``."""
    return consistent_settings(replace(args, prior_scale=scale), model.robot)


def torque_gains_selection(args: IdentifyOptions, selection: ModelSelection, train: Measurements,
                           validation: Measurements | None, *, base: str, given: str | None,
                           delay: DelayBounds | None
                           ) -> tuple[ModelSelection, tuple[TorqueGains, bool, str] | None, TrainingHalves | None]:
    """The default answer with an unknown gain on each joint's recorded torque a candidate
    (:mod:`estimation.consistent.torque_gains`): the gains fitted on the training record and checked on the
    validation record (:func:`~estimation.consistent.torque_gains.gains_on_validation`: the channel-weighted fit with
    them must validate better, beyond the record's sampling spread); only then the declared model (as
    ``selection``'s, with the motor laws when they were taken) chosen among its candidates on the torques divided by
    them, and taken when its answer validates better in the recorded units. Before that comparison the gains are
    fitted on each half of the training record (:func:`~estimation.consistent.training_halves.gains_halves`): when
    the halves disagree the plant changed during training, and the gains are not taken. ``(selection, None, None)``
    unchanged when the user chose the estimator, with a delay search or shaped laws, without a validation record of
    another motion, or for a model with channels other than joint torques; else ``(answer, (gains, taken, reason),
    halves)``, the reason the
    check's sentence (and the answers' comparison when the check let them be compared); the third item the
    training record's halves compared (``None``: not checked)."""
    model = selection.unconstrained.model
    channels = model.channels
    if given is not None or delay is not None or model_has_shapes(model) or validation is None \
            or selection.selection != "validation" or len(channels) < 2 \
            or not all(map(is_joint_torque, channels)) or passive_channels(model):  # a passive joint's 0: no gain
        return selection, None, None
    with step("an unknown gain on each joint's torque fitted and checked on the validation record"):
        try:
            gains, promising, checked = gains_on_validation(model, train, validation)
        except (ValueError, np.linalg.LinAlgError):
            return selection, None, None
    scale = other_scale(gains)
    if scale is not None and args.prior is None:
        # the description's bodies and the torques in other units (a description in grams: 0.001): the consistent
        # candidate's prior, the description's bodies, taken at the torques' scale (scale_note says which units)
        with step("the answer's candidates fitted again with the description's bodies at the torques' scale"):
            selection = carried_reasons(selection, select_model(model, train, validation, base=base,
                                                                consistent=prior_at_scale(args, model, scale)))
    if not promising:
        return selection, (gains, False, checked), None
    with step("the torque gains fitted on each half of the training record, compared"):
        halves = gains_halves(model, train)  # a sensor's gain holds over the whole record: the halves must agree
    if halves is not None and halves.changed:  # the plant changed during training: no gain taken
        selection, halves, why = changed_plant_selection(args, selection, train, validation, base=base, halves=halves)
        return selection, (gains, False, f"{checked}; then {halves.message()}" + (f"; {why}" if why else "")), halves
    with step("the answer's candidates fitted to the torques divided by the gains and compared"):
        other = select_model(model, divided_torques(train, gains), divided_torques(validation, gains), base=base,
                             consistent=consistent_settings(args, model.robot))
    answer, taken, compared = torque_gains_answer(selection, carried_reasons(selection, in_recorded_units(other, gains)),
                                                  gains)
    return answer, (gains, taken, f"{checked}; then {compared}" if compared else checked), halves


def changed_plant_selection(args: IdentifyOptions, selection: ModelSelection, train: Measurements,
                            validation: Measurements, *, base: str, halves: TrainingHalves
                            ) -> tuple[ModelSelection, TrainingHalves, str]:
    """The default answer when the training record's halves disagree (the plant changed during training,
    :mod:`estimation.consistent.training_halves`): the answer's model (``selection``'s) chosen among its candidates
    on each half of the training record too, and the whole record's answer kept unless a half's validates better by
    more than :data:`~estimation.consistent.training_halves.PART_TOLERANCE`
    (:func:`~estimation.consistent.training_halves.part_answer`, the same validation samples): ``(answer, halves,
    why)``, ``halves`` holding the part chosen and the scores, ``why`` the sentence (the answer's reason ends with it)."""
    model = selection.unconstrained.model
    with step("the plant changed during training: the answer made on each half of the training record, compared"):
        parts = {part: carried_reasons(selection, select_model(model, training_part(train, part), validation,
                                                                base=base, consistent=consistent_settings(args,
                                                                                                          model.robot)))
                 for part in PARTS}
    fitted_on, why, scores = parts_compared(selection, parts)
    halves = replace(halves, fitted_on=fitted_on, scores=scores)
    chosen = selection if fitted_on == "whole" else parts[fitted_on]
    return (replace(chosen, reason=f"{chosen.reason}; {why}") if why else chosen), halves, why


#: the sentences the candidates of the default answer append to its reason (motor-side friction, the armature, the
#: gravity found)
CANDIDATE_SENTENCES = ("; motor-side friction on the coupled motors", "; the rotors' reflected inertia",
                       "; the gravity the mount check found")


def carried_reasons(selection: ModelSelection, other: ModelSelection) -> ModelSelection:
    """``other`` (the model ``selection`` holds, fitted again to the torques divided by the gains) with the
    sentences that said how that model was chosen (motor-side friction, the armature: :data:`CANDIDATE_SENTENCES`)
    appended to its reason, so that an answer taken with the gains still says them."""
    starts = [selection.reason.find(mark) for mark in CANDIDATE_SENTENCES if mark in selection.reason]
    return other if not starts else replace(other, reason=other.reason + selection.reason[min(starts):])


def validation_fits(args: IdentifyOptions, model: IdentificationModel, delay: DelayBounds | None) -> tuple[str, ...]:
    """The unconstrained fits that choose the derivatives on a validation record of another motion
    (:mod:`estimation.identification.preprocessing_on_validation`): the weighting asked for, else OLS alone (the
    weighting is chosen afterwards on the same record, with the derivatives chosen; scored by the better of OLS and
    WLS, the minimum over twice as many pairs took a lucky one: 125 Hz by its WLS fit on the TX40 at 2.5 kHz,
    benchmarks/README.md, h-weakval2); none
    with a delay search or shaped laws (fitted by a search each, not repeated for every candidate: the
    training record's choice is kept)."""
    if delay is not None or model_has_shapes(model):
        return ()
    return ("ols",) if args.method == "auto" else (args.method,)


def floor_check(records: PreparedRecords, model: IdentificationModel, result: IdentificationResult,
                frequency_hz: float | None) -> ResidualReport:
    """The validation error against the validation record's noise floor (estimated from the file as read, without
    the model), and what the residual of a channel still above it follows (:mod:`estimation.diagnosis.statistics`)."""
    preprocessing = records.preprocessing
    frequency = preprocessing.frequency_hz if preprocessing.method == "fourier" else frequency_hz
    floor = records.validation.noise_floor(model.channels, frequency)
    return residual_report(result, result, records.train.measurements, records.validation.measurements, floor)


def above_floor_notes(report: ResidualReport | None, chosen: ChosenModel | None = None,
                      n_samples: int | None = None) -> list[str]:
    """A warning for each channel whose validation error stays significantly above its floor: the unconstrained
    fit's (``report``), or the ``chosen`` model's when it is the consistent fit (tested as ``report`` tests,
    ``n_samples`` the validation record's)."""
    if report is None or report.floor is None:
        return []
    comparisons = report.comparison.get("after", {})
    if chosen is not None and chosen.consistent and chosen.validation is not None:
        n_samples = chosen.validation.t.shape[0] if n_samples is None else n_samples
        comparisons = compare_with_floor(chosen.validation.mse, report.floor, n_samples, alpha=FLOOR_ALPHA)
        traced = {channel: report.statements.get(channel, "").partition("; ")[2] for channel in comparisons}
        return [f"{comparison.statement()}{'; ' + traced[channel] if traced[channel] else ''}: the model lacks "
                "something there; `oed diagnose` searches for it"
                for channel, comparison in comparisons.items() if comparison.above]
    above = [channel for channel, comparison in comparisons.items() if comparison.above]
    return [f"{report.statements[channel]}: the model lacks something there; `oed diagnose` searches for it"
            for channel in above]


def summary_lines(args: IdentifyOptions, identified: Identified) -> list[str]:
    """The lines ``oed identify`` prints, on both paths: the preprocessing, the records (streamed: how the files were
    read, and the batch-means standard deviations), the chosen model's estimate with its shape parameters and
    errors, the rows at rest dropped; in memory the consistent refit and the comparison of candidate models."""
    result, chosen = identified.result, identified.chosen
    model, estimate = result.model, result.estimate
    fit = f"{estimate.method.upper()}" if not chosen.consistent else \
        f"physically consistent, refitted from {estimate.method.upper()}"
    read = "" if result.path == "in-memory" else \
        f" from {len(result.streaming['files'])} file(s) in chunks of {identified.chunk_size}"
    lines = [identified.describe,
             f"{model.robot.name}: {model.kind.value} model, {model.n_base} base parameters, "
             f"{identified.n_samples or result.train.n_samples} samples{read}, {fit}, cond {estimate.cond:.4g}"]
    covariance = (result.streaming or {}).get("covariance") or {}
    if covariance.get("method") == "batch_means":
        lines.append(f"standard deviations: batch means (batches of {covariance['batch_length']} samples; a third "
                     f"pass over the files, {result.streaming['seconds']['covariance_pass']:.3g} s)")
    lines += chosen.parameter_lines()
    width = max(len(name) for name in estimate.names)
    for value in result.shapes:
        bound = "  (at its bound)" if value.at_bound else ""
        if chosen.consistent:  # held, not estimated: no standard deviation of the chosen model's
            lines.append(f"  {value.name:<{width}}  {value.value:+.5g}  (shape of {value.effect}; held by the "
                         f"consistent fit at the {estimate.method} fit's value){bound}")
            continue
        lines.append(f"  {value.name:<{width}}  {value.value:+.5g} ± {value.std:.2g}  (shape of {value.effect})"
                     f"{bound}")
    for label, errors in (("train", chosen.train), ("validation", chosen.validation)):
        if errors is None:
            continue
        if errors.mse is not None:
            lines.append(mse_line(f"{label} MSE (vs recorded)", errors.mse))
        if errors.mse_filtered is not None:
            against = "vs filtered" if errors.mse is not None else "vs filtered: not against the recording"
            lines.append(mse_line(f"{label} MSE ({against})", errors.mse_filtered))
    counted = channel_sample_line(channel_sample_counts(identified.records) if identified.records is not None else
                                  streamed_channel_counts(identified.result.streaming))
    if counted:
        lines.append(counted)
    message = rest_message("identify", identified.rest)
    if message:
        lines.append(message)
    selection, consistent = identified.selection, identified.consistent
    if consistent is not None and (args.consistent or selection.chosen == "consistent"):
        lines += consistent_lines(consistent)
    if selection is not None:
        lines += selection.lines()
    drift = [] if identified.friction_drift is None else identified.friction_drift.lines()
    return lines + range_lines(identified.range_checks) + drift
