"""One step of the diagnosis: fit every candidate effect against the current model, per channel.

A candidate (plain or shaped) is a :class:`~estimation.estimators.effect_blocks.Block` appended to the
current model's columns; its fit is a variable-projection fit (:func:`fit_shapes`, which for a
plain effect is the linear solve alone) on the per-channel Gram matrices of the current columns,
so one trial costs ``O(N p k)`` on the candidate's channels and an ``O((p+k)³)`` solve, instead
of a least-squares solve of the whole stacked ``(N m) x (p+k)`` problem.

Each trial carries the nested-model F test ``F = ((RSS₀ − RSS₁)/q) / (RSS₁/(N m − p₁))`` with
``q`` the candidate's linear and shape parameters, and the Bayesian information criterion
``N m log(RSS₁/RSS₀) + q log(N m)`` by which candidates of different sizes are ranked (a law with
more shape parameters must explain more to win).
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterator, Sequence
from dataclasses import dataclass

import numpy as np
import scipy.special
from numpy.typing import NDArray

from dynamics.channels import is_joint_torque, torque_joint
from dynamics.effects.linear import POSITIVE_EFFECTS, Effect
from dynamics.models import IdentificationModel
from estimation.estimators.effect_blocks import Block, ShapeSearchError, States
from estimation.estimators.separable_least_squares import FixedPart, LinearSolution, residuals, solve_linear
from estimation.estimators.shape_starts import product_grid
from estimation.estimators.variable_projection import ShapeFit, fit_shapes


#: each term of a several-term friction law must exceed this many standard deviations
SIGNIFICANT_TERM = 3.0


@dataclass(frozen=True)
class Trial:
    """A candidate (one effect, or a friction law with its joint's offset) fitted on training data
    against the current model, or against the current model without the adopted effects ``without``
    (candidate indices: the laws it would replace)."""

    group: tuple[int, ...]
    blocks: tuple[Block, ...]
    fit: ShapeFit
    rss: float
    f_statistic: float
    p_value: float
    bic: float
    without: tuple[int, ...] = ()

    def coefficients(self, position: int) -> NDArray[np.float64]:
        """The linear coefficients of the ``position``-th block."""
        stop = self.fit.theta.shape[0] - sum(block.n_linear for block in self.blocks[position + 1:])
        return self.fit.theta[stop - self.blocks[position].n_linear: stop]

    def coefficient_std(self, position: int) -> NDArray[np.float64]:
        """Standard deviations of the ``position``-th block's linear coefficients (white residuals)."""
        std = self.fit.theta_std
        stop = std.shape[0] - sum(block.n_linear for block in self.blocks[position + 1:])
        return std[stop - self.blocks[position].n_linear: stop]

    def shapes(self) -> list[NDArray[np.float64]]:
        parts, start = [], 0
        for block in self.blocks:
            parts.append(self.fit.shape[start:start + block.n_shape])
            start += block.n_shape
        return parts

    @property
    def n_parameters(self) -> int:
        return sum(block.n_linear + block.n_shape for block in self.blocks)


def nested_test(rss: float, rss_augmented: float, count: int, n_rows: int, n_fixed: int) -> tuple[float, float, float]:
    """``(F, p_value, BIC difference)`` of ``count`` added parameters (module docstring): the current
    model's weighted RSS ``rss`` with ``n_fixed`` parameters on ``n_rows`` rows, the augmented one's
    ``rss_augmented``."""
    dof = n_rows - n_fixed - count
    statistic = ((rss - rss_augmented) / count) / (rss_augmented / dof) if rss_augmented > 0 else np.inf
    # the F distribution's survival function (scipy.special.fdtrc is what scipy.stats.f.sf evaluates, without its
    # argument handling: 30x less time in a screen of ~1 ms)
    p_value = float(scipy.special.fdtrc(count, dof, statistic)) if np.isfinite(statistic) else 0.0
    bic = n_rows * np.log(max(rss_augmented, 1e-300) / rss) + count * np.log(n_rows)
    return float(statistic), p_value, float(bic)


def try_candidate(group: tuple[int, ...], blocks: Sequence[Block], fixed: FixedPart, states: States,
                  weights: NDArray[np.float64], rss: float, *, starts: NDArray[np.float64] | None = None,
                  search: bool = True) -> Trial:
    """Fit one candidate group; raises :class:`numpy.linalg.LinAlgError` when the current columns
    absorb plain candidates, :class:`ShapeSearchError` when a shaped search fails. Without
    ``search`` the shapes stay at ``starts`` (a screening by the linear solve alone)."""
    if all(block.n_shape == 0 for block in blocks):  # the linear solve is the fit (LinAlgError when absorbed)
        fit = _fitted(blocks, solve_linear(fixed, blocks, states, [np.zeros(0)] * len(blocks), weights), np.zeros(0))
    else:
        fit = None if search or starts is None else _screened(blocks, fixed, states, weights, starts[0])
    # a search from the grid whose law can end non-physical screens the same grid again (better_physical_optimum):
    # its points' columns are kept for that while the trial lasts, not evaluated twice
    with _grid_columns_kept(blocks, states, fit is None and search and starts is None):
        if fit is None:
            fit = fit_shapes(fixed, blocks, states, weights, starts=starts, refine=3 if starts is None else 1,
                             max_iter=60 if search else 0, covariance="none")
        count = sum(block.n_linear + block.n_shape for block in blocks)
        statistic, p_value, bic = nested_test(rss, fit.rss, count, fixed.n_rows, fixed.n_fixed)
        trial = Trial(tuple(group), tuple(blocks), fit, fit.rss, statistic, p_value, bic)
        if search and any(block.n_shape for block in blocks) and _non_physical(trial):
            better = better_physical_optimum(blocks, fixed, states, weights, fit.rss)
            if better is not None:
                statistic, p_value, bic = nested_test(rss, better.rss, count, fixed.n_rows, fixed.n_fixed)
                return Trial(tuple(group), tuple(blocks), better, better.rss, statistic, p_value, bic)
    return trial


@contextlib.contextmanager
def _grid_columns_kept(blocks: Sequence[Block], states: States, grid: bool) -> Iterator[None]:
    """Each block's columns along ``states`` kept by shape (:meth:`Block.keeping_shapes`) when ``grid`` (a search from
    the blocks' grid) and a block's law can be found non-physical (:func:`_non_physical`), else nothing kept."""
    physical = any(getattr(block.effect, "physical_kind", block.effect.name) in POSITIVE_EFFECTS for block in blocks)
    with contextlib.ExitStack() as stack:
        if grid and physical:
            for block in blocks:
                stack.enter_context(block.keeping_shapes(states))
        yield


def _non_physical(trial: Trial) -> bool:
    """Whether a law's coefficients have a non-physical sign (a friction or armature below zero)."""
    return any(getattr(block.effect, "physical_kind", block.effect.name) in POSITIVE_EFFECTS
               and np.any(np.asarray(trial.coefficients(position)) <= 0) for position, block in enumerate(trial.blocks))


def better_physical_optimum(blocks: Sequence[Block], fixed: FixedPart, states: States, weights: NDArray[np.float64],
                            rss: float) -> ShapeFit | None:
    """A physical optimum of a shaped law that fits the training data better than the non-physical one the
    search ended in (weighted RSS ``rss``), or ``None``.

    The search from the grid's valley floors is local: a Stribeck law can end where its shape trades against the
    viscous term over the velocities a joint reaches (``fc = 64.7, fs = −56.3`` for a truth ``5, 3``), a local
    optimum, while the best physical point of the shape grid (screened by the linear solve), refined by variable
    projection, fits better still. Only a *better* optimum of the same unconstrained problem replaces the search's:
    the law is never held physical at a cost (a constrained optimum worse than a non-physical one is the data
    asking for another law, which is refused as before)."""
    screened = [fit for fit in (_screened(blocks, fixed, states, weights, shape) for shape in product_grid(blocks))
                if fit is not None]
    for fit in sorted(screened, key=lambda fit: fit.rss):
        if _non_physical(Trial((), tuple(blocks), fit, fit.rss, 0.0, 1.0, 0.0)):
            continue
        try:
            refined = fit_shapes(fixed, blocks, states, weights, starts=fit.shape[None, :], refine=1, max_iter=60,
                                 covariance="none")
        except ShapeSearchError:
            refined = fit
        if _non_physical(Trial((), tuple(blocks), refined, refined.rss, 0.0, 1.0, 0.0)):
            refined = fit
        return refined if refined.rss < rss else None
    return None


def _screened(blocks: Sequence[Block], fixed: FixedPart, states: States, weights: NDArray[np.float64],
              shape: NDArray[np.float64]) -> ShapeFit | None:
    """The screening fit at ``shape`` by the linear solve alone (what :func:`fit_shapes` gives without
    iterations), or ``None`` where the columns are singular or non-finite there (the full search then
    says why)."""
    parts, start = [], 0
    for block in blocks:
        parts.append(np.asarray(shape[start:start + block.n_shape], dtype=float))
        start += block.n_shape
    try:
        with np.errstate(all="ignore"):
            solution = solve_linear(fixed, blocks, states, parts, weights)
    except (np.linalg.LinAlgError, FloatingPointError, ValueError):
        return None
    if not (np.isfinite(solution.rss) and np.all(np.isfinite(solution.theta))):
        return None
    return _fitted(blocks, solution, shape)


def _fitted(blocks: Sequence[Block], solution: LinearSolution, shape: NDArray[np.float64]) -> ShapeFit:
    """A screening :class:`ShapeFit` (no covariance) from the linear solution at ``shape``."""
    n_total = solution.theta.shape[0] + shape.shape[0]
    names = tuple(parameter.name for block in blocks for parameter in block.parameters)
    return ShapeFit(np.asarray(shape, dtype=float), solution.theta, np.full((n_total, n_total), np.nan), solution.rss,
                    names, 0)


def weighted_error(fixed: FixedPart, blocks: Sequence[Block], states: States, shapes: Sequence[NDArray[np.float64]],
                   theta: NDArray[np.float64], weights: NDArray[np.float64]) -> tuple[float, NDArray[np.float64]]:
    """Weighted MSE ``Σ_c w_c mean(r_c²)`` of ``θ`` (trained elsewhere) on a record, and ``r (m, N)``."""
    columns = [block.evaluate(states, shape) for block, shape in zip(blocks, shapes)]
    residual = residuals(fixed, blocks, LinearSolution(theta, 0.0, np.zeros((0, 0)), columns, None))
    return float(weights @ np.mean(residual**2, axis=1)), residual


def wrong_sign(trial: Trial, std: NDArray[np.float64] | None = None) -> str | None:
    """Why a candidate's estimate is not that effect, or ``None``: a friction law or armature
    estimated negative, a negative stiffness, a term of a several-term law within :data:`SIGNIFICANT_TERM`
    standard deviations of zero (``std``: the standard deviations of the trial's linear coefficients,
    block by block; default the fit's own), a shape parameter stopped at its bound."""
    stops = np.cumsum([block.n_linear for block in trial.blocks])
    for position, block in enumerate(trial.blocks):
        name = block.effect.name
        coefficients = trial.coefficients(position)
        if getattr(block.effect, "physical_kind", name) in POSITIVE_EFFECTS:
            if np.any(np.asarray(coefficients) <= 0):
                return f"{candidate_label(block.effect)} is estimated with a non-physical sign (a friction or inertia below zero)"
            if coefficients.shape[0] > 1:  # a law with several terms (Stribeck: fc, fs) needs each of them
                term_std = (trial.coefficient_std(position) if std is None
                            else std[stops[position] - block.n_linear: stops[position]])
                weak = [f"{term} = {value:.3g} ± {sigma:.2g}" for term, value, sigma in zip(block.names, coefficients, term_std)
                        if value < SIGNIFICANT_TERM * sigma]
                if weak:
                    return (f"its term {', '.join(weak)} is not significantly above zero: a law with fewer terms "
                            "describes the data")
        if name == "spring" and np.any(coefficients <= 0):
            return "a negative stiffness is not a physical spring (it pushes away from its rest position)"
    start = 0
    for block in trial.blocks:
        for parameter in block.parameters:
            value = trial.fit.shape[start]
            start += 1
            span = parameter.upper - parameter.lower
            if min(value - parameter.lower, parameter.upper - value) <= 1e-4 * span:
                return (f"its shape parameter {parameter.name} = {value:.4g} stopped at a bound [{parameter.lower:g}, "
                        f"{parameter.upper:g}]: the data ask for another law")
    return None


def direction_slopes(trial: Trial, model: IdentificationModel, std: NDArray[np.float64] | None = None,
                     held: Sequence[Block] = ()) -> str | None:
    """Why a viscous slope differing by direction (``viscous:direction``) is not that law, or ``None``: each
    direction's slope ``fv_j ± fvd_j`` must be positive (a friction that pushes a joint along one way is no
    friction), so ``|fvd_j| < fv_j`` with ``fv_j`` the joint's viscous coefficient fitted beside it in the trial (the
    declared model's base column ``fv{j}``, first among the trial's coefficients); a joint without a viscous law
    has slopes ``±fvd_j``, one of them negative. With ``std`` (the trial's linear coefficients' standard deviations,
    block by block, as :func:`wrong_sign` takes them) the weaker slope must stay positive by
    :data:`SIGNIFICANT_TERM` of ``fvd_j``'s standard deviations, as each term of a several-term law must.

    ``held``: the blocks the current model holds beside the declared columns in the trial's fit (the adopted ones it
    keeps, in their order: the trial's coefficients are the declared model's, then these, then the trial's own). A
    direction law among them is checked at the trial's estimate too (slope above zero): a move whose model turns a
    held direction law non-physical (its joint's ``fv`` falls below ``|fvd|`` once another law takes part of the
    viscous column) is refused at that move, never left for the final refit to drop after it changed the search's
    path."""
    names = model.base.names
    theta = np.asarray(trial.fit.theta, dtype=float)

    def viscous(joint: int) -> tuple[str, float]:
        name = f"fv{joint + 1}"
        return name, (float(theta[names.index(name)]) if name in names else 0.0)

    stops = np.cumsum([block.n_linear for block in trial.blocks])
    for position, block in enumerate(trial.blocks):
        if block.effect.name != "viscous:direction":
            continue
        spread = (np.zeros(block.n_linear) if std is None
                  else np.asarray(std[stops[position] - block.n_linear: stops[position]], dtype=float))
        for joint, direction, sigma in zip(joints_of(block, model), trial.coefficients(position), spread):
            name, slope = viscous(joint)
            if abs(direction) + SIGNIFICANT_TERM * sigma >= slope:
                margin = "" if std is None else f" within {SIGNIFICANT_TERM:g} standard deviations ({sigma:.2g}) of"
                return (f"{candidate_label(block.effect)} on tau{joint + 1} is estimated with a non-physical slope "
                        f"({name} = {slope:.3g}, fvd{joint + 1} = {float(direction):.3g}: one direction's viscous "
                        f"slope fv - |fvd|{margin} at or below zero)")
    stop = theta.shape[0] - int(stops[-1] if len(stops) else 0)
    start = stop - sum(block.n_linear for block in held)
    for block in held:
        coefficients, start = theta[start: start + block.n_linear], start + block.n_linear
        if block.effect.name != "viscous:direction":
            continue
        for joint, direction in zip(joints_of(block, model), coefficients):
            name, slope = viscous(joint)
            if abs(direction) >= slope:
                return (f"it turns the model's {candidate_label(block.effect)} on tau{joint + 1} non-physical ({name} "
                        f"= {slope:.3g}, fvd{joint + 1} = {float(direction):.3g} beside it: one direction's viscous "
                        "slope fv - |fvd| at or below zero)")
    return None


def joints_of(block: Block, model: IdentificationModel) -> tuple[int, ...]:
    """The joints (0-based) whose torque rows a block reaches."""
    joints = []
    for row in block.rows:
        channel = model.channels[row]
        if is_joint_torque(channel):
            joints.append(torque_joint(channel))
    return tuple(joints)


def trial_starts(previous: ShapeFit | None) -> NDArray[np.float64] | None:
    """Start from the candidate's last optimum once it has one (the grid only on the first round)."""
    if previous is None or previous.shape.size == 0:
        return None
    return previous.shape[None, :]


def fit_or_reason(group: tuple[int, ...], blocks: Sequence[Block], fixed: FixedPart, states: States,
                  weights: NDArray[np.float64], rss: float, previous: ShapeFit | None, *, search: bool = True) -> Trial | str:
    """A :class:`Trial`, or the reason the candidate cannot be fitted here (``search``: see
    :func:`try_candidate`; a candidate without a previous fit is always searched)."""
    try:
        return try_candidate(group, blocks, fixed, states, weights, rss, starts=trial_starts(previous),
                             search=search or previous is None)
    except np.linalg.LinAlgError:
        return "not identifiable: the base parameters already absorb it"
    except ShapeSearchError as error:
        return f"shape search failed: {error}"


def candidate_label(effect: Effect) -> str:
    return getattr(effect, "spec", effect.name)
