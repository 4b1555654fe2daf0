"""Variable projection: linear coefficients inside, shape parameters outside.

The model is ``y ≈ A₀ θ₀ + Σ_b C_b(s_b) θ_b`` per sample and channel: ``A₀`` the fixed columns
(the base regressor, effects already chosen), ``C_b`` the columns of shaped effects
(:mod:`dynamics.effects.shaped`) with shape parameters ``s_b``. For fixed ``s`` the weighted least
squares in ``θ = (θ₀, θ_b…)`` has a closed form; the shape parameters minimise the *projected*
weighted residual ``f(s) = ‖W^½ P⊥(s) y‖²`` (Golub & Pereyra, "The differentiation of
pseudo-inverses and nonlinear least squares problems whose variables separate", SIAM J. Numer.
Anal. 10, 1973). The search is Levenberg–Marquardt on ``f`` with Kaufman's Jacobian
``J_j = −P⊥ (∂C/∂s_j) θ̂`` (Kaufman, BIT 15, 1975) and the exact gradient ``∇f = 2 Jᵀ W r``; the
derivatives ``∂C/∂s`` come from the effects' own CasADi graphs (one named ``casadi.Function`` per
effect, built once, cached, mapped over the samples). Bounds are kept by projection; positive
scales (velocities) are searched on ``log s``. The search starts from every point of the declared
grid (:func:`dynamics.effects.shaped.start_grid`), evaluated by the linear solve alone, and refines
the best few.

Everything is per channel: the Gram matrices ``A_cᵀA_c`` of the fixed part are formed once; a
shaped block touches only its own channels (one joint's torque for a per-joint law), so an
evaluation costs ``O(N p k)`` on those channels plus an ``O((p+k)³)`` solve.

At the optimum the covariance of ``(θ, s)`` is ``σ̂² (J_fᵀ W J_f)⁻¹`` with the Jacobian of the
*full* problem ``J_f = [A(s), (∂C/∂s) θ̂]`` and ``σ̂² = f / (N m − p − n_s)``: the standard
deviations of the linear coefficients include the uncertainty of the shapes.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Literal

import numpy as np
import scipy.linalg
from numpy.typing import NDArray

from dynamics.effects.shaped import start_grid
from estimation.uncertainty.batch_means import batch_length, batch_means
from estimation.estimators.effect_blocks import (  # noqa: F401  (re-exported: the columns' contract lives there)
    ROW_CHECK_STATES,
    Block,
    NoRowsError,
    ShapeSearchError,
    States,
    effect_block_functions,
    effect_columns,
    effect_rows,
)


@dataclass(frozen=True)
class FixedPart:
    """The fixed columns ``A₀`` and measured channels of one record, arranged per channel."""

    A: NDArray[np.float64]  # (m, N, p0)
    y: NDArray[np.float64]  # (m, N)
    gram: NDArray[np.float64]  # (m, p0, p0)
    moment: NDArray[np.float64]  # (m, p0)
    power: NDArray[np.float64]  # (m,)

    @classmethod
    def from_arrays(cls, Y: NDArray[np.float64], y: NDArray[np.float64]) -> FixedPart:
        """From ``Y (N, m, p0)`` and ``y (N, m)``."""
        A = np.ascontiguousarray(np.transpose(Y, (1, 0, 2)))
        values = np.ascontiguousarray(y.T)
        gram = np.matmul(A.transpose(0, 2, 1), A)
        moment = np.matmul(A.transpose(0, 2, 1), values[:, :, None])[:, :, 0]
        return cls(A, values, gram, moment, np.sum(values**2, axis=1))

    def extended(self, columns: NDArray[np.float64], rows: Sequence[int]) -> FixedPart:
        """With extra columns ``(N, rows, k)`` that are zero off ``rows``."""
        m, n_samples, _ = self.A.shape
        extra = np.zeros((m, n_samples, columns.shape[2]))
        extra[list(rows)] = columns.transpose(1, 0, 2)
        return FixedPart.from_arrays(np.concatenate([self.A, extra], axis=2).transpose(1, 0, 2), self.y.T)

    @property
    def n_fixed(self) -> int:
        return self.A.shape[2]

    @property
    def n_rows(self) -> int:
        return self.A.shape[0] * self.A.shape[1]


@dataclass(frozen=True)
class LinearSolution:
    """``θ`` at fixed shapes with what the search and the covariance need."""

    theta: NDArray[np.float64]
    rss: float  # weighted
    normal: NDArray[np.float64]
    columns: list[NDArray[np.float64]]  # per block (N, rows, k)
    derivatives: list[NDArray[np.float64]] | None  # per block (n_s, N, rows, k)


def _layout(blocks: Sequence[Block], n_fixed: int) -> list[slice]:
    slices, start = [], n_fixed
    for block in blocks:
        slices.append(slice(start, start + block.n_linear))
        start += block.n_linear
    return slices


def solve_linear(fixed: FixedPart, blocks: Sequence[Block], states: States, shapes: Sequence[NDArray[np.float64]],
                 weights: NDArray[np.float64], *, jacobian: bool = False) -> LinearSolution:
    """Weighted least squares in ``θ = (θ₀, θ_b…)`` at the given shapes, from per-channel Gram matrices."""
    p0 = fixed.n_fixed
    slices = _layout(blocks, p0)
    p = slices[-1].stop if slices else p0
    normal = np.zeros((p, p))
    right = np.zeros(p)
    normal[:p0, :p0] = np.tensordot(weights, fixed.gram, axes=1)
    right[:p0] = weights @ fixed.moment
    columns, derivatives = [], [] if jacobian else None
    for block, shape in zip(blocks, shapes):
        if jacobian:
            values, derivative = block.evaluate(states, shape, jacobian=True)
            derivatives.append(derivative)
        else:
            values = block.evaluate(states, shape)
        columns.append(values)
    for index, (block, values, where) in enumerate(zip(blocks, columns, slices)):
        for position, row in enumerate(block.rows):
            w, C = weights[row], values[:, position, :]
            normal[:p0, where] += w * (fixed.A[row].T @ C)
            normal[where, where] += w * (C.T @ C)
            right[where] += w * (C.T @ fixed.y[row])
            for other, other_values, other_where in zip(blocks[index + 1:], columns[index + 1:], slices[index + 1:]):
                if row in other.rows:
                    normal[where, other_where] += w * (C.T @ other_values[:, other.rows.index(row), :])
    normal = np.triu(normal) + np.triu(normal, 1).T
    theta = solve_normal(normal, right)
    rss = float(weights @ fixed.power - 2 * theta @ right + theta @ normal @ theta)
    return LinearSolution(theta, max(rss, 0.0), normal, columns, derivatives)


def solve_normal(normal: NDArray[np.float64], right: NDArray[np.float64]) -> NDArray[np.float64]:
    """``θ`` of the normal equations ``normal θ = right`` by Cholesky after equilibration (unit diagonal).

    Raises ``FloatingPointError`` for non-finite entries and ``LinAlgError`` for an all-zero column or
    rank-deficient columns (smallest eigenvalue of the equilibrated matrix below 1e-13 of the largest).
    """
    if not (np.all(np.isfinite(normal)) and np.all(np.isfinite(right))):
        raise FloatingPointError("non-finite columns")
    scale = np.sqrt(np.diag(normal))
    if np.any(scale == 0):
        raise np.linalg.LinAlgError("an all-zero column")
    equilibrated = normal / np.outer(scale, scale)
    eigenvalues = np.linalg.eigvalsh(equilibrated)
    if eigenvalues[0] < 1e-13 * eigenvalues[-1]:
        raise np.linalg.LinAlgError("rank-deficient columns")
    factor = scipy.linalg.cho_factor(equilibrated, check_finite=False)
    return scipy.linalg.cho_solve(factor, right / scale, check_finite=False) / scale


def residuals(fixed: FixedPart, blocks: Sequence[Block], solution: LinearSolution,
              rows: Sequence[int] | None = None) -> NDArray[np.float64]:
    """``y − A θ`` per channel, ``(m, N)``; with ``rows``, only those channels (the others zero)."""
    theta = solution.theta
    p0 = fixed.n_fixed
    if rows is None:
        values = fixed.y - np.matmul(fixed.A, theta[:p0])
    else:
        values = np.zeros_like(fixed.y)
        for row in rows:
            values[row] = fixed.y[row] - fixed.A[row] @ theta[:p0]
    for block, columns, where in zip(blocks, solution.columns, _layout(blocks, p0)):
        for position, row in enumerate(block.rows):
            if rows is None or row in rows:
                values[row] -= columns[:, position, :] @ theta[where]
    return values


def _shape_directions(fixed: FixedPart, blocks: Sequence[Block], solution: LinearSolution):
    """``D_j = (∂C/∂s_j) θ̂`` per shape parameter: list of ``(rows, (N, rows))``."""
    directions = []
    for block, derivative, where in zip(blocks, solution.derivatives, _layout(blocks, fixed.n_fixed)):
        values = derivative @ solution.theta[where]  # (n_s, N, rows)
        for j in range(block.n_shape):
            directions.append((block.rows, values[j]))
    return directions


def full_information(fixed: FixedPart, blocks: Sequence[Block], solution: LinearSolution,
                     weights: NDArray[np.float64], residual: NDArray[np.float64]):
    """``(J_fᵀWJ_f, gradient of f in s)`` for the full Jacobian ``J_f = [A, D]``."""
    p = solution.normal.shape[0]
    directions = _shape_directions(fixed, blocks, solution)
    n_s = len(directions)
    information = np.zeros((p + n_s, p + n_s))
    information[:p, :p] = solution.normal
    gradient = np.zeros(n_s)
    slices = _layout(blocks, fixed.n_fixed)
    for j, (rows, D) in enumerate(directions):
        for position, row in enumerate(rows):
            w, d = weights[row], D[:, position]
            information[:fixed.n_fixed, p + j] += w * (fixed.A[row].T @ d)
            for block, columns, where in zip(blocks, solution.columns, slices):
                if row in block.rows:
                    information[where, p + j] += w * (columns[:, block.rows.index(row), :].T @ d)
            gradient[j] += -2.0 * w * (residual[row] @ d)
            for i, (other_rows, other) in enumerate(directions[: j + 1]):
                if row in other_rows:
                    information[p + i, p + j] += w * (other[:, other_rows.index(row)] @ d)
    information = np.triu(information) + np.triu(information, 1).T
    return information, gradient


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
    solution: LinearSolution

    @property
    def n_linear(self) -> int:
        return self.theta.shape[0]

    @property
    def shape_std(self) -> NDArray[np.float64]:
        return np.sqrt(np.clip(np.diag(self.cov)[self.n_linear:], 0.0, None))

    @property
    def theta_std(self) -> NDArray[np.float64]:
        return np.sqrt(np.clip(np.diag(self.cov)[: self.n_linear], 0.0, None))


def _split(blocks: Sequence[Block], vector: NDArray[np.float64]) -> list[NDArray[np.float64]]:
    parts, start = [], 0
    for block in blocks:
        parts.append(np.asarray(vector[start:start + block.n_shape], dtype=float))
        start += block.n_shape
    return parts


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
        The best this many grid points (by the linear solve alone) are refined.
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

    Raises
    ------
    ShapeSearchError
        When the columns are non-finite or singular at every start, or the search ends non-finite.
    """
    parameters = [parameter for block in blocks for parameter in block.parameters]
    names = tuple(parameter.name for parameter in parameters)
    lower = np.array([parameter.lower for parameter in parameters])
    upper = np.array([parameter.upper for parameter in parameters])
    logs = np.array([parameter.log_scale for parameter in parameters], dtype=bool)

    def to_u(s):
        return np.where(logs, np.log(np.where(logs, s, 1.0)), s)

    def to_s(u):
        return np.where(logs, np.exp(np.where(logs, u, 0.0)), u)

    u_lower, u_upper = to_u(lower), to_u(upper)

    def cost(s):
        try:
            with np.errstate(all="ignore"):
                return solve_linear(fixed, blocks, states, _split(blocks, s), weights).rss
        except (np.linalg.LinAlgError, FloatingPointError, ValueError):
            return np.inf

    if not parameters:
        candidates = [np.zeros(0)]
    else:
        if starts is None:
            grid = _product_grid(blocks)
        else:
            grid = np.atleast_2d(np.asarray(starts, dtype=float))
        costs = np.array([cost(point) for point in grid])
        finite = np.flatnonzero(np.isfinite(costs))
        if finite.size == 0:
            raise ShapeSearchError(
                f"shape search for {', '.join(names)}: the columns are non-finite or singular at every start "
                f"({len(grid)} tried): check the effect's law and its bounds")
        order = finite[np.argsort(costs[finite])]
        candidates = [grid[index] for index in _distinct(order, grid, refine)]

    best: tuple[float, NDArray[np.float64], int] | None = None
    for start in candidates:
        s, f, iterations = _levenberg_marquardt(fixed, blocks, states, weights, start, to_u, to_s, u_lower, u_upper,
                                                logs, cost, max_iter, tol)
        if np.isfinite(f) and (best is None or f < best[0]):
            best = (f, s, iterations)
    if best is None:
        raise ShapeSearchError(f"shape search for {', '.join(names)} ended non-finite from every start")
    _, s, iterations = best
    try:
        with np.errstate(all="ignore"):
            solution = solve_linear(fixed, blocks, states, _split(blocks, s), weights, jacobian=bool(parameters))
            residual = residuals(fixed, blocks, solution)
    except (np.linalg.LinAlgError, FloatingPointError) as error:
        raise ShapeSearchError(f"shape search for {', '.join(names) or 'the linear columns'}: {error} at the optimum") from None
    if parameters:
        information, _ = full_information(fixed, blocks, solution, weights, residual)
    else:
        information = solution.normal
    dof = fixed.n_rows - information.shape[0]
    sigma2 = solution.rss / max(dof, 1)
    if covariance == "none":
        return ShapeFit(np.asarray(s, dtype=float), solution.theta, np.full(information.shape, np.nan), solution.rss,
                        names, iterations, solution)
    try:
        inverse = _inverse(information)
        if covariance == "hac":
            scores = sample_scores(fixed, blocks, solution, weights, residual)
            meat = batch_means(scores, batch_length(residual, weights, segments), segments)
            cov = inverse @ meat @ inverse * fixed.A.shape[1] / max(fixed.A.shape[1] - information.shape[0], 1)
            cov = np.maximum(np.diag(cov), sigma2 * np.diag(inverse))  # never below the white-noise value
            cov = _with_diagonal(sigma2 * inverse, cov)
        else:
            cov = sigma2 * inverse
    except np.linalg.LinAlgError:
        raise ShapeSearchError(f"shape parameters {', '.join(names)} are not determined by these data at the optimum "
                               f"({', '.join(f'{n} = {v:.4g}' for n, v in zip(names, s))})") from None
    return ShapeFit(np.asarray(s, dtype=float), solution.theta, cov, solution.rss, names, iterations, solution)


def _with_diagonal(matrix: NDArray[np.float64], diagonal: NDArray[np.float64]) -> NDArray[np.float64]:
    """``matrix`` rescaled to the given diagonal (its correlations kept)."""
    scale = np.sqrt(np.clip(diagonal, 0.0, None) / np.clip(np.diag(matrix), np.finfo(float).tiny, None))
    return matrix * np.outer(scale, scale)


def sample_scores(fixed: FixedPart, blocks: Sequence[Block], solution: LinearSolution, weights: NDArray[np.float64],
                  residual: NDArray[np.float64]) -> NDArray[np.float64]:
    """Per sample ``s_t = Σ_c w_c r_{c,t} J_{c,t}``, ``(N, p + n_s)``, ``J = [A, (∂C/∂s) θ̂]``."""
    weighted = weights[:, None] * residual  # (m, N)
    columns = [np.einsum("cn,cnp->np", weighted, fixed.A)]
    for block, values in zip(blocks, solution.columns):
        columns.append(np.einsum("nr,nrk->nk", weighted[list(block.rows)].T, values))
    if solution.derivatives is not None:
        for rows, D in _shape_directions(fixed, blocks, solution):
            columns.append(np.einsum("nr,nr->n", weighted[list(rows)].T, D)[:, None])
    return np.concatenate(columns, axis=1)


def _inverse(matrix: NDArray[np.float64]) -> NDArray[np.float64]:
    scale = np.sqrt(np.diag(matrix))
    if np.any(~np.isfinite(scale)) or np.any(scale == 0):
        raise np.linalg.LinAlgError("singular")
    equilibrated = matrix / np.outer(scale, scale)
    eigenvalues, vectors = np.linalg.eigh(equilibrated)
    if eigenvalues[0] < 1e-14 * eigenvalues[-1]:
        raise np.linalg.LinAlgError("singular")
    return (vectors / eigenvalues) @ vectors.T / np.outer(scale, scale)


def _product_grid(blocks: Sequence[Block]) -> NDArray[np.float64]:
    """The declared grids of the blocks: one block's grid at a time, the others at their reference
    (the blocks are coupled through the shared linear part only), plus all at their grid's i-th point."""
    parameters = [parameter for block in blocks for parameter in block.parameters]
    reference = np.array([parameter.reference for parameter in parameters])
    grids = [start_grid(block.parameters) for block in blocks]
    if len(blocks) == 1:
        return grids[0]
    points = []
    longest = max(len(grid) for grid in grids)
    for i in range(longest):  # the same start index on every block (a law on every joint)
        point, start = [], 0
        for grid in grids:
            point.append(grid[min(i, len(grid) - 1)])
        points.append(np.concatenate(point))
    start = 0
    for block, grid in zip(blocks, grids):
        for row in grid:
            point = reference.copy()
            point[start:start + block.n_shape] = row
            points.append(point)
        start += block.n_shape
    return np.unique(np.array(points), axis=0)


def _distinct(order: NDArray[np.int64], grid: NDArray[np.float64], count: int) -> list[int]:
    """The first ``count`` of ``order`` that are not neighbours of one already chosen (one start
    per valley)."""
    chosen: list[int] = []
    for index in order:
        if all(np.max(np.abs(np.log(np.abs(grid[index]) + 1e-9) - np.log(np.abs(grid[other]) + 1e-9))) > 1e-6
               for other in chosen):
            chosen.append(int(index))
        if len(chosen) == count:
            break
    return chosen


def _levenberg_marquardt(fixed, blocks, states, weights, start, to_u, to_s, u_lower, u_upper, logs, cost, max_iter, tol):
    """Bounded Levenberg–Marquardt on ``u`` (``log s`` for log-scale parameters)."""
    u = np.clip(to_u(np.asarray(start, dtype=float)), u_lower, u_upper)
    touched = sorted({row for block in blocks for row in block.rows})
    if u.size == 0:
        return to_s(u), cost(to_s(u)), 0
    damping = 1e-3
    f = np.inf
    iterations = 0
    for iterations in range(1, max_iter + 1):
        s = to_s(u)
        try:
            with np.errstate(all="ignore"):
                solution = solve_linear(fixed, blocks, states, _split(blocks, s), weights, jacobian=True)
                residual = residuals(fixed, blocks, solution, rows=touched)  # the gradient needs the blocks' rows only
                information, gradient = full_information(fixed, blocks, solution, weights, residual)
        except (np.linalg.LinAlgError, FloatingPointError, ValueError):
            return s, np.inf, iterations
        f = solution.rss
        p = solution.normal.shape[0]
        # Gauss–Newton matrix of the projected problem: the Schur complement of the full one (Kaufman)
        cross = information[:p, p:]
        hessian = 2.0 * (information[p:, p:] - cross.T @ _solve_many(solution.normal, cross))
        chain = np.where(logs, s, 1.0)  # ds/du: s on a log scale, 1 otherwise
        gradient_u = gradient * chain
        hessian_u = hessian * np.outer(chain, chain)
        if not (np.all(np.isfinite(gradient_u)) and np.all(np.isfinite(hessian_u))):
            return s, np.inf, iterations
        improved = False
        for _ in range(30):
            diagonal = np.diag(np.diag(hessian_u)) + 1e-12 * np.eye(u.size) * max(np.max(np.abs(np.diag(hessian_u))), 1e-300)
            try:
                step = -np.linalg.solve(hessian_u + damping * diagonal, gradient_u)
            except np.linalg.LinAlgError:
                damping *= 10
                continue
            trial = np.clip(u + step, u_lower, u_upper)
            f_trial = cost(to_s(trial))
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
    s = to_s(u)
    return s, cost(s), iterations


def _solve_many(normal: NDArray[np.float64], right: NDArray[np.float64]) -> NDArray[np.float64]:
    scale = np.sqrt(np.diag(normal))
    factor = scipy.linalg.cho_factor(normal / np.outer(scale, scale), check_finite=False)
    return scipy.linalg.cho_solve(factor, right / scale[:, None], check_finite=False) / scale[:, None]
