"""``oed diagnose``: find what an identified model lacks in measured data, add it, report before/after."""

from __future__ import annotations

import argparse
import sys
import warnings
from pathlib import Path

from dynamics.models import ModelKind, build_model
from estimation.diagnosis import diagnose
from estimation.diagnosis_report import markdown_report, plot_residuals, plot_trace
from estimation.loading import read_measurements
from estimation.noise_floor import NoiseFloor, NoiseFloorError, noise_floor
from oed.cli.common import OutputFiles, add_robot_arguments, json_text, robot_from_arguments
from oed.cli.identify import add_derivative_arguments, differentiation, prepare


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
    parser.add_argument("--friction", default="viscous", help="declared effects (default: viscous)")
    parser.add_argument("--data", type=Path, required=True, help="training data (.csv or .parquet)")
    parser.add_argument("--validate", type=Path, required=True, help="held-out data from another experiment")
    parser.add_argument("--out", type=Path, required=True, help="report JSON")
    parser.add_argument("--report", type=Path, help="Markdown report (a residual figure is written beside it)")
    parser.add_argument("--alpha", type=float, default=1e-3, help="significance level of the F test (default 1e-3)")
    add_derivative_arguments(parser)
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


def recorded_floor(path: Path, model, args: argparse.Namespace) -> NoiseFloor | None:
    """The noise floor of a record as loaded, before any differentiation, averaging or filtering
    (period-to-period with ``--frequency`` or the file's frequency, else differences); ``None``
    with a warning when the record cannot give one."""
    recorded = read_measurements(path, model=model)
    try:
        return noise_floor(recorded, model.channels, frequency_hz=args.frequency)
    except NoiseFloorError as error:
        warnings.warn(f"no noise floor from {path}: {error}", stacklevel=2)
        return None


def run(args: argparse.Namespace) -> int:
    if args.data.expanduser().resolve() == args.validate.expanduser().resolve():
        raise ValueError(f"--validate is --data ({args.data}): diagnose confirms every effect on held-out data "
                         "from another experiment")
    differentiation(args)  # contradicting derivative options are an error even when the data hold dq, ddq
    robot = robot_from_arguments(args)
    model = build_model(robot, args.model, args.friction)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        train = prepare(args.data, model, args)
        validate = prepare(args.validate, model, args)
        floor = recorded_floor(args.validate, model, args)
        diagnosis = diagnose(model, train, validate, alpha=args.alpha, noise_floor=floor)
    for message in dict.fromkeys(str(warning.message) for warning in caught):  # once each, in order
        print(f"oed diagnose: warning: {message}", file=sys.stderr)
    with OutputFiles() as outputs:  # all files or none
        with outputs.open(args.out) as stream:
            stream.write(json_text(diagnosis.to_dict()))
        if args.report is not None:
            figure = residual_figure(args.report)
            plot_residuals(diagnosis, train, outputs.stage_figure(figure))
            tracing = trace_figure(args.report)
            plot_trace(diagnosis, validate, outputs.stage_figure(tracing))
            with outputs.open(args.report) as stream:
                stream.write(markdown_report(diagnosis, figure.name, tracing.name))
    print_summary(diagnosis)
    print(f"wrote {args.out}" + (f" and {args.report}" if args.report else ""))
    return 0


def print_summary(diagnosis) -> None:
    """Effects found and the validation MSE per channel before and after."""
    if diagnosis.effects:
        for effect in diagnosis.effects:
            values = ", ".join(f"{n} = {v:.4g} ± {s:.2g}" for n, v, s in zip(effect.parameters, effect.values, effect.std))
            print(f"found {effect.name} on {', '.join(effect.channels)}: {values} (p = {effect.p_value:.2g})")
    else:
        print("found nothing: the declared model explains the data")
    before, after = diagnosis.before.validation.mse, diagnosis.after.validation.mse
    print("validation MSE   " + "  ".join(f"{channel:>9s}" for channel in before))
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
    print(f"  noise floor    " + "  ".join(f"{floor[channel]:9.4g}" for channel in floor)
          + f"   ({statistics.floor.method}; {statistics.floor_note})")
    ratios = statistics.ratios("after")
    print("  after / floor  " + "  ".join(f"{ratios[channel]:9.3g}" for channel in floor))
    for text in statistics.statements.values():
        print(f"  {text}")
