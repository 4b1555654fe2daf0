"""``oed identify`` as a library call: base parameters from measured data, with uncertainties and validation.

:func:`identify` takes the verb's options as keywords (:class:`IdentifyOptions`), decides the path (in memory, or
the files streamed chunk by chunk: :mod:`oed.workflows.memory_path`), identifies and returns an
:class:`IdentifyRun`: ``to_dict()`` is ``result.json``, ``write(out, plot=...)`` writes it (and the figure),
``summary()`` the lines ``oed identify`` prints, ``warnings`` the warnings it prints on stderr.
"""

from __future__ import annotations

import copy
import warnings
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

from dynamics.models import IdentificationModel, build_model
from dynamics.robot import RobotModel
from dynamics.runtime.output_files import OutputFiles, check_figure_path, json_text
from dynamics.runtime.progress import step
from dynamics.runtime.report_document import Report
from dynamics.transmission import Transmission
from estimation.data.input_findings import grouped_messages
from estimation.data.log_cleaning import DEFAULT_MAX_GAP
from estimation.diagnosis.statistics import ResidualReport, residual_report
from estimation.estimators.normal_equations import DEFAULT_CHUNK_SIZE
from estimation.identification.fit import IdentificationResult
from estimation.identification.prepared import InMemoryBudget, PreparedRecords, prepare_records
from estimation.identification.preprocessing_choice import ChoiceWindow
from estimation.identification.repeated_motion import repeated_motion_note
from estimation.identification.report import identification_report
from estimation.identification.validation import plot_comparison
from estimation.identification.weighting_choice import choose_weighting, weighting_samples
from estimation.preprocessing.delay import DelayBounds, split_delay
from estimation.preprocessing.plan import Preprocessing
from estimation.streaming.cutoff_choice import streamed_window
from estimation.streaming.identification import identify_files
from estimation.streaming.periods import plan_options
from estimation.streaming.recorded_errors import streamed_plan, streamed_recorded_mse
from oed.workflows.asbuilt import (
    finish_document,
    model_effects,
    resolve_transmission,
    rest_message,
    rest_records,
    trivial_predictors,
)
from estimation.consistent.model_selection import select_model
from oed.workflows.consistent import check_consistent_arguments, consistent_lines, consistent_settings
from oed.workflows.memory_path import decide_path, streamed_choice
from oed.workflows.model_files import add_model_file, add_summed_model_file
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
    (``auto``, ``wls``, ``ols``), ``plot`` and ``report`` (whether a figure or the report, which draw every sample,
    will be written: they keep the run in memory), ``consistent``, ``prior_weight`` (a number or ``"auto"``), ``prior``, ``link_bounds``."""

    method: str = "auto"
    plot: bool = False
    report: bool = False
    consistent: bool = False
    prior_weight: float | str | None = None
    prior: str | None = None
    link_bounds: str | None = None

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
        The :class:`~estimation.identification.fit.IdentificationResult` of the in-memory path, or the
        :class:`~estimation.streaming.identification.StreamedIdentification` of the streamed one.
    streamed
        Whether the files were streamed (no figure then).
    title
        The figure's title.
    """

    document: dict[str, Any] = field(repr=False)
    lines: tuple[str, ...]
    warnings: tuple[str, ...]
    result: Any = field(repr=False)
    streamed: bool
    title: str = ""
    #: the preprocessing chosen, in one line (the report's choices)
    preprocessing: str = ""

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
        comparisons = [self.result.train] + ([self.result.validation] if self.result.validation is not None else [])
        plot_comparison(comparisons, path, title=self.title)

    def report(self) -> Report:
        """The report a person reads (:func:`estimation.identification.report.identification_report`): the choices,
        every warning, the parameters with their standard deviations, the errors beside the floor, measured
        against predicted per channel. Written as Markdown or HTML (:meth:`write`)."""
        if self.streamed:
            raise ValueError(f"--report draws every sample: not with {STREAMED}")
        return identification_report(self.result, self.document, preprocessing=self.preprocessing,
                                     warnings=self.warnings, title=self.title)

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
    """:func:`identify` of checked options."""
    differentiation(args)  # contradicting derivative options are an error even when the data hold dq, ddq
    check_consistent_arguments(args)
    robot = robot_of(args)
    transmission = resolve_transmission(args, robot)
    friction, delay = split_delay(args.friction)  # the delay moves the motion: not a column effect
    effects = model_effects(args, friction, robot, transmission)
    model = build_model(robot, args.model, effects)
    check_shaped_effects_kept(effects, model)
    check_model_request(args, model, delay)
    if streaming_requested(args):
        check_streamed_request(args, model)
        return identify_streaming(args, robot, model)
    decision = decide_path(args, model, task="identifying", bytes_per_value=IN_MEMORY.bytes_per_value,
                           in_memory_only=lambda: in_memory_only(args, model, delay), say=say,
                           validation_fits=validation_fits(args, model, delay))
    if decision.stream:
        return identify_streaming(args, robot, model, decision.plan)
    return identify_in_memory(args, robot, model, transmission, delay, decision.plan)


def identify_streaming(args: IdentifyOptions, robot: RobotModel, model: IdentificationModel,
                       plan: Preprocessing | None = None) -> IdentifyRun:
    """Identify from the files read chunk by chunk (:func:`estimation.streaming.identification.identify_files`), their
    derivatives chosen as in memory (``plan``: already chosen)."""
    chunk_size = DEFAULT_CHUNK_SIZE if args.chunk_size is None else args.chunk_size
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        if plan is None:
            plan = streamed_choice(args, model, validation_fits=validation_fits(args, model, None)).chosen
        options = plan_options(plan)
        weighting = choose_weighting(model, weighting_samples(streamed_window(args.data, model), plan)) \
            if args.method == "auto" else None  # on the samples the in-memory path chooses it on
        with executor_for(args) as executor:
            result = identify_files(model, args.data, args.validate or [],
                                    method=args.method if weighting is None else weighting.method, chunk_size=chunk_size,
                                    cutoff_hz=options["cutoff_hz"], frequency_hz=options["frequency_hz"],
                                    harmonics=options["harmonics"], decimation=options["decimation"],
                                    held_torques=options["held_torques"], executor=executor)
    notes = grouped_messages(caught, [*args.data, *(args.validate or ())])  # one line per finding across files
    document = result.to_dict()
    document["preprocessing"] = plan.to_dict()
    if weighting is not None:
        document["method_selection"] = weighting.to_dict()
    notes += add_streamed_model_file(document, args, result, chunk_size)
    estimate = result.estimate
    lines = [plan.describe(),
             f"{robot.name}: {model.kind.value} model, {model.n_base} base parameters, {result.train.n_samples} samples "
             f"from {len(result.files)} file(s) in chunks of {chunk_size}, {estimate.method.upper()}, "
             f"cond {estimate.cond:.4g}"]
    if result.cov_method == "batch_means":
        lines.append(f"standard deviations: batch means (batches of {result.batch_length} samples; a third pass over "
                     f"the files, {result.seconds['covariance_pass']:.3g} s)")
    lines += estimate_lines(estimate)
    for label in ("train", "validation"):
        errors = document[label]
        if errors is not None:
            against, mse = ("vs recorded", errors["mse"]) if errors["mse"] is not None else \
                ("vs filtered: not against the recording", errors["mse_filtered"])
            lines.append(f"{label} MSE ({against}): " + "  ".join(f"{channel} {value:.4g}" for channel, value in mse.items()))
    return IdentifyRun(document, tuple(lines), tuple(notes), result, streamed=True)


def add_streamed_model_file(document: dict[str, Any], args: IdentifyOptions, result: Any,
                            chunk_size: int) -> tuple[str, ...]:
    """The model file of the streamed identification. Its validation error is the one ``oed predict`` measures:
    against the channels as recorded, on the samples the in-memory preprocessing keeps; on the filter path (where
    the sums hold filtered channels) from one more pass over the validation files
    (:func:`estimation.streaming.recorded_errors.streamed_recorded_mse`); on the Fourier path none is reported. Returns the
    plausibility warnings."""
    if result.frequency_hz is not None:
        plan = {"method": "fourier", "frequency_hz": result.frequency_hz, "harmonics": 5 if args.harmonics is None
                else args.harmonics, "frequency_source": "given", "average_periods": "auto",
                "decimation": args.decimate, "held_torques": bool(args.held_torques)}
    else:
        plan = streamed_plan(args.data[0], result.model, cutoff_hz=result.cutoff_hz, decimation=args.decimate,
                             held_torques=bool(args.held_torques), chunk_size=chunk_size)
    validation = None if document["validation"] is None else document["validation"]["mse"]
    if result.frequency_hz is not None:
        validation = None
    elif document["validation"] is not None and validation is None:  # the sums hold filtered channels
        validation = streamed_recorded_mse(result.model, result.estimate.values, args.validate, chunk_size=chunk_size,
                                  cutoff_hz=result.cutoff_hz, decimation=args.decimate,
                                  held_torques=bool(args.held_torques))
        document["validation"]["mse"] = validation
    return add_summed_model_file(document, result.model, result.estimate, args, plan,
                                 recorded_mse=document["train"]["mse"], validation_mse=validation)


def estimate_lines(estimate: Any) -> list[str]:
    """One line a base parameter: value, standard deviation and relative standard deviation."""
    width = max(len(name) for name in estimate.names)
    return [f"  {record['name']:<{width}}  {record['value']:+.5g} ± {record['std']:.2g}  ({record['relative_std']:.3g} %)"
            for record in estimate.records()]


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
    for option, given in (("--plot", args.plot), ("--report", args.report)):
        if given:
            raise ValueError(f"{option} draws every sample: not with {STREAMED}")
    if args.min_speed is not None:
        raise ValueError(f"--min-speed drops rows of the whole record: not with {STREAMED}")
    if model_has_shapes(model):
        raise ValueError("laws with shape parameters (coulomb:tanh, sigmoid…) are fitted by variable projection "
                         f"in memory: not with {STREAMED}")
    if args.consistent:
        raise ValueError(f"--consistent refits in memory: not with {STREAMED}")
    unsupported = [option for option, given in (
        ("--transmission", args.transmission is not None), ("--average-periods", args.average_periods != "auto"),
        ("--max-gap", args.max_gap != DEFAULT_MAX_GAP)) if given]
    if unsupported:
        raise ValueError(f"{', '.join(unsupported)}: not with {STREAMED}, which reads whole files without holes, "
                         "joint-side columns, and averages periods whenever --frequency is given")


def identify_in_memory(args: IdentifyOptions, robot: RobotModel, model: IdentificationModel,
                       transmission: Transmission | None, delay: DelayBounds | None,
                       plan: Preprocessing | None = None) -> IdentifyRun:
    """Read and prepare the records (:func:`estimation.identification.prepared.prepare_records`; ``plan``: the
    derivatives chosen before reading), identify, and build the document."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        records = prepare_records(model, args.data, args.validate or (),  # reports its steps
                                  settings=replace(preparation_settings(args, transmission, IN_MEMORY), plan=plan,
                                                   validation_fits=validation_fits(args, model, delay)))
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
        result, consistent = selection.unconstrained, selection.consistent
        trivial, notes = trivial_predictors(result, validation)
        with step("noise floor of the validation record"):
            floor_report = None if validation is None else floor_check(records, model, result, args.frequency)
        notes = (*notes, *above_floor_notes(floor_report))
        repeat = None if validation is None else repeated_motion_note(train, validation)
        notes = notes if repeat is None else (*notes, repeat)
    messages = caught_messages(caught) + list(notes)
    rest = rest_records(records)
    document = finish_document(result.to_dict(), result, trivial=trivial, warnings=notes, rest=rest,
                               transmission=transmission)
    if consistent is not None:
        document.update(consistent.to_dict())
    if weighting is not None:
        document["method_selection"] = weighting.to_dict()
    document["model_selection"] = selection.to_dict()
    messages += add_model_file(document, result, args, records.preprocessing, transmission, consistent=consistent,
                               selection=selection)
    if floor_report is not None and document.get("validation") is not None:
        document["validation"]["mse_over_floor"] = floor_report.ratios("after") or None
        document["noise_floor"] = None if floor_report.floor is None else {
            "mse": floor_report.floor.mse(), "method": floor_report.floor.method, "note": floor_report.floor_note}
    lines = summary_lines(robot, model, result, records.preprocessing, train.n_samples, rest)
    if consistent is not None and (args.consistent or selection.chosen == "consistent"):
        lines += consistent_lines(consistent)
    lines += selection.lines()
    return IdentifyRun(document, tuple(lines), tuple(messages), result, streamed=False,
                       title=f"{robot.name}: {model.kind.value} model ({result.estimate.method})",
                       preprocessing=records.preprocessing.describe())


def validation_fits(args: IdentifyOptions, model: IdentificationModel, delay: DelayBounds | None) -> tuple[str, ...]:
    """The unconstrained fits that choose the derivatives on a validation record of another motion
    (:mod:`estimation.identification.preprocessing_on_validation`): the weighting asked for, else both; none
    with a delay search or shaped laws (fitted by a search each, not repeated for every candidate: the
    training record's choice is kept)."""
    if delay is not None or model_has_shapes(model):
        return ()
    return ("ols", "wls") if args.method == "auto" else (args.method,)


def floor_check(records: PreparedRecords, model: IdentificationModel, result: IdentificationResult,
                frequency_hz: float | None) -> ResidualReport:
    """The validation error against the validation record's noise floor (estimated from the file as read, without
    the model), and what the residual of a channel still above it follows (:mod:`estimation.diagnosis.statistics`)."""
    preprocessing = records.preprocessing
    frequency = preprocessing.frequency_hz if preprocessing.method == "fourier" else frequency_hz
    floor = records.validation.noise_floor(model.channels, frequency)
    return residual_report(result, result, records.train.measurements, records.validation.measurements, floor)


def above_floor_notes(report: ResidualReport | None) -> list[str]:
    """A warning for each channel whose validation error stays significantly above its floor."""
    if report is None or report.floor is None:
        return []
    above = [channel for channel, comparison in report.comparison.get("after", {}).items() if comparison.above]
    return [f"{report.statements[channel]}: the model lacks something there; `oed diagnose` searches for it"
            for channel in above]


def summary_lines(robot: RobotModel, model: IdentificationModel, result: IdentificationResult,
                  preprocessing: Preprocessing, n_samples: int, rest: dict[str, dict | None]) -> list[str]:
    """The preprocessing, the estimate with its shape parameters, the errors and the rows at rest dropped."""
    estimate = result.estimate
    lines = [preprocessing.describe(),
             f"{robot.name}: {model.kind.value} model, {model.n_base} base parameters, {n_samples} samples, "
             f"{estimate.method.upper()}, cond {estimate.cond:.4g}"]
    lines += estimate_lines(estimate)
    width = max(len(name) for name in estimate.names)
    for value in result.shapes:
        bound = "  (at its bound)" if value.at_bound else ""
        lines.append(f"  {value.name:<{width}}  {value.value:+.5g} ± {value.std:.2g}  (shape of {value.effect}){bound}")
    for label, comparison in (("train", result.train), ("validation", result.validation)):
        if comparison is not None:
            lines.append(f"{label} MSE (vs recorded): " + "  ".join(
                f"{channel} {value:.4g}" for channel, value in comparison.mse.items()))
            if comparison.mse_filtered is not None:
                lines.append(f"{label} MSE (vs filtered): " + "  ".join(
                    f"{channel} {value:.4g}" for channel, value in comparison.mse_filtered.items()))
    message = rest_message("identify", rest)
    if message:
        lines.append(message)
    return lines
