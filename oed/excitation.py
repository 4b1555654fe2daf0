"""Optimal excitation design, one-shot: multi-start IPOPT over Fourier trajectories (PUMA paper, IV.A).

:func:`design_excitation` draws random feasible starts, solves each with the reusable problem
object :class:`oed.design_problem.ExcitationDesign` (in turn, or through any
``concurrent.futures.Executor``), and returns the best as a :class:`DesignResult`.
"""

from __future__ import annotations

import time
import warnings
from collections.abc import Callable
from concurrent.futures import as_completed
from dataclasses import dataclass
from typing import Any

import numpy as np

from dynamics.models import ModelKind
from dynamics.robot import RobotModel
from oed.bounds import STATE_LABELS, InfeasibleBoundsError, JointBounds
from oed.design_problem import (
    SUCCESS_STATUSES,
    DesignSettings,
    ExcitationDesign,
    StartResult,
    default_bounds,
)
from oed.design_parallel import payload_of, solve_start
from oed.fourier import FourierTrajectory
from oed.rest_ramps import RestStart, choose_periods

class ShrunkDesignWarning(UserWarning):
    """The returned trajectory was scaled down onto the bounds after the solver's refinements."""


#: most starts one design accepts (their start vectors are built up front)
MAX_STARTS = 100_000

__all__ = [
    "SUCCESS_STATUSES", "DesignError", "DesignResult", "DesignSettings", "ExcitationDesign", "StartResult",
    "default_bounds", "design_excitation", "solve_start",
]


class DesignError(RuntimeError):
    """The optimiser failed on every start (the message gives each start's solver status)."""


@dataclass(frozen=True)
class DesignResult:
    """The best start's trajectory and every start's statistics."""

    trajectory: FourierTrajectory
    cost: float
    cond: float
    criterion: str
    criterion_value: float
    starts: tuple[StartResult, ...]
    best: int
    build_time_s: float
    total_time_s: float
    margins: tuple[dict[str, Any], ...] = ()


def check_room_to_move(problem: ExcitationDesign) -> None:
    """Raise :class:`InfeasibleBoundsError` naming the joint and bound when a bound is so narrow that the
    optimiser's constraint, pulled in by its safety margin, becomes empty (IPOPT would only report an
    ill-posed problem on constraint row k)."""
    _, lower, upper = problem.constraint_matrix(np.zeros(1))
    bounds = problem.bounds
    for row in np.flatnonzero(lower > upper):
        joint, state = divmod(int(row), len(STATE_LABELS))
        key = ("q", "dq", "ddq")[state]
        limit = (f"position range [{bounds.q_min[joint]:.10g}, {bounds.q_max[joint]:.10g}]" if key == "q"
                 else f"{STATE_LABELS[key]} bound {key}_max = {getattr(bounds, key + '_max')[joint]:.3g}")
        raise InfeasibleBoundsError(
            f"joint {bounds.joint_names[joint]!r}: {limit} is too narrow: "
            "no trajectory can be optimised within it (the constraints keep a margin of about 1e-7)"
        )


def design_excitation(
    robot: RobotModel,
    *,
    model: ModelKind | str = ModelKind.COMBINED,
    bounds: JointBounds | None = None,
    criterion: Any = "logdet",
    effects: Any = ("viscous",),
    starts: int = 4,
    seed: int | None = 0,
    executor: Any = None,
    settings: DesignSettings | None = None,
    progress: Callable[[StartResult, int], None] | None = None,
    problem: ExcitationDesign | None = None,
    constraints: tuple = (),
    rest: RestStart | None = None,
) -> DesignResult:
    """Optimal Fourier excitation (PUMA paper, section IV.A, eqs. 18–19): multi-start IPOPT.

    Parameters
    ----------
    robot, model, bounds, criterion, effects, settings
        The problem (see :class:`ExcitationDesign`); ``bounds`` default to eq. 19 for the PUMA.
    starts, seed
        Number of random feasible starts and the seed of their generator.
    executor
        Any :class:`concurrent.futures.Executor` (a process pool, a ``dask.distributed`` client…);
        each start is submitted as :func:`solve_start` with picklable arguments. ``None``: in turn.
    progress
        Called with each finished start and the number of starts.
    problem
        A prebuilt :class:`ExcitationDesign` to reuse (then the problem arguments are ignored).
    constraints, rest
        Torque limits, a floor, self-collision (:mod:`oed.design_constraints`) and a start and end at
        rest (:class:`oed.rest_ramps.RestStart`), inside the optimisation (issue #36).

    Returns
    -------
    DesignResult
        The best feasible start's trajectory (its metadata holds ``model, criterion, cost, cond,
        bounds, solver``), ``cost = −log det(Y_bᵀY_b)`` over one period at ``rate_hz``, every start.

    Raises
    ------
    DesignError
        When no start ends with a successful solver status and a trajectory within the bounds.
    InfeasibleBoundsError
        When a bound is too narrow for the optimiser's constraints (named with its joint).
    """
    seed = _checked_arguments(starts, seed, bounds, executor)
    started = time.perf_counter()
    if problem is None:
        problem = ExcitationDesign(robot, model, bounds, criterion, effects, settings or DesignSettings(),
                                   constraints=tuple(constraints), rest=rest)
    check_room_to_move(problem)
    generator = np.random.default_rng(seed)
    initial = [problem.random_start(generator) for _ in range(starts)]
    if executor is None:
        build_time, results = _solve_in_turn(problem, initial, progress)
    else:
        build_time = float("nan")  # paid once in each worker
        results = _solve_on(executor, problem, initial, progress)
    best = _best_start(problem, results)
    values = problem.evaluate(best.x)
    metadata = _trajectory_metadata(problem, values, best, results, starts, seed)
    periods = 1
    if problem.rest is not None:
        periods, efficiencies = (problem.rest.periods, []) if problem.rest.periods else choose_periods(
            problem.information, problem.trajectory(best.x), problem.rest, problem.settings.rate_hz)
        metadata["experiment"] = {**problem.rest.to_dict(), "periods": periods,
                                  "d_efficiency_by_periods": efficiencies,
                                  "duration_s": 2 * problem.rest.ramp_s + periods / problem.settings.frequency_hz,
                                  "rate_hz": problem.settings.rate_hz}
    margins = tuple(problem.margin_report(best.x, periods))
    if margins:
        metadata["constraints"] = [{key: value for key, value in entry.items() if key not in ("t_s", "margin")}
                                   for entry in margins]
    return DesignResult(
        trajectory=problem.trajectory(best.x, **metadata),
        cost=values["cost"],
        cond=values["cond"],
        criterion=problem.criterion.name,
        criterion_value=values["criterion"],
        starts=tuple(results),
        best=best.index,
        build_time_s=build_time,
        total_time_s=time.perf_counter() - started,
        margins=margins,
    )


def _checked_arguments(starts: Any, seed: Any, bounds: Any, executor: Any) -> int | None:
    """Refuse a bad ``starts``, ``seed``, ``bounds`` or ``executor`` of :func:`design_excitation`; the
    seed as a plain ``int`` (for the JSON metadata) or ``None``."""
    if isinstance(starts, bool) or not isinstance(starts, (int, np.integer)) or not 1 <= starts <= MAX_STARTS:
        raise ValueError(f"starts must be an integer from 1 to {MAX_STARTS}, got {starts!r}")
    if seed is not None and (isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0):
        raise TypeError(f"seed must be a non-negative integer or None, got {seed!r}")
    if bounds is not None and not isinstance(bounds, JointBounds):
        raise TypeError(f"bounds must be JointBounds (e.g. JointBounds.from_dict(...)), got {type(bounds).__name__}")
    if executor is not None and not callable(getattr(executor, "submit", None)):
        raise TypeError(f"executor must be a concurrent.futures.Executor (with submit), got {type(executor).__name__}")
    return None if seed is None else int(seed)


def _solve_in_turn(problem: ExcitationDesign, initial: list[np.ndarray],
                   progress: Callable[[StartResult, int], None] | None) -> tuple[float, list[StartResult]]:
    """Every start solved here, one after the other: the problem's build time and the results."""
    results: list[StartResult] = []
    build_time = problem.build()
    for index, x0 in enumerate(initial):
        results.append(problem.solve(x0, index))
        if progress is not None:
            progress(results[-1], len(initial))
    return build_time, results


def _solve_on(executor: Any, problem: ExcitationDesign, initial: list[np.ndarray],
              progress: Callable[[StartResult, int], None] | None) -> list[StartResult]:
    """Every start submitted to ``executor`` as :func:`solve_start`; the results in start order
    (``progress`` called as they finish). On an error or Ctrl-C the other starts are cancelled."""
    results: list[StartResult] = []
    payload = payload_of(problem)
    futures = [executor.submit(solve_start, payload, x0, index) for index, x0 in enumerate(initial)]
    try:
        for future in as_completed(futures):
            results.append(future.result())
            if progress is not None:
                progress(results[-1], len(initial))
    except BaseException:  # Ctrl-C or a failed start: do not leave the other starts running
        for future in futures:
            future.cancel()
        raise
    results.sort(key=lambda result: result.index)
    return results


def _best_start(problem: ExcitationDesign, results: list[StartResult]) -> StartResult:
    """The successful start of least criterion; :class:`DesignError` when none succeeded, a
    :class:`ShrunkDesignWarning` (for the caller of :func:`design_excitation`) when it was scaled down."""
    good = [result for result in results if result.success]
    if not good:
        details = "; ".join(
            f"start {r.index}: {r.status}" + ("" if r.feasible else f" ({', '.join(problem.broken(r.x)) or 'bounds'}"
                                                                  " not met)") for r in results
        )
        raise DesignError(f"IPOPT found no acceptable trajectory in {len(results)} start(s): {details}")
    best = min(good, key=lambda result: result.criterion_value)
    if best.shrunk:
        warnings.warn(
            f"the best start ({best.index}) met the {problem.settings.rate_hz:g} Hz bounds only after its oscillation "
            "was scaled down onto them: the trajectory is weaker than the optimiser's (more constraint_points or "
            "refinements avoid it)", ShrunkDesignWarning, stacklevel=3)
    return best


def _trajectory_metadata(problem: ExcitationDesign, values: dict[str, Any], best: StartResult,
                         results: list[StartResult], starts: int, seed: int | None) -> dict[str, Any]:
    """What the designed trajectory carries: ``model, criterion, cost, cond, bounds, solver, robot``."""
    s = problem.settings
    return {
        "model": problem.model.value,
        "criterion": problem.criterion.name,
        "cost": values["cost"],
        "cond": values["cond"],
        "criterion_value": values["criterion"],
        "bounds": problem.bounds.to_dict(),
        "solver": {
            "name": "ipopt",
            "sqp_after": s.sqp_after if problem.hands_over else None,
            "status": best.status,
            "iterations": best.iterations,
            "starts": starts,
            "seed": seed,
            "best_start": best.index,
            "cost_samples": s.cost_samples,
            "constraint_points": s.constraint_points,
            "rate_hz": s.rate_hz,
            "effects": [effect.name for effect in problem.effects],
            "per_start": [result.to_dict() for result in results],
        },
        "robot": problem.robot.name,
    }
