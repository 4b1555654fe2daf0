"""``oed diagnose``: find what an identified model lacks in measured data, add it, report before/after."""

from __future__ import annotations

import argparse
import sys
import warnings
from pathlib import Path

from dynamics.models import ModelKind, build_model
from estimation.coupling_candidates import coupling_candidates
from estimation.diagnosis import default_candidates, diagnose
from estimation.diagnosis_report import markdown_report, plot_residuals
from oed.cli.asbuilt import (add_asbuilt_arguments, finish_document, model_effects, resolve_transmission, rest_message,
                             rest_rows, trivial_predictors, worse_after)
from oed.cli.common import OutputFiles, add_robot_arguments, json_text, robot_from_arguments
from oed.cli.identify import add_data_arguments, add_derivative_arguments, differentiation, prepare_data, print_warnings


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
    parser.add_argument("--friction", default="viscous", help="declared effects (default: viscous; the grammar of "
                        "oed identify --friction: coulomb@1-4, motor_coulomb, coulomb[q5+q6])")
    add_asbuilt_arguments(parser)
    add_data_arguments(parser, validate_required=True)
    parser.add_argument("--out", type=Path, required=True, help="report JSON")
    parser.add_argument("--report", type=Path, help="Markdown report (a residual figure is written beside it)")
    parser.add_argument("--alpha", type=float, default=1e-3, help="significance level of the F test (default 1e-3)")
    parser.add_argument("--max-effects", type=int, default=10, metavar="N",
                        help="add at most N effects (default 10); the output says when the cap stopped the search")
    add_derivative_arguments(parser)
    return parser


def residual_figure(report: Path) -> Path:
    """The residual figure written beside the Markdown report."""
    return report.with_suffix(".residuals.png")


def derived_outputs(args: argparse.Namespace) -> dict[str, Path]:
    """Files written besides the named outputs (checked against them by :func:`oed.cli.paths.check_paths`)."""
    return {} if args.report is None else {"the report's residual figure": residual_figure(args.report)}


def run(args: argparse.Namespace) -> int:
    training = {path.expanduser().resolve(): path for path in args.data}
    for path in args.validate:
        if path.expanduser().resolve() in training:
            raise ValueError(f"--validate is --data ({path}): diagnose confirms every effect on held-out data "
                             "from another experiment")
    if isinstance(args.max_effects, bool) or args.max_effects < 1:
        raise ValueError(f"--max-effects must be a positive integer, got {args.max_effects}")
    differentiation(args)  # contradicting derivative options are an error even when the data hold dq, ddq
    robot = robot_from_arguments(args)
    transmission = resolve_transmission(args, robot)
    model = build_model(robot, args.model, model_effects(args, robot, transmission))
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        train, validate, preprocessing = prepare_data(model, args, transmission)
        train, rest_train = rest_rows(train, model, args, "train")
        validate, rest_validate = rest_rows(validate, model, args, "validation")
        candidates = default_candidates(model) + coupling_candidates(model, transmission, train=train)
        diagnosis = diagnose(model, train, validate, alpha=args.alpha, candidates=candidates,
                             max_effects=args.max_effects)
        trivial, notes = trivial_predictors(diagnosis.after, validate)
        notes += worse_after(diagnosis)
    print_warnings("diagnose", caught)
    for note in notes:
        print(f"oed diagnose: warning: {note}", file=sys.stderr)
    rest_record = {"train": rest_train, "validation": rest_validate}
    document = finish_document(diagnosis.to_dict(), diagnosis.after, trivial=trivial, warnings=notes, rest=rest_record,
                               transmission=transmission, warnings_key=("warnings", "after"))
    document["preprocessing"] = preprocessing.to_dict()
    document["max_effects"] = args.max_effects
    document["max_effects_reached"] = len(diagnosis.effects) >= args.max_effects
    with OutputFiles() as outputs:  # all files or none
        with outputs.open(args.out) as stream:
            stream.write(json_text(document))
        if args.report is not None:
            figure = residual_figure(args.report)
            plot_residuals(diagnosis, train, outputs.stage_figure(figure))
            with outputs.open(args.report) as stream:
                stream.write(markdown_report(diagnosis, figure.name) + f"\n{preprocessing.describe()[0].upper()}"
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
            print(f"found {effect.name} on {', '.join(effect.channels)}: {values} (p = {effect.p_value:.2g})")
    else:
        print("found nothing: the declared model explains the data")
    before, after = diagnosis.before.validation.mse, diagnosis.after.validation.mse
    print("validation MSE vs recorded")
    print("                 " + "  ".join(f"{channel:>9s}" for channel in before))
    print("  before         " + "  ".join(f"{value:9.4g}" for value in before.values()))
    print("  after          " + "  ".join(f"{after[channel]:9.4g}" for channel in before))
