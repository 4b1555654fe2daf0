"""``oed design``: optimal Fourier excitation trajectory (PUMA paper, section IV.A)."""

from __future__ import annotations

import argparse
import sys
import warnings
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

from dynamics.models import ModelKind
from estimation.streaming.cluster import SCHEDULER_VARIABLE, connect, scheduler_address
from oed.cli.shared.common import (
    OutputFiles,
    add_robot_arguments,
    check_csv_path,
    check_figure_path,
    check_json_path,
    json_text,
    robot_from_arguments,
    seed,
)
from oed.cli.shared.options import check_hertz, handover, sqp_after
from oed.cli.design_sequential import add_sequential_arguments, run_sequential, sequential_requested
from oed.criteria import CRITERIA
from oed.cli.shared.design_bounds import bounds_from_arguments
from oed.design import DesignSettings, ShrunkDesignWarning, design_excitation
from oed.design_constraints import DEFAULT_COLLISION_MARGIN, constraints_from_options
from oed.rest_ramps import RestStart, experiment_samples, rest_of
from oed.sequential.criteria import SEQUENTIAL_CRITERIA
from oed.sequential.problem import SEQUENTIAL_MAX_ITER
from oed.cli.shared.verbs import verb_summary


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
    parser.add_argument("--frequency", type=float, default=0.2, help="fundamental frequency, Hz (default 0.2)")
    parser.add_argument("--harmonics", type=int, default=5)
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
    verbosity = parser.add_mutually_exclusive_group()
    verbosity.add_argument("--quiet", action="store_true", help="no progress output")
    verbosity.add_argument("--verbose", action="store_true", help="IPOPT iteration log")
    return parser


def joint_positions(text: str) -> tuple[float, ...]:
    """``--start`` values: a comma list of numbers."""
    try:
        return tuple(float(value) for value in text.split(","))
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be a comma list of joint positions, got {text!r}") from None


def trajectory_table(trajectory, rate_hz: float = 1000.0) -> tuple[list[str], np.ndarray]:
    """Columns ``t, q1..qn, dq1..dqn, ddq1..ddqn`` and the samples of one period (with a rest start:
    the whole experiment, ramps in and out, its last sample at rest)."""
    rest, periods = rest_of(trajectory)
    t, q, dq, ddq = experiment_samples(trajectory, rest, rate_hz, periods)
    n = trajectory.n_joints
    header = ["t"] + [f"{state}{i}" for state in ("q", "dq", "ddq") for i in range(1, n + 1)]
    return header, np.column_stack([t, q, dq, ddq])


def run(args: argparse.Namespace) -> int:
    if sequential_requested(args):
        if args.start is not None:
            raise ValueError("--start cannot be combined with --from yet (sequential designs: the next experiment's "
                             "information is that of whole periods)")
        return run_sequential(args)
    args.model = args.model or "combined"
    args.criterion = args.criterion or "logdet"
    args.friction = args.friction or "viscous"
    args.max_iter = 500 if args.max_iter is None else args.max_iter
    check_hertz(args, "frequency")
    check_figure_path(args.plot)
    check_json_path(args.out)
    if args.csv is not None:
        check_csv_path(args.csv, "--csv")
    robot = robot_from_arguments(args)
    bounds = bounds_from_arguments(args, robot)
    settings = DesignSettings(
        frequency_hz=args.frequency, harmonics=args.harmonics, cost_samples=args.samples,
        constraint_points=args.constraint_points, max_iter=args.max_iter, verbose=args.verbose,
        sqp_after=handover(args, DesignSettings.sqp_after),
    )
    if args.starts < 1:
        raise ValueError(f"--starts must be at least 1, got {args.starts}")
    if args.workers < 0:
        raise ValueError(f"--workers must be 0 (run the starts in turn) or a pool size, got {args.workers}")

    def progress(start, total) -> None:
        if not args.quiet:
            print(f"start {start.index + 1}/{total}: {start.status}, {start.iterations} iterations, "
                  f"{start.time_s:.2f} s, cost {start.cost:.4f}" + ("" if start.feasible else " (bounds not met)"),
                  file=sys.stderr, flush=True)

    constraints = constraints_from_options(robot, args.urdf, torque_limits=args.torque_limits, floor=args.floor,
                                           self_collision=args.self_collision, collision_margin=args.collision_margin)
    rest = None if args.start is None else RestStart(args.start)
    options = dict(model=args.model, bounds=bounds, criterion=args.criterion, effects=args.friction,
                   starts=args.starts, seed=args.seed, settings=settings, progress=progress,
                   constraints=constraints, rest=rest)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", ShrunkDesignWarning)
        address = scheduler_address(args.scheduler)
        if address is not None and args.workers > 0:
            raise ValueError("give --scheduler (a dask cluster) or --workers (a local pool), not both")
        if address is not None:
            with connect(address) as executor:
                result = design_excitation(robot, executor=executor, **options)
        elif args.workers > 0:
            with ProcessPoolExecutor(args.workers) as executor:
                result = design_excitation(robot, executor=executor, **options)
        else:
            result = design_excitation(robot, **options)
    for warning in caught:
        print(f"oed design: warning: {warning.message}", file=sys.stderr)
    trajectory = result.trajectory
    # the files are staged and renamed into place together: a failure leaves none of them
    with OutputFiles() as outputs:
        with outputs.open(args.out) as stream:
            stream.write(json_text(trajectory.to_dict()))
        if args.csv is not None:
            header, table = trajectory_table(trajectory, settings.rate_hz)
            with outputs.open(args.csv) as stream:
                np.savetxt(stream, table, delimiter=",", header=",".join(header), comments="", fmt="%.10g")
        if args.plot is not None:
            from dynamics.runtime.output_files import save_figure
            from oed.design_plot import plot_trajectory

            figure = plot_trajectory(trajectory, bounds, rate_hz=settings.rate_hz, margins=result.margins,
                                     title=f"{robot.name}, {args.model} model, cost {result.cost:.2f}")
            save_figure(figure, outputs.stage_figure(args.plot))
    if not args.quiet:
        print(f"{robot.name}, {args.model} model, {args.criterion}: best start {result.best + 1}/{len(result.starts)}, "
              f"cost -log det(Y'Y) = {result.cost:.4f}, cond = {result.cond:.2f}, "
              f"{result.total_time_s:.2f} s -> {args.out}", file=sys.stderr)
    return 0
