"""``oed design`` as a library call: an optimal Fourier excitation trajectory (PUMA paper, section IV.A), or with
``from_model`` (``--from``) the next experiment for an identified model (:mod:`oed.sequential`).

:func:`design` takes the verb's options as keywords (:class:`DesignOptions`) and returns a :class:`DesignRun`:
``to_dict()`` is the trajectory JSON (``next.json`` with ``from_model``), ``write(out, csv=..., plot=...)`` writes
it with the sampled trajectory and the figure, ``summary()`` the lines ``oed design`` prints on stderr.

With ``from_model`` (a result.json or report.json) and the records already run (``data``), the design maximises
the posterior information of the model's parameters (D-optimality; with ``focus``, by default, it minimises a
smooth maximum of the focus group's relative variances, or with ``criterion="ds"`` their marginal log det);
with ``discriminate`` it maximises how far the predictions of the model and a rival separate
(:mod:`oed.sequential.discrimination`): the runner-up the ``from_model`` report kept, or ``rival``
(:mod:`oed.sequential.rivals`).
"""

from __future__ import annotations

import dataclasses

import copy
import warnings
from collections.abc import Callable
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from dynamics.robot import RobotModel
from dynamics.runtime.output_files import OutputFiles, json_text, save_figure
from estimation.identification.identified_model import IdentifiedModel
from estimation.streaming.cluster import connect, scheduler_address
from oed.bounds import JointBounds
from oed.excitation import DesignSettings, ShrunkDesignWarning, design_excitation
from oed.sequential.criteria import SEQUENTIAL_CRITERIA
from oed.sequential.discrimination import design_discriminating
from oed.sequential.jacobian import SequentialDesignError
from oed.sequential.next_experiment import check_bounds, design_next
from oed.sequential.prior import read_records
from oed.sequential.problem import SEQUENTIAL_MAX_ITER
from oed.sequential.rivals import load_rival
from oed.payload_design import design_payload_excitation
from oed.payload_design.design import PAYLOAD_FREQUENCY_HZ, PAYLOAD_HARMONICS
from oed.design_constraints import constraints_from_options
from oed.rest_ramps import RestStart, experiment_samples, rest_of
from oed.workflows.design_bounds import bounds_of
from oed.workflows.options import RobotOptions, check_hertz, optional_path, paths, robot_of

__all__ = ["IPOPT_ALONE", "DesignOptions", "DesignRun", "design", "trajectory_table"]

#: ``sqp_after="none"`` (``--sqp-after none``): IPOPT alone (``None``: the verb's default)
IPOPT_ALONE = "none"
#: a plain design's fundamental frequency (Hz) and harmonics when not given (the PUMA paper's)
DEFAULT_FREQUENCY_HZ = 0.2
DEFAULT_HARMONICS = 5
#: options of a plain design that a model file fixes
FIXED_BY_MODEL = ("model", "friction")


@dataclass(frozen=True, kw_only=True)
class DesignOptions(RobotOptions):
    """The options of ``oed design`` by their names (``--ddq-max`` -> ``ddq_max``, ``--from`` -> ``from_model``);
    ``csv``: whether the sampled trajectory will be written (not with ``from_model``)."""

    model: str | None = None
    criterion: str | None = None
    friction: str | None = None
    bounds: Path | None = None
    ddq_max: list[float] | None = None
    starts: int = 4
    seed: int = 0
    workers: int = 0
    scheduler: str | None = None
    frequency: float | None = None
    harmonics: int | None = None
    samples: int = 250
    constraint_points: int = 60
    max_iter: int | None = None
    sqp_after: int | str | None = None
    verbose: bool = False
    csv: bool = False
    from_model: Path | None = None
    data: tuple[Path, ...] | None = None
    focus: str | None = None
    periods: float | None = None
    discriminate: bool = False
    rival: Path | None = None
    torque_limits: bool = False
    start: tuple[float, ...] | None = None
    floor: float | None = None
    self_collision: bool = False
    collision_margin: float | None = None
    payload: bool = False
    link: str | None = None
    payload_mass: float | None = None
    payload_noise_only: bool = False
    payload_robot_share: bool = False

    def __post_init__(self) -> None:
        super().__post_init__()
        for name in ("bounds", "from_model", "rival"):
            object.__setattr__(self, name, optional_path(getattr(self, name)))
        if self.data is not None:
            object.__setattr__(self, "data", paths(self.data))


def handover(options: DesignOptions, default: int | None) -> int | None:
    """``DesignSettings.sqp_after`` from ``sqp_after``: ``default`` when not given, ``None`` for ``none``."""
    if options.sqp_after is None:
        return default
    return None if options.sqp_after == IPOPT_ALONE else options.sqp_after


def trajectory_table(trajectory: Any, rate_hz: float = 1000.0) -> tuple[list[str], np.ndarray]:
    """Columns ``t, q1..qn, dq1..dqn, ddq1..ddqn`` and the samples of one period (with a rest start:
    the whole experiment, ramps in and out, its last sample at rest)."""
    rest, periods = rest_of(trajectory)
    t, q, dq, ddq = experiment_samples(trajectory, rest, rate_hz, periods)
    n = trajectory.n_joints
    header = ["t"] + [f"{state}{i}" for state in ("q", "dq", "ddq") for i in range(1, n + 1)]
    return header, np.column_stack([t, q, dq, ddq])


@dataclass(frozen=True)
class DesignRun:
    """What ``oed design`` computed.

    Attributes
    ----------
    document
        The trajectory JSON (``next.json`` with ``from_model``; :meth:`to_dict` returns a copy).
    lines
        The lines ``oed design`` prints on stderr at the end (:meth:`summary`; the last without `` -> OUT``).
    warnings
        The warnings it prints on stderr.
    result
        The :class:`~oed.excitation.DesignResult`, or the sequential design's result.
    figure
        Draws the figure (``plot``): a callable returning a matplotlib figure.
    trajectory
        The designed :class:`~oed.fourier.FourierTrajectory`.
    rate_hz
        The rate of the sampled trajectory (``csv``).
    sequential
        Whether it is the next experiment of a model (no ``csv`` then).
    """

    document: dict[str, Any] = field(repr=False)
    lines: tuple[str, ...]
    warnings: tuple[str, ...]
    result: Any = field(repr=False)
    figure: Callable[[], Any] = field(repr=False)
    trajectory: Any = field(repr=False)
    rate_hz: float
    sequential: bool = False

    def to_dict(self) -> dict[str, Any]:
        """The JSON ``oed design`` writes."""
        return copy.deepcopy(self.document)

    def summary(self) -> list[str]:
        """The lines ``oed design`` prints on stderr at the end."""
        return list(self.lines)

    def write(self, out: str | Path, *, csv: str | Path | None = None, plot: str | Path | None = None) -> None:
        """The JSON at ``out`` and, with ``csv``, the sampled trajectory, with ``plot`` the figure: all or none."""
        if csv is not None and self.sequential:
            raise SequentialDesignError("--csv: write the sampled trajectory with a plain `oed design`; not with --from")
        with OutputFiles() as outputs:  # the files are staged and renamed into place together
            with outputs.open(out) as stream:
                stream.write(json_text(self.document))
            if csv is not None:
                header, table = trajectory_table(self.trajectory, self.rate_hz)
                with outputs.open(csv) as stream:
                    np.savetxt(stream, table, delimiter=",", header=",".join(header), comments="", fmt="%.10g")
            if plot is not None:
                save_figure(self.figure(), outputs.stage_figure(plot))


def design(*, say: Callable[[str], None] | None = None, **options: Any) -> DesignRun:
    """``oed design``: the excitation trajectory (or with ``from_model`` the next experiment).

    Parameters
    ----------
    say
        Called with a line on each start as it ends (``start 1/4: Solve_Succeeded, 46 iterations…``).
    **options
        The verb's options by their names (:class:`DesignOptions`): ``robot`` or ``urdf``, ``joints``, ``model``,
        ``criterion``, ``friction``, ``bounds``, ``starts``, ``seed``, ``frequency``, ``harmonics``…

    Returns
    -------
    DesignRun
        ``to_dict()`` is the trajectory JSON; ``write(out, csv=None, plot=None)``.
    """
    settings = DesignOptions(**options)
    say = say or (lambda line: None)
    if payload_requested(settings):
        return design_payload(settings, say)
    settings = dataclasses.replace(settings, frequency=DEFAULT_FREQUENCY_HZ if settings.frequency is None
                                   else settings.frequency,
                                   harmonics=DEFAULT_HARMONICS if settings.harmonics is None else settings.harmonics)
    if sequential_requested(settings):
        return design_sequential(settings, say)
    return design_plain(settings, say)


def design_plain(args: DesignOptions, say: Callable[[str], None]) -> DesignRun:
    """The optimal excitation of ``args`` (:func:`oed.excitation.design_excitation`)."""
    model = args.model or "combined"
    criterion = args.criterion or "logdet"
    friction = args.friction or "viscous"
    check_hertz(args, "frequency")
    robot = robot_of(args)
    check_commanded(robot)
    bounds = bounds_of(args, robot)
    settings = DesignSettings(
        frequency_hz=args.frequency, harmonics=args.harmonics, cost_samples=args.samples,
        constraint_points=args.constraint_points, max_iter=500 if args.max_iter is None else args.max_iter,
        verbose=args.verbose, sqp_after=handover(args, DesignSettings.sqp_after),
    )
    if args.starts < 1:
        raise ValueError(f"--starts must be at least 1, got {args.starts}")
    if args.workers < 0:
        raise ValueError(f"--workers must be 0 (run the starts in turn) or a pool size, got {args.workers}")

    def progress(start: Any, total: int) -> None:
        say(f"start {start.index + 1}/{total}: {start.status}, {start.iterations} iterations, "
            f"{start.time_s:.2f} s, cost {start.cost:.4f}" + ("" if start.feasible else " (bounds not met)"))

    constraints = constraints_from_options(robot, args.urdf, torque_limits=args.torque_limits, floor=args.floor,
                                           self_collision=args.self_collision, collision_margin=args.collision_margin)
    rest = None if args.start is None else RestStart(tuple(args.start))
    options = dict(model=model, bounds=bounds, criterion=criterion, effects=friction,
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
    trajectory = result.trajectory

    def figure() -> Any:
        from oed.design_plot import plot_trajectory

        return plot_trajectory(trajectory, bounds, rate_hz=settings.rate_hz, margins=result.margins,
                               title=f"{robot.name}, {model} model, cost {result.cost:.2f}")

    line = (f"{robot.name}, {model} model, {criterion}: best start {result.best + 1}/{len(result.starts)}, "
            f"cost -log det(Y'Y) = {result.cost:.4f}, cond = {result.cond:.2f}, {result.total_time_s:.2f} s")
    return DesignRun(trajectory.to_dict(), (line,), tuple(str(warning.message) for warning in caught), result,
                     figure, trajectory, settings.rate_hz)


def payload_requested(args: DesignOptions) -> bool:
    """Whether ``payload`` was given; its options without it are an error."""
    if not args.payload:
        given = [option for option, value in (("--link", args.link), ("--payload-mass", args.payload_mass))
                 if value is not None] + (["--payload-noise-only"] if args.payload_noise_only else []) \
            + (["--payload-robot-share"] if args.payload_robot_share else [])
        if given:
            raise ValueError(f"{', '.join(given)} belong to a payload's design: give --payload too")
    return bool(args.payload)


def design_payload(args: DesignOptions, say: Callable[[str], None]) -> DesignRun:
    """``oed design --payload --from robot.json`` (:func:`oed.payload_design.design_payload_excitation`): one short
    period for the mass and centre of mass of a payload on the identified robot, within the bounds."""
    if args.from_model is None:
        raise ValueError("--payload designs for an identified robot: give its result.json or report.json with --from")
    given = [option for option, value in (("--data", args.data), ("--focus", args.focus), ("--periods", args.periods),
                                          ("--rival", args.rival), ("--model", args.model), ("--friction", args.friction),
                                          ("--criterion", args.criterion)) if value is not None] \
        + (["--discriminate"] if args.discriminate else [])
    if given:
        raise ValueError(f"{', '.join(given)}: not with --payload (the model file fixes the model; the criterion is "
                         "the worst relative standard deviation of the mass and the centre of mass)")
    if args.payload_noise_only and args.payload_robot_share:
        raise ValueError("--payload-noise-only and --payload-robot-share: give one (by default the criterion counts the "
                         "record's noise, the robot model's share at most random excitations')")
    args = dataclasses.replace(args, frequency=PAYLOAD_FREQUENCY_HZ if args.frequency is None else args.frequency,
                               harmonics=PAYLOAD_HARMONICS if args.harmonics is None else args.harmonics)
    check_hertz(args, "frequency")
    model = IdentifiedModel.load(args.from_model)
    bounds = bounds_of(args, model.robot)
    settings = DesignSettings(frequency_hz=args.frequency, harmonics=args.harmonics, cost_samples=args.samples,
                              constraint_points=args.constraint_points, verbose=args.verbose,
                              max_iter=500 if args.max_iter is None else args.max_iter,
                              sqp_after=handover(args, DesignSettings.sqp_after))

    def progress(start: Any, total: int) -> None:
        say(f"start {start.index + 1}/{total}: {start.status}, {start.iterations} iterations, {start.time_s:.2f} s, "
            f"criterion {start.criterion_value:.4f}" + ("" if start.feasible else " (bounds not met)"))

    result = design_payload_excitation(model, bounds=bounds, link=args.link,
                                       mass=1.0 if args.payload_mass is None else args.payload_mass,
                                       robot_share="counted" if args.payload_robot_share else
                                       "ignored" if args.payload_noise_only else "bounded", settings=settings,
                                       starts=args.starts, seed=args.seed, progress=progress)

    def figure() -> Any:
        from oed.design_plot import plot_trajectory

        return plot_trajectory(result.trajectory, bounds, rate_hz=settings.rate_hz,
                               title=f"{model.robot.name}: payload excitation")

    lines = (result.summary(), f"{result.design.total_time_s:.2f} s")
    return DesignRun(result.to_dict(), lines, result.warnings, result, figure, result.trajectory, settings.rate_hz)


def sequential_requested(args: DesignOptions) -> bool:
    """Whether ``from_model`` was given; the sequential options without it are an error."""
    if args.from_model is not None and args.start is not None and not args.payload:
        raise ValueError("--start cannot be combined with --from yet (sequential designs: the next experiment's "
                         "information is that of whole periods)")
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


def check_commanded(robot: RobotModel) -> None:
    """Refuse a robot with a passive (unactuated) joint, naming it: the design commands every joint's motion (a
    Fourier series per joint), and a passive joint's motion is a consequence of the others' (its dynamics with zero
    torque), not a command; designing one would give a motion the robot cannot run."""
    if robot.passive_joints:
        raise ValueError(
            f"passive joint(s) {', '.join(robot.passive_joints)}: the design commands every joint's motion, and a "
            "passive joint's motion is a consequence of the others' (no motor drives it), so a designed motion could "
            "not be run; excite the robot through its driven joints (a motion of your own: the identification reads "
            "the passive joint's torque as zero, its motion as logged)")


def check_sequential_options(args: DesignOptions, model: IdentifiedModel) -> None:
    """The options of a sequential design against one another and the model."""
    check_commanded(model.robot)
    fixed = [f"--{name}" for name in FIXED_BY_MODEL if getattr(args, name) is not None]
    if fixed:
        raise SequentialDesignError(f"{', '.join(fixed)}: the model file (--from) fixes the model and its effects; "
                                    "drop the option")
    if args.workers or args.scheduler:
        raise SequentialDesignError("--workers and --scheduler are not available with --from: the starts run in turn")
    if args.urdf is not None or args.joints is not None or args.robot != "puma560":
        robot = robot_of(args)
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


def design_sequential(args: DesignOptions, say: Callable[[str], None]) -> DesignRun:
    """``oed design --from`` (module docstring): the design of the next experiment."""
    check_hertz(args, "frequency")
    if args.csv:
        raise SequentialDesignError("--csv: write the sampled trajectory with a plain `oed design`; not with --from")
    model = IdentifiedModel.load(args.from_model)
    check_sequential_options(args, model)
    bounds: JointBounds = bounds_of(args, model.robot)
    check_bounds(bounds, model)
    rival = load_rival(model, args.from_model, args.rival) if args.discriminate else None  # checked against model
    records = read_records(model, args.data)
    settings = DesignSettings(frequency_hz=args.frequency, harmonics=args.harmonics, cost_samples=args.samples,
                              constraint_points=args.constraint_points, verbose=args.verbose,
                              max_iter=SEQUENTIAL_MAX_ITER if args.max_iter is None else args.max_iter,
                              sqp_after=handover(args, None))  # IPOPT alone unless asked: sign(dq) makes it jump
    duration = None if args.periods is None else args.periods / args.frequency

    def progress(start: Any, total: int) -> None:
        say(f"start {start.index + 1}/{total}: {start.status}, {start.iterations} iterations, {start.time_s:.2f} s, "
            f"criterion {start.criterion_value:.4f}" + ("" if start.feasible else " (bounds not met)"))

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
    document = result.to_dict()
    if rival is not None:
        document["discrimination"]["rival_source"] = rival.to_dict()

    def figure() -> Any:
        from oed.sequential.figure import plot_next_experiment

        return plot_next_experiment(records, result.design.trajectory, rate_hz=settings.rate_hz,
                                    title=f"{model.robot.name}: the records so far and the designed experiment")

    lines = (result.summary(), f"{result.design.total_time_s:.2f} s")
    return DesignRun(document, lines, tuple(str(warning.message) for warning in caught), result, figure,
                     result.design.trajectory, settings.rate_hz, sequential=True)
