"""``oed diagnose`` as a library call: find what an identified model lacks in measured data, add it, report the
error before and after.

:func:`diagnose` takes the verb's options as keywords (:class:`DiagnoseOptions`), decides the path (in memory, or
the files streamed chunk by chunk: :func:`diagnose_streaming`, :mod:`estimation.streaming.diagnosis`, the same
report keys; in memory the answer is the adopted model or its consistent refit, :func:`diagnosis_selection`) and
returns a :class:`DiagnoseRun`:
``to_dict()`` is ``report.json``, ``write(out, report=...)`` writes it (and the report, HTML or Markdown:
:meth:`DiagnoseRun.report`), ``summary()`` the lines ``oed diagnose`` prints.
"""

from __future__ import annotations

import copy
import functools
import warnings
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

from dynamics.models import IdentificationModel, build_model
from dynamics.runtime.output_files import OutputFiles, json_text
from dynamics.runtime.processes import run_tasks, worker_count
from dynamics.runtime.progress import step
from dynamics.transmission import Transmission
from estimation.consistent.model_selection import ModelSelection, select_refit
from estimation.diagnosis.candidates.coupling import coupling_candidates
from dynamics.runtime.report_document import Report, figure_path, report_format
from estimation.diagnosis.report import diagnosis_report, plot_residuals, plot_trace
from estimation.diagnosis.results import Diagnosis, runner_up_line
from estimation.diagnosis.search import default_candidates
from estimation.diagnosis.search import diagnose as diagnose_model
from estimation.diagnosis.statistics import FLOOR_ALPHA
from estimation.diagnosis.untouched import UntouchedErrors, recorded_comparison, untouched_errors
from estimation.identification.prepared import InMemoryBudget, PreparedRecords, prepare_records
from estimation.identification.repeated_motion import repeated_motion_note
from estimation.preprocessing.delay import DelayBounds, split_delay
from estimation.preprocessing.plan import Preprocessing
from estimation.streaming.diagnosis import DEFAULT_SUBSAMPLE, diagnose_files
from estimation.streaming.diagnosis_result import StreamedDiagnosis
from estimation.streaming.recorded_errors import streamed_plan
from estimation.identification.model_file import summed_model_file_document
from estimation.estimators.normal_equations import DEFAULT_CHUNK_SIZE
from estimation.data.input_findings import grouped_messages
from estimation.data.log_cleaning import DEFAULT_MAX_GAP
from dynamics.robot import RobotModel
from estimation.streaming.diagnosis_passes import FLOOR_WINDOW
from estimation.uncertainty.floor_comparison import compare_with_floor
from estimation.uncertainty.noise_floor import NoiseFloor
from oed.workflows.asbuilt import (
    finish_document,
    model_effects,
    resolve_transmission,
    rest_message,
    rest_records,
    trivial_predictors,
    worse_after,
)
from oed.workflows.chosen_model import ChosenModel, answer_diagnosis, mse_line
from oed.workflows.memory_path import decide_path, streamed_choice
from oed.workflows.consistent import check_consistent_arguments, consistent_lines, consistent_settings
from oed.workflows.model_files import (
    add_model_file,
    add_runner_up_model_file,
    add_summed_model_file,
    add_summed_runner_up_model_file,
    recorded_validation_mse,
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
    streaming_requested,
)

__all__ = ["IN_MEMORY", "DiagnoseOptions", "DiagnoseRun", "diagnose", "report_figures", "residual_figure",
           "trace_figure"]

#: what the in-memory diagnosis holds at its peak: bytes a sample, channel and base parameter (measured: 2.8 GB
#: for 100 000 samples of the 7-joint KUKA, m r = 350, i.e. about 75; a lower bound is used)
IN_MEMORY = InMemoryBudget(64, "diagnosing", "use --chunk-size to stream them in bounded memory")


@dataclass(frozen=True, kw_only=True)
class DiagnoseOptions(RecordOptions):
    """The options of ``oed diagnose`` (:class:`~oed.workflows.options.RecordOptions` and these): ``test`` (a path
    or a list), ``report`` (whether the report, HTML or Markdown, will be written: it keeps the run in memory), ``alpha``,
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
    floor_window: int = FLOOR_WINDOW
    unseen_stretches: bool = False
    consistent: bool = False
    prior_weight: float | str | None = None
    prior: str | None = None
    link_bounds: str | None = None

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
        The :class:`~estimation.diagnosis.results.Diagnosis` (in memory) or the
        :class:`~estimation.streaming.diagnosis_result.StreamedDiagnosis` (streamed).
    records
        The prepared records (in memory; ``None`` when streamed: no Markdown report then).
    untouched
        The errors on the ``test`` record, or ``None``.
    """

    document: dict[str, Any] = field(repr=False)
    lines: tuple[str, ...]
    warnings: tuple[str, ...]
    diagnosis: Any = field(repr=False)
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
        written as Markdown (:meth:`markdown`) or HTML (:meth:`html`)."""
        self._check_in_memory()
        diagnosis, records = self.diagnosis, self.records
        validation = (diagnosis.before.validation, diagnosis.after.validation)
        test = None
        if self.untouched is not None and records.test is not None:
            test = tuple(recorded_comparison(result, records.test.measurements, "test")
                         for result in (diagnosis.before, diagnosis.after))
        return diagnosis_report(
            diagnosis, train=records.train.measurements, validate=records.validation.measurements,
            validation=validation, test=test, preprocessing=records.preprocessing.describe(), warnings=self.warnings,
            test_errors=None if self.untouched is None else self.untouched.to_dict(), test_note=TEST_NOTE)

    def markdown(self, report: str | Path = "report.md") -> str:
        """The Markdown report, linking its figures as the files beside ``report`` (:func:`report_figures`)."""
        return self.report().markdown(lambda figure: figure_path(report, figure.name).name)

    def html(self) -> str:
        """The report as one self-contained HTML page (figures inline)."""
        return self.report().html()

    def plot_residuals(self, path: str | Path) -> None:
        """The residual figure of the report, saved at ``path``."""
        self._check_in_memory()
        plot_residuals(self.diagnosis, self.records.train.measurements, path)

    def plot_trace(self, path: str | Path) -> None:
        """The residual against the variables that say something about it, saved at ``path`` (nothing written
        when none does)."""
        self._check_in_memory()
        plot_trace(self.diagnosis, self.records.validation.measurements, path)

    def write(self, out: str | Path, *, report: str | Path | None = None) -> None:
        """The report JSON at ``out`` and, with ``report``, the report: Markdown with its figures beside it
        (:func:`report_figures`) or HTML with them inline, by the suffix: all files or none."""
        check_json_path(out)
        check_report_path(report)
        if report is not None:
            self._check_in_memory()
        with OutputFiles() as outputs:
            with outputs.open(out) as stream:
                stream.write(json_text(self.document))
            if report is not None:
                self.report().write(report, outputs)

    def _check_in_memory(self) -> None:
        if self.records is None:
            raise ValueError("--report: not with the streamed path (--chunk-size, --scheduler or --workers), which "
                             "writes the JSON report only")


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
    """:func:`diagnose` of checked options."""
    check_request(args)
    check_consistent_arguments(args)
    differentiation(args)  # contradicting derivative options are an error even when the data hold dq, ddq
    friction, delay = split_delay(args.friction)  # a candidate in every diagnosis: 'delay:S' sets its bound
    if streaming_requested(args):  # bounded memory (estimation.streaming.diagnosis)
        check_streamed_request(args, delay)
        return diagnose_streaming(args, friction)
    robot = robot_of(args)
    transmission = resolve_transmission(args, robot)
    effects = model_effects(args, friction, robot, transmission)
    model = build_model(robot, args.model, effects)
    check_shaped_effects_kept(effects, model)
    decision = decide_path(args, model, task="diagnosing", bytes_per_value=IN_MEMORY.bytes_per_value,
                           in_memory_only=lambda: in_memory_only(args, model, delay), say=say)
    if decision.stream:
        return diagnose_streaming(args, friction, decision.plan)
    return diagnose_in_memory(args, model, transmission, delay, decision.plan)


def check_streamed_request(args: DiagnoseOptions, delay: DelayBounds | None) -> None:
    """``--test`` and a delay are in-memory only: an error when the streamed path was asked for."""
    if args.test:
        raise ValueError("--test is read in memory: not with the streamed path (--chunk-size, --scheduler or "
                         "--workers)")
    if delay is not None:
        raise ValueError("the delay between torques and motion is searched in memory: not with the streamed path "
                         "(--chunk-size, --scheduler or --workers), which does not try it")
    if args.consistent:
        raise ValueError("--consistent refits in memory: not with the streamed path (--chunk-size, --scheduler or "
                         "--workers)")


def in_memory_only(args: DiagnoseOptions, model: IdentificationModel, delay: DelayBounds | None) -> str | None:
    """The options given that the streamed diagnosis lacks, in a few words, or ``None``."""
    try:
        check_streamed_request(args, delay)
        check_streamed_arguments(args, model)
    except ValueError as error:
        return str(error).split(":")[0] + " (not on the streamed path)"
    return None


def diagnose_in_memory(args: DiagnoseOptions, model: IdentificationModel, transmission: Transmission | None,
                       delay: DelayBounds | None, plan: Preprocessing | None) -> DiagnoseRun:
    """Read and prepare the records (``plan``: the derivatives chosen before reading), diagnose, build the document."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        records = prepare_records(model, args.data, args.validate, args.test or (),  # reports its steps
                                  settings=replace(preparation_settings(args, transmission, IN_MEMORY), plan=plan))
        with step("noise floors of the held-out records"):
            validation_floor, test_floor = record_floors(records, model, args.frequency, args.jobs)
        with step("diagnosis in memory"):
            diagnosis = diagnose_records(args, model, transmission, records, delay, validation_floor)
        untouched = test_errors(records, diagnosis, test_floor)
        trivial, notes = trivial_predictors(diagnosis.after, records.validation.measurements)
        notes += worse_after(diagnosis)
        repeat = repeated_motion_note(records.train.measurements, records.validation.measurements)
        notes += () if repeat is None else (repeat,)
        with step("the default answer: the adopted model or its consistent refit"):
            selection = diagnosis_selection(args, diagnosis, records)
        consistent = selection.consistent
    messages = caught_messages(caught) + list(notes)
    rest = rest_records(records)
    document = finish_document(diagnosis.to_dict(), diagnosis.after, trivial=trivial, warnings=notes, rest=rest,
                               transmission=transmission, warnings_key=("warnings", "after"))
    document["preprocessing"] = records.preprocessing.to_dict()
    document["test"] = None if untouched is None else untouched.to_dict()
    if consistent is not None:
        document.update(consistent.to_dict())
        document["consistent"]["test"] = None if records.test is None else \
            {"mse": consistent.compare(records.test.measurements).mse}
    document["model_selection"] = selection.to_dict()
    if document["test"] is not None:  # the chosen model's error on the test record (what `oed predict` gives there)
        document["test"]["chosen"] = {"name": selection.chosen, "mse": dict(
            untouched.after if selection.chosen != "consistent" else document["consistent"]["test"]["mse"])}
    messages += add_model_file(document, diagnosis.after, args, records.preprocessing, transmission,
                               consistent=consistent, selection=selection)
    chosen = ChosenModel.of(selection)  # its errors beside the diagnosis's before and after
    answer_diagnosis(document, chosen, floor=validation_floor)
    add_runner_up_model_file(document, diagnosis.runner_up, args, records.preprocessing, transmission)
    document["diagnosis_path"] = "in-memory"  # "streamed": --chunk-size (diagnose_streaming)
    document["max_effects"] = args.max_effects
    document["max_effects_reached"] = len(diagnosis.effects) >= args.max_effects
    lines = [records.preprocessing.describe(), *summary_lines(diagnosis), *test_lines(untouched)]
    if consistent is not None and (args.consistent or selection.chosen == "consistent"):
        lines += consistent_lines(consistent)
    lines += selection.lines() + chosen_lines(document["validation"]) + chosen_test_lines(document["test"])
    if len(diagnosis.effects) >= args.max_effects:
        untested = sum(rejected.reason.startswith("not tested") for rejected in diagnosis.rejected)
        lines.append(f"stopped at --max-effects {args.max_effects}: {untested} candidate(s) not tested; raise "
                     "--max-effects to test them")
    message = rest_message("diagnose", rest)
    if message:
        lines.append(message)
    return DiagnoseRun(document, tuple(lines), tuple(messages), diagnosis, records, untouched)


def diagnosis_selection(args: DiagnoseOptions, diagnosis: Diagnosis, records: PreparedRecords) -> ModelSelection:
    """The default answer (:func:`estimation.consistent.model_selection.select_refit`): the adopted model as fitted
    (unconstrained) or its consistent refit (the description's bodies as prior, its weight chosen on the validation
    record; shaped laws and a delay at their fitted values), by the validation error when the validation record is
    another motion, else the consistent refit; ``--consistent`` forces it. A refit that fails is no candidate."""
    return select_refit(diagnosis.after, records.train.measurements, records.validation.measurements,
                        given="consistent" if args.consistent else None,
                        consistent=consistent_settings(args, diagnosis.after.model.robot),
                        note="with the diagnosed effects")


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
                     records: PreparedRecords, delay: DelayBounds | None, floor: NoiseFloor | None) -> Diagnosis:
    """The diagnosis of the prepared records; ``floor``: the validation record's as recorded (:func:`record_floors`)."""
    train, validation = records.train.measurements, records.validation.measurements
    candidates = default_candidates(model) + coupling_candidates(model, transmission, train=train)
    return diagnose_model(model, train, validation, alpha=args.alpha, candidates=candidates,
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
    lines = ["test MSE vs recorded (a record no choice used)",
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


def summary_lines(diagnosis: Diagnosis) -> list[str]:
    """Effects found and the validation MSE per channel before and after."""
    lines = found_lines(diagnosis.effects, shape_std=True)
    lines.append(runner_up_line(diagnosis.runner_up, diagnosis.runner_up_reason))
    before, after = diagnosis.before.validation.mse, diagnosis.after.validation.mse
    lines += ["validation MSE vs recorded",
              "                 " + "  ".join(f"{channel:>9s}" for channel in before),
              "  before         " + "  ".join(f"{value:9.4g}" for value in before.values()),
              "  after          " + "  ".join(f"{after[channel]:9.4g}" for channel in before)]
    return lines + floor_lines(diagnosis)


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
        ("--report", bool(args.report)),
        ("--transmission", args.transmission is not None),
        ("--min-speed", args.min_speed is not None),
        ("--average-periods no", args.average_periods == "no"),
        ("--max-gap", args.max_gap != DEFAULT_MAX_GAP)) if given]
    if unsupported:
        raise ValueError(f"{', '.join(unsupported)}: not with {STREAMED}, which reads whole files without holes "
                         "on the filter path, the files' dq, ddq or a Fourier fit of averaged periods, and writes the "
                         "JSON report only")
    if model_has_shapes(model):
        raise ValueError(f"declared laws with shape parameters (coulomb:tanh, sigmoid…) are fitted in memory: not with "
                         f"{STREAMED}; declare their plain forms, or let the diagnosis find them")
    for option in ("subsample", "floor_window"):
        value = getattr(args, option)
        if isinstance(value, bool) or value < 1:
            raise ValueError(f"--{option.replace('_', '-')} must be a positive integer, got {value}")


def diagnose_streaming(args: DiagnoseOptions, friction: str, plan: Preprocessing | None = None) -> DiagnoseRun:
    """Diagnose the files read chunk by chunk (:func:`estimation.streaming.diagnosis.diagnose_files`), their
    derivatives chosen as in memory (``plan``: already chosen); ``friction``: the declared effects without the delay."""
    robot = robot_of(args)
    effects = model_effects(args, friction, robot, None)
    model = build_model(robot, args.model, effects)
    check_shaped_effects_kept(effects, model)
    check_streamed_arguments(args, model)
    chunk_size = DEFAULT_CHUNK_SIZE if args.chunk_size is None else args.chunk_size
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        if plan is None:
            plan = streamed_choice(args, model).chosen
        with executor_for(args) as executor:
            result = diagnose_files(model, args.data, args.validate, chunk_size=chunk_size, alpha=args.alpha,
                                    max_effects=args.max_effects, subsample=args.subsample,
                                    floor_window=args.floor_window, executor=executor, preprocessing=plan)
    messages = grouped_messages(caught, [*args.data, *args.validate])  # one line per finding across files
    document = result.to_dict()
    document["preprocessing"] = {"cutoff_hz": result.streaming["cutoff_hz"], **plan.to_dict()}
    document["max_effects"] = args.max_effects
    document["max_effects_reached"] = len(result.effects) >= args.max_effects
    # the model file: the final model's estimate from the sums; on the filter path (and with measured derivatives)
    # its validation error is against the channels as recorded, on the samples the in-memory preprocessing keeps,
    # which is what `oed predict` measures; a Fourier fit of averaged periods is not what `oed predict` repeats
    if plan.method == "fourier":
        model_plan, validation_mse = plan.to_dict(), None
    else:
        model_plan = streamed_plan(args.data[0], model, cutoff_hz=result.streaming["cutoff_hz"],
                                   decimation=plan.decimation, held_torques=plan.held_torques, chunk_size=chunk_size)
        validation_mse = result.validation_mse["after"]
    messages += add_summed_model_file(document, result.final_model(), result.after, args, model_plan,
                                      shape=result.final_shape(), recorded_mse=result.train_mse["after"],
                                      validation_mse=validation_mse)
    if validation_mse is not None and resampled_validation(document):  # the errors on the samples as recorded
        validation_mse = recorded_errors(document, result, args, model_plan) or validation_mse
    name = result.after.method  # the one model the report's model file holds: its errors, named as predict names it
    document["train"]["chosen"] = {"name": name, "mse": dict(result.train_mse["after"])}
    document["validation"]["chosen"] = {"name": name, "mse": None if validation_mse is None else dict(validation_mse)}
    runner_up = result.runner_up
    add_summed_runner_up_model_file(document, runner_up, args, model_plan, None if validation_mse is None or
                                    runner_up is None else runner_up.validation_mse)
    lines = [plan.describe(), *streamed_summary_lines(args, robot, model, result, chunk_size, document["validation"]),
             *chosen_lines(document["validation"])]
    return DiagnoseRun(document, tuple(lines), tuple(messages), result)


def recorded_errors(document: dict[str, Any], result: StreamedDiagnosis, args: DiagnoseOptions,
                    plan: dict[str, Any]) -> dict[str, float] | None:
    """When the loader cleaned or resampled a validation record (jitter, re-sent rows, stalls), the validation
    MSE before and after on its samples as recorded (:func:`oed.workflows.model_files.recorded_validation_mse`,
    what ``oed predict`` measures), put into ``document`` (``validation.before``/``after``, the model file's
    reported error) in place; the 'after' one is returned. ``None``: the records were read as recorded."""
    after = recorded_validation_mse(document["model_file"], args.validate)
    if after is None:
        return None
    declared = summed_model_file_document(result.model, result.before, robot=robot_source(result.model.robot, args),
                                          preprocessing=plan, recorded_mse=result.train_mse["before"])
    before = recorded_validation_mse(declared, args.validate)
    document["model_file"]["reported"]["validation_mse"] = after
    for which, mse in (("before", before), ("after", after)):
        document["validation"][which]["mse"] = mse
        if result.floor is not None:  # the floor's comparisons of these errors
            comparison = compare_with_floor(mse, result.floor, result.n_validation, alpha=FLOOR_ALPHA)
            document["validation"][which]["mse_over_floor"] = {c: value.ratio for c, value in comparison.items()}
            document["floor_comparison"][which] = {c: value.to_dict() for c, value in comparison.items()}
            if which == "after":
                document["floor_statements"] = {c: value.statement() for c, value in comparison.items()}
    return after


def streamed_summary_lines(args: DiagnoseOptions, robot: RobotModel, model: IdentificationModel, result: StreamedDiagnosis,
                           chunk_size: int, validation: dict[str, Any] | None = None) -> list[str]:
    """The records, the effects found, the validation MSE before and after (``validation``: the report's, else
    the result's) and the noise floor."""
    streaming = result.streaming
    lines = [f"{robot.name}: {model.kind.value} model, streamed diagnosis of {result.n_train} training samples from "
             f"{len(streaming['files'])} file(s) in chunks of {chunk_size}, {result.n_validation} validation samples; "
             f"shapes searched on {streaming['subsample']['samples']} samples"]
    lines += found_lines(result.effects, shape_std=False)
    lines.append(runner_up_line(result.runner_up, result.runner_up_reason))
    before, after = result.validation_mse["before"], result.validation_mse["after"]
    if validation is not None:
        before, after = validation["before"]["mse"], validation["after"]["mse"]
    lines += ["validation MSE vs recorded",
              "                 " + "  ".join(f"{channel:>9s}" for channel in before),
              "  before         " + "  ".join(f"{value:9.4g}" for value in before.values()),
              "  after          " + "  ".join(f"{after[channel]:9.4g}" for channel in before)]
    if result.floor is not None:
        floor = result.floor.mse()
        lines.append("  noise floor    " + "  ".join(f"{floor[channel]:9.4g}" for channel in before)
                     + f"   ({result.floor.method}; {result.floor_note})")
    else:
        lines.append(result.floor_note)
    if len(result.effects) >= args.max_effects:
        lines.append(f"stopped at --max-effects {args.max_effects}; raise --max-effects to test the rest")
    return lines
