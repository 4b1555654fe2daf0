"""``oed diagnose``: find what an identified model lacks in measured data, add it, report before/after."""

from __future__ import annotations

import argparse
import sys
import warnings
from pathlib import Path

from dynamics.models import ModelKind, build_model
from estimation.diagnosis import diagnose
from estimation.diagnosis_report import markdown_report, plot_residuals
from oed.cli.common import OutputFiles, add_robot_arguments, json_text, robot_from_arguments
from oed.cli.identify import add_derivative_arguments, check_shaped_effects_kept, differentiation, prepare


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
                        "such as coulomb:tanh included; default: viscous)")
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


def derived_outputs(args: argparse.Namespace) -> dict[str, Path]:
    """Files written besides the named outputs (checked against them by :func:`oed.cli.paths.check_paths`)."""
    return {} if args.report is None else {"the report's residual figure": residual_figure(args.report)}


def run(args: argparse.Namespace) -> int:
    if args.data.expanduser().resolve() == args.validate.expanduser().resolve():
        raise ValueError(f"--validate is --data ({args.data}): diagnose confirms every effect on held-out data "
                         "from another experiment")
    differentiation(args)  # contradicting derivative options are an error even when the data hold dq, ddq
    robot = robot_from_arguments(args)
    model = build_model(robot, args.model, args.friction)
    check_shaped_effects_kept(args.friction, model)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        train = prepare(args.data, model, args)
        validate = prepare(args.validate, model, args)
        diagnosis = diagnose(model, train, validate, alpha=args.alpha)
    for message in dict.fromkeys(str(warning.message) for warning in caught):  # once each, in order
        print(f"oed diagnose: warning: {message}", file=sys.stderr)
    with OutputFiles() as outputs:  # all files or none
        with outputs.open(args.out) as stream:
            stream.write(json_text(diagnosis.to_dict()))
        if args.report is not None:
            figure = residual_figure(args.report)
            plot_residuals(diagnosis, train, outputs.stage_figure(figure))
            with outputs.open(args.report) as stream:
                stream.write(markdown_report(diagnosis, figure.name))
    print_summary(diagnosis)
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
    print("validation MSE   " + "  ".join(f"{channel:>9s}" for channel in before))
    print("  before         " + "  ".join(f"{value:9.4g}" for value in before.values()))
    print("  after          " + "  ".join(f"{after[channel]:9.4g}" for channel in before))
