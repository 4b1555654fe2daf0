"""Variable projection: linear coefficients inside, shape parameters outside.

The model is ``y ≈ A₀ θ₀ + Σ_b C_b(s_b) θ_b`` per sample and channel: ``A₀`` the fixed columns
(the base regressor, effects already chosen), ``C_b`` the columns of shaped effects
(:mod:`dynamics.effects.shaped`) with shape parameters ``s_b``. For fixed ``s`` the weighted least
squares in ``θ = (θ₀, θ_b…)`` has a closed form (:mod:`estimation.estimators.separable_least_squares`,
per channel); the shape parameters minimise the *projected* weighted residual
``f(s) = ‖W^½ P⊥(s) y‖²`` (Golub & Pereyra, "The differentiation of pseudo-inverses and nonlinear
least squares problems whose variables separate", SIAM J. Numer. Anal. 10, 1973). The search is
Levenberg–Marquardt on ``f`` with Kaufman's Jacobian ``J_j = −P⊥ (∂C/∂s_j) θ̂`` (Kaufman, BIT 15,
1975) and the exact gradient ``∇f = 2 Jᵀ W r``; the derivatives ``∂C/∂s`` come from the effects' own
CasADi graphs (one named ``casadi.Function`` per effect, built once, cached, mapped over the
samples). Bounds are kept by projection (a shape held at a bound its descent direction leaves is left out of
the step: :meth:`_ShapeSearch.free`); positive scales (velocities) are searched on ``log s``.
The search starts from every point of the declared grid (:func:`dynamics.effects.shaped.start_grid`),
evaluated by the linear solve alone, and refines the best few valley floors (one start a valley).

At the optimum the covariance of ``(θ, s)`` is ``σ̂² (J_fᵀ W J_f)⁻¹`` with the Jacobian of the
*full* problem ``J_f = [A(s), (∂C/∂s) θ̂]`` and ``σ̂² = f / (N m − p − n_s)``: the standard
deviations of the linear coefficients include the uncertainty of the shapes.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace
from typing import Literal

import numpy as np
from numpy.typing import NDArray

from estimation.estimators.bordered_normal import FixedFactor
from estimation.estimators.effect_blocks import Block, ShapeSearchError, States
from estimation.estimators.shape_starts import grid_costs, product_grid, valley_floors
from estimation.estimators.separable_least_squares import (
    FixedPart,
    LinearSolution,
    full_information,
    residuals,
    sample_scores,
    solve_linear,
)
from estimation.uncertainty.batch_means import batch_length, batch_means

__all__ = ["ShapeFit", "fit_shapes"]

#: the latest linear solves a shape search keeps, beside the lowest (:meth:`_ShapeSearch.remember`)
KEPT_SOLVES = 4


@dataclass(frozen=True)
class ShapeFit:
    """Result of :func:`fit_shapes`.

    Attributes
    ----------
    shape
        Fitted shape values, all blocks in order.
    theta
        Linear coefficients ``(θ₀, θ_b…)``.
    cov
        Covariance of ``(θ, s)`` from the full Jacobian (``σ̂²`` included).
    rss
        Weighted residual sum of squares.
    names
        Shape-parameter names.
    iterations
        Levenberg–Marquardt iterations of the best start.
    """

    shape: NDArray[np.float64]
    theta: NDArray[np.float64]
    cov: NDArray[np.float64]
    rss: float
    names: tuple[str, ...]
    iterations: int

    @property
    def n_linear(self) -> int:
        return self.theta.shape[0]

    @property
    def shape_std(self) -> NDArray[np.float64]:
        return np.sqrt(np.clip(np.diag(self.cov)[self.n_linear:], 0.0, None))

    @property
    def theta_std(self) -> NDArray[np.float64]:
        return np.sqrt(np.clip(np.diag(self.cov)[: self.n_linear], 0.0, None))


def fit_shapes(
    fixed: FixedPart,
    blocks: Sequence[Block],
    states: States,
    weights: NDArray[np.float64],
    *,
    starts: NDArray[np.float64] | None = None,
    refine: int = 3,
    max_iter: int = 60,
    tol: float = 1e-10,
    covariance: Literal["hac", "white", "none"] = "hac",
    segments: Sequence[tuple[int, int]] | None = None,
    factored: FixedFactor | None = None,
) -> ShapeFit:
    """Variable projection: the shapes minimising the projected weighted residual, then ``θ`` and
    the full covariance.

    Parameters
    ----------
    fixed
        The fixed columns and measured channels.
    blocks
        The effects whose columns are appended (shaped or plain).
    states
        The record's joint states.
    weights
        Channel weights ``(m,)`` (kept fixed).
    starts
        Starting points ``(S, n_s)``; default the blocks' declared grid.
    refine
        The best this many valley floors of the grid (by the linear solve alone:
        :func:`estimation.estimators.shape_starts.valley_floors`) are refined.
    max_iter, tol
        Levenberg–Marquardt iterations and relative decrease of ``f`` that stops it.
    covariance
        ``"hac"`` (default): batch-means sandwich ``H⁻¹ (Σ_b S_b S_bᵀ) H⁻¹`` over blocks of
        consecutive samples (:func:`batch_length`), which holds when the residuals are correlated
        in time (derivative errors near velocity reversals, unmodelled slow effects); ``"white"``:
        ``σ̂² H⁻¹``; ``"none"``: skip it (a screening fit).
    segments
        ``(start, stop)`` samples of each segment of a stacked record: the batches restart at each
        boundary (:mod:`estimation.uncertainty.batch_means`).
    factored
        The fixed block's factor at ``weights`` (:class:`~estimation.estimators.bordered_normal.FixedFactor`),
        shared by the fits of a round; default: factored here, once for every linear solve of the search.

    Raises
    ------
    ShapeSearchError
        When the columns are non-finite or singular at every start, or the search ends non-finite.
    """
    search = _ShapeSearch(fixed, blocks, states, weights, factored)
    s, iterations = search.best(search.candidates(starts, refine), max_iter, tol)
    if covariance == "none":  # a screening fit: neither the residual nor the information is needed
        solution = search.solution_at(s)
        size = solution.normal.shape[0] + len(search.parameters)
        return ShapeFit(np.asarray(s, dtype=float), solution.theta, np.full((size, size), np.nan), solution.rss,
                        search.names, iterations)
    solution, residual, information = search.at_optimum(s)
    cov = _covariance(search, s, solution, residual, information, covariance, segments)
    return ShapeFit(np.asarray(s, dtype=float), solution.theta, cov, solution.rss, search.names, iterations)


def _covariance(search: _ShapeSearch, s: NDArray[np.float64], solution: LinearSolution, residual: NDArray[np.float64],
                information: NDArray[np.float64], covariance: Literal["hac", "white"],
                segments: Sequence[tuple[int, int]] | None) -> NDArray[np.float64]:
    """Covariance of ``(θ, s)`` at the optimum: ``σ̂² H⁻¹`` (``"white"``), or the batch-means
    sandwich, never below it on the diagonal (``"hac"``); :class:`ShapeSearchError` when ``H`` is singular."""
    fixed = search.fixed
    dof = fixed.n_rows - information.shape[0]
    sigma2 = solution.rss / max(dof, 1)
    try:
        inverse = _inverse(information)
        if covariance == "hac":
            scores = sample_scores(fixed, search.blocks, solution, search.weights, residual)
            meat = batch_means(scores, batch_length(residual, search.weights, segments), segments)
            cov = inverse @ meat @ inverse * fixed.n_samples / max(fixed.n_samples - information.shape[0], 1)
            cov = np.maximum(np.diag(cov), sigma2 * np.diag(inverse))  # never below the white-noise value
            cov = _with_diagonal(sigma2 * inverse, cov)
        else:
            cov = sigma2 * inverse
    except np.linalg.LinAlgError:
        names = search.names
        raise ShapeSearchError(f"shape parameters {', '.join(names)} are not determined by these data at the optimum "
                               f"({', '.join(f'{n} = {v:.4g}' for n, v in zip(names, s))})") from None
    return cov


class _ShapeSearch:
    """The projected residual ``f(s)`` of one problem and its bounded Levenberg–Marquardt search in
    ``u`` (``log s`` for log-scale parameters, ``s`` otherwise)."""

    def __init__(self, fixed: FixedPart, blocks: Sequence[Block], states: States, weights: NDArray[np.float64],
                 factored: FixedFactor | None = None) -> None:
        self.fixed, self.blocks, self.states, self.weights = fixed, blocks, states, weights
        self.factored = FixedFactor.of(fixed.gram, weights) if factored is None else factored
        self.parameters = [parameter for block in blocks for parameter in block.parameters]
        self.names = tuple(parameter.name for parameter in self.parameters)
        self.logs = np.array([parameter.log_scale for parameter in self.parameters], dtype=bool)
        self.u_lower = self.to_u(np.array([parameter.lower for parameter in self.parameters]))
        self.u_upper = self.to_u(np.array([parameter.upper for parameter in self.parameters]))
        self.touched = sorted({row for block in blocks for row in block.rows})
        self.solved: dict[bytes, LinearSolution] = {}  # by the shapes' bytes (:meth:`remember`)
        self.evaluated: list[dict[bytes, tuple]] = [{} for _ in blocks]  # per block, by its shape's bytes (:meth:`evaluate`)
        self.lowest: bytes | None = None

    def to_u(self, s: NDArray[np.float64]) -> NDArray[np.float64]:
        return np.where(self.logs, np.log(np.where(self.logs, s, 1.0)), s)

    def to_s(self, u: NDArray[np.float64]) -> NDArray[np.float64]:
        return np.where(self.logs, np.exp(np.where(self.logs, u, 0.0)), u)

    def split(self, vector: NDArray[np.float64]) -> list[NDArray[np.float64]]:
        """All blocks' shapes in one vector, block by block."""
        parts, start = [], 0
        for block in self.blocks:
            parts.append(np.asarray(vector[start:start + block.n_shape], dtype=float))
            start += block.n_shape
        return parts

    def solve(self, s: NDArray[np.float64], *, jacobian: bool = False) -> LinearSolution:
        """The linear solve at ``s``; the search asks for the same ``s`` again (a step accepted by its cost is the
        next iteration's point, its end the optimum's), so the last solves are kept and one known without
        the derivatives gets only those evaluated (the normal equations are not assembled twice)."""
        key = np.asarray(s, dtype=float).tobytes()
        known = self.solved.get(key)
        if known is not None and (known.derivatives is not None or not jacobian):
            return known
        shapes = self.split(s)
        evaluated = [self.evaluate(index, shape, jacobian) for index, shape in enumerate(shapes)]
        if known is not None:
            known = replace(known, derivatives=[derivative for _, derivative in evaluated])
        else:
            known = solve_linear(self.fixed, self.blocks, self.states, shapes, self.weights, jacobian=jacobian,
                                 factored=self.factored, evaluated=evaluated)
        self.remember(key, known)
        return known

    def evaluate(self, index: int, shape: NDArray[np.float64], jacobian: bool
                 ) -> tuple[NDArray[np.float64], NDArray[np.float64] | None]:
        """Block ``index``'s columns at ``shape`` and, with ``jacobian``, their derivatives (:meth:`Block.evaluate`);
        the :data:`KEPT_SOLVES` latest of each block kept: a plain block's columns, or a shape held at its bound while
        the others move, are evaluated once, not at every solve (the same arrays, so the same solves)."""
        kept = self.evaluated[index]
        key = shape.tobytes()
        known = kept.pop(key, None)
        if known is None or (jacobian and known[1] is None):
            block = self.blocks[index]
            known = block.evaluate(self.states, shape, jacobian=True) if jacobian else (block.evaluate(self.states, shape), None)
        kept[key] = known
        for old in list(kept)[:-KEPT_SOLVES]:
            del kept[old]
        return known

    def remember(self, key: bytes, solution: LinearSolution) -> None:
        """Keep ``solution``: the :data:`KEPT_SOLVES` latest and the lowest RSS seen (the optimum, once found)."""
        self.solved.pop(key, None)
        self.solved[key] = solution
        if self.lowest is None or solution.rss < self.solved[self.lowest].rss:
            self.lowest = key
        for old in [item for item in self.solved if item != self.lowest][:-KEPT_SOLVES]:
            del self.solved[old]

    def cost(self, s: NDArray[np.float64], *, jacobian: bool = False) -> float:
        """``f(s)``, or ``inf`` where the columns are non-finite or singular; ``jacobian``: the solve kept with the
        shape derivatives (a step of the search: accepted, it is the next iteration's point, whose derivatives cost
        no more evaluated with the columns than after them)."""
        try:
            with np.errstate(all="ignore"):
                return self.solve(s, jacobian=jacobian).rss
        except (np.linalg.LinAlgError, FloatingPointError, ValueError):
            return np.inf

    def candidates(self, starts: NDArray[np.float64] | None, refine: int) -> list[NDArray[np.float64]]:
        """The starts refined: the best ``refine`` valley floors of ``starts`` (default the blocks' grid) by the linear
        solve alone (:func:`estimation.estimators.shape_starts.valley_floors`)."""
        if not self.parameters:
            return [np.zeros(0)]
        grid = product_grid(self.blocks) if starts is None else np.atleast_2d(np.asarray(starts, dtype=float))
        costs = self.grid_costs(grid)
        finite = np.flatnonzero(np.isfinite(costs))
        if finite.size == 0:
            raise ShapeSearchError(
                f"shape search for {', '.join(self.names)}: the columns are non-finite or singular at every start "
                f"({len(grid)} tried): check the effect's law and its bounds")
        return [grid[index] for index in valley_floors(grid, costs, refine)]

    def grid_costs(self, grid: NDArray[np.float64]) -> NDArray[np.float64]:
        """``f`` at every grid point: one block's points batched (:func:`estimation.estimators.shape_starts.grid_costs`,
        equal to the linear solve's to rounding: they only choose the starts), the rest, and any point the batch
        leaves to it, by the linear solve."""
        costs = np.full(grid.shape[0], np.nan)
        if len(self.blocks) == 1 and grid.shape[0] > 1 and self.factored is not None:
            costs = grid_costs(self.fixed, self.blocks[0], self.states, grid, self.weights, self.factored)
        for index in np.flatnonzero(np.isnan(costs)):
            costs[index] = self.cost(grid[index])
        return costs

    def best(self, candidates: list[NDArray[np.float64]], max_iter: int, tol: float) -> tuple[NDArray[np.float64], int]:
        """The lowest finite ``f`` reached from the candidates, and its iterations."""
        best: tuple[float, NDArray[np.float64], int] | None = None
        for start in candidates:
            s, f, iterations = self.levenberg_marquardt(start, max_iter, tol)
            if np.isfinite(f) and (best is None or f < best[0]):
                best = (f, s, iterations)
        if best is None:
            raise ShapeSearchError(f"shape search for {', '.join(self.names)} ended non-finite from every start")
        return best[1], best[2]

    def solution_at(self, s: NDArray[np.float64]) -> LinearSolution:
        """The linear solution at the optimum ``s``, with the shape derivatives."""
        try:
            with np.errstate(all="ignore"):
                return self.solve(s, jacobian=bool(self.parameters))
        except (np.linalg.LinAlgError, FloatingPointError) as error:
            raise ShapeSearchError(f"shape search for {', '.join(self.names) or 'the linear columns'}: {error} at the "
                                   "optimum") from None

    def at_optimum(self, s: NDArray[np.float64]) -> tuple[LinearSolution, NDArray[np.float64], NDArray[np.float64]]:
        """The linear solution (with the shape derivatives), residual and information at ``s``."""
        solution = self.solution_at(s)
        with np.errstate(all="ignore"):
            residual = residuals(self.fixed, self.blocks, solution)
        if self.parameters:
            information, _ = full_information(self.fixed, self.blocks, solution, self.weights, residual)
        else:
            information = solution.normal
        return solution, residual, information

    def levenberg_marquardt(self, start: NDArray[np.float64], max_iter: int, tol: float
                            ) -> tuple[NDArray[np.float64], float, int]:
        """Bounded Levenberg–Marquardt on ``u`` from ``start``: the shapes, ``f`` there and the iterations."""
        u = np.clip(self.to_u(np.asarray(start, dtype=float)), self.u_lower, self.u_upper)
        if u.size == 0:
            return self.to_s(u), self.cost(self.to_s(u)), 0
        damping = 1e-3
        f = np.inf
        iterations = 0
        for iterations in range(1, max_iter + 1):
            s = self.to_s(u)
            try:
                with np.errstate(all="ignore"):
                    solution = self.solve(s, jacobian=True)
                    # the gradient needs the blocks' rows only
                    residual = residuals(self.fixed, self.blocks, solution, rows=self.touched)
                    information, gradient = full_information(self.fixed, self.blocks, solution, self.weights, residual)
            except (np.linalg.LinAlgError, FloatingPointError, ValueError):
                return s, np.inf, iterations
            f = solution.rss
            p = solution.normal.shape[0]
            # Gauss–Newton matrix of the projected problem: the Schur complement of the full one (Kaufman)
            cross = information[:p, p:]
            hessian = 2.0 * (information[p:, p:] - cross.T @ solution.solve(cross))
            chain = np.where(self.logs, s, 1.0)  # ds/du: s on a log scale, 1 otherwise
            gradient_u = gradient * chain
            hessian_u = hessian * np.outer(chain, chain)
            if not (np.all(np.isfinite(gradient_u)) and np.all(np.isfinite(hessian_u))):
                return s, np.inf, iterations
            improved = False
            free = self.free(u, gradient_u)
            for _ in range(30):
                diagonal = (np.diag(np.diag(hessian_u))
                            + 1e-12 * np.eye(u.size) * max(np.max(np.abs(np.diag(hessian_u))), 1e-300))
                try:
                    if free is None:
                        step = -np.linalg.solve(hessian_u + damping * diagonal, gradient_u)
                    else:  # the shapes held at their bounds stay there: the step of the others alone
                        step = np.zeros(u.size)
                        step[free] = -np.linalg.solve((hessian_u + damping * diagonal)[np.ix_(free, free)],
                                                      gradient_u[free])
                except np.linalg.LinAlgError:
                    damping *= 10
                    continue
                trial = np.clip(u + step, self.u_lower, self.u_upper)
                f_trial = self.cost(self.to_s(trial), jacobian=True)
                if np.isfinite(f_trial) and f_trial <= f:
                    decrease = f - f_trial
                    u = trial
                    damping = max(damping / 3, 1e-9)
                    improved = True
                    break
                damping *= 4
                if damping > 1e10:
                    break
            if not improved or decrease <= tol * max(f, 1e-300):
                break
        s = self.to_s(u)
        return s, self.cost(s), iterations

    def free(self, u: NDArray[np.float64], gradient_u: NDArray[np.float64]) -> NDArray[np.bool_] | None:
        """The shapes a step may move when some, not all, sit at a bound their descent direction leaves (the
        projected Newton step: Bertsekas, "Projected Newton methods for optimization problems with simple
        constraints", SIAM J. Control Optim. 20, 1982); ``None`` when none does, or all do (the full step, clipped).

        A step of every shape clipped at the bound moves the others by a step that assumed the held one moves
        too; it decreases ``f`` little and the search runs to its iteration limit (a ripple's period held at its
        lower bound beside seven shapes: 60 iterations a reweighting round)."""
        held = ((u <= self.u_lower) & (gradient_u > 0)) | ((u >= self.u_upper) & (gradient_u < 0))
        if not held.any() or held.all():
            return None
        return ~held


def _with_diagonal(matrix: NDArray[np.float64], diagonal: NDArray[np.float64]) -> NDArray[np.float64]:
    """``matrix`` rescaled to the given diagonal (its correlations kept)."""
    scale = np.sqrt(np.clip(diagonal, 0.0, None) / np.clip(np.diag(matrix), np.finfo(float).tiny, None))
    return matrix * np.outer(scale, scale)


def _inverse(matrix: NDArray[np.float64]) -> NDArray[np.float64]:
    scale = np.sqrt(np.diag(matrix))
    if np.any(~np.isfinite(scale)) or np.any(scale == 0):
        raise np.linalg.LinAlgError("singular")
    equilibrated = matrix / np.outer(scale, scale)
    eigenvalues, vectors = np.linalg.eigh(equilibrated)
    if eigenvalues[0] < 1e-14 * eigenvalues[-1]:
        raise np.linalg.LinAlgError("singular")
    return (vectors / eigenvalues) @ vectors.T / np.outer(scale, scale)
