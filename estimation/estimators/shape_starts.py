"""Where a shape search starts: the blocks' declared grid, and one start a valley of the cost over it.

:func:`estimation.estimators.variable_projection.fit_shapes` evaluates the projected residual at every point of the
grid (:func:`product_grid`, or the starts given) by the linear solve alone and refines the lowest valley floors
(:func:`valley_floors`): Levenberg–Marquardt from two neighbouring grid points descends into the same optimum, so a
second start is spent only in another valley.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from dynamics.effects.shaped import start_grid
from estimation.estimators.effect_blocks import Block

__all__ = ["product_grid", "valley_floors"]


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
