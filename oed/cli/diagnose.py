"""``oed diagnose``: find what an identified model lacks in measured data, add it, report before/after
(the work: :func:`oed.workflows.diagnose.diagnose`)."""

from __future__ import annotations

import argparse
from pathlib import Path

from dynamics.models import ModelKind
from dynamics.runtime.progress import show_progress
from dynamics.runtime.report_document import HTML_SUFFIXES
from oed.cli.shared.asbuilt import add_asbuilt_arguments
from oed.cli.shared.common import (
    add_data_arguments,
    add_derivative_arguments,
    add_jobs_argument,
    add_robot_arguments,
    add_streaming_arguments,
    print_lines,
    print_warnings,
    stderr_say,
    verb_keywords,
)
from oed.cli.identify_consistent import add_consistent_arguments
from oed.cli.shared.verbs import verb_summary
from oed.workflows.diagnose import DiagnoseOptions, diagnose, residual_figure, trace_figure
from oed.workflows.options import check_json_path, check_report_path
from estimation.streaming.settings import DEFAULT_SUBSAMPLE


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
                        help="test data from a third experiment, never used for a decision: the chosen model's error "
                             "on it is the one to quote (test.chosen in the report, what oed predict gives; "
                             "test{before,after}: the declared and the diagnosed model as fitted); repeatable like "
                             "--data")
    parser.add_argument("--out", type=Path, required=True, help="report JSON")
    parser.add_argument("--report", type=Path, help="the report a person reads: report.html (one self-contained "
                        "page, figures inline) or report.md (Markdown, its figures as PNG files beside it)")
    parser.add_argument("--alpha", type=float, default=1e-3, help="significance level of the F test (default 1e-3)")
    parser.add_argument("--max-effects", type=int, default=20, metavar="N",
                        help="add at most N effects (default 20); the output says when the cap stopped the search")
    add_derivative_arguments(parser)
    add_jobs_argument(parser, "the derivative candidates' scores, each round's candidate fits and its confirmations on the validation record")
    add_streaming_arguments(parser)
    add_streamed_diagnosis_arguments(parser)
    parser.add_argument("--unseen-stretches", action="store_true",
                        help="when --validate repeats the training motion, also refuse an effect that raises the error "
                             "on the stretches of the motion its fit did not see (off by default)")
    add_consistent_arguments(parser)  # --consistent: the adopted model refitted consistently (estimation.consistent)
    return parser


def add_streamed_diagnosis_arguments(parser: argparse.ArgumentParser) -> None:
    """``--subsample`` and ``--floor-window`` (``--chunk-size``, ``--workers``, ``--scheduler``: as identify's)."""
    group = parser.add_argument_group("streamed diagnosis (estimation.streaming.diagnosis)")
    group.add_argument("--subsample", type=int, default=DEFAULT_SUBSAMPLE, metavar="N",
                       help=f"training samples, spread evenly, on which shaped laws' shapes are searched and coupling "
                            f"pairs traced (default {DEFAULT_SUBSAMPLE}; up to twice that are kept)")
    group.add_argument("--floor-window", type=int, default=None, metavar="N",
                       help="rows of each validation file the noise floor is estimated on (default: every row, "
                            "memory's floor)")


def derived_outputs(args: argparse.Namespace) -> dict[str, Path]:
    """Files written besides the named outputs (checked against them by :func:`oed.cli.shared.paths.check_paths`)."""
    if args.report is None or args.report.suffix.lower() in HTML_SUFFIXES:
        return {}
    return {"the report's residual figure": residual_figure(args.report),
            "the report's tracing figure": trace_figure(args.report)}


def run(args: argparse.Namespace) -> int:
    check_json_path(args.out)
    check_report_path(args.report)
    with show_progress("oed diagnose", quiet=args.quiet) as shown:
        result = diagnose(say=stderr_say("diagnose"),
                          **verb_keywords(args, DiagnoseOptions, report=args.report is not None))
        print_warnings("diagnose", shown.unsaid(result.warnings))  # those about the inputs: said as read
        result.write(args.out, report=args.report)
        print_lines(result.summary())
        print(f"wrote {args.out}" + (f" and {args.report}" if args.report else ""))
    return 0
