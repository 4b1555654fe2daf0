"""``oed diagnose`` as a library call: find what an identified model lacks in measured data, add it, report the
error before and after.

:func:`diagnose` takes the verb's options as keywords (:class:`DiagnoseOptions`) and runs one workflow
(:func:`run_diagnose`): the path is decided by the records (:func:`~oed.workflows.memory_path.decide_path`), the data
are read whole (:func:`diagnosis_in_memory`) or in blocks (:func:`diagnosis_streamed`,
:mod:`estimation.streaming.diagnosis`), both give one :class:`~estimation.diagnosis.results.Diagnosis` (what the
streamed path cannot compute is ``None``, its reason in ``not_computed``), and one builder makes the document
(:func:`diagnose_document`) and the summary (:func:`summary_lines`) from it; in memory the answer is the adopted
model or its consistent refit (:func:`diagnosis_selection`). It returns a :class:`DiagnoseRun`:
``to_dict()`` is ``report.json``, ``write(out, report=...)`` writes it (and the report, HTML or Markdown:
:meth:`DiagnoseRun.report`), ``summary()`` the lines ``oed diagnose`` prints.
"""

from __future__ import annotations

import copy
import functools
import warnings
from collections.abc import Callable
from contextlib import ExitStack
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from dynamics.channels import is_joint_torque
from dynamics.effects.linear import ViscousFriction
from dynamics.measurements import Measurements
from dynamics.models import IdentificationModel, build_model
from dynamics.runtime.output_files import OutputFiles, json_text
from dynamics.runtime.processes import beside, run_tasks, worker_count
from dynamics.runtime.progress import step
from dynamics.transmission import Transmission
from estimation.consistent.model_selection import ModelSelection, select_refit
from estimation.consistent.torque_gains import (
    TorqueGains,
    channel_factors,
    diagnosed_gains_answer,
    divided_records,
    gains_for_records,
    in_recorded_units,
    other_scale,
    scale_notes,
)
from estimation.identification.fit import identify as identify_model
from estimation.identification.mount import MountCheck
from estimation.identification.subtracted_load import SubtractedLoad, added_back_records, load_channels
from estimation.consistent.mounted_gravity import gravity_answer, subtracted_answer, turned_model
from estimation.identification.relative_error import relative_scores
from estimation.identification.validation import ChannelErrors
from estimation.consistent.completion import completed_laws, completed_note, completion_repeat, held_completion
from estimation.diagnosis.candidates.coupling import coupling_candidates
from estimation.diagnosis.plain_laws import completion_laws, plain_completion, plain_model
from dynamics.runtime.report_document import Report, figure_path, report_format
from estimation.diagnosis.results import Diagnosis, SummedFit, runner_up_line
from estimation.diagnosis.search import default_candidates
from estimation.diagnosis.search import diagnose as diagnose_model
from estimation.diagnosis.untouched import UntouchedErrors, recorded_comparison, recorded_mse, untouched_errors
from estimation.identification.prepared import (InMemoryBudget, PreparedRecords, channel_sample_counts,
                                                channel_sample_line, prepare_records, saturated_sample_counts)
from estimation.identification.repeated_motion import repeat_note, repeated_motion_note
from estimation.identification.undetermined import fitted_without_undetermined
from estimation.preprocessing.delay import DelayBounds, split_delay
from estimation.preprocessing.plan import Preprocessing
from estimation.streaming.settings import DEFAULT_SUBSAMPLE
from estimation.identification.model_file import summed_model_file_document
from estimation.identification.friction_drift import FrictionDrift, check_friction_drift
from estimation.consistent.training_halves import PARTS, TrainingHalves, gains_halves, parts_compared, training_part
from estimation.identification.time_base_choice import STREAMED_TIME_BASE
from estimation.identification.joint_zeros import JointZeroCheck
from estimation.identification.training_range import RangeCheck, TrainingRange, merged_ranges
from estimation.estimators.normal_equations import DEFAULT_CHUNK_SIZE
from estimation.data.input_findings import FindingsSaid
from estimation.data.log_cleaning import DEFAULT_MAX_GAP
from estimation.uncertainty.noise_floor import NoiseFloor
from oed.workflows.asbuilt import (
    competing_checks,
    diagnosis_mount,
    diagnosis_mount_notes,
    finish_document,
    marked_joint_zeros,
    mount_candidates,
    DIAGNOSIS_MOUNT_SAMPLES,
    streamed_checks,
    streamed_marked_joint_zeros,
    model_effects,
    resolve_joint_directions,
    resolve_joint_offsets,
    resolve_transmission,
    rest_message,
    rest_records,
    trivial_predictors,
    worse_after,
)
from oed.workflows.chosen_model import ChosenModel, answer_diagnosis, mse_line
from oed.workflows.diagnosis_training import averaged_errors, averaged_sums, recorded_training, summed_unconstrained
from oed.workflows.joint_side import named_as_given, records_to_read
from oed.workflows.memory_path import (IN_MEMORY_ROUTE, decide_path, on_time_base, stamps_kept, streamed_choice,
                                      streamed_records, with_time_base)
from oed.workflows.consistent import check_consistent_arguments, consistent_lines, consistent_settings
from oed.workflows.model_files import (
    add_model_file,
    add_runner_up_model_file,
    add_summed_model_file,
    add_summed_runner_up_model_file,
    add_training_range,
    range_lines,
    recorded_validation_scores,
    recorded_validation_mse,
    recorded_validations_counted,
    resampled_validation,
    robot_source,
)
from oed.workflows.options import (
    RecordOptions,
    caught_messages,
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

if TYPE_CHECKING:
    from estimation.streaming.diagnosis_result import StreamedRun

# the streamed path's modules and the Markdown/HTML report's are imported where they are used: a run in memory
# without --report never imports them (each run compiles and imports every module it imports)

__all__ = ["IN_MEMORY", "DiagnoseOptions", "DiagnoseRun", "diagnose", "report_figures", "residual_figure",
           "trace_figure"]

#: what the in-memory diagnosis holds at its peak: bytes a sample, channel and base parameter (measured: 2.8 GB
#: for 100 000 samples of the 7-joint KUKA, m r = 350, i.e. about 75; a lower bound is used)
IN_MEMORY = InMemoryBudget(64, "diagnosing", "use --chunk-size to stream them in bounded memory")


@dataclass(frozen=True, kw_only=True)
class DiagnoseOptions(RecordOptions):
    """The options of ``oed diagnose`` (:class:`~oed.workflows.options.RecordOptions` and these): ``test`` (a path
    or a list), ``report`` (whether the report, HTML or Markdown, will be written: streamed, without figures), ``alpha``,
    ``max_effects``, ``subsample`` and ``floor_window`` (the streamed path's), ``unseen_stretches`` (with a validation
    record that repeats the training motion, refuse an effect that raises the error on stretches its fit did not
    see), and ``consistent`` (the answer forced to the adopted model's physically consistent refit, shaped laws and
    a delay at their fitted values; without it the refit is a candidate of the default answer,
    :func:`diagnosis_selection`) with ``prior_weight`` (a number or ``"auto"``), ``prior``, ``link_bounds``."""

    test: tuple[Path, ...] = ()
    report: bool = False
    alpha: float = 1e-3
    max_effects: int = 20
    subsample: int = DEFAULT_SUBSAMPLE
    floor_window: int | None = None
    unseen_stretches: bool = False
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
        object.__setattr__(self, "test", self.sources(self.test))
        if not self.validate:
            raise ValueError("diagnose confirms every effect on held-out data: give validate=... (--validate FILE)")


def residual_figure(report: str | Path) -> Path:
    """The residual figure written beside the Markdown report."""
    return figure_path(report, "residuals")


def trace_figure(report: str | Path) -> Path:
    """The figure of the residual against its strongest variables, beside the Markdown report (written when a
    traced variable says something)."""
    return figure_path(report, "trace")


def report_figures(report: str | Path, channels: tuple[str, ...] = (), test: bool = False) -> tuple[Path, ...]:
    """The figure files beside the Markdown report ``report`` (none beside an HTML one): the residual and
    tracing figures, and one per channel and record (``report.validation.tau1.png``, ``report.test.tau1.png``)."""
    if report_format(report) == "html":
        return ()
    records = ("validation", "test") if test else ("validation",)
    return (residual_figure(report), trace_figure(report),
            *(figure_path(report, f"{record}.{channel}") for record in records for channel in channels))


#: the report's note when no test record was given
TEST_NOTE = ("The 'after' error is measured on the validation record, which chose the effects: it is optimistic. "
             "Give `--test FILE` (a third record) for an error no choice saw.")


@dataclass(frozen=True)
class DiagnoseRun:
    """What ``oed diagnose`` computed: the document it writes, the lines it prints, and the objects behind them.

    Attributes
    ----------
    document
        ``report.json`` (:meth:`to_dict` returns a copy).
    lines
        The lines ``oed diagnose`` prints on stdout (:meth:`summary`).
    warnings
        The warnings it prints on stderr, in order.
    diagnosis
        The :class:`~estimation.diagnosis.results.Diagnosis`, in memory or streamed (``diagnosis.path``).
    records
        The prepared records (in memory; ``None`` when streamed: no Markdown report then).
    untouched
        The errors on the ``test`` record, or ``None``.
    """

    document: dict[str, Any] = field(repr=False)
    lines: tuple[str, ...]
    warnings: tuple[str, ...]
    diagnosis: Diagnosis = field(repr=False)
    records: PreparedRecords | None = field(default=None, repr=False)
    untouched: UntouchedErrors | None = field(default=None, repr=False)

    def to_dict(self) -> dict[str, Any]:
        """``report.json``, as ``oed diagnose`` writes it."""
        return copy.deepcopy(self.document)

    def summary(self) -> list[str]:
        """The lines ``oed diagnose`` prints (the effects found, the errors before and after, the floor)."""
        return list(self.lines)

    def report(self) -> Report:
        """The report a person reads (:func:`estimation.diagnosis.report.diagnosis_report`): the parameters with
        their uncertainties, the choices made, every warning, the errors before and after, measured against
        predicted on the validation and test records, the floor and what the residual follows. One document,
        written as Markdown (:meth:`markdown`) or HTML (:meth:`html`). A streamed run's report has no figures (no
        samples held) and says what its path did not compute."""
        from estimation.diagnosis.report import diagnosis_report

        diagnosis, records = self.diagnosis, self.records
        if records is None:  # streamed
            return diagnosis_report(diagnosis, preprocessing=self.lines[0], warnings=self.warnings,
                                    answer=self.document)
        validation = (diagnosis.before.validation, diagnosis.after.validation)
        test = None
        if self.untouched is not None and records.test is not None:
            test = tuple(recorded_comparison(result, records.test.measurements, "test")
                         for result in (diagnosis.before, diagnosis.after))
        return diagnosis_report(
            diagnosis, train=records.train.measurements, validate=records.validation.measurements,
            validation=validation, test=test, preprocessing=records.preprocessing.describe(), warnings=self.warnings,
            test_errors=None if self.untouched is None else self.untouched.to_dict(), test_note=TEST_NOTE,
            answer=self.document)

    def markdown(self, report: str | Path = "report.md") -> str:
        """The Markdown report, linking its figures as the files beside ``report`` (:func:`report_figures`)."""
        return self.report().markdown(lambda figure: figure_path(report, figure.name).name)

    def html(self) -> str:
        """The report as one self-contained HTML page (figures inline)."""
        return self.report().html()

    def plot_residuals(self, path: str | Path) -> None:
        """The residual figure of the report, saved at ``path``."""
        from estimation.diagnosis.report import plot_residuals

        self._check_in_memory()
        plot_residuals(self.diagnosis, self.records.train.measurements, path)

    def plot_trace(self, path: str | Path) -> None:
        """The residual against the variables that say something about it, saved at ``path`` (nothing written
        when none does)."""
        from estimation.diagnosis.report import plot_trace

        self._check_in_memory()
        plot_trace(self.diagnosis, self.records.validation.measurements, path)

    def write(self, out: str | Path, *, report: str | Path | None = None) -> None:
        """The report JSON at ``out`` and, with ``report``, the report: Markdown with its figures beside it
        (:func:`report_figures`) or HTML with them inline, by the suffix: all files or none."""
        check_json_path(out)
        check_report_path(report)
        with OutputFiles() as outputs:
            with outputs.open(out) as stream:
                stream.write(json_text(self.document))
            if report is not None:
                self.report().write(report, outputs)

    def _check_in_memory(self) -> None:
        if self.records is None:
            raise ValueError("the residual figures need the samples: not with the streamed path (--chunk-size, "
                             "--scheduler, --workers or a record over --memory-budget), which holds none")


def diagnose(*, say: Callable[[str], None] | None = None, **options: Any) -> DiagnoseRun:
    """``oed diagnose``: the effects the declared model lacks in ``data``, confirmed on ``validate``, and the error
    before and after (on ``test`` too when given).

    Parameters
    ----------
    say
        Called with each line said as the run goes (the path decision); default: nothing.
    **options
        The verb's options by their names (:class:`DiagnoseOptions`): ``data``, ``validate`` and ``test`` (a path
        or a list of paths), ``robot`` or ``urdf``, ``joints``, ``model``, ``friction``, ``alpha``,
        ``max_effects``, the derivative options… as ``oed diagnose --help`` lists them.

    Returns
    -------
    DiagnoseRun
        ``to_dict()`` is ``report.json``; ``write(out, report=None)``.
    """
    settings = DiagnoseOptions(**options)
    return run_diagnose(settings, say=say or (lambda line: None))


def run_diagnose(args: DiagnoseOptions, *, say: Callable[[str], None]) -> DiagnoseRun:
    """:func:`diagnose` of checked options: the path decided by the records (:func:`decide_path`: their rows against
    the memory budget, or the streamed path asked for), the data read whole or in blocks
    (:func:`diagnosis_in_memory`, :func:`diagnosis_streamed`), one :class:`Diagnosed` either way, and from it the
    one document (:func:`diagnose_document`) and summary (:func:`summary_lines`)."""
    check_request(args)
    check_consistent_arguments(args)
    differentiation(args)  # contradicting derivative options are an error even when the data hold dq, ddq
    friction, delay = split_delay(args.friction)  # a candidate in every diagnosis: 'delay:S' sets its bound
    if streaming_requested(args):  # bounded memory (estimation.streaming.diagnosis)
        check_streamed_request(args, delay)
    args, chain = with_logged_chain(args)  # a branching or mimic URDF read as the log's chain
    args, passive = with_passive_joints(args)  # named, or the description's joints without a motor the log lacks
    robot = robot_of(args)
    transmission = resolve_transmission(args, robot)
    effects = model_effects(args, friction, robot, transmission)
    model = build_model(robot, args.model, effects)
    with ExitStack() as copies:
        with warnings.catch_warnings(record=True) as copying:  # what the copies' reading said (a controller's log)
            warnings.simplefilter("always")
            read, names = copies.enter_context(records_to_read(  # joint-side copies of motor-side, zeroed records
                args, model, transmission, bytes_per_value=IN_MEMORY.bytes_per_value,
                in_memory_only=lambda: in_memory_only(args, model, delay)))
        # a Coulomb column one with the offset merged, a still joint's left out: said (both paths)
        diagnosed, merged = fitted_without_undetermined(
            lambda effects, model, merged: diagnosis_by_path(read, friction, effects, model, transmission, delay, say,
                                                             merged=bool(merged)),
            effects, model, lambda effects: build_model(robot, args.model, effects))
        if merged:
            said = tuple(column.statement() for column in merged)
            diagnosed = replace(diagnosed, messages=(*said, *diagnosed.messages), notes=(*said, *diagnosed.notes))
        copied = tuple(dict.fromkeys(str(item.message) for item in copying))
        if copied:
            diagnosed = replace(diagnosed, messages=(*copied, *diagnosed.messages))  # said as the reader says it
        document, messages = diagnose_document(args, diagnosed)
        # a torque sensor past its range: the samples left out of the fit and of the errors (said when read)
        document["saturated_samples"] = saturated_sample_counts(diagnosed.records)
        # each channel's errors over its valid samples where they differ by channel (its masked samples out)
        document["channel_samples"] = channel_sample_counts(diagnosed.records)
        if diagnosed.records is None:  # streamed: the files' masked cells counted as the streamed reader masks them
            from estimation.streaming.masked_counts import streamed_mask_counts  # the streamed path's, imported there
            document["saturated_samples"], document["channel_samples"] = streamed_mask_counts(
                {role: paths for role, paths in (("train", read.data), ("validation", read.validate),
                                                 ("test", read.test)) if paths}, model,
                chunk_size=DEFAULT_CHUNK_SIZE if read.chunk_size is None else read.chunk_size)
            (document.get("not_computed") or {}).pop("saturated_samples", None)
        if merged:
            document["not_determined"] = [column.to_dict() for column in merged]
        if chain is not None:
            document["logged_chain"] = chain
        if passive is not None:
            document["passive_joints"] = passive
        summary = tuple(summary_lines(args, diagnosed, document)) + (() if passive is None else (passive["statement"],))
    if names:  # the files as given, not their joint-side copies
        document, messages, summary = (named_as_given(value, names) for value in (document, messages, summary))
    return DiagnoseRun(document, summary, messages, diagnosed.diagnosis, diagnosed.records, diagnosed.untouched)


def diagnosis_by_path(read: DiagnoseOptions, friction: str | None, effects: tuple[Any, ...],
                      model: IdentificationModel, transmission: Transmission | None, delay: DelayBounds | None,
                      say: Callable[[str], None], *, merged: bool = False) -> Diagnosed:
    """The diagnosis of the records ``read``, streamed when asked for or when they exceed the memory budget
    (:func:`decide_path`), else in memory. ``merged``: ``effects`` are the declared ones with a Coulomb column
    merged into its offset or a still joint's columns left out
    (:func:`~estimation.identification.undetermined.not_determined`), which the streamed path then takes as they are
    instead of building them again from ``friction``."""
    declared = effects if merged else None
    if streaming_requested(read):
        return diagnosis_streamed(read, friction, effects=declared, delay=delay)
    check_shaped_effects_kept(effects, model)
    decision = decide_path(read, model, task="diagnosing", bytes_per_value=IN_MEMORY.bytes_per_value,
                           in_memory_only=lambda: in_memory_only(read, model, delay), say=say,
                           **derivatives_on_validation(model, delay))
    return (diagnosis_streamed(read, friction, decision.plan, decision.findings, effects=declared, delay=delay)
            if decision.stream
            else diagnosis_in_memory(read, model, transmission, delay, decision.plan))


@dataclass(frozen=True)
class Diagnosed:
    """A diagnosis, in memory or streamed, and what its document and summary need besides it.

    Attributes
    ----------
    diagnosis
        The :class:`~estimation.diagnosis.results.Diagnosis` (``diagnosis.path``: which path made it).
    preprocessing
        How the motion was derived: the document's ``preprocessing``.
    describe
        The preprocessing in one line (the summary's first).
    messages
        The warnings said, in order (the model files' come after them: :func:`diagnose_document`).
    records, untouched, selection, transmission, notes
        In memory: the prepared records, the test record's errors, the default answer
        (:func:`diagnosis_selection`), the transmission, the run's own notes; ``None`` when streamed, but the notes
        (a channel made worse, a repeat of the training motion, the joint zeros: said and in ``warnings.after``).
    chunk_size
        Streamed: the rows a block; ``None`` in memory.
    model_file
        Streamed: what the summed model file is written with (its plan and validation error).
    """

    diagnosis: Diagnosis
    preprocessing: dict[str, Any]
    describe: str
    messages: tuple[str, ...]
    records: PreparedRecords | None = None
    untouched: UntouchedErrors | None = None
    selection: ModelSelection | None = None
    transmission: Transmission | None = None
    notes: tuple[str, ...] = ()
    chunk_size: int | None = None
    model_file: tuple[dict[str, Any], dict[str, float] | None] | None = None
    #: streamed, Fourier path: the sums' training errors against the averaged period, by the report's entry, beside
    #: those measured against the recording (:func:`oed.workflows.diagnosis_training.recorded_training`)
    averaged_train: dict[str, Any] | None = None
    #: in memory: the per-joint torque gains the records were divided by (the validation record measured them)
    torque_gains: TorqueGains | None = None
    #: each joint's range on the samples fitted (:mod:`estimation.identification.training_range`; ``None``: not
    #: taken), and the held-out records against it by the report's key (``validation``, ``test``)
    training_range: TrainingRange | None = None
    range_checks: dict[str, RangeCheck | None] = field(default_factory=dict)
    #: in memory: each joint's friction on the validation record against the training record's
    #: (:mod:`estimation.identification.friction_drift`; ``None``: not checked)
    friction_drift: FrictionDrift | None = None
    #: the load the logged torques lack, when the answer is the diagnosis of such a log (the result file's
    #: ``model_file.subtracted``: :mod:`estimation.identification.subtracted_load`), else ``None``
    subtracted: SubtractedLoad | None = None
    #: in memory: the torque gains the quick check took, fitted on each half of the training record
    #: (:mod:`estimation.consistent.training_halves`; ``None``: not checked)
    training_stationarity: TrainingHalves | None = None


def check_streamed_request(args: DiagnoseOptions, delay: DelayBounds | None) -> None:
    """``--test`` is in-memory only: an error when the streamed path was asked for (a delay, ``delay``, is searched
    on both paths; passive joints are read on both)."""
    if args.test:
        raise ValueError("--test is read in memory: not with the streamed path (--chunk-size, --scheduler or "
                         "--workers)")


def in_memory_only(args: DiagnoseOptions, model: IdentificationModel, delay: DelayBounds | None) -> str | None:
    """The options given that the streamed diagnosis lacks, in a few words, or ``None``."""
    try:
        check_streamed_request(args, delay)
        check_streamed_arguments(args, model)
    except ValueError as error:
        return str(error).split(":")[0] + " (not on the streamed path)"
    return None


def diagnosis_in_memory(args: DiagnoseOptions, model: IdentificationModel, transmission: Transmission | None,
                        delay: DelayBounds | None, plan: Preprocessing | None, *,
                        refused: str | None = None, halves: TrainingHalves | None = None,
                        part: str | None = None) -> Diagnosed:
    """Read and prepare the records whole (``plan``: the derivatives chosen before reading), diagnose, and choose
    the default answer.

    Torque gains the quick check takes (:func:`~estimation.consistent.torque_gains.gains_for_records`, the plain
    model's) are kept only when the answer of the diagnosis of the torques divided by them predicts the validation
    record better than the adopted model fitted again to the torques as recorded (:func:`confirmed_gains`, the rule
    of ``oed identify``); otherwise the diagnosis is made again without them, ``refused`` the sentence saying why
    (``halves``: the stationarity check of the first pass). Before that, the gains are fitted on each half of the
    training record (:func:`~estimation.consistent.training_halves.gains_halves`): when the halves disagree the plant
    changed during training, the gains are not taken, and the answer is made on each half of the training record too
    (``part``: the half, :func:`changed_plant_answer`), the validation record choosing among the three."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        records = prepare_records(model, args.data, args.validate, args.test or (),  # reports its steps
                                  settings=replace(preparation_settings(args, transmission, IN_MEMORY), plan=plan,
                                                   joint_offsets=resolve_joint_offsets(args, model.robot),
                                                   joint_directions=resolve_joint_directions(args, model.robot),
                                                   **derivatives_on_validation(model, delay)))
        if part is not None:  # the plant changed during training: the answer made on this half of it
            records = replace(records, train=replace(records.train,
                                                     measurements=training_part(records.train.measurements, part)))
        # an unknown gain on each joint's recorded torque, measured on the validation record: the diagnosis then of
        # the torques divided by the gains, its answer's errors in the log's units (estimation.consistent.torque_gains)
        gains = None if args.consistent or delay is not None or model_has_shapes(model) or part is not None \
            else gains_for_records(plain_model(model), records)
        # the description's bodies and the torques in other units (grams, kN m): said, the gains taken or not
        scale = scale_notes(None if gains is None else gains[0])
        factor = None if gains is None else other_scale(gains[0])
        gains = gains if gains is not None and gains[1] and refused is None else None
        if gains is not None:  # a sensor's gain holds over the whole training record: the halves must agree
            with step("the torque gains fitted on each half of the training record, compared"):
                halves = gains_halves(plain_model(model), records.train.measurements)
            if halves is not None and halves.changed:  # the plant changed during training: no gain taken
                scale, gains = (*scale, f"{gains[2]}; then {halves.message()}"), None
        if gains is None and factor is not None and args.prior is None:
            # the torques diagnosed as recorded: the consistent candidate's prior the description's bodies at their
            # scale, as oed identify's (torque_gains_selection; known here before any candidate is fitted)
            args = replace(args, prior_scale=factor)
        recorded, refusal = records, None  # the records as logged: the gains confirmed against them (below)
        if gains is not None:
            records = divided_records(records, gains[0])
        # the joint-zero check reads the prepared records only: it runs beside the diagnosis and the default answer,
        # in the cores they leave idle (their serial steps, the slower worker of a pool), and is said where it was
        checks = functools.partial(checks_beside, model, records.train.measurements, records.validation.measurements,
                                   delay=delay)
        with beside(checks, worker_count(args.jobs, 2)) as beside_checks:
            # gravity's direction against the description's, before the search: the laws of a joint's position
            # alone are not tried where the found gravity explains the load (oed.workflows.asbuilt.mount_candidates)
            mount = diagnosis_mount(model, records.train.measurements, records.validation.measurements, delay=delay)
            with step("noise floors of the held-out records"):
                validation_floor, test_floor = record_floors(records, model, args.frequency, args.jobs)
            diagnosis, selection, swap_note = answered_diagnosis(args, model, transmission, records, delay,
                                                                 validation_floor, mount=mount)
            gravity_taken, checked, subtracted = False, None, None
            if mount is not None and not args.consistent and selection.selection == "validation":
                # the model with the found gravity diagnosed as the declared one was, its answer a candidate
                # (estimation.consistent.mounted_gravity): taken only when it predicts the validation record better,
                # and only when the mount is what is said (not the joints' zeros or directions)
                with step("the diagnosis with the gravity the mount check found, compared"):
                    # torques without gravity (mount.absent): the error of the gravity model the logger subtracted
                    # stays a load of the positions, which a spring or a ripple would stand in for: not tried there
                    turned = answered_diagnosis(args, turned_model(model, mount.gravity), transmission, records, delay,
                                                validation_floor, mount=mount if mount.absent else None)
                    checked = beside_checks()
                    if competing_checks(checked[0], mount)[1] is not None:
                        selection, gravity_taken = gravity_answer(selection, turned[1], mount.gravity)
                if gravity_taken:
                    diagnosis, swap_note = turned[0], turned[2]
                if mount.absent and gains is None and load_channels(model) \
                        and competing_checks(checked[0], mount)[1] is not None:
                    # the exact model of a log less the description's gravity torque: the diagnosis of the torques
                    # with it added back (every law a candidate: the load is modelled), its answer a third candidate
                    # (estimation.consistent.mounted_gravity.subtracted_answer)
                    with step("the diagnosis of the log less the description's gravity torque, compared"):
                        added = added_back_records(records, SubtractedLoad(), model.robot)
                        floors = record_floors(added, model, args.frequency, args.jobs)
                        answered = answered_diagnosis(args, model, transmission, added, delay, floors[0])
                        selection, taken = subtracted_answer(selection, answered[1])
                    if taken:
                        diagnosis, swap_note, subtracted = answered[0], answered[2], SubtractedLoad()
                        records, (validation_floor, test_floor), gravity_taken = added, floors, False
            untouched = test_errors(records, diagnosis, test_floor)
            trivial, notes = trivial_predictors(diagnosis.after, records.validation.measurements)
            diagnosis = replace(diagnosis, trivial=trivial)
            notes += worse_after(diagnosis) + (() if swap_note is None else (swap_note,))
            repeat = repeated_motion_note(records.train.measurements, records.validation.measurements)
            notes += () if repeat is None else (repeat,)
            if gains is not None:
                selection = in_recorded_units(selection, gains[0])
                with step("the torque gains confirmed: the adopted model fitted to the torques as recorded, compared"):
                    taken, why = confirmed_gains(args, diagnosis, recorded, selection, gains[0])
                said = f"{gains[2]}; then {why}" if why else gains[2]
                refusal = None if taken else said
                selection = replace(selection, reason=f"{selection.reason}; {why}") if why else selection
                notes += (said,)
            notes += scale + (() if refused is None else (refused,))
            zeros, drift = beside_checks() if checked is None else checked
            notes += diagnosis_mount_notes(model, zeros, mount, gravity_taken=gravity_taken,
                                           subtracted=subtracted is not None)
            notes += () if drift is None or drift.message() is None else (drift.message(),)
    if refusal is not None:  # the gains refused: the diagnosis of the torques as recorded, the refusal said
        return diagnosis_in_memory(args, model, transmission, delay, plan, refused=refusal, halves=halves)
    train = records.train.measurements  # the samples fitted: the training range, and the held-out records against it
    ranges = TrainingRange.of(train.q, train.dq, model.robot.joint_names)
    checks = {key: ranges.check(held.measurements.q, held.measurements.dq)
              for key, held in (("validation", records.validation), ("test", records.test)) if held is not None}
    diagnosed = Diagnosed(diagnosis, records.preprocessing.to_dict(), records.preprocessing.describe(),
                          (*caught_messages(caught), *notes), records=records, untouched=untouched, selection=selection,
                          transmission=transmission, notes=notes, torque_gains=None if gains is None else gains[0],
                          training_range=ranges, range_checks=checks, friction_drift=drift, subtracted=subtracted,
                          training_stationarity=halves)
    if part is None and halves is not None and halves.changed:
        return changed_plant_answer(args, model, transmission, delay, plan, diagnosed, halves)
    return diagnosed


def changed_plant_answer(args: DiagnoseOptions, model: IdentificationModel, transmission: Transmission | None,
                         delay: DelayBounds | None, plan: Preprocessing | None, whole: Diagnosed,
                         halves: TrainingHalves) -> Diagnosed:
    """The default answer when the training record's halves disagree (the plant changed during training,
    :mod:`estimation.consistent.training_halves`): the diagnosis made again on each half of the training record,
    and the answer of the whole record's, or of a half's when it validates better by more than
    :data:`~estimation.consistent.training_halves.PART_TOLERANCE` (:func:`~estimation.consistent.training_halves.part_answer`,
    every answer scored on the same validation samples). The chosen diagnosis whole (its records, errors and model
    file), the comparison said in the notes, the selection's reason and ``training_stationarity``."""
    with step("the plant changed during training: the answer made on each half of the training record, compared"):
        parts = {part: diagnosis_in_memory(args, model, transmission, delay, plan, halves=halves, part=part)
                 for part in PARTS}
    fitted_on, why, scores = parts_compared(whole.selection, {part: other.selection for part, other in parts.items()})
    halves = replace(halves, fitted_on=fitted_on, scores=scores)
    chosen = whole if fitted_on == "whole" else parts[fitted_on]
    said = halves.message() or ""
    before = () if fitted_on == "whole" else tuple(note for note in whole.notes if said in note)
    after = (why,) if why else ()
    selection = chosen.selection if not why or chosen.selection is None else \
        replace(chosen.selection, reason=f"{chosen.selection.reason}; {why}")
    return replace(chosen, notes=(*before, *chosen.notes, *after), messages=(*before, *chosen.messages, *after),
                   selection=selection, training_stationarity=halves)


def confirmed_gains(args: DiagnoseOptions, diagnosis: Diagnosis, records: PreparedRecords,
                    selection: ModelSelection, gains: TorqueGains) -> tuple[bool, str]:
    """Whether the gains of the diagnosis of the torques divided by them stay (``(taken, why)``,
    :func:`~estimation.consistent.torque_gains.diagnosed_gains_answer`): its default answer ``selection`` (in the
    recorded units) against the same choice (:func:`diagnosis_selection`) for the adopted model fitted again to
    ``records`` as logged, its shaped laws at their fitted values (no second search). Kept, unsaid, when the adopted
    model carries a delay or the refit fails."""
    after = diagnosis.after
    if after.delay is not None:
        return True, ""
    starts = {value.name: value.value for value in after.shapes} or None
    try:
        with warnings.catch_warnings():  # a comparator only: what it warns of is no part of the answer
            warnings.simplefilter("ignore")
            refit = identify_model(after.model, records.train.measurements, records.validation.measurements,
                                   weighted=after.estimate.method == "wls", shape_starts=starts, shape_search=False)
            without = diagnosis_selection(args, replace(diagnosis, after=refit), records)
    except (ValueError, np.linalg.LinAlgError) as error:
        return True, f"the answer without them not fitted ({error}): kept"
    return diagnosed_gains_answer(without, selection, gains)


def answered_diagnosis(args: DiagnoseOptions, model: IdentificationModel, transmission: Transmission | None,
                       records: PreparedRecords, delay: DelayBounds | None, floor: NoiseFloor | None, *,
                       mount: MountCheck | None = None) -> tuple[Diagnosis, ModelSelection, str | None]:
    """The diagnosis of ``model`` on the prepared records (:func:`diagnose_records`; ``mount``: its positional laws
    left out where a marked mount explains the load), the plain-law swap judged (:func:`judged_swap`), and its
    default answer (:func:`diagnosis_selection`): ``(diagnosis, selection, the swap's note or None)``."""
    with step("diagnosis in memory"):
        diagnosis = diagnose_records(args, model, transmission, records, delay, floor, mount=mount)
    if diagnosis.swap is not None:
        with step("the plain-law swap judged on the default answer's candidates"):
            return judged_swap(args, diagnosis, records)
    with step("the default answer: the adopted model or its consistent refit"):
        return diagnosis, diagnosis_selection(args, diagnosis, records), None


def checks_beside(model: IdentificationModel, train: Measurements, validation: Measurements | None, *,
                  delay: DelayBounds | None) -> tuple[JointZeroCheck | None, FrictionDrift | None]:
    """What runs beside the diagnosis on the prepared records: the joint-zero check when it marks
    (:func:`~oed.workflows.asbuilt.marked_joint_zeros`, said with the mount's by
    :func:`~oed.workflows.asbuilt.diagnosis_mount_notes`) and each joint's friction on the validation record against
    the training record's (:func:`~estimation.identification.friction_drift.check_friction_drift`, the plain model
    with viscous friction: the plain fit's class of issue 34; none with a delay search or shaped laws)."""
    zeros = marked_joint_zeros(model, train, validation, delay=delay)
    if delay is not None or model_has_shapes(model):
        return zeros, None
    with step("friction checked on the validation record against the training record's"):
        return zeros, check_friction_drift(drift_model(model), train, validation)


def drift_model(model: IdentificationModel) -> IdentificationModel:
    """The model whose friction the diagnosis's drift check scales (:func:`checks_beside`, on both paths): the plain
    model of the declared one, with viscous friction on every joint."""
    plain = plain_model(model)
    if not any(effect.name == "viscous" for effect in plain.effects):
        plain = build_model(plain.robot, plain.kind, (*plain.effects, ViscousFriction()))
    return plain


def derivatives_on_validation(model: IdentificationModel, delay: DelayBounds | None) -> dict[str, Any]:
    """How the derivatives are chosen again on a validation record of another motion, as ``oed identify`` chooses
    them (:mod:`estimation.identification.preprocessing_on_validation`), as keywords of
    :class:`~estimation.identification.prepared.PreparationSettings` and of
    :func:`~oed.workflows.memory_path.decide_path` (the streamed path chooses alike): each candidate scored by the OLS fit
    of the plain model (the weighting is chosen afterwards, as ``oed identify`` does) (:func:`estimation.diagnosis.plain_laws.plain_model`: the declared model plus Coulomb
    friction and an offset on every joint), not of the declared one, whose missing friction would otherwise decide
    the filter (a low cut-off smooths the targets' jumps at each velocity reversal, which then look like a shaped
    law). None with a declared delay bound or declared shaped laws (as ``oed identify``: fitted by a search each); the
    training record's choice is kept then."""
    if delay is not None or model_has_shapes(model):
        return {}
    return {"validation_fits": ("ols",), "validation_model": plain_model(model)}


def diagnose_document(args: DiagnoseOptions, diagnosed: Diagnosed) -> tuple[dict[str, Any], tuple[str, ...]]:
    """``report.json`` (the same keys on both paths: :meth:`estimation.diagnosis.results.Diagnosis.to_dict`, the
    preprocessing, the held-out and chosen models' errors, the model files), and the run's warnings with those of
    its model files."""
    diagnosis = diagnosed.diagnosis
    document = diagnosis.to_dict()
    records, selection = diagnosed.records, diagnosed.selection
    if records is not None:  # in memory
        # the unconstrained fit behind the answer: the adopted model, or the adopted model with the plain law
        # completed (:func:`completed_selection`)
        answered = selection.unconstrained
        finish_document(document, answered, trivial=None, warnings=diagnosed.notes, rest=rest_records(records),
                        transmission=diagnosed.transmission, warnings_key=("warnings", "after"))
    document["preprocessing"] = diagnosed.preprocessing
    drift = diagnosed.friction_drift
    document["friction_drift"] = None if drift is None else drift.to_dict()
    halves = diagnosed.training_stationarity
    document["training_stationarity"] = None if halves is None else halves.to_dict()
    if records is None:  # streamed: the transmission read, as in memory
        transmission = diagnosed.transmission
        document["transmission"] = None if transmission is None else {**transmission.to_dict(),
                                                                       "source": transmission.source}
    document["torque_gains"] = None  # the in-memory path's, when the validation record measured them (below)
    if records is not None:
        untouched, consistent = diagnosed.untouched, selection.consistent
        document["test"] = None if untouched is None else untouched.to_dict()
        if consistent is not None:
            document.update(consistent.to_dict())
            document["consistent"]["test"] = None if records.test is None else \
                {"mse": consistent.compare(records.test.measurements).mse}
        document["model_selection"] = selection.to_dict()
        if document["test"] is not None:  # the chosen model's error on the test record (what `oed predict` gives)
            # the adopted model's errors are the diagnosis's own; the plain law completed (completed_selection), its
            # own prediction of the record
            mse = document["consistent"]["test"]["mse"] if selection.chosen == "consistent" else untouched.after \
                if answered is diagnosis.after else recorded_mse(answered, records.test.measurements)
            if diagnosed.torque_gains is not None:  # in the log's units, as `oed predict` measures it
                factors = dict(zip(mse, channel_factors(diagnosed.torque_gains, tuple(mse)) ** 2))
                mse = {channel: value * factors[channel] for channel, value in mse.items()}
            document["test"]["chosen"] = {"name": selection.chosen, "mse": dict(mse)}
        files = add_model_file(document, answered, args, records.preprocessing, diagnosed.transmission,
                               consistent=consistent, selection=selection)
        if diagnosed.torque_gains is not None:  # oed predict multiplies the model's torques by them
            document["model_file"]["torque_gains"] = diagnosed.torque_gains.to_dict()
        document["torque_gains"] = None if diagnosed.torque_gains is None else diagnosed.torque_gains.to_dict()
        chosen = ChosenModel.of(selection)  # its errors beside the diagnosis's before and after
        answer_diagnosis(document, chosen, floor=None if diagnosis.statistics is None else diagnosis.statistics.floor)
        files = (*files, *(text for text in chosen.warnings if text not in diagnosed.messages))  # said of it too
        add_runner_up_model_file(document, diagnosis.runner_up, args, records.preprocessing, diagnosed.transmission)
        runner_up = document.get("runner_up") or {}
        if diagnosed.torque_gains is not None and runner_up.get("model_file") is not None:  # fitted alike
            runner_up["model_file"]["torque_gains"] = diagnosed.torque_gains.to_dict()
        if diagnosed.subtracted is not None:  # oed predict subtracts the load the log lacks from the model's torques
            for entry in (document, runner_up):  # both fitted to the torques with it added back
                if entry.get("model_file") is not None:
                    entry["model_file"]["subtracted"] = diagnosed.subtracted.to_dict()
    else:
        # the model file: the final model's estimate from the sums; its validation error is against the channels
        # as recorded, on the samples the in-memory preprocessing keeps (on the Fourier path every sample of the
        # whole periods), which is what `oed predict` measures (on a resampled validation file, measured at its
        # recorded samples: diagnosis_streamed)
        model_plan, validation_mse = diagnosed.model_file
        after, runner_up = diagnosis.after, diagnosis.runner_up
        if selection is not None:  # the default answer from the sums (diagnosis_streamed), as in memory
            files = summed_answer(document, args, diagnosed, selection)
        else:
            files = add_summed_model_file(document, diagnosis.final_model(), after.estimate, args, model_plan,
                                          shape=diagnosis.final_shape(), recorded_mse=after.train.mse,
                                          validation_mse=validation_mse, transmission=diagnosed.transmission)
            name = after.estimate.method  # the one model the model file holds: its errors, as predict names it
            document["train"]["chosen"] = {"name": name, "mse": dict(after.train.mse)}
            document["warnings"]["chosen"] = list(after.warnings)
            document["validation"]["chosen"] = {"name": name,
                                                "mse": None if validation_mse is None else dict(validation_mse)}
        document["warnings"]["after"] = list(document["warnings"].get("after", [])) + list(diagnosed.notes)
        add_summed_runner_up_model_file(document, runner_up, args, model_plan, None if validation_mse is None or
                                        runner_up is None else runner_up.validation_mse, diagnosed.transmission,
                                        shape=diagnosis.runner_up_shape())  # moved by the chosen delay, as memory
        if diagnosed.torque_gains is not None:  # the files divided by them (divided_diagnosis): as in memory
            gains = diagnosed.torque_gains.to_dict()
            document["torque_gains"] = gains
            for entry in (document, document.get("runner_up") or {}):
                if entry.get("model_file") is not None:  # oed predict multiplies the model's torques by them
                    entry["model_file"]["torque_gains"] = gains
        if diagnosed.subtracted is not None:  # oed predict subtracts the load the log lacks from the model's torques
            for entry in (document, document.get("runner_up") or {}):  # both fitted to the torques with it added back
                if entry.get("model_file") is not None:
                    entry["model_file"]["subtracted"] = diagnosed.subtracted.to_dict()
        if diagnosed.averaged_train is not None:  # measured against the recording, the sums' errors beside
            averaged_errors(document, diagnosed.averaged_train)
        elif averaged_sums(diagnosis.streaming):
            averaged_training_errors(document)
    said = add_training_range(document, diagnosed.training_range, diagnosed.range_checks)
    if said:  # a held-out record beyond the training range: what was measured on it is some extrapolation
        files = (*files, *said)
        document["warnings"]["after"] = [*document["warnings"].get("after", []), *said]
    document["diagnosis_path"] = diagnosis.path
    document["max_effects"] = args.max_effects
    document["max_effects_reached"] = len(diagnosis.effects) >= args.max_effects
    return document, (*diagnosed.messages, *files)


def averaged_training_errors(document: dict[str, Any]) -> None:
    """Label the training errors of a streamed diagnosis on the Fourier path (``document``, in place) as what they
    are: its training sums hold the averaged period (a Fourier fit of averaged periods, whose torques are averaged
    over the periods too), not the recording, so each training ``mse`` is moved to ``mse_filtered`` and ``mse`` is
    ``null``, as the streamed ``oed identify`` labels them (``train.before``, ``train.after``, ``train.chosen``,
    ``runner_up.train``, ``consistent.train``, ``model_selection.candidates[].train_mse`` to ``train_mse_filtered``).
    The validation errors are against every recorded sample of the whole periods (what ``oed predict`` measures)."""
    entries = [document["train"].get(key) for key in ("before", "after", "chosen")]
    entries += [(document.get(key) or {}).get("train") for key in ("runner_up", "consistent")]
    for entry in entries:
        if isinstance(entry, dict) and entry.get("mse") is not None:
            entry["mse_filtered"], entry["mse"] = entry["mse"], None
    for candidate in (document.get("model_selection") or {}).get("candidates", ()):
        candidate["train_mse_filtered"], candidate["train_mse"] = candidate.get("train_mse"), None
    document["train"]["against"] = ("the averaged period of the training files (a Fourier fit of averaged periods): "
                                    "mse_filtered, not the recording")


def summed_answer(document: dict[str, Any], args: DiagnoseOptions, diagnosed: Diagnosed,
                  selection: ModelSelection) -> tuple[str, ...]:
    """The streamed document (in place) given the default answer made from the sums, with the in-memory keys:
    ``consistent`` and ``links`` (the refit; its shapes held at the adopted model's), ``model_selection``, the model
    file holding the chosen model and the other as an alternative, and the chosen model's errors beside the
    diagnosis's (``train.chosen``, ``validation.chosen``); return the model file's warnings and the chosen model's
    own not said yet."""
    diagnosis = diagnosed.diagnosis
    consistent = selection.consistent
    if consistent is not None:
        document.update(consistent.to_dict())
        document["consistent"]["test"] = None  # --test is read in memory
        shape = diagnosis.final_shape()
        if shape:  # held at the adopted model's fixed shapes (the sums' columns)
            document["consistent"].update(shape=shape, delay=None, shapes_held="at the unconstrained fit's values "
                                          "(estimation.streaming.diagnosis_selection)")
    document["model_selection"] = selection.to_dict()
    model_plan, _ = diagnosed.model_file
    answered = summed_unconstrained(selection)  # the adopted model, or on a repeat that model with the plain law
    files = add_summed_model_file(document, answered.model, answered.estimate, args, model_plan,
                                  shape=diagnosis.final_shape(), selection=selection,
                                  transmission=diagnosed.transmission)
    chosen = ChosenModel.of(selection)
    answer_diagnosis(document, chosen, floor=None if diagnosis.statistics is None else diagnosis.statistics.floor)
    return (*files, *(text for text in chosen.warnings if text not in diagnosed.messages))


def diagnosis_selection(args: DiagnoseOptions, diagnosis: Diagnosis, records: PreparedRecords, *,
                        complete: bool = True) -> ModelSelection:
    """The default answer (:func:`estimation.consistent.model_selection.select_refit`): the adopted model as fitted
    (unconstrained) or its consistent refit (the description's bodies as prior, its weight chosen on the validation
    record; shaped laws and a delay at their fitted values), by the validation error when the validation record is
    another motion, else the consistent refit; ``--consistent`` forces it. A refit that fails is no candidate.

    ``complete``: then :func:`completed_selection` (the plain law completed where the diagnosis named none) judges
    the answer against the adopted model's; :func:`judged_swap` completes only the model it keeps."""
    train, validation = records.train.measurements, records.validation.measurements
    settings = consistent_settings(args, diagnosis.after.model.robot)
    # the completed model's fit waits for nothing the adopted model's refit gives: it runs beside it (used only when
    # the completion is judged, completion_repeat), its model built here so that it comes back by reference
    after = diagnosis.after
    laws = completion_laws(after.model) if complete and not args.consistent else ()
    shared = (build_model(after.model.robot, after.model.kind, (*after.model.effects, *laws)), after.model,
              after.model.robot, train, validation) if laws else ()
    with beside(functools.partial(plain_completion, after, train, validation),
                worker_count(args.jobs, 2) if laws else 1, shared=shared) as completion:
        selection = select_refit(after, train, validation, given="consistent" if args.consistent else None,
                                 consistent=settings, note="with the diagnosed effects")
        return completed_selection(args, diagnosis, records, selection, completion=completion) if complete \
            else selection


def completed_selection(args: DiagnoseOptions, diagnosis: Diagnosis, records: PreparedRecords,
                        selection: ModelSelection, *,
                        completion: Callable[[], Any] | None = None) -> ModelSelection:
    """``selection`` (the default answer of the adopted model, :func:`diagnosis_selection`), or the same choice made
    for the adopted model completed with the plain law on the joints the diagnosis left without one
    (:func:`estimation.diagnosis.plain_laws.plain_completion`; not named as findings) when that answer predicts
    the validation record better by the criterion of the default answer (any lower score, on a repeat of the
    training motion and, :data:`~estimation.consistent.completion.COMPLETION_TOLERANCE` being zero, on another
    motion), as :func:`judged_swap` judges a plain-law swap; the selection's reason says which and the two scores.

    The search's refusals (a law refused by the Wald test at the search's Bonferroni threshold although it lowered
    the validation error, or never proposed beside a stronger law on another joint) leave a joint without the plain
    law's terms that a plain least-squares fit holds. On a validation record of another motion the two answers
    (each the better of as fitted and consistent refit) are compared there; on a repeat of the training motion
    (``repeated-motion``) only the two consistent refits, since nothing measured the extrapolation. A validation
    record at rest, ``--consistent``, or a model that needs nothing added keep ``selection``.

    On another motion the completed model's consistent refit takes the prior weight the validation record chose for
    the adopted model's (its search kept in the result): the laws are compared, and the weight search is not made
    again (five refits of the Panda's 7 joints, about 1 s); on a repeat the weight is searched again. ``completion``:
    gives what :func:`~estimation.diagnosis.plain_laws.plain_completion` of the diagnosis gives (made beside the
    adopted model's refit by :func:`diagnosis_selection`)."""
    repeat = completion_repeat(selection, consistent=args.consistent)
    if repeat is None:
        return selection
    train, validation = records.train.measurements, records.validation.measurements
    completion = plain_completion(diagnosis.after, train, validation) if completion is None else completion()
    if completion is None:
        return selection
    completed, added = completion
    laws = completed_laws(completed.model, added)
    return held_completion(selection, consistent_settings(args, completed.model.robot), laws, repeat=repeat,
                           select=lambda settings: select_refit(completed, train, validation, consistent=settings,
                                                                note=completed_note(laws)))


def judged_swap(args: DiagnoseOptions, diagnosis: Diagnosis,
                records: PreparedRecords) -> tuple[Diagnosis, ModelSelection, str | None]:
    """The diagnosis whose default answer predicts the validation record better: ``diagnosis`` or its
    :attr:`~estimation.diagnosis.results.Diagnosis.swap` (the mixed model of
    :mod:`estimation.diagnosis.plain_laws`, refused on the unconstrained fits' score alone), with its selection.

    Each model's answer is the better of it as fitted and its consistent refit (:func:`diagnosis_selection`); the
    two answers are compared by the criterion of the default answer
    (:func:`estimation.identification.relative_error.relative_scores`) on the same validation samples, the
    diagnosed model kept on a tie. Without a validation record of another motion, or with ``--consistent`` given,
    nothing is compared there beyond what the selection itself does, and the swap stays refused. One consistent
    refit more than the diagnosis alone, and only when a swap was refused. The third item: a note saying what was
    compared and chosen (``None`` when nothing was)."""
    kept = replace(diagnosis, swap=None)
    selection = diagnosis_selection(args, kept, records, complete=False)
    if selection.selection != "validation" or args.consistent:
        return kept, completed_selection(args, kept, records, selection), None
    swapped = replace(diagnosis.swap, swap=None, runner_up=diagnosis.runner_up,
                      runner_up_reason=diagnosis.runner_up_reason)
    other = diagnosis_selection(args, swapped, records, complete=False)
    answers = {"diagnosed": selection.chosen_candidate, "swap": other.chosen_candidate}
    if any(answer.fit is None or answer.validation is None for answer in answers.values()):
        return kept, completed_selection(args, kept, records, selection), None
    channels = answers["diagnosed"].validation.channels
    scored = relative_scores({name: answer.validation.mse for name, answer in answers.items()}, channels)
    adopted = scored["swap"] < scored["diagnosed"]
    note = (f"the plain-law swap, refused on the unconstrained fits, judged on the default answer's candidates: the "
            f"model with the plain law ({other.chosen}) {scored['swap']:.4g} against the diagnosed model "
            f"({selection.chosen}) {scored['diagnosed']:.4g} on the validation record (relative error): "
            + ("adopted" if adopted else "refused"))
    if adopted:
        return swapped, completed_selection(args, swapped, records, other), note
    return kept, completed_selection(args, kept, records, selection), note


def chosen_lines(validation: dict[str, Any]) -> list[str]:
    """The chosen model's MSE on the validation record (what `oed predict` gives there)."""
    chosen = validation.get("chosen")
    if chosen is None or chosen["mse"] is None:
        return []
    return [mse_line(f"validation MSE vs recorded, the chosen model ({chosen['name']})", chosen["mse"])]


def chosen_test_lines(test: dict[str, Any] | None) -> list[str]:
    """The chosen model's MSE on the ``--test`` record (none without one)."""
    if test is None or "chosen" not in test:
        return []
    chosen = test["chosen"]
    return [f"test MSE vs recorded, the chosen model ({chosen['name']}): "
            + "  ".join(f"{channel} {value:.4g}" for channel, value in chosen["mse"].items())]


def check_request(args: DiagnoseOptions) -> None:
    """Held-out data from another file, and a positive ``--max-effects``."""
    training = {path.expanduser().resolve(): path for path in args.data}
    for path in args.validate:
        if path.expanduser().resolve() in training:
            raise ValueError(f"--validate is --data ({path}): diagnose confirms every effect on held-out data "
                             "from another experiment")
    if isinstance(args.max_effects, bool) or args.max_effects < 1:
        raise ValueError(f"--max-effects must be a positive integer, got {args.max_effects}")


def record_floors(records: PreparedRecords, model: IdentificationModel, frequency_hz: float | None,
                  jobs: int | None) -> tuple[NoiseFloor | None, NoiseFloor | None]:
    """The noise floors of the validation and the ``--test`` record (``None`` without one) from the files as read, at
    the frequency of a Fourier preprocessing, else ``frequency_hz``; side by side in ``jobs`` processes (each floor
    a fit of its own: :mod:`dynamics.runtime.processes`, the same floors in any number)."""
    preprocessing = records.preprocessing
    frequency = preprocessing.frequency_hz if preprocessing.method == "fourier" else frequency_hz
    tasks = [functools.partial(record.noise_floor, model.channels, frequency)
             for record in (records.validation, records.test) if record is not None]
    floors = run_tasks(tasks, worker_count(jobs, len(tasks)))
    return floors[0], floors[1] if records.test is not None else None


def diagnose_records(args: DiagnoseOptions, model: IdentificationModel, transmission: Transmission | None,
                     records: PreparedRecords, delay: DelayBounds | None, floor: NoiseFloor | None, *,
                     mount: MountCheck | None = None) -> Diagnosis:
    """The diagnosis of the prepared records; ``floor``: the validation record's as recorded (:func:`record_floors`);
    ``mount``: a marked mount check (:func:`oed.workflows.asbuilt.diagnosis_mount`), whose explained joints are
    tried without the laws of their position alone (:func:`oed.workflows.asbuilt.mount_candidates`)."""
    train, validation = records.train.measurements, records.validation.measurements
    candidates = default_candidates(model) + coupling_candidates(model, transmission, train=train, held_out=validation)
    return diagnose_model(model, train, validation, alpha=args.alpha, candidates=mount_candidates(model, candidates, mount),
                          max_effects=args.max_effects, noise_floor=floor, delay=delay or DelayBounds(), jobs=args.jobs,
                          unseen_stretches=args.unseen_stretches)


def test_errors(records: PreparedRecords, diagnosis: Diagnosis, floor: NoiseFloor | None) -> UntouchedErrors | None:
    """The errors on the ``--test`` record (:mod:`estimation.diagnosis.untouched`); ``floor``: its floor from the files
    as read (:func:`record_floors`)."""
    if records.test is None:
        return None
    return untouched_errors(diagnosis, records.test.measurements, floor)


def test_lines(untouched: UntouchedErrors | None) -> list[str]:
    """The test record's MSE before and after, or a note that the 'after' error was measured on data the choices used."""
    if untouched is None:
        return ["note: the 'after' error above is on the --validate record, which chose the effects: it is optimistic; "
                "give --test FILE (a third record) for an error no choice saw"]
    lines = ["test MSE vs recorded (a record no choice used): before, the declared model; after, the diagnosed model as "
             "fitted; the chosen model's, what `oed predict` gives, on its own line below",
             "  before         " + "  ".join(f"{value:9.4g}" for value in untouched.before.values()),
             "  after          " + "  ".join(f"{value:9.4g}" for value in untouched.after.values())]
    ratios = untouched.over_floor("after")
    if ratios:
        lines.append("  after / floor  " + "  ".join(f"{ratios.get(channel, float('nan')):9.3g}"
                                                     for channel in untouched.after))
    return lines


def found_lines(effects: Any, *, shape_std: bool) -> list[str]:
    """One line an effect found (its values with standard deviations, its shape, its p-value), or that none was;
    ``shape_std``: the shapes' standard deviations too (the streamed path has none)."""
    if not effects:
        return ["found nothing: the declared model explains the data"]
    lines = []
    for effect in effects:
        values = ", ".join(f"{n} = {v:.4g} ± {s:.2g}" for n, v, s in zip(effect.parameters, effect.values, effect.std))
        values += "".join(f", {n} = {v:.4g}" + (f" ± {effect.shape_std[n]:.2g}" if shape_std else "")
                          for n, v in effect.shape.items())
        lines.append(f"found {effect.spec or effect.name} on {', '.join(effect.channels)}: {values} "
                     f"(p = {effect.p_value:.2g})")
    return lines


def summary_lines(args: DiagnoseOptions, diagnosed: Diagnosed, document: dict[str, Any]) -> list[str]:
    """The lines ``oed diagnose`` prints, on both paths: the preprocessing (and, streamed, how the files were
    read), the effects found, the validation MSE per channel before and after, the floor; in memory the test
    record's errors and the default answer (``document``: :func:`diagnose_document`); the stop at
    ``max_effects``."""
    diagnosis = diagnosed.diagnosis
    lines = [diagnosed.describe]
    if diagnosis.path == "streamed":
        lines.append(streamed_line(diagnosis, diagnosed.chunk_size))
    lines += found_lines(diagnosis.effects, shape_std=diagnosis.path == "in-memory")
    lines.append(runner_up_line(diagnosis.runner_up, diagnosis.runner_up_reason))
    before, after = diagnosis.before.validation.mse, diagnosis.after.validation.mse
    lines += ["validation MSE vs recorded",
              "                 " + "  ".join(f"{channel:>9s}" for channel in before),
              "  before         " + "  ".join(f"{value:9.4g}" for value in before.values()),
              "  after          " + "  ".join(f"{after[channel]:9.4g}" for channel in before)]
    lines += floor_lines(diagnosis)
    selection = diagnosed.selection
    if diagnosed.records is not None:  # in memory
        counted = channel_sample_line(channel_sample_counts(diagnosed.records))
        lines += [counted] if counted else []
        lines += test_lines(diagnosed.untouched)
    if selection is not None:
        consistent = selection.consistent
        if consistent is not None and (args.consistent or selection.chosen == "consistent"):
            lines += consistent_lines(consistent)
        lines += selection.lines() + chosen_lines(document["validation"]) + chosen_test_lines(document.get("test"))
    else:  # the one model its model file holds
        lines += chosen_lines(document["validation"])
    lines += range_lines(diagnosed.range_checks)
    lines += [] if diagnosed.friction_drift is None else diagnosed.friction_drift.lines()
    if len(diagnosis.effects) >= args.max_effects:
        untested = sum(rejected.reason.startswith("not tested") for rejected in diagnosis.rejected)
        lines.append(f"stopped at --max-effects {args.max_effects}: {untested} candidate(s) not tested; raise "
                     "--max-effects to test them")
    message = None if diagnosed.records is None else rest_message("diagnose", rest_records(diagnosed.records))
    if message:
        lines.append(message)
    return lines


def streamed_line(diagnosis: Diagnosis, chunk_size: int | None) -> str:
    """How a streamed diagnosis read its files: the samples, files, blocks and the shape search's subsample."""
    streaming = diagnosis.streaming
    return (f"{diagnosis.model.robot.name}: {diagnosis.model.kind.value} model, streamed diagnosis of "
            f"{diagnosis.after.train.n_samples} training samples from {len(streaming['files'])} file(s) in chunks of "
            f"{chunk_size}, {diagnosis.after.validation.n_samples} validation samples; shapes searched on "
            f"{streaming['subsample']['samples']} samples")


def floor_lines(diagnosis: Diagnosis) -> list[str]:
    """The noise floor per channel and how far above it each channel stays."""
    statistics = diagnosis.statistics
    if statistics is None:
        return []
    if statistics.floor is None:
        return [statistics.floor_note]
    floor = statistics.floor.mse()
    ratios = statistics.ratios("after")
    return ["  noise floor    " + "  ".join(f"{floor[channel]:9.4g}" for channel in floor)
            + f"   ({statistics.floor.method}; {statistics.floor_note})",
            "  after / floor  " + "  ".join(f"{ratios[channel]:9.3g}" for channel in floor),
            *(f"  {text}" for text in statistics.statements.values())]


STREAMED = "the streamed path (--chunk-size, --scheduler or --workers)"


def check_streamed_arguments(args: DiagnoseOptions, model: IdentificationModel) -> None:
    """Options the streamed diagnosis does not have: an error naming them, before anything is read."""
    unsupported = [option for option, given in (
        ("--min-speed", args.min_speed is not None),
        ("--max-gap", args.max_gap != DEFAULT_MAX_GAP)) if given]
    if unsupported:
        raise ValueError(f"{', '.join(unsupported)}: not with {STREAMED}, which reads whole files without holes "
                         "on the filter path, the files' dq, ddq or a Fourier fit of averaged periods or of every "
                         f"sample; {IN_MEMORY_ROUTE}")
    if model_has_shapes(model):
        raise ValueError(f"declared laws with shape parameters (coulomb:tanh, sigmoid…) are fitted in memory: not with "
                         f"{STREAMED}; declare their plain forms, or let the diagnosis find them")
    for option in ("subsample", "floor_window"):
        value = getattr(args, option)
        if value is None and option == "floor_window":  # every row: memory's floor
            continue
        if isinstance(value, bool) or value < 1:
            raise ValueError(f"--{option.replace('_', '-')} must be a positive integer, got {value}")


def diagnosis_streamed(args: DiagnoseOptions, friction: str, plan: Preprocessing | None = None,
                       findings: FindingsSaid | None = None, *, effects: tuple[Any, ...] | None = None,
                       delay: DelayBounds | None = None,
                       gains: tuple[TorqueGains, bool, str] | None = None,
                       turned: MountCheck | None = None, subtracted: SubtractedLoad | None = None) -> Diagnosed:
    """Diagnose the files read in blocks (:func:`estimation.streaming.diagnosis.diagnose_files`), their
    derivatives chosen as in memory (``plan``: already chosen); ``friction``: the declared effects without the delay
    (``effects``: those effects as built already, a Coulomb column merged into its offset; ``None``: from
    ``friction``); ``delay``: the declared delay's bounds (``delay:S``), else the default ones: the delay between
    torques and motion is a candidate as in memory.
    The findings about the files are said as each pass ends, each once (``findings``: what the path decision said
    already).

    The per-joint torque gains are fitted and checked first, as in memory (:func:`streamed_gains`); when the check
    takes them the files are diagnosed with their torques divided by the gains (:func:`divided_diagnosis`: copies
    written block by block), ``gains`` then the check's outcome, and the answer's errors are in the log's units.

    When the mount check (on the search's subsamples, before the search) marks, the whole diagnosis is run again
    with the found gravity and its default answer compared with the description's, as in memory
    (:func:`streamed_gravity_diagnosis`); ``turned``: the mount whose gravity this run's model takes (that run
    checks no mount, gains or joint zeros of its own: the caller's are said).

    Where the torques hold no gravity load (the mount check's ``absent``), the whole diagnosis is run once more on
    the files with the description's gravity torque added back to every prepared chunk, every law a candidate, and
    its default answer compared with the answer chosen so far, as in memory (:func:`streamed_subtracted_diagnosis`);
    ``subtracted``: the load this run adds back (that run checks no mount, gains or joint zeros of its own)."""
    from estimation.streaming.diagnosis import diagnose_files_run
    from estimation.streaming.model_selection import streamed_repeated_motion, warned_still_motion
    from estimation.streaming.recorded_errors import streamed_plan
    from estimation.streaming.description_checks import prepared_count
    from estimation.streaming.periods import check_averaged

    robot = robot_of(args)
    transmission = resolve_transmission(args, robot)  # its motor laws; motor-side records read as joint-side copies
    if effects is None:
        effects = model_effects(args, friction, robot, transmission)
    model = build_model(robot, args.model, effects)
    check_shaped_effects_kept(effects, model)
    check_streamed_arguments(args, model)
    declared = model  # the model the checks are said of (the description's gravity)
    if turned is not None:  # the diagnosis with the gravity the mount check found (streamed_gravity_diagnosis)
        model = turned_model(model, turned.gravity)
    chunk_size = DEFAULT_CHUNK_SIZE if args.chunk_size is None else args.chunk_size
    if findings is None:  # each pass's findings said as it ends, each once
        findings = FindingsSaid([*args.data, *args.validate])
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        given = args
        args = streamed_records(args, model)  # a file with holes: its segments, each on its own as in memory
        if plan is None:
            with findings.reading():
                plan = streamed_choice(args, model, **derivatives_on_validation(model, None)).chosen
        args = on_time_base(args, plan)  # the regular clock chosen: every pass reads the sources on it, as memory
        check_averaged(plan, [*args.data, *args.validate], model, chunk_size=chunk_size)  # "yes" stops as in memory
        still = warned_still_motion(model, args.data, args.validate, chunk_size=chunk_size)  # said as in memory
        checked, ratio = None, None
        if gains is None and turned is None and subtracted is None and delay is None:
            # the torque gains checked first, as in memory (not with a declared delay; the run with a found gravity
            # takes its caller's)
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")  # the files' findings are said on the diagnosis's passes
                ratio = streamed_repeated_motion(model, args.data, args.validate, chunk_size=chunk_size)
            checked = streamed_gains(args, model, plan, chunk_size, ratio=ratio, still=still)
            if checked is not None and checked[1]:
                divided = divided_diagnosis(given, friction, plan, effects, checked)
                if divided is not None:
                    said = tuple(text for text in caught_messages(caught) if text not in divided.messages)
                    return replace(divided, messages=(*said, *divided.messages))
        mounts: list[MountCheck | None] = []  # the mount check of the search's subsamples (screened below)

        def screened(candidates: tuple[Any, ...], sample: Measurements, held: Measurements | None) -> tuple[Any, ...]:
            """The candidates without the laws of a joint's position where a turned gravity explains the load, the
            mount checked on the search's subsamples as in memory on the records (before the search)."""
            if turned is not None:  # as in memory: every law a candidate (gravity is modelled), but where the
                # torques hold no gravity load (the error of the gravity model the logger subtracted is a load of the
                # positions, which a spring or a ripple would stand in for)
                return mount_candidates(model, candidates, turned if turned.absent else None)
            if subtracted is not None:  # as in memory: every law a candidate (the load is modelled)
                return tuple(candidates)
            mount = None if held is None else diagnosis_mount(model, sample, held, delay=delay)
            mounts.append(mount)
            return mount_candidates(model, candidates, mount)

        with executor_for(args) as executor:
            diagnosis, run = diagnose_files_run(model, args.data, args.validate, chunk_size=chunk_size, alpha=args.alpha,
                                       max_effects=args.max_effects, subsample=args.subsample,
                                       floor_window=args.floor_window, executor=executor, preprocessing=plan,
                                       findings=findings, still=still, transmission=transmission,
                                       delay=delay or DelayBounds(),  # a candidate in every diagnosis, as in memory
                                       jobs=args.jobs,  # the search's rounds side by side, as in memory
                                       screen=screened, load=subtracted)
        still_search = diagnosis.streaming.get("still_search") == "on the record at rest"
        if still_search:  # the choices below ignore it, as in memory; the effect search above did not (Fourier path)
            warnings.warn(STILL_SEARCH, stacklevel=2)
    messages = tuple(caught_messages(caught))  # the findings as said (one line per finding across files), others
    cutoff_hz = diagnosis.streaming["cutoff_hz"]
    if plan.method == "fourier":  # validated on every sample of whole periods as recorded: what predict measures
        model_file = plan.to_dict(), diagnosis.after.validation.mse
    else:
        model_plan = streamed_plan(args.data[0], model, cutoff_hz=cutoff_hz, decimation=plan.decimation,
                                   held_torques=plan.held_torques, chunk_size=chunk_size)
        if resampled_validation({"streaming": diagnosis.streaming}):  # the errors on the samples as recorded
            diagnosis = recorded_errors(diagnosis, args, model_plan, load=subtracted)
        model_file = with_time_base(model_plan, plan), diagnosis.after.validation.mse
    if ratio is None:  # else measured before the gains' check
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # the files' findings were said on the diagnosis's passes
            ratio = streamed_repeated_motion(model, args.data, args.validate, chunk_size=chunk_size)
    with step("the default answer: the adopted model or its consistent refit (from the sums)"):
        selection = streamed_selection(args, diagnosis, run, model_file[0], chunk_size, still=still, ratio=ratio,
                                       load=subtracted)
    # the notes said in memory: a channel made worse, a repeat of the training motion, the joint zeros
    repeat = repeat_note(ratio)
    notes = worse_after(diagnosis) + (() if repeat is None else (repeat,))
    # the joint zeros, the mount (checked before the search) and the friction drift, said as in memory; none with a
    # declared delay, as in memory (the run with a found gravity says none: its caller does)
    counts = (prepared_count(run.sums.train_parts), prepared_count(run.sums.validate_parts))
    aside = turned is not None or subtracted is not None  # a candidate's run: its caller's checks are said
    zeros = None if delay is not None or aside else streamed_marked_joint_zeros(
        model, run.paths, counts[0], run.validate, counts[1], options=run.settings.reading())
    mount = next((mount for mount in mounts if mount is not None), None)
    runs: list[Diagnosed] = []  # the candidates' runs (the found gravity, the log less the load): what they said
    answer_run, taken, subtracted_taken = None, False, False  # the run whose answer is taken, if another one
    if mount is not None and not args.consistent and selection.selection == "validation" \
            and competing_checks(zeros, mount)[1] is not None:  # the found gravity a candidate, as in memory
        gravity_run = streamed_gravity_diagnosis(given, friction, plan, findings, mount, selection, effects=effects,
                                                 delay=delay, gains=gains)
        if gravity_run is not None:
            runs.append(gravity_run[0])
            selection, taken = gravity_run[1], gravity_run[2]
            answer_run = gravity_run[0] if taken else None
        if mount.absent and gains is None and not (checked is not None and checked[1]) and load_channels(model):
            # the exact model of a log less the description's gravity torque, a third candidate, as in memory
            subtracted_run = streamed_subtracted_diagnosis(given, friction, plan, findings, selection,
                                                           effects=effects, delay=delay)
            if subtracted_run is not None:
                runs.append(subtracted_run[0])
                selection, subtracted_taken = subtracted_run[1], subtracted_run[2]
                if subtracted_taken:  # the answer is that run's, the found gravity's no more
                    answer_run, taken = subtracted_run[0], False
    if answer_run is not None:  # the answer is another run's: its notes (a channel made worse, a repeat)
        notes = tuple(answer_run.notes)
    if not aside:
        notes += diagnosis_mount_notes(declared, zeros, mount, gravity_taken=taken, subtracted=subtracted_taken)
    drift = None if delay is not None or model_has_shapes(model) or aside else streamed_checks(
        declared, run.paths, counts[0], run.validate, counts[1], options=run.settings.reading(), mount_model=None,
        mount_samples=DIAGNOSIS_MOUNT_SAMPLES, drift_model=drift_model(declared)).friction_drift
    notes += () if drift is None or drift.message() is None else (drift.message(),)
    for other in runs:  # what the candidates' runs said, as memory's catches it
        messages = (*messages, *(text for text in other.messages if text not in messages and text not in other.notes))
    gains_note = None
    if checked is not None and checked[1]:  # the gains taken, not applied (divided_diagnosis could not): said
        gains_note = streamed_gains_note(checked)
        notes += () if gains_note is None else (gains_note,)
    messages = (*messages, *notes)
    if answer_run is not None:  # the run taken made its training errors against the recording, its ranges
        diagnosis = answer_run.diagnosis if gains_note is None else replace(
            answer_run.diagnosis, not_computed={**answer_run.diagnosis.not_computed, "torque_gains": gains_note})
        return replace(answer_run, diagnosis=diagnosis, messages=messages, notes=notes, friction_drift=drift,
                       selection=selection)
    diagnosis = replace(diagnosis, not_computed={**{key: reason for key, reason in diagnosis.not_computed.items()
                                                    if key not in (*SELECTION_KEYS, "gravity", "subtracted")},
                                                    # computed now (a mount found is tried:
                                                    # streamed_gravity_diagnosis; the log less the description's
                                                    # gravity torque: streamed_subtracted_diagnosis)
                                                 **({"time_base": STREAMED_TIME_BASE}
                                                    if stamps_kept(args.data) else {})})
    if gains_note is not None:  # said above
        diagnosis = replace(diagnosis, not_computed={**diagnosis.not_computed, "torque_gains": gains_note})
    # the training errors against the recording where the sums hold averaged periods or a resampled grid
    diagnosis, selection, averaged = recorded_training(args, diagnosis, selection, model_file[0], chunk_size,
                                                       load=subtracted)
    if still_search:
        diagnosis = replace(diagnosis, streaming={**diagnosis.streaming, "effect_search_on_still_validation": STILL_SEARCH})
    ranges = merged_ranges([record.get("joint_range") for _, record in run.sums.train_parts])  # the sums pass's
    validation_range = merged_ranges([record.get("joint_range") for _, record in run.sums.validate_parts])
    return Diagnosed(diagnosis, {"cutoff_hz": cutoff_hz, **plan.to_dict()}, plan.describe(), messages,
                     selection=selection, chunk_size=chunk_size, model_file=model_file, averaged_train=averaged,
                     notes=notes, transmission=transmission, training_range=ranges, friction_drift=drift,
                     range_checks={"validation": None if ranges is None or validation_range is None
                                   else ranges.check_range(validation_range)}, subtracted=subtracted)


def streamed_gravity_diagnosis(args: DiagnoseOptions, friction: str, plan: Preprocessing, findings: FindingsSaid,
                               mount: MountCheck, selection: ModelSelection, *, effects: tuple[Any, ...] | None,
                               delay: DelayBounds | None, gains: tuple[TorqueGains, bool, str] | None
                               ) -> tuple[Diagnosed, ModelSelection, bool] | None:
    """The found gravity a candidate of a streamed diagnosis's default answer, as in memory
    (:func:`diagnosis_in_memory`): the whole diagnosis run again on the same files with the same derivatives, its
    model of the gravity the mount check found (:func:`~estimation.consistent.mounted_gravity.turned_model`; every
    law a candidate, but the laws of a joint's position where the torques hold no gravity load), its default answer
    chosen from its own sums and compared with ``selection`` (the description's gravity) on the same validation
    samples by :func:`~estimation.consistent.mounted_gravity.gravity_answer`: ``(that run, the answer, taken)``, or
    ``None`` when the run with the found gravity chooses no answer. ``gains``: the torque gains'
    outcome of the declared model's run (the files already divided by them when taken)."""
    with step("the diagnosis with the gravity the mount check found, compared (streamed)"):
        other = diagnosis_streamed(args, friction, plan, findings, effects=effects, delay=delay, gains=gains,
                                   turned=mount)
    if other.selection is None:
        return None
    answer, taken = gravity_answer(selection, other.selection, mount.gravity)
    return other, answer, taken


def streamed_subtracted_diagnosis(args: DiagnoseOptions, friction: str, plan: Preprocessing, findings: FindingsSaid,
                                  selection: ModelSelection, *, effects: tuple[Any, ...] | None,
                                  delay: DelayBounds | None) -> tuple[Diagnosed, ModelSelection, bool] | None:
    """The log less the description's gravity torque a candidate of a streamed diagnosis's default answer, as in
    memory (:func:`diagnosis_in_memory`): the whole diagnosis run again on the same files with the same derivatives,
    the declared model, the description's gravity torque added back to every prepared chunk of every pass
    (:func:`estimation.streaming.chunks.loaded_chunk`; every law a candidate: the load is modelled), its default
    answer chosen from its own sums and compared with ``selection`` (the answer chosen between the description's
    gravity and the found one) on the same validation samples by
    :func:`~estimation.consistent.mounted_gravity.subtracted_answer`: ``(that run, the answer, taken)``, or ``None``
    when that run chooses no answer."""
    with step("the diagnosis of the log less the description's gravity torque, compared (streamed)"):
        other = diagnosis_streamed(args, friction, plan, findings, effects=effects, delay=delay,
                                   subtracted=SubtractedLoad())
    if other.selection is None:
        return None
    answer, taken = subtracted_answer(selection, other.selection)
    return other, answer, taken


def streamed_gains(args: DiagnoseOptions, model: IdentificationModel, plan: Preprocessing, chunk_size: int, *,
                   ratio: float | None, still: bool) -> tuple[TorqueGains, bool, str] | None:
    """The per-joint torque gains of a streamed diagnosis, fitted from the training files' sums of the plain model
    and checked on the validation files by the in-memory rule (:func:`streamed_gains_note`'s conditions and passes),
    before the diagnosis as in memory (:func:`diagnosis_in_memory`), or ``None`` when they are not tried. ``ratio``:
    the validation record's repeated-motion ratio."""
    reading = {"chunk_size": chunk_size, "cutoff_hz": plan.cutoff_hz if plan.method == "butterworth" else None,
               "decimation": plan.decimation, "held_torques": plan.held_torques}
    if plan.method == "fourier":  # the averaged periods summed, every recorded validation row checked (plan_chunks)
        reading.update(frequency_hz=plan.frequency_hz, harmonics=plan.harmonics, average=plan.average_periods)
    return streamed_gains_check(args, model, reading, ratio=ratio, still=still)


def divided_diagnosis(args: DiagnoseOptions, friction: str, plan: Preprocessing, effects: tuple[Any, ...] | None,
                      gains: tuple[TorqueGains, bool, str]) -> Diagnosed | None:
    """The streamed diagnosis of the files with their torques divided by ``gains`` (taken by the check,
    :func:`streamed_gains`), as the in-memory diagnosis divides its records (:func:`diagnosis_in_memory`): copies
    written block by block in a temporary folder (:func:`estimation.data.motor_side.divided_torque_copies`, removed
    on return), diagnosed by :func:`diagnosis_streamed`, its default answer's errors put back in the log's units
    (:func:`~estimation.consistent.torque_gains.in_recorded_units`: each channel's MSE times its gain squared, what
    ``oed predict`` measures with the model file's ``torque_gains``), the copies' names replaced by the files' as
    given. ``None`` when a file cannot be copied so (then the gains are said, not applied)."""
    import shutil
    import tempfile

    from estimation.data.motor_side import divided_torque_copies

    folder = Path(tempfile.mkdtemp(prefix="oed-divided-torques-"))
    try:
        factors = dict(zip(gains[0].channels, map(float, gains[0].values)))
        names: dict[str, str] = {}
        changes: dict[str, Any] = {}
        for role in ("data", "validate"):
            paths = getattr(args, role)
            try:
                copies = divided_torque_copies(paths, folder / role, factors)
            except (ValueError, OSError):  # a MeasurementError is a ValueError
                return None
            names.update({str(copy): str(path) for copy, path in zip(copies, paths)})
            changes[role] = [str(copy) for copy in copies]
        diagnosed = diagnosis_streamed(replace(args, **changes), friction, plan, effects=effects, gains=gains)
    finally:
        shutil.rmtree(folder, ignore_errors=True)
    selection = None if diagnosed.selection is None else in_recorded_units(diagnosed.selection, gains[0])
    diagnosis = replace(diagnosed.diagnosis, streaming=named_as_given(diagnosed.diagnosis.streaming, names))
    model_file = None if diagnosed.model_file is None else named_as_given(diagnosed.model_file, names)
    return replace(diagnosed, diagnosis=diagnosis, selection=selection, model_file=model_file,
                   messages=(*named_as_given(diagnosed.messages, names), gains[2]),
                   notes=(*named_as_given(diagnosed.notes, names), gains[2]), torque_gains=gains[0])


def streamed_gains_check(args: DiagnoseOptions, model: IdentificationModel, reading: dict[str, Any], *,
                         ratio: float | None, still: bool) -> tuple[TorqueGains, bool, str] | None:
    """The per-joint torque gains of a streamed diagnosis, under the in-memory conditions
    (:func:`~estimation.consistent.torque_gains.gains_for_records`: joint torques only, no ``--consistent``, no
    shaped law declared, a validation record of another motion that moves): fitted from the training files' sums of
    the plain model and checked on the validation files by the in-memory rule
    (:func:`estimation.streaming.torque_gains.files_gains_check`, three passes in bounded memory): ``(gains, taken,
    sentence)``, or ``None`` when they are not tried or cannot be fitted."""
    from estimation.identification.repeated_motion import REPEAT_FRACTION
    import numpy as np

    from estimation.streaming.torque_gains import files_gains_check

    channels = model.channels
    if args.consistent or model_has_shapes(model) or not args.validate or still or ratio is None \
            or ratio <= REPEAT_FRACTION or len(channels) < 2 \
            or not all(map(is_joint_torque, channels)):
        return None
    with step("an unknown gain on each joint's torque fitted and checked on the validation record"):
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")  # the files' findings are said on the diagnosis's passes
                return files_gains_check(plain_model(model), args.data, args.validate, reading)
        except (ValueError, np.linalg.LinAlgError):
            return None


def streamed_gains_note(checked: tuple[TorqueGains, bool, str]) -> str | None:
    """When the per-joint torque gains are taken by the check (``checked``: :func:`streamed_gains_check`'s) but the
    files could not be divided by them (:func:`divided_diagnosis`: a file neither .csv nor .parquet), the sentence
    saying so and that the streamed diagnosis does not divide the records by them (in memory it does):
    ``result.json``'s ``not_computed.torque_gains`` and a warning; else ``None`` (as in memory, ``torque_gains``
    stays ``null``)."""
    if not checked[1]:
        return None
    return (f"{checked[2]}; the streamed diagnosis does not divide the records by these gains (in memory it does, "
            "and diagnoses the torques so divided): its effects and errors are those of the torques as logged; run "
            "`oed diagnose` in memory (a larger --memory-budget, without --chunk-size) to diagnose with them")


#: what the streamed diagnosis says of a validation record at rest when its effect search compares the candidates
#: there (the Fourier path: its sums hold averaged periods, no stretches of the recording)
STILL_SEARCH = ("the streamed diagnosis compared its candidate effects on that validation record at rest (in memory "
                "they are compared on stretches of the training record their fits did not see): an effect it adopted "
                "was judged on a record that measures little of the dynamics; run `oed diagnose` in memory (a larger "
                "--memory-budget, without --chunk-size) or give a validation record of another motion")

#: the keys of report.json the default answer fills (on the streamed path too, :func:`streamed_selection`)
SELECTION_KEYS = ("consistent", "links", "model_selection")


def streamed_selection(args: DiagnoseOptions, diagnosis: Diagnosis, run: StreamedRun, plan: dict[str, Any],
                       chunk_size: int, *, still: bool = False, ratio: float | None = None,
                       load: SubtractedLoad | None = None) -> ModelSelection:
    """The default answer of a streamed diagnosis, chosen as in memory (:func:`diagnosis_selection`) from its sums
    (:func:`estimation.streaming.diagnosis_selection.streamed_refit_selection`): the adopted model or its consistent
    refit, every candidate (every weight of the prior's search) scored on the same validation samples against the
    channels as recorded: from the validation sums, or, on a validation file the loader resampled onto a uniform
    grid, at its recorded samples as ``oed predict`` measures them (:func:`resampled_scorer`, read in memory as the
    adopted model's own error there is). ``plan``: the model files' preprocessing; ``still``: the validation record
    is at rest (:func:`estimation.streaming.model_selection.warned_still_motion`): it chooses nothing, as in memory;
    ``ratio``: the validation record's repeated-motion ratio (``None``: computed here). The plain law is completed
    as in memory (:func:`completed_selection`: on a repeat of the training motion, and on another motion with the
    prior weight chosen for the adopted model held, :func:`~estimation.consistent.completion.held_completion`) from
    the same sums (:func:`estimation.streaming.diagnosis_selection.streamed_completion`). ``load``: the load the
    logged torques lack, which the run added back (:func:`resampled_scorer`'s model files subtract it)."""
    from estimation.identification.repeated_motion import REPEAT_FRACTION
    from estimation.streaming.diagnosis_selection import (
        refit_selection,
        streamed_completion,
        streamed_refit_selection,
        validation_blocks,
    )
    from estimation.streaming.model_selection import streamed_repeated_motion

    model = diagnosis.model
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the files' findings were said on the diagnosis's passes
        if ratio is None:
            ratio = streamed_repeated_motion(model, args.data, args.validate, chunk_size=chunk_size)
        score, blocks = None, None
        if resampled_validation({"streaming": diagnosis.streaming}):
            score = resampled_scorer(args, diagnosis, plan, load=load)
        elif not args.consistent and not still and ratio is not None and ratio > REPEAT_FRACTION:
            # chosen on a validation record of another motion: the paired difference of the candidates' scores is
            # reported, as in memory, from the validation sums on each block (one more pass over the files)
            with step("the validation files summed by block (the paired difference of the candidates)"):
                blocks = validation_blocks(diagnosis, run)
        settings = consistent_settings(args, model.robot)
        selection = streamed_refit_selection(diagnosis, run, given="consistent" if args.consistent else None,
                                             consistent=settings, score=score, ratio=ratio, still=still,
                                             blocks=blocks)
        repeat = completion_repeat(selection, consistent=args.consistent)
        if repeat is None:
            return selection
        completion = streamed_completion(diagnosis, run)  # the plain law completed, as in memory
        if completion is None:
            return selection
        completed, columns, added = completion
        if score is not None:  # every candidate on the validation file's recorded samples
            score = resampled_scorer(args, diagnosis, plan, fit=completed, load=load)
            completed = replace(completed, validation=score({"completed": completed.estimate.values})["completed"])
        laws = completed_laws(completed.model, added)
        return held_completion(selection, settings, laws, repeat=repeat,
                               select=lambda held: refit_selection(completed, columns, run, consistent=held,
                                                                   score=score, ratio=ratio, still=still,
                                                                   note=completed_note(laws), blocks=blocks))


def resampled_scorer(args: DiagnoseOptions, diagnosis: Diagnosis, plan: dict[str, Any], *,
                     fit: SummedFit | None = None, load: SubtractedLoad | None = None
                     ) -> Callable[[Any], dict[Any, ChannelErrors]]:
    """The validation errors of base-parameter vectors of the adopted model (in its base order; ``fit``: of that
    fit's model instead, the adopted model completed with the plain law), on a validation
    file the loader resampled: at its recorded samples, against the torques as recorded, as ``oed predict``
    measures the model file holding each (:func:`~oed.workflows.model_files.recorded_validation_errors`, shaped
    laws at their fixed shapes; the record read once for all the vectors), each also on the blocks of those samples
    (:func:`~oed.workflows.model_files.recorded_validation_scores`). ``load``: the load the logged torques lack
    (the model file's ``subtracted``: each prediction less it, as ``oed predict`` makes it)."""
    from estimation.streaming.chunks import source_files

    model, estimate = (diagnosis.final_model(), diagnosis.after.estimate) if fit is None else (fit.model, fit.estimate)
    document = with_load(summed_model_file_document(model, estimate, robot=robot_source(diagnosis.model.robot, args),
                                                    preprocessing=plan, shape=diagnosis.final_shape()), load)
    n_samples = diagnosis.after.validation.n_samples

    def score(thetas: Any) -> dict[Any, ChannelErrors]:
        errors = recorded_validation_scores(document, thetas, source_files(args.validate))
        if errors is None:
            raise ValueError("the validation files were read as recorded: score them from the sums")
        # each vector's MSE on each block of the recorded samples too (the paired difference of two candidates)
        return {key: ChannelErrors(dict(errors[key].mse), n_samples, block_mse=errors[key].block_mse,
                                   block_samples=None if errors[key].n_samples == n_samples
                                   else errors[key].n_samples) for key in thetas}
    return score


def with_load(document: dict[str, Any], load: SubtractedLoad | None) -> dict[str, Any]:
    """A model file ``document`` with ``subtracted`` (``load``, the load the logged torques lack: ``oed predict``
    subtracts it from the model's torques), or unchanged without one."""
    return document if load is None else {**document, "subtracted": load.to_dict()}


def recorded_errors(diagnosis: Diagnosis, args: DiagnoseOptions, plan: dict[str, Any], *,
                    load: SubtractedLoad | None = None) -> Diagnosis:
    """When the loader cleaned or resampled a validation record (jitter, re-sent rows, stalls), ``diagnosis`` with
    its validation MSE before and after measured on the record's samples as recorded
    (:func:`oed.workflows.model_files.recorded_validation_mse`, what ``oed predict`` measures) and the floor's
    comparisons of those errors; the streamed passes scored the record on the uniform grid. Unchanged when the
    records were read as recorded. ``plan``: the model files' preprocessing. The runner-up's validation MSE is
    measured again alike (its model file's, :func:`~oed.workflows.model_files.add_summed_runner_up_model_file`).
    ``load``: the load the logged torques lack, which the run added back (every model file subtracts it)."""
    from estimation.streaming.chunks import source_files
    from estimation.streaming.diagnosis_result import floor_report

    robot = robot_source(diagnosis.model.robot, args)
    after_file = with_load(summed_model_file_document(diagnosis.final_model(), diagnosis.after.estimate, robot=robot,
                                                      preprocessing=plan, shape=diagnosis.final_shape(),
                                                      recorded_mse=diagnosis.after.train.mse), load)
    declared = with_load(summed_model_file_document(diagnosis.model, diagnosis.before.estimate, robot=robot,
                                                    preprocessing=plan, recorded_mse=diagnosis.before.train.mse), load)
    # both models' errors on the validation files read and prepared once
    counted, counted_before = recorded_validations_counted([after_file, declared], source_files(args.validate))
    if counted is None:
        return diagnosis
    after, n_samples = counted  # the recorded samples, as in memory (the floor's test and the summary count them)
    before = None if counted_before is None else counted_before[0]
    fits = {which: replace(fit, validation=replace(fit.validation, mse=mse, n_samples=n_samples))
            for which, fit, mse in (("before", diagnosis.before, before), ("after", diagnosis.after, after))}
    statistics = diagnosis.statistics
    if statistics is not None:  # the floor's comparisons of these errors
        statistics = floor_report(fits["before"], fits["after"], statistics.floor, statistics.floor_note)
    runner_up = diagnosis.runner_up
    if runner_up is not None and runner_up.validation_mse is not None:
        rival = with_load(summed_model_file_document(runner_up.model, runner_up.fit, robot=robot, preprocessing=plan,
                                                     shape=diagnosis.runner_up_shape(),
                                                     recorded_mse=runner_up.train_mse), load)
        runner_up = replace(runner_up, validation_mse=recorded_validation_mse(rival, source_files(args.validate)))
    return replace(diagnosis, before=fits["before"], after=fits["after"], statistics=statistics, runner_up=runner_up)
