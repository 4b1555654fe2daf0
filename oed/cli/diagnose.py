"""``oed diagnose``: find what an identified model lacks in measured data, add it, report before/after."""

from __future__ import annotations

import argparse
import sys
import warnings
from pathlib import Path

from dynamics.models import ModelKind, build_model
from estimation.preprocessing.delay import DelayBounds, split_delay
from estimation.diagnosis.coupling_candidates import coupling_candidates
from estimation.diagnosis.search import default_candidates, diagnose
from estimation.diagnosis.report import markdown_report, plot_residuals, plot_trace
from estimation.data.motor_side import read_record_with_transmission
from estimation.uncertainty.noise_floor import NoiseFloor, NoiseFloorError, noise_floor, pooled_floor
from oed.cli.asbuilt import (add_asbuilt_arguments, finish_document, model_effects, resolve_transmission, rest_message,
                             rest_rows, trivial_predictors, worse_after)
from oed.cli.common import OutputFiles, add_robot_arguments, json_text, robot_from_arguments
from oed.cli.model_files import add_model_file
from oed.cli.diagnose_streaming import add_streamed_diagnosis_arguments, check_in_memory_diagnosis, run_streaming
from oed.cli.identify import (add_data_arguments, add_derivative_arguments, add_streaming_arguments,
                              check_shaped_effects_kept, differentiation, prepare_data, print_warnings,
                              streaming_requested)


def register(subparsers: argparse._SubParsersAction) -> argparse.ArgumentParser:
    parser = subparsers.add_parser(
        "diagnose",
        help="find the effects a model lacks in measured data and report the error before and after",
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
    parser.add_argument("--out", type=Path, required=True, help="report JSON")
    parser.add_argument("--report", type=Path, help="Markdown report (a residual figure is written beside it)")
    parser.add_argument("--alpha", type=float, default=1e-3, help="significance level of the F test (default 1e-3)")
    parser.add_argument("--max-effects", type=int, default=20, metavar="N",
                        help="add at most N effects (default 20); the output says when the cap stopped the search")
    add_derivative_arguments(parser)
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
    """Files written besides the named outputs (checked against them by :func:`oed.cli.paths.check_paths`)."""
    if args.report is None:
        return {}
    return {"the report's residual figure": residual_figure(args.report),
            "the report's tracing figure": trace_figure(args.report)}


def recorded_floor(paths: list[Path], model, args: argparse.Namespace, transmission=None,
                   frequency_hz: float | None = None) -> NoiseFloor | None:
    """The noise floor of the validation record as loaded, before any differentiation, averaging or
    filtering (period-to-period at ``frequency_hz`` (given or detected) or the file's frequency, else
    differences), pooled over the segments that can give one; ``None`` with a warning when none can."""
    floors, failures = [], []
    for path in paths:
        for segment in read_record_with_transmission(path, model=model, transmission=transmission,
                                                     max_gap=args.max_gap, split=False):
            try:
                floors.append(noise_floor(segment, model.channels, frequency_hz=frequency_hz))
            except NoiseFloorError as error:
                failures.append(f"{path}: {error}")
    if failures:
        warnings.warn("no noise floor from " + "; ".join(failures)
                      + ("" if floors else " (the floor is then estimated from the prepared validation data, if they "
                         "can give one)"), stacklevel=2)
    return pooled_floor(floors)


def run(args: argparse.Namespace) -> int:
    training = {path.expanduser().resolve(): path for path in args.data}
    for path in args.validate:
        if path.expanduser().resolve() in training:
            raise ValueError(f"--validate is --data ({path}): diagnose confirms every effect on held-out data "
                             "from another experiment")
    if isinstance(args.max_effects, bool) or args.max_effects < 1:
        raise ValueError(f"--max-effects must be a positive integer, got {args.max_effects}")
    differentiation(args)  # contradicting derivative options are an error even when the data hold dq, ddq
    args.friction, delay = split_delay(args.friction)  # a candidate in every diagnosis: 'delay:S' sets its bound
    if streaming_requested(args):  # bounded memory (estimation.streaming.diagnosis)
        if delay is not None:
            raise ValueError("the delay between torques and motion is searched in memory: not with the streamed path "
                             "(--chunk-size, --scheduler or --workers), which does not try it")
        return run_streaming(args)
    robot = robot_from_arguments(args)
    transmission = resolve_transmission(args, robot)
    effects = model_effects(args, robot, transmission)
    model = build_model(robot, args.model, effects)
    check_shaped_effects_kept(effects, model)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        train, validate, preprocessing = prepare_data(model, args, transmission)
        check_in_memory_diagnosis(model, train, validate)
        train, rest_train = rest_rows(train, model, args, "train")
        validate, rest_validate = rest_rows(validate, model, args, "validation")
        candidates = default_candidates(model) + coupling_candidates(model, transmission, train=train)
        frequency = preprocessing.frequency_hz if preprocessing.method == "fourier" else args.frequency
        floor = recorded_floor(args.validate, model, args, transmission, frequency)
        diagnosis = diagnose(model, train, validate, alpha=args.alpha, candidates=candidates,
                             max_effects=args.max_effects, noise_floor=floor, delay=delay or DelayBounds())
        trivial, notes = trivial_predictors(diagnosis.after, validate)
        notes += worse_after(diagnosis)
    print_warnings("diagnose", caught)
    for note in notes:
        print(f"oed diagnose: warning: {note}", file=sys.stderr)
    rest_record = {"train": rest_train, "validation": rest_validate}
    document = finish_document(diagnosis.to_dict(), diagnosis.after, trivial=trivial, warnings=notes, rest=rest_record,
                               transmission=transmission, warnings_key=("warnings", "after"))
    document["preprocessing"] = preprocessing.to_dict()
    document["diagnosis_path"] = "in-memory"  # "streamed": --chunk-size (oed.cli.diagnose_streaming)
    document["max_effects"] = args.max_effects
    document["max_effects_reached"] = len(diagnosis.effects) >= args.max_effects
    add_model_file(document, diagnosis.after, args, preprocessing, transmission, verb="diagnose")
    with OutputFiles() as outputs:  # all files or none
        with outputs.open(args.out) as stream:
            stream.write(json_text(document))
        if args.report is not None:
            figure = residual_figure(args.report)
            plot_residuals(diagnosis, train, outputs.stage_figure(figure))
            tracing = trace_figure(args.report)
            plot_trace(diagnosis, validate, outputs.stage_figure(tracing))
            with outputs.open(args.report) as stream:
                stream.write(markdown_report(diagnosis, figure.name, tracing.name) + f"\n{preprocessing.describe()[0].upper()}"
                             f"{preprocessing.describe()[1:]}; validation MSEs against the recorded channels.\n")
    print(preprocessing.describe())
    print_summary(diagnosis)
    if len(diagnosis.effects) >= args.max_effects:
        untested = sum(rejected.reason.startswith("not tested") for rejected in diagnosis.rejected)
        print(f"stopped at --max-effects {args.max_effects}: {untested} candidate(s) not tested; raise --max-effects "
              "to test them")
    if rest_message("diagnose", rest_record):
        print(rest_message("diagnose", rest_record))
    print(f"wrote {args.out}" + (f" and {args.report}" if args.report else ""))
    return 0


def print_summary(diagnosis) -> None:
    """Effects found and the validation MSE per channel before and after."""
    if diagnosis.effects:
        for effect in diagnosis.effects:
            values = ", ".join(f"{n} = {v:.4g} ± {s:.2g}" for n, v, s in zip(effect.parameters, effect.values, effect.std))
            values += "".join(f", {n} = {v:.4g} ± {effect.shape_std[n]:.2g}" for n, v in effect.shape.items())
            print(f"found {effect.spec or effect.name} on {', '.join(effect.channels)}: {values} (p = {effect.p_value:.2g})")
    else:
        print("found nothing: the declared model explains the data")
    before, after = diagnosis.before.validation.mse, diagnosis.after.validation.mse
    print("validation MSE vs recorded")
    print("                 " + "  ".join(f"{channel:>9s}" for channel in before))
    print("  before         " + "  ".join(f"{value:9.4g}" for value in before.values()))
    print("  after          " + "  ".join(f"{after[channel]:9.4g}" for channel in before))
    print_floor(diagnosis)


def print_floor(diagnosis) -> None:
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
