"""``oed design --from FILE --data FILE``: the next experiment, from what an identified model left uncertain.

With ``--from`` (a result.json or report.json) and the records already run (``--data``), ``oed design`` maximises
the posterior information of the model's parameters (D-optimality; with ``--focus``, by default, it minimises a
smooth maximum of the focus group's relative variances, or with ``--criterion ds`` their marginal log det;
:mod:`oed.sequential`); with ``--discriminate`` it maximises how far the predictions of the model and a rival
separate (:mod:`oed.sequential.discrimination`): the runner-up the ``--from`` report kept, or ``--rival FILE``
(:mod:`oed.sequential.rivals`). The trajectory's options are those of ``oed design``.
"""

from __future__ import annotations

import argparse
import sys
import warnings
from pathlib import Path

from dynamics.runtime.output_files import save_figure
from estimation.identification.identified_model import IdentifiedModel
from oed.cli.shared.common import OutputFiles, check_figure_path, check_json_path, json_text, robot_from_arguments
from oed.cli.shared.design_bounds import bounds_from_arguments
from oed.cli.shared.options import check_hertz, handover
from oed.design import DesignSettings, ShrunkDesignWarning
from oed.design_constraints import constraints_from_options
from oed.sequential.criteria import SEQUENTIAL_CRITERIA
from oed.sequential.discrimination import design_discriminating
from oed.sequential.figure import plot_next_experiment
from oed.sequential.jacobian import SequentialDesignError
from oed.sequential.next_experiment import check_bounds, design_next
from oed.sequential.prior import read_records
from oed.sequential.rivals import load_rival
from oed.sequential.problem import SEQUENTIAL_MAX_ITER

#: options of a plain design that a model file fixes
FIXED_BY_MODEL = ("model", "friction")


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


def sequential_requested(args: argparse.Namespace) -> bool:
    """Whether ``--from`` was given; the sequential options without it are an error."""
    if args.from_model is None:
        given = [option for option, value in (("--data", args.data), ("--focus", args.focus), ("--periods", args.periods),
                                              ("--rival", args.rival)) if value is not None]
        if args.criterion in SEQUENTIAL_CRITERIA:
            given.append(f"--criterion {args.criterion}")
        if args.discriminate:
            given.append("--discriminate")
        if given:
            raise ValueError(f"{', '.join(given)} belong to a sequential design: give the model with --from FILE")
        return False
    return True


def _check_options(args: argparse.Namespace, model: IdentifiedModel) -> None:
    fixed = [f"--{name}" for name in FIXED_BY_MODEL if getattr(args, name) is not None]
    if fixed:
        raise SequentialDesignError(f"{', '.join(fixed)}: the model file (--from) fixes the model and its effects; "
                                    "drop the option")
    if args.workers or args.scheduler:
        raise SequentialDesignError("--workers and --scheduler are not available with --from: the starts run in turn")
    if args.urdf is not None or args.joints is not None or args.robot != "puma560":
        robot = robot_from_arguments(args)
        if robot.name != model.robot.name or list(robot.joint_names) != list(model.file.joint_names):
            raise SequentialDesignError(f"the robot given ({robot.name}, joints {', '.join(robot.joint_names)}) is not "
                                        f"the model's ({model.robot.name}, joints {', '.join(model.file.joint_names)})")
    if not args.data:
        raise SequentialDesignError("give the records of the experiments already run with --data FILE")
    if args.rival is not None and not args.discriminate:
        raise SequentialDesignError("--rival names the rival of a discriminating design: give --discriminate too")
    if args.discriminate and args.focus is not None:
        raise SequentialDesignError("--focus chooses parameters to determine: not with --discriminate")
    if args.discriminate and args.criterion is not None:
        raise SequentialDesignError("--criterion: --discriminate has its own criterion (T-optimality); drop the option")
    if args.criterion is not None and args.criterion not in SEQUENTIAL_CRITERIA:
        raise SequentialDesignError(f"--criterion {args.criterion} is a plain design's; with --from choose "
                                    f"{', '.join(SEQUENTIAL_CRITERIA)}")
    if args.periods is not None and not args.periods > 0:
        raise SequentialDesignError(f"--periods must be positive, got {args.periods}")


def run_sequential(args: argparse.Namespace) -> int:
    """``oed design --from`` (module docstring): the design, ``next.json`` and the figure, all or nothing."""
    check_hertz(args, "frequency")
    check_figure_path(args.plot)
    check_json_path(args.out)
    if args.csv is not None:
        raise SequentialDesignError("--csv: write the sampled trajectory with a plain `oed design`; not with --from")
    model = IdentifiedModel.load(args.from_model)
    _check_options(args, model)
    bounds = bounds_from_arguments(args, model.robot)
    check_bounds(bounds, model)
    rival = load_rival(model, args.from_model, args.rival) if args.discriminate else None  # checked against model
    records = read_records(model, args.data)
    settings = DesignSettings(frequency_hz=args.frequency, harmonics=args.harmonics, cost_samples=args.samples,
                              constraint_points=args.constraint_points, verbose=args.verbose,
                              max_iter=SEQUENTIAL_MAX_ITER if args.max_iter is None else args.max_iter,
                              sqp_after=handover(args, None))  # IPOPT alone unless asked: sign(dq) makes it jump
    duration = None if args.periods is None else args.periods / args.frequency

    def progress(start, total) -> None:
        if not args.quiet:
            print(f"start {start.index + 1}/{total}: {start.status}, {start.iterations} iterations, {start.time_s:.2f} s, "
                  f"criterion {start.criterion_value:.4f}" + ("" if start.feasible else " (bounds not met)"),
                  file=sys.stderr, flush=True)

    recorded = model.file.robot.urdf_path  # the model's URDF when --urdf is not given
    urdf = args.urdf if args.urdf is not None or recorded is None or not Path(recorded).is_file() else Path(recorded)
    constraints = constraints_from_options(model.robot, urdf, torque_limits=args.torque_limits, floor=args.floor,
                                           self_collision=args.self_collision, collision_margin=args.collision_margin)
    options = dict(bounds=bounds, settings=settings, duration_s=duration, starts=args.starts, seed=args.seed,
                   progress=progress, constraints=constraints)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", ShrunkDesignWarning)
        if rival is None:
            result = design_next(model, records, focus=args.focus, criterion=args.criterion, **options)
        else:
            result = design_discriminating(model, rival.model, records, **options)
    for warning in caught:
        print(f"oed design: warning: {warning.message}", file=sys.stderr)
    with OutputFiles() as outputs:  # all files or none
        with outputs.open(args.out) as stream:
            document = result.to_dict()
            if rival is not None:
                document["discrimination"]["rival_source"] = rival.to_dict()
            stream.write(json_text(document))
        if args.plot is not None:
            figure = plot_next_experiment(records, result.design.trajectory, rate_hz=settings.rate_hz,
                                          title=f"{model.robot.name}: the records so far and the designed experiment")
            save_figure(figure, outputs.stage_figure(args.plot))
    if not args.quiet:
        print(result.summary(), file=sys.stderr)
        print(f"{result.design.total_time_s:.2f} s -> {args.out}", file=sys.stderr)
    return 0
