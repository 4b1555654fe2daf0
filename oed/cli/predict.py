"""``oed predict``: an identified model (result.json or report.json) applied to another record."""

from __future__ import annotations

import argparse
import sys
import warnings
from pathlib import Path

import pandas as pd

from estimation.identification.identified_model import IdentifiedModel
from estimation.identification.trivial_predictors import trivial_warnings
from oed.cli.shared.common import OutputFiles, check_csv_path, check_json_path, json_text
from oed.cli.shared.verbs import verb_summary


def register(subparsers: argparse._SubParsersAction) -> argparse.ArgumentParser:
    parser = subparsers.add_parser(
        "predict",
        help=verb_summary("predict"),
        description="Load the model of a result.json (oed identify) or report.json (oed diagnose), derive the "
        "motion of the record as the model's preprocessing says, predict its channels with 95 %% prediction bands "
        "and compare them with the channels as recorded (MSE per channel, beside a zero prediction and the "
        "nominal description).",
    )
    parser.add_argument("--model", type=Path, required=True, help="result.json or report.json holding a model_file")
    parser.add_argument("--data", type=Path, required=True, action="append",
                        help="the record (.csv or .parquet); repeat for several segments of one record")
    parser.add_argument("--alternative", metavar="NAME",
                        help="predict with the alternative model NAME the file holds beside the chosen one (ols, wls, "
                             "consistent; unconstrained: the unconstrained fit behind the choice); default: the model "
                             "the verb chose (model_selection.chosen)")
    parser.add_argument("--consistent", action="store_true",
                        help="the same as --alternative consistent: the physically consistent estimate, what "
                             "`oed export` writes")
    parser.add_argument("--out", type=Path, help="predictions CSV: t, each channel, and its _lo/_hi 95 %% band")
    parser.add_argument("--metrics", type=Path, help="metrics JSON: mse, mse_over_floor, n_samples, zero_mse, "
                                                     "nominal_mse, noise_floor_mse, reported_validation_mse")
    return parser


def derived_outputs(args: argparse.Namespace) -> dict[str, Path]:
    """``--metrics``, checked with ``--out`` against the inputs (:func:`oed.cli.shared.paths.check_paths`)."""
    return {} if args.metrics is None else {"--metrics": args.metrics}


def check_not_model(args: argparse.Namespace, *outputs: tuple[str, Path | None]) -> None:
    """Refuse an output that is the model file itself (it would be overwritten)."""
    model = args.model.expanduser().resolve()
    for option, path in outputs:
        if path is not None and path.expanduser().resolve() == model:
            raise ValueError(f"{option} {path} is the model file (--model): it would be overwritten; write elsewhere")


def run(args: argparse.Namespace) -> int:
    check_not_model(args, ("--out", args.out), ("--metrics", args.metrics))
    if args.out is not None:
        check_csv_path(args.out)
    if args.metrics is not None:
        check_json_path(args.metrics, "--metrics")
    if args.consistent and args.alternative not in (None, "consistent"):
        raise ValueError(f"--consistent is --alternative consistent: not with --alternative {args.alternative}")
    model = IdentifiedModel.load(args.model, estimate="consistent" if args.consistent else args.alternative)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        evaluation = model.evaluate(args.data)
    prediction = evaluation.prediction
    notes = trivial_warnings(prediction.mse, {"zero_mse": evaluation.zero_mse, "nominal_mse": evaluation.nominal_mse},
                             label="model")
    for message in dict.fromkeys([str(warning.message) for warning in caught] + list(notes)):
        print(f"oed predict: warning: {message}", file=sys.stderr)
    with OutputFiles() as outputs:  # all files or none
        if args.out is not None:
            with outputs.open(args.out) as stream:
                pd.DataFrame(prediction.columns()).to_csv(stream, index=False)
        if args.metrics is not None:
            with outputs.open(args.metrics) as stream:
                stream.write(json_text(evaluation.to_dict()))
    print(f"{model.robot.name}: {model.file.model} model ({model.file.effects}, {model.estimate}"
          + ("" if model.estimate == (model.file.chosen or "unconstrained") else ": an alternative")
          + (f", delay {1e3 * model.delay:.3g} ms" if model.delay is not None else "")
          + f"), {prediction.t.shape[0]} samples; {model.preprocessing.describe().removeprefix('preprocessing: ')}")
    print_table(evaluation)
    written = [str(path) for path in (args.out, args.metrics) if path is not None]
    if written:
        print("wrote " + " and ".join(written))
    return 0


def print_table(evaluation) -> None:
    """MSE per channel against the record as recorded, beside the yardsticks."""
    mse = evaluation.prediction.mse
    rows = [("model", mse), ("zero", evaluation.zero_mse), ("nominal", evaluation.nominal_mse)]
    if evaluation.floor_mse is not None:
        rows.append(("noise floor", evaluation.floor_mse))
    print("MSE vs recorded   " + "  ".join(f"{channel:>10s}" for channel in mse))
    for label, values in rows:
        print(f"  {label:<16s}" + "  ".join(f"{values[channel]:10.4g}" for channel in mse))
