"""``oed identify``: base parameters from measured data, with uncertainties and validation."""

from __future__ import annotations

import argparse
import sys
import warnings
from dataclasses import replace
from pathlib import Path
from typing import Any

from dynamics.models import IdentificationModel, ModelKind, build_model
from dynamics.robot import RobotModel
from dynamics.runtime.progress import show_progress, step
from dynamics.transmission import Transmission
from estimation.data.log_cleaning import DEFAULT_MAX_GAP
from estimation.estimators.normal_equations import DEFAULT_CHUNK_SIZE
from estimation.identification.fit import IdentificationResult
from estimation.identification.validation import plot_comparison
from estimation.preprocessing.delay import DelayBounds, split_delay
from estimation.preprocessing.plan import Preprocessing
from estimation.identification.prepared import InMemoryBudget, PreparedRecords, prepare_records
from estimation.identification.preprocessing_choice import ChoiceWindow
from estimation.identification.repeated_motion import repeated_motion_note
from estimation.identification.weighting_choice import choose_weighting, weighting_samples
from estimation.diagnosis.statistics import ResidualReport, residual_report
from estimation.streaming.cutoff_choice import streamed_window
from estimation.streaming.identification import identify_files
from estimation.streaming.periods import plan_options
from estimation.streaming.recorded_errors import recorded_mse, streamed_plan
from oed.cli.shared.memory_path import decide_path, streamed_choice
from oed.cli.shared.model_files import add_model_file, add_summed_model_file
from oed.cli.shared.asbuilt import (
    add_asbuilt_arguments,
    finish_document,
    model_effects,
    resolve_transmission,
    rest_message,
    rest_records,
    trivial_predictors,
)
from oed.cli.shared.common import (
    OutputFiles,
    add_data_arguments,
    add_derivative_arguments,
    add_jobs_argument,
    add_robot_arguments,
    add_streaming_arguments,
    check_figure_path,
    check_shaped_effects_kept,
    differentiation,
    executor_from_arguments,
    json_text,
    model_has_shapes,
    preparation_settings,
    print_warnings,
    robot_from_arguments,
    streaming_requested,
)
from oed.cli.identify_consistent import (
    add_consistent_arguments,
    check_consistent_arguments,
    consistent_settings,
    print_consistent,
)
from estimation.consistent.model_selection import select_model
from oed.cli.shared.verbs import verb_summary

STREAMED = "the streamed path (--chunk-size, --scheduler or --workers)"

#: what the in-memory identification holds at its peak: bytes a sample, channel and base parameter (the
#: stacked regressor and the prediction's; measured 3.5 KB a sample for the 7-joint KUKA, m r = 350)
IN_MEMORY = InMemoryBudget(2 * 8, "identifying", "use --chunk-size to stream them in bounded memory")


def register(subparsers: argparse._SubParsersAction) -> argparse.ArgumentParser:
    parser = subparsers.add_parser(
        "identify",
        help=verb_summary("identify"),
        description="Least-squares identification of the base parameters of the internal, external or combined "
        "model (PUMA paper, section IV) from a CSV/Parquet file (columns t, q1..qn [, dq.., ddq..], tau1..taun, "
        "fx fy fz mx my mz), with validation on another experiment.",
    )
    add_robot_arguments(parser)
    parser.add_argument("--model", choices=[kind.value for kind in ModelKind], default="internal", help="which model (default: internal)")
    parser.add_argument(
        "--friction", default="viscous",
        help="extra columns, comma-separated: viscous, coulomb, offset, armature, stribeck, spring, wrench_offset "
             "(default: viscous; 'none'); laws whose shape is estimated too (variable projection): coulomb:tanh "
             "(smoothing velocity), stribeck:velocity, sigmoid (Gaz et al. 2019), ripple (period in position); "
             "NAME[:VARIANT]@JOINTS for some joints (coulomb:tanh@1-4,offset@2+5); motor_viscous, motor_coulomb, "
             "motor_inertia on the transmission's motors; coulomb[q5+q6] on a joint combination; delay: a delay "
             "between torques and motion, one for the records, estimated within ±50 ms (delay:S: within ±S s)",
    )
    add_asbuilt_arguments(parser)
    add_data_arguments(parser, validate_required=False)
    parser.add_argument("--out", type=Path, required=True, help="result JSON file")
    parser.add_argument("--plot", type=Path, help="figure of measured vs predicted channels (.png, .pdf, .svg)")
    parser.add_argument("--method", choices=("auto", "wls", "ols"), default="auto",
                        help="auto (default): channel-weighted least squares unless ordinary least squares predicts "
                             "held-out blocks of the training data clearly better (method_selection in the JSON); "
                             "wls: channel-weighted; ols: ordinary")
    add_derivative_arguments(parser)
    add_jobs_argument(parser, "the derivative candidates' scores")
    add_streaming_arguments(parser)
    add_consistent_arguments(parser)
    return parser


def run_streaming(args: argparse.Namespace, robot: RobotModel, model: IdentificationModel,
                  plan: Preprocessing | None = None) -> int:
    """Identify from the files read chunk by chunk (:func:`estimation.streaming.identification.identify_files`), their
    derivatives chosen as in memory (``plan``: already chosen)."""
    chunk_size = DEFAULT_CHUNK_SIZE if args.chunk_size is None else args.chunk_size
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        if plan is None:
            plan = streamed_choice(args, model).chosen
        options = plan_options(plan)
        weighting = choose_weighting(model, weighting_samples(streamed_window(args.data, model), plan)) \
            if args.method == "auto" else None  # on the samples the in-memory path chooses it on
        with executor_from_arguments(args) as executor:
            result = identify_files(model, args.data, args.validate or [],
                                    method=args.method if weighting is None else weighting.method, chunk_size=chunk_size,
                                    cutoff_hz=options["cutoff_hz"], frequency_hz=options["frequency_hz"],
                                    harmonics=options["harmonics"], decimation=options["decimation"],
                                    held_torques=options["held_torques"], executor=executor)
    print_warnings("identify", caught)
    document = result.to_dict()
    document["preprocessing"] = plan.to_dict()
    if weighting is not None:
        document["method_selection"] = weighting.to_dict()
    add_streamed_model_file(document, args, result, chunk_size)
    with OutputFiles() as outputs, outputs.open(args.out) as stream:
        stream.write(json_text(document))
    estimate = result.estimate
    print(plan.describe())
    print(f"{robot.name}: {model.kind.value} model, {model.n_base} base parameters, {result.train.n_samples} samples "
          f"from {len(result.files)} file(s) in chunks of {chunk_size}, {estimate.method.upper()}, cond {estimate.cond:.4g}")
    if result.cov_method == "batch_means":
        print(f"standard deviations: batch means (batches of {result.batch_length} samples; a third pass over the files, "
              f"{result.seconds['covariance_pass']:.3g} s)")
    print_estimate(estimate)
    for label in ("train", "validation"):
        errors = document[label]
        if errors is not None:
            against, mse = ("vs recorded", errors["mse"]) if errors["mse"] is not None else \
                ("vs filtered: not against the recording", errors["mse_filtered"])
            print(f"{label} MSE ({against}): " + "  ".join(f"{channel} {value:.4g}" for channel, value in mse.items()))
    print(f"wrote {args.out}")
    return 0


def add_streamed_model_file(document: dict[str, Any], args: argparse.Namespace, result: Any, chunk_size: int) -> None:
    """The model file of the streamed identification. Its validation error is the one ``oed predict`` measures:
    against the channels as recorded, on the samples the in-memory preprocessing keeps; on the filter path (where
    the sums hold filtered channels) from one more pass over the validation files
    (:func:`estimation.streaming.recorded_errors.recorded_mse`); on the Fourier path none is reported."""
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
        validation = recorded_mse(result.model, result.estimate.values, args.validate, chunk_size=chunk_size,
                                  cutoff_hz=result.cutoff_hz, decimation=args.decimate,
                                  held_torques=bool(args.held_torques))
        document["validation"]["mse"] = validation
    add_summed_model_file(document, result.model, result.estimate, args, plan, verb="identify",
                          recorded_mse=document["train"]["mse"], validation_mse=validation)


def print_estimate(estimate: Any) -> None:
    """One line a base parameter: value, standard deviation and relative standard deviation."""
    width = max(len(name) for name in estimate.names)
    for record in estimate.records():
        relative = record["relative_std"]
        print(f"  {record['name']:<{width}}  {record['value']:+.5g} ± {record['std']:.2g}  ({relative:.3g} %)")


def run(args: argparse.Namespace) -> int:
    check_figure_path(args.plot)
    differentiation(args)  # contradicting derivative options are an error even when the data hold dq, ddq
    check_consistent_arguments(args)
    robot = robot_from_arguments(args)
    transmission = resolve_transmission(args, robot)
    args.friction, delay = split_delay(args.friction)  # the delay moves the motion: not a column effect
    effects = model_effects(args, robot, transmission)
    model = build_model(robot, args.model, effects)
    check_shaped_effects_kept(effects, model)
    check_model_request(args, model, delay)
    with show_progress("oed identify", quiet=args.quiet):
        if streaming_requested(args):
            check_streamed_request(args, model)
            return run_streaming(args, robot, model)
        decision = decide_path(args, model, verb="identify", task="identifying",
                               bytes_per_value=IN_MEMORY.bytes_per_value,
                               in_memory_only=lambda: in_memory_only(args, model, delay))
        if decision.stream:
            return run_streaming(args, robot, model, decision.plan)
        return run_in_memory(args, robot, model, transmission, delay, decision.plan)


def in_memory_only(args: argparse.Namespace, model: IdentificationModel, delay: DelayBounds | None) -> str | None:
    """The options given that the streamed identification lacks, in a few words, or ``None``."""
    if delay is not None:
        return "a delay is searched in memory"
    try:
        check_streamed_request(args, model)
    except ValueError as error:
        return str(error).split(":")[0] + " (not on the streamed path)"
    return None


def check_model_request(args: argparse.Namespace, model: IdentificationModel, delay: DelayBounds | None) -> None:
    """A delay only in memory without ``--consistent``; ``--consistent`` only without laws with shape parameters."""
    if delay is not None and (args.consistent or streaming_requested(args)):
        raise ValueError("a delay between torques and motion is searched in memory by the weighted least squares: "
                         "not with --consistent or the streamed path (--chunk-size, --scheduler or --workers)")
    if args.consistent and model_has_shapes(model):
        raise ValueError("--consistent refits the linear effects: laws with shape parameters (coulomb:tanh, sigmoid…) "
                         "are not supported there yet; declare their plain forms (coulomb) for the consistent fit")


def check_streamed_request(args: argparse.Namespace, model: IdentificationModel) -> None:
    """Options the streamed identification does not have: an error naming them, before anything is read."""
    if args.plot is not None:
        raise ValueError(f"--plot draws every sample: not with {STREAMED}")
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


def run_in_memory(args: argparse.Namespace, robot: RobotModel, model: IdentificationModel,
                  transmission: Transmission | None, delay: DelayBounds | None, plan: Preprocessing | None = None) -> int:
    """Read and prepare the records (:func:`estimation.identification.prepared.prepare_records`; ``plan``: the
    derivatives chosen before reading), identify, write, print."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        with step(f"read and prepared {len(args.data) + len(args.validate or ())} file(s)"):
            records = prepare_records(model, args.data, args.validate or (),
                                      settings=replace(preparation_settings(args, transmission, IN_MEMORY), plan=plan))
        train = records.train.measurements
        validation = None if records.validation is None else records.validation.measurements
        weighting = choose_weighting(model, weighting_samples(ChoiceWindow.of(records.train.segments),
                                                              records.preprocessing, train)) \
            if args.method == "auto" and delay is None and not model_has_shapes(model) else None
        base = weighting.method if weighting is not None else "ols" if args.method == "ols" else "wls"
        given = "consistent" if args.consistent else None if args.method == "auto" else args.method
        selection = select_model(model, train, validation, base=base, given=given, delay=delay,
                                 consistent=consistent_settings(args, robot))
        result, consistent = selection.unconstrained, selection.consistent
        trivial, notes = trivial_predictors(result, validation)
        floor_report = None if validation is None else floor_check(records, model, result, args.frequency)
        notes = (*notes, *above_floor_notes(floor_report))
        repeat = None if validation is None else repeated_motion_note(train, validation)
        notes = notes if repeat is None else (*notes, repeat)
    print_warnings("identify", caught)
    for note in notes:
        print(f"oed identify: warning: {note}", file=sys.stderr)
    rest = rest_records(records)
    document = finish_document(result.to_dict(), result, trivial=trivial, warnings=notes, rest=rest,
                               transmission=transmission)
    if consistent is not None:
        document.update(consistent.to_dict())
    if weighting is not None:
        document["method_selection"] = weighting.to_dict()
    document["model_selection"] = selection.to_dict()
    add_model_file(document, result, args, records.preprocessing, transmission, verb="identify", consistent=consistent,
                   selection=selection)
    if floor_report is not None and document.get("validation") is not None:
        document["validation"]["mse_over_floor"] = floor_report.ratios("after") or None
        document["noise_floor"] = None if floor_report.floor is None else {
            "mse": floor_report.floor.mse(), "method": floor_report.floor.method, "note": floor_report.floor_note}
    write_outputs(args, robot, model, result, document)
    print_summary(robot, model, result, records.preprocessing, train.n_samples, rest)
    if consistent is not None and (args.consistent or selection.chosen == "consistent"):
        print_consistent(consistent)
    for line in selection.lines():
        print(line)
    print(f"wrote {args.out}" + (f" and {args.plot}" if args.plot else ""))
    return 0


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


def write_outputs(args: argparse.Namespace, robot: RobotModel, model: IdentificationModel,
                  result: IdentificationResult, document: dict[str, Any]) -> None:
    """The result JSON and, with ``--plot``, the figure: all files or none."""
    with OutputFiles() as outputs:
        with outputs.open(args.out) as stream:
            stream.write(json_text(document))
        if args.plot is not None:
            comparisons = [result.train] + ([result.validation] if result.validation is not None else [])
            plot_comparison(comparisons, outputs.stage_figure(args.plot),
                            title=f"{robot.name}: {model.kind.value} model ({result.estimate.method})")


def print_summary(robot: RobotModel, model: IdentificationModel, result: IdentificationResult,
                  preprocessing: Preprocessing, n_samples: int, rest: dict[str, dict | None]) -> None:
    """The preprocessing, the estimate with its shape parameters, the errors and the rows at rest dropped."""
    estimate = result.estimate
    print(preprocessing.describe())
    print(f"{robot.name}: {model.kind.value} model, {model.n_base} base parameters, {n_samples} samples, "
          f"{estimate.method.upper()}, cond {estimate.cond:.4g}")
    print_estimate(estimate)
    width = max(len(name) for name in estimate.names)
    for value in result.shapes:
        bound = "  (at its bound)" if value.at_bound else ""
        print(f"  {value.name:<{width}}  {value.value:+.5g} ± {value.std:.2g}  (shape of {value.effect}){bound}")
    for label, comparison in (("train", result.train), ("validation", result.validation)):
        if comparison is not None:
            print(f"{label} MSE (vs recorded): " + "  ".join(f"{channel} {value:.4g}" for channel, value in comparison.mse.items()))
            if comparison.mse_filtered is not None:
                print(f"{label} MSE (vs filtered): " + "  ".join(
                    f"{channel} {value:.4g}" for channel, value in comparison.mse_filtered.items()))
    if rest_message("identify", rest):
        print(rest_message("identify", rest))
