"""``oed design``: optimal Fourier excitation trajectory (PUMA paper, section IV.A), or with ``--from`` the next
experiment for an identified model (the work: :func:`oed.workflows.design.design`)."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from dynamics.models import ModelKind
from dynamics.runtime.output_files import check_figure_path
from estimation.streaming.cluster import SCHEDULER_VARIABLE
from oed.cli.shared.common import add_robot_arguments, print_lines, print_warnings, seed, verb_keywords
from oed.cli.shared.options import sqp_after
from oed.cli.shared.verbs import verb_summary
from oed.criteria import CRITERIA
from oed.design_constraints import DEFAULT_COLLISION_MARGIN
from oed.excitation import DesignSettings
from oed.sequential.criteria import SEQUENTIAL_CRITERIA
from oed.sequential.problem import SEQUENTIAL_MAX_ITER
from oed.workflows.design import DesignOptions, design
from oed.workflows.options import check_csv_path, check_json_path


def register(subparsers: argparse._SubParsersAction) -> argparse.ArgumentParser:
    parser = subparsers.add_parser(
        "design",
        help=verb_summary("design"),
        description="Optimise a finite-Fourier-series excitation (eq. 18) for -log det(Y_b'Y_b) or another "
        "criterion under position, velocity and acceleration bounds (eq. 19) with IPOPT, multi-start.",
    )
    add_robot_arguments(parser)
    parser.add_argument("--model", choices=[k.value for k in ModelKind], default=None, help="default: combined")
    parser.add_argument("--criterion", choices=[*sorted(CRITERIA), *SEQUENTIAL_CRITERIA], default=None,
                        help="default: logdet; with --from: d (every parameter), ds (the --focus group's log det) "
                        "or worst-relative (the --focus group's largest relative variance; the default with --focus)")
    parser.add_argument("--friction", default=None, help="effects columns (as in `oed model`; default: viscous)")
    parser.add_argument("--bounds", type=Path, help="JSON bounds file {q_min?, q_max, dq_max, ddq_max}")
    parser.add_argument("--ddq-max", type=float, nargs="+", help="acceleration bounds when the bounds come from the URDF")
    parser.add_argument("--starts", type=int, default=4)
    parser.add_argument("--seed", type=seed, default=0)
    parser.add_argument("--workers", type=int, default=0, help="run the starts in a process pool of this size")
    parser.add_argument("--scheduler", help=f"dask scheduler address (tcp://host:8786) to run the starts on a cluster "
                        f"(default: ${SCHEDULER_VARIABLE}); needs pip install 'robot-oed[cluster]'")
    parser.add_argument("--frequency", type=float, default=None,
                        help="fundamental frequency, Hz (default 0.2; with --payload 0.1: one period of 10 s)")
    parser.add_argument("--harmonics", type=int, default=None, help="default 5; with --payload 10")
    parser.add_argument("--samples", type=int, default=250, help="cost samples per period during optimisation")
    parser.add_argument("--constraint-points", type=int, default=60)
    parser.add_argument("--max-iter", type=int, default=None,
                        help=f"IPOPT iterations a start (default: 500; with --from {SEQUENTIAL_MAX_ITER})")
    parser.add_argument("--sqp-after", type=sqp_after, default=None, metavar="N|none",
                        help=f"IPOPT iterations before an SQP method finishes each start (default "
                        f"{DesignSettings.sqp_after}; with --from: none; none: IPOPT alone)")
    parser.add_argument("--out", type=Path, required=True, help="trajectory JSON")
    parser.add_argument("--csv", type=Path, help="sampled trajectory t, q1..qn, dq1..dqn, ddq1..ddqn (1 kHz)")
    parser.add_argument("--plot", type=Path, help="figure of q, dq, ddq with the bounds")
    feasible = parser.add_argument_group("a design the robot can run (docs/cli/design.md)")
    feasible.add_argument("--torque-limits", action="store_true",
                          help="the URDF's effort limits hold for the nominal model's torque at every sample")
    feasible.add_argument("--start", type=joint_positions, metavar="Q1,Q2,...",
                          help="start and end at rest there (rad or m), quintic ramps in and out")
    feasible.add_argument("--floor", type=float, metavar="Z", help="collision geometry stays above z = Z (base frame, m)")
    feasible.add_argument("--self-collision", action="store_true",
                          help="non-adjacent links keep --collision-margin between their collision geometries")
    feasible.add_argument("--collision-margin", type=float, default=None, metavar="M",
                          help=f"least distance between non-adjacent links, m (default {DEFAULT_COLLISION_MARGIN})")
    add_sequential_arguments(parser)
    add_payload_arguments(parser)
    verbosity = parser.add_mutually_exclusive_group()
    verbosity.add_argument("--quiet", action="store_true", help="no progress output")
    verbosity.add_argument("--verbose", action="store_true", help="IPOPT iteration log")
    return parser


def add_sequential_arguments(parser: argparse.ArgumentParser) -> None:
    group = parser.add_argument_group("the next experiment (sequential design)")
    group.add_argument("--from", dest="from_model", type=Path,
                       help="design the next experiment for the model of this result.json or report.json")
    group.add_argument("--data", type=Path, action="append", default=None,
                       help="a record of the experiments already run (repeatable): their information is the prior")
    group.add_argument("--focus", help="parameters (fs2,vs2) or effects (stribeck) the design is for (by default it "
                                       "minimises their largest relative variance, see --criterion); default: every "
                                       "parameter (D-optimality)")
    group.add_argument("--periods", type=float, help="length of the new experiment in periods (default: as long as "
                                                     "the records)")
    group.add_argument("--discriminate", action="store_true",
                       help="design the experiment that best tells the model apart from its rival (T-optimality): "
                            "the runner-up the --from report.json of `oed diagnose` kept, or --rival FILE")
    group.add_argument("--rival", type=Path, help="the rival model (result.json or report.json) for --discriminate, "
                                                  "instead of the --from report's runner-up")


def joint_positions(text: str) -> tuple[float, ...]:
    """``--start`` values: a comma list of numbers."""
    try:
        return tuple(float(value) for value in text.split(","))
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be a comma list of joint positions, got {text!r}") from None


def add_payload_arguments(parser: argparse.ArgumentParser) -> None:
    group = parser.add_argument_group("a payload's excitation")
    group.add_argument("--payload", action="store_true",
                       help="design one period (default 10 s) for the mass and centre of mass of a payload on the "
                            "robot of --from (its identified model), within the bounds")
    group.add_argument("--link", help="with --payload: the payload's link (URDF name, joint name or link<k>; "
                                      "default the last)")
    group.add_argument("--payload-mass", type=float, default=None,
                       help="with --payload: the payload's expected mass, kg (default 1)")
    group.add_argument("--payload-noise-only", action="store_true",
                       help="with --payload: the criterion counts the record's torque noise, the robot model given, "
                            "and nothing holds the robot model's share (reported apart; by default it is kept at most "
                            "random excitations')")
    group.add_argument("--payload-robot-share", action="store_true",
                       help="with --payload: the criterion counts the robot model's share of the uncertainty too "
                            "(by default it is a bound: at most random excitations')")


def run(args: argparse.Namespace) -> int:
    check_figure_path(args.plot)
    check_json_path(args.out)
    if args.csv is not None and (args.from_model is None or args.payload):
        check_csv_path(args.csv, "--csv")
    result = design(say=None if args.quiet else stderr_say_plain(),
                    **verb_keywords(args, DesignOptions, csv=args.csv is not None))
    print_warnings("design", result.warnings)
    result.write(args.out, csv=args.csv, plot=args.plot)
    if not args.quiet:
        lines = result.summary()
        print_lines([*lines[:-1], f"{lines[-1]} -> {args.out}"], file=sys.stderr)
    return 0


def stderr_say_plain():
    """Each start's line on stderr as it ends, flushed."""
    def say(line: str) -> None:
        print(line, file=sys.stderr, flush=True)
    return say
