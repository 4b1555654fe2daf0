"""``oed predict``: an identified model (result.json or report.json) applied to another record
(the work: :func:`oed.workflows.predict.predict`)."""

from __future__ import annotations

import argparse
from pathlib import Path

from dynamics.runtime.output_files import check_figure_path
from oed.cli.shared.common import add_log_arguments, print_lines, print_warnings, stderr_say
from oed.cli.shared.verbs import verb_summary
from oed.workflows.options import check_csv_path, check_json_path
from oed.workflows.predict import predict


def register(subparsers: argparse._SubParsersAction) -> argparse.ArgumentParser:
    parser = subparsers.add_parser(
        "predict",
        help=verb_summary("predict"),
        description="Load the model of a result.json (oed identify) or report.json (oed diagnose), derive the "
        "motion of the record as the model's preprocessing says, predict its channels with 95 % prediction bands "
        "and compare them with the channels as recorded (MSE per channel, beside a zero prediction and the "
        "nominal description).",
    )
    parser.add_argument("--model", type=Path, required=True, help="result.json or report.json holding a model_file")
    parser.add_argument("--data", type=Path, required=True, action="append",
                        help="the record (.csv or .parquet, a ROS bag, .npz or .mat); repeat for several segments "
                             "of one record")
    add_log_arguments(parser)
    parser.add_argument("--alternative", metavar="NAME",
                        help="predict with the alternative model NAME the file holds beside the chosen one (ols, wls, "
                             "consistent; unconstrained: the unconstrained fit behind the choice); default: the model "
                             "the verb chose (model_selection.chosen)")
    parser.add_argument("--consistent", action="store_true",
                        help="the same as --alternative consistent: the physically consistent estimate, what "
                             "`oed export` writes")
    parser.add_argument("--out", type=Path, help="predictions CSV: t, each channel, and its _lo/_hi 95 %% band, then "
                        "each channel's _measured (as recorded) and _residual (measured minus predicted)")
    parser.add_argument("--plot", type=Path, help="figure of measured against predicted per channel, with the 95 %% "
                        "band and the residual (.png, .pdf, .svg)")
    parser.add_argument("--metrics", type=Path, help="metrics JSON: mse, mse_over_floor, n_samples, zero_mse, "
                                                     "nominal_mse, noise_floor_mse, reported_validation_mse, "
                                                     "outside_training_range (per joint), changed (a payload on the "
                                                     "last link or gravity turned, tested on this record)")
    streaming = parser.add_argument_group(
        "bounded memory (estimation.streaming.prediction)",
        "read and predict the record chunk by chunk (peak memory set by the chunk, not the record): the errors, the "
        "zero and nominal predictors' and the training range as in memory; not the per-sample predictions (--out, "
        "--plot), the record's noise floor or the record-change check (the metrics' not_computed says so)")
    streaming.add_argument("--chunk-size", type=int, help="rows a chunk (selects this path)")
    streaming.add_argument("--memory-budget", metavar="SIZE",
                           help="memory the in-memory prediction may take (2GB, 500MB, 1.5GiB or bytes; default 1GB, "
                                "as identify's): past it, estimated from the files' rows, a record of .csv or .parquet "
                                "files is streamed unless --out or --plot is given (one line on stderr says so)")
    return parser


def derived_outputs(args: argparse.Namespace) -> dict[str, Path]:
    """``--metrics``, checked with ``--out`` against the inputs (:func:`oed.cli.shared.paths.check_paths`)."""
    return {option: path for option, path in (("--metrics", args.metrics), ("--plot", args.plot)) if path is not None}


def check_not_model(args: argparse.Namespace, *outputs: tuple[str, Path | None]) -> None:
    """Refuse an output that is the model file itself (it would be overwritten)."""
    model = args.model.expanduser().resolve()
    for option, path in outputs:
        if path is not None and path.expanduser().resolve() == model:
            raise ValueError(f"{option} {path} is the model file (--model): it would be overwritten; write elsewhere")


def run(args: argparse.Namespace) -> int:
    check_not_model(args, ("--out", args.out), ("--metrics", args.metrics), ("--plot", args.plot))
    check_figure_path(args.plot)
    if args.out is not None:
        check_csv_path(args.out)
    if args.metrics is not None:
        check_json_path(args.metrics, "--metrics")
    result = predict(model=args.model, data=args.data, consistent=args.consistent, alternative=args.alternative,
                     topic=args.topic, columns=args.columns, chunk_size=args.chunk_size,
                     memory_budget=args.memory_budget, per_sample=args.out is not None or args.plot is not None,
                     say=stderr_say("predict"))
    print_warnings("predict", result.warnings)
    result.write(out=args.out, metrics=args.metrics, plot=args.plot)
    print_lines(result.summary())
    written = [str(path) for path in (args.out, args.metrics, args.plot) if path is not None]
    if written:
        print("wrote " + " and ".join(written))
    return 0
