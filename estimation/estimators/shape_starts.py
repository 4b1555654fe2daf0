"""Where a shape search starts: the blocks' declared grid, its costs, and one start a valley of them.

:func:`estimation.estimators.variable_projection.fit_shapes` evaluates the projected residual ``f(s)`` (the
weighted RSS of the linear solve at the shapes ``s``) at every point of the grid (:func:`product_grid`, or the
starts given) and refines the lowest valley floors (:func:`valley_floors`): Levenberg–Marquardt from two
neighbouring grid points descends into the same optimum, so a second start is spent only in another valley.

For one block appended to the fixed columns the grid points differ only in the block's columns ``C(s_g)``:
:func:`grid_costs` forms the products ``A_cᵀ C(s_g)`` of a batch of points as one matrix product on each of the
block's channels (the fixed columns read once, not once a point), and each point's RSS from the Schur complement of
its border (Golub & Van Loan, *Matrix Computations*, 4th ed., §3.2.10), the fixed block factored once
(:class:`~estimation.estimators.bordered_normal.FixedFactor`). In the equilibrated variables of
:mod:`estimation.estimators.bordered_normal`,

    ``f(s) = P − b₀ᵀ z₀ − vᵀ S⁻¹ v``,  ``z₀ = E₀₀⁻¹ b₀``,  ``S = E₁₁ − E₁₀ E₀₀⁻¹ E₀₁``,  ``v = b₁ − E₁₀ z₀``,

with ``P = Σ_c w_c ‖y_c‖²`` and ``b`` the equilibrated right-hand side. A point whose columns are not finite, whose
``S`` is not positive definite, or whose rank the bound of :mod:`~estimation.estimators.bordered_normal` does not
decide is returned as NaN: the caller solves it alone (the same verdict as every other solve). The values equal
the linear solve's to rounding; they choose the starts only, and the search solves again at each start.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from dynamics.effects.shaped import start_grid
from estimation.estimators.bordered_normal import MARGIN, RANK_THRESHOLD, FixedFactor
from estimation.estimators.effect_blocks import Block, States
from estimation.estimators.separable_least_squares import FixedPart

__all__ = ["BATCH", "grid_costs", "product_grid", "valley_floors"]


def product_grid(blocks: Sequence[Block]) -> NDArray[np.float64]:
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
        points.append(np.concatenate([grid[min(i, len(grid) - 1)] for grid in grids]))
    start = 0
    for block, grid in zip(blocks, grids):
        for row in grid:
            point = reference.copy()
            point[start:start + block.n_shape] = row
            points.append(point)
        start += block.n_shape
    return np.unique(np.array(points), axis=0)


def valley_floors(grid: NDArray[np.float64], costs: NDArray[np.float64], count: int) -> list[int]:
    """The ``count`` lowest points of ``grid`` that are lower than each of their neighbours: one start a valley
    of the cost over the grid (Levenberg–Marquardt from two neighbouring points descends into the same optimum).

    Neighbours: every coordinate the same grid value or the next one up or down (each parameter's values ranked);
    points with a non-finite cost are neither starts nor neighbours. Of equal costs the earlier point of the grid
    is the lower."""
    finite = np.flatnonzero(np.isfinite(costs))
    ranks = np.stack([np.unique(column, return_inverse=True)[1] for column in grid.T], axis=1)[finite]
    floors = []
    for position, index in enumerate(finite):
        near = finite[np.all(np.abs(ranks - ranks[position]) <= 1, axis=1)]
        if all((costs[index], index) <= (costs[other], other) for other in near):
            floors.append(int(index))
    floors.sort(key=lambda index: (costs[index], index))
    return floors[:count]


#: grid points whose columns are held at once (14 000 samples, two columns: 7 MB)
BATCH = 32


def grid_costs(fixed: FixedPart, block: Block, states: States, grid: NDArray[np.float64],
               weights: NDArray[np.float64], factored: FixedFactor) -> NDArray[np.float64]:
    """``f`` at each point of ``grid (G, n_s)`` for ``block`` appended to ``fixed`` at channel ``weights``; NaN where
    the point must be solved alone (module docstring)."""
    right = weights @ fixed.moment
    start = right / factored.scale
    solved = factored.solve(start)
    rest = float(weights @ fixed.power - start @ solved)
    costs = np.full(grid.shape[0], np.nan)
    with np.errstate(all="ignore"):
        for first in range(0, grid.shape[0], BATCH):
            points = grid[first:first + BATCH]
            costs[first:first + points.shape[0]] = _batch(fixed, block, states, points, weights, factored, solved, rest)
    return costs


def _batch(fixed: FixedPart, block: Block, states: States, points: NDArray[np.float64], weights: NDArray[np.float64],
           factored: FixedFactor, solved: NDArray[np.float64], rest: float) -> NDArray[np.float64]:
    """The costs of one batch of points (NaN: to be solved alone)."""
    n_points, k, p0, n_rows = points.shape[0], block.n_linear, fixed.n_fixed, len(block.rows)
    columns = np.empty((n_rows, n_points, k, states.n_samples))  # each channel's columns, a point's after another's
    finite = np.ones(n_points, dtype=bool)
    for point, shape in enumerate(points):
        values = block.evaluate(states, shape)  # (N, rows, k)
        finite[point] = np.all(np.isfinite(values))
        columns[:, point] = np.transpose(values, (1, 2, 0)) if finite[point] else 0.0
    border = np.zeros((p0, n_points * k))
    corner = np.zeros((n_points, k, k))
    right = np.zeros((n_points, k))
    for position, row in enumerate(block.rows):
        C = columns[position]  # (G, k, N)
        flat = C.reshape(n_points * k, states.n_samples)
        border += weights[row] * fixed.cross(row, flat.T)
        corner += weights[row] * np.matmul(C, np.transpose(C, (0, 2, 1)))
        right += weights[row] * (flat @ fixed.y[row]).reshape(n_points, k)
    scale = np.sqrt(np.einsum("gkk->gk", corner))  # (G, k)
    usable = finite & np.all(scale > 0, axis=1)
    scale[~usable] = 1.0
    border = border.reshape(p0, n_points, k) / (factored.scale[:, None, None] * scale[None])
    corner = corner / (scale[:, :, None] * scale[:, None, :])
    eliminated = factored.solve(border.reshape(p0, n_points * k)).reshape(p0, n_points, k)
    complement = corner - np.einsum("pgk,pgl->gkl", border, eliminated)
    complement = (complement + np.transpose(complement, (0, 2, 1))) / 2
    v = right / scale - np.einsum("pgk,p->gk", border, solved)
    return _points_costs(complement, eliminated, border, corner, v, factored, rest, usable)


def _points_costs(complement: NDArray[np.float64], eliminated: NDArray[np.float64], border: NDArray[np.float64],
                  corner: NDArray[np.float64], v: NDArray[np.float64], factored: FixedFactor, rest: float,
                  usable: NDArray[np.bool_]) -> NDArray[np.float64]:
    """:func:`_point_cost` of every usable point of a batch (``complement (G, k, k)``, ``eliminated`` and ``border``
    ``(p0, G, k)``, ``corner (G, k, k)``, ``v (G, k)``) with each step stacked: the same LAPACK and BLAS calls on
    each point's matrices, and the same sums in the same order, so the same values bit for bit (a point whose
    Cholesky factor fails is NaN, the batch then factored a point at a time)."""
    costs = np.full(usable.shape[0], np.nan)
    points = np.flatnonzero(usable)
    if points.size == 0:
        return costs
    stack = complement[points]
    try:
        lower = np.linalg.cholesky(stack)
    except np.linalg.LinAlgError:  # some point is not positive definite: the others factored one at a time
        factors = []
        kept = []
        for position, matrix in enumerate(stack):
            try:
                factors.append(np.linalg.cholesky(matrix))
                kept.append(position)
            except np.linalg.LinAlgError:
                continue
        if not kept:
            return costs
        points, lower = points[kept], np.stack(factors)
    inverse = np.linalg.inv(lower)
    complement_inverse = np.matmul(np.swapaxes(inverse, 1, 2), inverse)
    k = complement.shape[1]
    taken = eliminated[:, points]  # (p0, g, k)
    gram = np.matmul(np.transpose(taken, (1, 2, 0)), np.transpose(taken, (1, 0, 2)))
    product = np.matmul(complement_inverse, np.eye(k) + gram)
    traces = np.trace(product, axis1=1, axis2=2)
    borders = np.ascontiguousarray(np.transpose(border[:, points], (1, 0, 2))) ** 2
    corners = np.ascontiguousarray(corner[points]) ** 2
    for position, point in enumerate(points):
        trace_inverse = factored.trace_inverse + float(traces[position])
        frobenius = np.sqrt(factored.frobenius2 + 2 * np.sum(borders[position]) + np.sum(corners[position]))
        if not trace_inverse * frobenius * RANK_THRESHOLD * MARGIN <= 1.0:
            continue  # the bound does not decide the rank
        value = rest - float(v[point] @ complement_inverse[position] @ v[point])
        costs[point] = max(value, 0.0) if np.isfinite(value) else np.nan
    return costs


def _point_cost(complement: NDArray[np.float64], eliminated: NDArray[np.float64], border: NDArray[np.float64],
                corner: NDArray[np.float64], v: NDArray[np.float64], factored: FixedFactor, rest: float) -> float:
    """One point's RSS from its Schur complement, or NaN where the linear solve alone decides."""
    try:
        lower = np.linalg.cholesky(complement)
    except np.linalg.LinAlgError:
        return np.nan  # not positive definite: the whole matrix's eigenvalues decide
    inverse = np.linalg.inv(lower)
    complement_inverse = inverse.T @ inverse
    k = complement.shape[0]
    trace_inverse = factored.trace_inverse + float(np.trace(complement_inverse @ (np.eye(k) + eliminated.T @ eliminated)))
    frobenius = np.sqrt(factored.frobenius2 + 2 * np.sum(border**2) + np.sum(corner**2))
    if not trace_inverse * frobenius * RANK_THRESHOLD * MARGIN <= 1.0:
        return np.nan  # the bound does not decide the rank
    value = rest - float(v @ complement_inverse @ v)
    return max(value, 0.0) if np.isfinite(value) else np.nan
