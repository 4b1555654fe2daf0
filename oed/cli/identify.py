"""``oed identify``: base parameters from measured data, with uncertainties and validation
(the work: :func:`oed.workflows.identify.identify`)."""

from __future__ import annotations

import argparse
from pathlib import Path

from dynamics.models import ModelKind
from dynamics.runtime.output_files import check_figure_path
from dynamics.runtime.progress import show_progress
from oed.cli.identify_consistent import add_consistent_arguments
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
from oed.cli.shared.verbs import verb_summary
from oed.workflows.identify import IdentifyOptions, identify
from oed.workflows.options import check_json_path, check_report_path


def register(subparsers: argparse._SubParsersAction) -> argparse.ArgumentParser:
    parser = subparsers.add_parser(
        "identify",
        help=verb_summary("identify"),
        description="Least-squares identification of the base parameters of the internal, external or combined "
        "model (PUMA paper, section IV) from a CSV/Parquet file (columns t, q1..qn [, dq.., ddq..], tau1..taun, "
        "fx fy fz mx my mz; .npz, .mat and ROS bags with --columns and --topic), with validation on another "
        "experiment. The answer is chosen by the --validate record's error (model_selection in the result): oed "
        "predict and oed export use it.",
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
    parser.add_argument("--report", type=Path, help="the report a person reads: report.html (one self-contained "
                        "page, figures inline) or report.md (Markdown, its figures as PNG files beside it)")
    parser.add_argument("--method", choices=("auto", "wls", "ols"), default="auto",
                        help="auto (default): channel-weighted least squares unless ordinary least squares predicts "
                             "held-out blocks of the training data clearly better (method_selection in the JSON); "
                             "wls: channel-weighted; ols: ordinary")
    add_derivative_arguments(parser)
    add_jobs_argument(parser, "the derivative candidates' scores")
    add_streaming_arguments(parser)
    add_consistent_arguments(parser)
    return parser


def run(args: argparse.Namespace) -> int:
    check_json_path(args.out)
    check_figure_path(args.plot)
    check_report_path(args.report)
    with show_progress("oed identify", quiet=args.quiet) as shown:
        result = identify(say=stderr_say("identify"),
                          **verb_keywords(args, IdentifyOptions, plot=args.plot is not None,
                                          report=args.report is not None))
        print_warnings("identify", shown.unsaid(result.warnings))  # those about the inputs: said as read
        result.write(args.out, plot=args.plot, report=args.report)
        print_lines(result.summary())
        print("wrote " + " and ".join(str(path) for path in (args.out, args.plot, args.report) if path is not None))
    return 0
