"""``oed diagnose``: find what an identified model lacks in measured data, add it, report before/after."""

from __future__ import annotations

import argparse
import functools
import sys
import warnings
from dataclasses import replace
from pathlib import Path
from typing import Any

from dynamics.models import IdentificationModel, ModelKind, build_model
from dynamics.runtime.processes import run_tasks, worker_count
from dynamics.runtime.progress import show_progress, step
from dynamics.transmission import Transmission
from estimation.diagnosis.candidates.coupling import coupling_candidates
from estimation.diagnosis.report import markdown_report, plot_residuals, plot_trace
from estimation.diagnosis.results import Diagnosis, runner_up_line
from estimation.diagnosis.search import default_candidates, diagnose
from estimation.diagnosis.untouched import UntouchedErrors, untouched_errors
from estimation.preprocessing.delay import DelayBounds, split_delay
from estimation.preprocessing.plan import Preprocessing
from estimation.uncertainty.noise_floor import NoiseFloor
from estimation.identification.prepared import (
    InMemoryBudget,
    PreparedRecords,
    prepare_records,
)
from oed.cli.shared.asbuilt import (
    add_asbuilt_arguments,
    finish_document,
    model_effects,
    resolve_transmission,
    rest_message,
    rest_records,
    trivial_predictors,
    worse_after,
)
from oed.cli.shared.common import (
    OutputFiles,
    add_data_arguments,
    add_derivative_arguments,
    add_jobs_argument,
    add_robot_arguments,
    add_streaming_arguments,
    check_shaped_effects_kept,
    differentiation,
    json_text,
    preparation_settings,
    print_warnings,
    robot_from_arguments,
    streaming_requested,
)
from oed.cli.diagnose_streaming import add_streamed_diagnosis_arguments, check_streamed_arguments, run_streaming
from estimation.identification.repeated_motion import repeated_motion_note
from oed.cli.shared.memory_path import decide_path
from oed.cli.shared.model_files import add_model_file, add_runner_up_model_file
from oed.cli.shared.verbs import verb_summary

#: what the in-memory diagnosis holds at its peak: bytes a sample, channel and base parameter (measured: 2.8 GB
#: for 100 000 samples of the 7-joint KUKA, m r = 350, i.e. about 75; a lower bound is used)
IN_MEMORY = InMemoryBudget(64, "diagnosing", "use --chunk-size to stream them in bounded memory")


def register(subparsers: argparse._SubParsersAction) -> argparse.ArgumentParser:
    parser = subparsers.add_parser(
        "diagnose",
        help=verb_summary("diagnose"),
        description="Identify the declared model, test candidate effects (Coulomb, offsets, armature, Stribeck, "
        "springs, plate offsets) by forward selection on the training data, keep only those that lower the "
        "validation error, and report the validation MSE per channel before and after.",
    )
    add_robot_arguments(parser)
    parser.add_argument("--model", choices=[kind.value for kind in ModelKind], default="internal")
    parser.add_argument("--friction", default="viscous", help="declared effects, as for `oed identify` (shaped laws "
                        "such as coulomb:tanh, per-joint coulomb@1-4, motor_coulomb, coulomb[q5+q6]; default: viscous); "
                        "a delay between torques and motion is always a candidate, delay:S bounds it to ±S s")
    add_asbuilt_arguments(parser)
    add_data_arguments(parser, validate_required=True)
    parser.add_argument("--test", type=Path, action="append", default=None,
                        help="test data from a third experiment, never used for a decision: the error before and after "
                             "on it is the one to quote (test{before,after} in the report); repeatable like --data")
    parser.add_argument("--out", type=Path, required=True, help="report JSON")
    parser.add_argument("--report", type=Path, help="Markdown report (a residual figure is written beside it)")
    parser.add_argument("--alpha", type=float, default=1e-3, help="significance level of the F test (default 1e-3)")
    parser.add_argument("--unseen-stretches", action="store_true",
                        help="when --validate repeats the training motion, also refuse an effect that raises the error "
                             "on the stretches of the motion its fit did not see (off by default)")
    parser.add_argument("--max-effects", type=int, default=20, metavar="N",
                        help="add at most N effects (default 20); the output says when the cap stopped the search")
    add_derivative_arguments(parser)
    add_jobs_argument(parser, "the derivative candidates' scores and each round's candidate fits")
    add_streaming_arguments(parser)
    add_streamed_diagnosis_arguments(parser)
    return parser


def residual_figure(report: Path) -> Path:
    """The residual figure written beside the Markdown report."""
    return report.with_suffix(".residuals.png")


def trace_figure(report: Path) -> Path:
    """The figure of the residual against its strongest variables, beside the Markdown report."""
    return report.with_suffix(".trace.png")


def derived_outputs(args: argparse.Namespace) -> dict[str, Path]:
    """Files written besides the named outputs (checked against them by :func:`oed.cli.shared.paths.check_paths`)."""
    if args.report is None:
        return {}
    return {"the report's residual figure": residual_figure(args.report),
            "the report's tracing figure": trace_figure(args.report)}


def run(args: argparse.Namespace) -> int:
    check_request(args)
    differentiation(args)  # contradicting derivative options are an error even when the data hold dq, ddq
    args.friction, delay = split_delay(args.friction)  # a candidate in every diagnosis: 'delay:S' sets its bound
    with show_progress("oed diagnose", quiet=args.quiet):
        if streaming_requested(args):  # bounded memory (estimation.streaming.diagnosis)
            check_streamed_request(args, delay)
            return run_streaming(args)
        robot = robot_from_arguments(args)
        transmission = resolve_transmission(args, robot)
        effects = model_effects(args, robot, transmission)
        model = build_model(robot, args.model, effects)
        check_shaped_effects_kept(effects, model)
        decision = decide_path(args, model, verb="diagnose", task="diagnosing", bytes_per_value=IN_MEMORY.bytes_per_value,
                               in_memory_only=lambda: in_memory_only(args, model, delay))
        if decision.stream:
            return run_streaming(args, decision.plan)
        return run_in_memory(args, model, transmission, delay, decision.plan)


def check_streamed_request(args: argparse.Namespace, delay: DelayBounds | None) -> None:
    """``--test`` and a delay are in-memory only: an error when the streamed path was asked for."""
    if args.test:
        raise ValueError("--test is read in memory: not with the streamed path (--chunk-size, --scheduler or "
                         "--workers)")
    if delay is not None:
        raise ValueError("the delay between torques and motion is searched in memory: not with the streamed path "
                         "(--chunk-size, --scheduler or --workers), which does not try it")


def in_memory_only(args: argparse.Namespace, model: IdentificationModel, delay: DelayBounds | None) -> str | None:
    """The options given that the streamed diagnosis lacks, in a few words, or ``None``."""
    try:
        check_streamed_request(args, delay)
        check_streamed_arguments(args, model)
    except ValueError as error:
        return str(error).split(":")[0] + " (not on the streamed path)"
    return None


def run_in_memory(args: argparse.Namespace, model: IdentificationModel, transmission: Transmission | None,
                  delay: DelayBounds | None, plan: Preprocessing | None) -> int:
    """Read and prepare the records (``plan``: the derivatives chosen before reading), diagnose, write, print."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        with step(f"read and prepared {len(args.data) + len(args.validate) + len(args.test or ())} file(s)"):
            records = prepare_records(model, args.data, args.validate, args.test or (),
                                      settings=replace(preparation_settings(args, transmission, IN_MEMORY), plan=plan))
        validation_floor, test_floor = record_floors(records, model, args.frequency, args.jobs)
        with step("diagnosis in memory"):
            diagnosis = diagnose_records(args, model, transmission, records, delay, validation_floor)
        untouched = test_errors(records, diagnosis, test_floor)
        trivial, notes = trivial_predictors(diagnosis.after, records.validation.measurements)
        notes += worse_after(diagnosis)
        repeat = repeated_motion_note(records.train.measurements, records.validation.measurements)
        notes += () if repeat is None else (repeat,)
    print_warnings("diagnose", caught)
    for note in notes:
        print(f"oed diagnose: warning: {note}", file=sys.stderr)
    rest = rest_records(records)
    document = finish_document(diagnosis.to_dict(), diagnosis.after, trivial=trivial, warnings=notes, rest=rest,
                               transmission=transmission, warnings_key=("warnings", "after"))
    document["preprocessing"] = records.preprocessing.to_dict()
    document["test"] = None if untouched is None else untouched.to_dict()
    add_model_file(document, diagnosis.after, args, records.preprocessing, transmission, verb="diagnose")
    add_runner_up_model_file(document, diagnosis.runner_up, args, records.preprocessing, transmission)
    document["diagnosis_path"] = "in-memory"  # "streamed": --chunk-size (oed.cli.diagnose_streaming)
    document["max_effects"] = args.max_effects
    document["max_effects_reached"] = len(diagnosis.effects) >= args.max_effects
    write_outputs(args, diagnosis, records, document, untouched)
    print(records.preprocessing.describe())
    print_summary(diagnosis)
    print_test(untouched)
    if len(diagnosis.effects) >= args.max_effects:
        untested = sum(rejected.reason.startswith("not tested") for rejected in diagnosis.rejected)
        print(f"stopped at --max-effects {args.max_effects}: {untested} candidate(s) not tested; raise --max-effects "
              "to test them")
    if rest_message("diagnose", rest):
        print(rest_message("diagnose", rest))
    print(f"wrote {args.out}" + (f" and {args.report}" if args.report else ""))
    return 0


def check_request(args: argparse.Namespace) -> None:
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


def diagnose_records(args: argparse.Namespace, model: IdentificationModel, transmission: Transmission | None,
                     records: PreparedRecords, delay: DelayBounds | None, floor: NoiseFloor | None) -> Diagnosis:
    """The diagnosis of the prepared records; ``floor``: the validation record's as recorded (:func:`record_floors`)."""
    train, validation = records.train.measurements, records.validation.measurements
    candidates = default_candidates(model) + coupling_candidates(model, transmission, train=train)
    return diagnose(model, train, validation, alpha=args.alpha, candidates=candidates, max_effects=args.max_effects,
                    noise_floor=floor, delay=delay or DelayBounds(), jobs=args.jobs,
                    unseen_stretches=getattr(args, "unseen_stretches", False))


def test_errors(records: PreparedRecords, diagnosis: Diagnosis, floor: NoiseFloor | None) -> UntouchedErrors | None:
    """The errors on the ``--test`` record (:mod:`estimation.diagnosis.untouched`); ``floor``: its floor from the files
    as read (:func:`record_floors`)."""
    if records.test is None:
        return None
    return untouched_errors(diagnosis, records.test.measurements, floor)


def print_test(untouched: UntouchedErrors | None) -> None:
    """The test record's MSE before and after, or a note that the 'after' error was measured on data the choices used."""
    if untouched is None:
        print("note: the 'after' error above is on the --validate record, which chose the effects: it is optimistic; "
              "give --test FILE (a third record) for an error no choice saw")
        return
    print("test MSE vs recorded (a record no choice used)")
    print("  before         " + "  ".join(f"{value:9.4g}" for value in untouched.before.values()))
    print("  after          " + "  ".join(f"{value:9.4g}" for value in untouched.after.values()))
    ratios = untouched.over_floor("after")
    if ratios:
        print("  after / floor  " + "  ".join(f"{ratios.get(channel, float('nan')):9.3g}" for channel in untouched.after))


def markdown_test(untouched: UntouchedErrors | None) -> str:
    """The report's section on the test record."""
    if untouched is None:
        return ("\nThe 'after' error is measured on the validation record, which chose the effects: it is optimistic. "
                "Give `--test FILE` (a third record) for an error no choice saw.\n")
    ratios = untouched.over_floor("after") or {}
    rows = "".join(f"| {channel} | {untouched.before[channel]:.4g} | {value:.4g} | "
                   f"{ratios[channel]:.3g} |\n" if channel in ratios else
                   f"| {channel} | {untouched.before[channel]:.4g} | {value:.4g} | n/a |\n"
                   for channel, value in untouched.after.items())
    return ("\n## Test record (no choice used it)\n\n| channel | MSE before | MSE after | after / floor |\n"
            "|---|---|---|---|\n" + rows)


def write_outputs(args: argparse.Namespace, diagnosis: Diagnosis, records: PreparedRecords, document: dict[str, Any],
                  untouched: UntouchedErrors | None = None) -> None:
    """The report JSON and, with ``--report``, the Markdown report and its two figures: all files or none."""
    preprocessing: Preprocessing = records.preprocessing
    with OutputFiles() as outputs:
        with outputs.open(args.out) as stream:
            stream.write(json_text(document))
        if args.report is not None:
            figure = residual_figure(args.report)
            plot_residuals(diagnosis, records.train.measurements, outputs.stage_figure(figure))
            tracing = trace_figure(args.report)
            plot_trace(diagnosis, records.validation.measurements, outputs.stage_figure(tracing))
            with outputs.open(args.report) as stream:
                stream.write(markdown_report(diagnosis, figure.name, tracing.name) + f"\n{preprocessing.describe()[0].upper()}"
                             f"{preprocessing.describe()[1:]}; validation MSEs against the recorded channels.\n"
                             + markdown_test(untouched))


def print_summary(diagnosis: Diagnosis) -> None:
    """Effects found and the validation MSE per channel before and after."""
    if diagnosis.effects:
        for effect in diagnosis.effects:
            values = ", ".join(f"{n} = {v:.4g} ± {s:.2g}" for n, v, s in zip(effect.parameters, effect.values, effect.std))
            values += "".join(f", {n} = {v:.4g} ± {effect.shape_std[n]:.2g}" for n, v in effect.shape.items())
            print(f"found {effect.spec or effect.name} on {', '.join(effect.channels)}: {values} (p = {effect.p_value:.2g})")
    else:
        print("found nothing: the declared model explains the data")
    print(runner_up_line(diagnosis.runner_up, diagnosis.runner_up_reason))
    before, after = diagnosis.before.validation.mse, diagnosis.after.validation.mse
    print("validation MSE vs recorded")
    print("                 " + "  ".join(f"{channel:>9s}" for channel in before))
    print("  before         " + "  ".join(f"{value:9.4g}" for value in before.values()))
    print("  after          " + "  ".join(f"{after[channel]:9.4g}" for channel in before))
    print_floor(diagnosis)


def print_floor(diagnosis: Diagnosis) -> None:
    """The noise floor per channel and how far above it each channel stays."""
    statistics = diagnosis.statistics
    if statistics is None:
        return
    if statistics.floor is None:
        print(statistics.floor_note)
        return
    floor = statistics.floor.mse()
    print("  noise floor    " + "  ".join(f"{floor[channel]:9.4g}" for channel in floor)
          + f"   ({statistics.floor.method}; {statistics.floor_note})")
    ratios = statistics.ratios("after")
    print("  after / floor  " + "  ".join(f"{ratios[channel]:9.3g}" for channel in floor))
    for text in statistics.statements.values():
        print(f"  {text}")
