"""Separable weighted least squares at fixed shapes: the inner problem of variable projection.

The model is ``y ≈ A₀ θ₀ + Σ_b C_b(s_b) θ_b`` per sample and channel: ``A₀`` the fixed columns
(the base regressor, effects already chosen), ``C_b`` the columns of the blocks appended to it
(:class:`estimation.estimators.effect_blocks.Block`, shaped effects with shape parameters ``s_b``
or plain ones). For fixed ``s`` the weighted least squares in ``θ = (θ₀, θ_b…)`` has a closed form
(:func:`solve_linear`); :mod:`estimation.estimators.variable_projection` searches the shapes.

Everything is per channel: the Gram matrices ``A_cᵀA_c`` of the fixed part are formed once
(:class:`FixedPart`); a block touches only its own channels (one joint's torque for a per-joint
law), so an evaluation costs ``O(N p_c k)`` on those channels plus an ``O((p+k)³)`` solve, ``p_c`` the
columns channel ``c`` has (a distal joint's torque reaches few of the base parameters: 8 of 50 for the
last joint of a 7-joint arm, 28 on average), which are stored alone.

With the derivatives ``∂C/∂s`` the same sums give the information ``J_fᵀ W J_f`` of the full
Jacobian ``J_f = [A(s), (∂C/∂s) θ̂]`` and the gradient of the projected residual in ``s``
(Kaufman's Jacobian ``J_j = −P⊥ (∂C/∂s_j) θ̂``, Kaufman, BIT 15, 1975) (:func:`full_information`), and
the per-sample scores of a sandwich covariance (:func:`sample_scores`).
"""

from __future__ import annotations

import functools
import weakref
from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np
import scipy.linalg
from numpy.typing import NDArray

from estimation.estimators.bordered_normal import (RANK_THRESHOLD, BorderedFactor, FixedFactor, cholesky_solve,
                                                  solve_bordered, symmetric_upper)
from estimation.estimators.effect_blocks import Block, States
from estimation.estimators.identification_problem import ResidualBand

__all__ = ["FixedPart", "LinearSolution", "consecutive_runs", "full_information", "residuals", "sample_scores", "solve_linear",
           "solve_normal"]


@dataclass(frozen=True)
class FixedPart:
    """The fixed columns ``A₀ (m, N, p0)`` and measured channels of one record, arranged per channel.

    Each channel stores only the columns that are not zero on it: ``own[c] (N, q_c)``, contiguous, and
    ``where[c] (q_c,)`` their places among the ``p0`` columns, ``−1`` for a stored column that is not one of
    this part's (a part that leaves columns out shares its parent's arrays: :meth:`kept`). The products with
    ``A_c`` (:meth:`cross`, :meth:`predict`) read those alone; :attr:`A` is the dense array, made when asked.
    """

    own: tuple[NDArray[np.float64], ...]  # per channel (N, q_c)
    where: tuple[NDArray[np.intp], ...]  # per channel (q_c,)
    y: NDArray[np.float64]  # (m, N)
    gram: NDArray[np.float64]  # (m, p0, p0)
    moment: NDArray[np.float64]  # (m, p0)
    power: NDArray[np.float64]  # (m,)
    band: ResidualBand | None = None  # the motion's band: channel weights from the residual in it

    @classmethod
    def from_arrays(cls, Y: NDArray[np.float64], y: NDArray[np.float64], band: ResidualBand | None = None) -> FixedPart:
        """From ``Y (N, m, p0)`` and ``y (N, m)``; ``band``: the band the motion was low-passed to
        (:class:`estimation.estimators.identification_problem.ResidualBand`)."""
        part = cls.per_channel(np.transpose(Y, (1, 0, 2)), np.ascontiguousarray(y.T))
        return part if band is None else replace(part, band=band)

    @classmethod
    def per_channel(cls, A: NDArray[np.float64], values: NDArray[np.float64]) -> FixedPart:
        """From the per-channel layout ``A (m, N, p0)`` (any strides: a view of ``(N, m, p0)`` is read in
        place) and ``values (m, N)`` (C-contiguous)."""
        m, _, p0 = A.shape
        own, where = [], []
        gram, moment = np.zeros((m, p0, p0)), np.zeros((m, p0))
        # (m, p0): ``A.any`` reads the strided view in place; ``np.any(A != 0)`` first wrote a boolean copy of all
        # of ``A`` (the same booleans: NaN counts as nonzero, −0.0 as zero, in both)
        support = A.any(axis=1)
        for channel in range(m):
            columns = np.flatnonzero(support[channel])
            stored = np.compress(support[channel], A[channel], axis=1)  # a C-contiguous copy
            gram[channel][np.ix_(columns, columns)] = stored.T @ stored
            moment[channel, columns] = stored.T @ values[channel]
            own.append(stored)
            where.append(columns)
        return cls(tuple(own), tuple(where), values, gram, moment, np.sum(values**2, axis=1))

    def cross(self, channel: int, columns: NDArray[np.float64], products: NDArray[np.float64] | None = None
              ) -> NDArray[np.float64]:
        """``A_cᵀ C``, ``(p0, k)``, of columns ``C (N, k)`` on ``channel``; ``products``: the stored columns' products
        ``own[channel]ᵀ C`` when the caller has them (:func:`solve_linear`)."""
        products = self.own[channel].T @ columns if products is None else products
        where = self.where[channel]
        result = np.zeros((self.n_fixed, columns.shape[1]))
        kept = where >= 0
        result[where[kept]] = products[kept]
        return result

    def weighted(self, weights: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64], float]:
        """``(Σ_c w_c A_cᵀA_c, Σ_c w_c A_cᵀy_c, Σ_c w_c y_cᵀy_c)`` at the channel weights ``weights`` (upper
        triangle and all); the latest kept, read-only: the solves of a search, or a round's screens, share their part
        and weights (:func:`solve_linear`)."""
        values = np.asarray(weights)
        key = (values.dtype.str, values.shape, values.tobytes())
        latest = self.__dict__.get("_weighted")
        if latest is None or latest[0] != key:
            normal, right = np.tensordot(weights, self.gram, axes=1), weights @ self.moment
            normal.flags.writeable = right.flags.writeable = False
            latest = (key, (normal, right, weights @ self.power))
            self.__dict__["_weighted"] = latest  # a cache beside the frozen fields (as functools.cached_property)
        return latest[1]

    def predict(self, theta: NDArray[np.float64], channel: int | None = None) -> NDArray[np.float64]:
        """``A_c θ`` on ``channel`` ``(N,)``, or on every channel ``(m, N)``."""
        padded = np.append(theta, 0.0)  # where = −1 reads the appended zero
        if channel is not None:
            return self.own[channel] @ padded[self.where[channel]]
        # each channel's product written in its row: the same products as stacked, without the copy
        predicted = np.empty(self.y.shape)
        for row, (own, where) in enumerate(zip(self.own, self.where)):
            np.matmul(own, padded[where], out=predicted[row])
        return predicted

    def moments(self, values: NDArray[np.float64]) -> NDArray[np.float64]:
        """``A_cᵀ v_c`` of other values ``(m, N)`` on each channel, ``(m, p0)``."""
        return np.stack([self.cross(channel, values[channel][:, None])[:, 0] for channel in range(len(self.own))])

    def kept(self, columns: Sequence[int]) -> FixedPart:
        """This part with only ``columns`` (in that order): the Gram matrices and moments taken, the stored
        columns shared."""
        place = np.full(self.n_fixed + 1, -1, dtype=np.intp)  # place[-1]: a stored column already left out
        place[list(columns)] = np.arange(len(columns))
        index = np.asarray(columns, dtype=np.intp)
        return FixedPart(self.own, tuple(place[where] for where in self.where), self.y,
                         self.gram[:, index][:, :, index], self.moment[:, index], self.power, self.band)

    def extended(self, columns: NDArray[np.float64], rows: Sequence[int]) -> FixedPart:
        """With extra columns ``(N, rows, k)`` that are zero off ``rows``: only those channels' products are
        formed (``O(N p_c k)`` each), the others keep their arrays."""
        m, p0, k = len(self.own), self.n_fixed, columns.shape[2]
        gram, moment = np.zeros((m, p0 + k, p0 + k)), np.zeros((m, p0 + k))
        gram[:, :p0, :p0], moment[:, :p0] = self.gram, self.moment
        own, where = list(self.own), list(self.where)
        for position, row in enumerate(rows):
            C = np.ascontiguousarray(columns[:, position, :])
            cross = self.cross(row, C)
            gram[row, :p0, p0:], gram[row, p0:, :p0], gram[row, p0:, p0:] = cross, cross.T, C.T @ C
            moment[row, p0:] = C.T @ self.y[row]
            own[row] = np.concatenate([self.own[row], C], axis=1)
            where[row] = np.concatenate([self.where[row], np.arange(p0, p0 + k)])
        return FixedPart(tuple(own), tuple(where), self.y, gram, moment, self.power, self.band)

    def with_blocks(self, blocks: Sequence[Block], states: States, shapes: Sequence[NDArray[np.float64]]) -> FixedPart:
        """This part extended by each block's columns at its shape along ``states``, block after block
        (:meth:`extended`: only the blocks' channels' products formed)."""
        fixed = self
        for block, shape in zip(blocks, shapes):
            fixed = fixed.extended(block.evaluate(states, shape), block.rows)
        return fixed

    @functools.cached_property
    def A(self) -> NDArray[np.float64]:  # noqa: N802 (the columns' name in the equations)
        """The dense columns ``(m, N, p0)``."""
        dense = np.zeros((len(self.own), self.n_samples, self.n_fixed))
        for channel, (own, where) in enumerate(zip(self.own, self.where)):
            kept = where >= 0
            dense[channel][:, where[kept]] = own[:, kept]
        return dense

    @property
    def n_fixed(self) -> int:
        return self.gram.shape[1]

    @property
    def n_samples(self) -> int:
        return self.y.shape[1]

    @property
    def n_rows(self) -> int:
        return self.y.shape[0] * self.y.shape[1]


@dataclass(frozen=True)
class LinearSolution:
    """``θ`` at fixed shapes with what the search and the covariance need."""

    theta: NDArray[np.float64]
    rss: float  # weighted
    normal: NDArray[np.float64]
    columns: list[NDArray[np.float64]]  # per block (N, rows, k)
    derivatives: list[NDArray[np.float64]] | None  # per block (n_s, N, rows, k)
    factor: BorderedFactor | None = None  # ``normal`` factored by blocks, when it was solved so

    def solve(self, right: NDArray[np.float64]) -> NDArray[np.float64]:
        """``normal⁻¹ right`` for ``right (p,)`` or ``(p, r)`` (by blocks when solved so, else by the Cholesky
        factor of the equilibrated matrix)."""
        if self.factor is not None:
            return self.factor.solve(right)
        scale = np.sqrt(np.diag(self.normal))
        scale_right = scale if right.ndim == 1 else scale[:, None]
        factor = scipy.linalg.cho_factor(self.normal / np.outer(scale, scale), check_finite=False)
        return scipy.linalg.cho_solve(factor, right / scale_right, check_finite=False) / scale_right


def _layout(blocks: Sequence[Block], n_fixed: int) -> list[slice]:
    slices, start = [], n_fixed
    for block in blocks:
        slices.append(slice(start, start + block.n_linear))
        start += block.n_linear
    return slices


def solve_linear(fixed: FixedPart, blocks: Sequence[Block], states: States, shapes: Sequence[NDArray[np.float64]],
                 weights: NDArray[np.float64], *, jacobian: bool = False,
                 factored: FixedFactor | None = None,
                 evaluated: Sequence[tuple[NDArray[np.float64], NDArray[np.float64] | None]] | None = None,
                 ) -> LinearSolution:
    """Weighted least squares in ``θ = (θ₀, θ_b…)`` at the given shapes, from per-channel Gram matrices;
    ``factored``: the fixed block's factor at these ``weights`` (:class:`FixedFactor`), the blocks then
    eliminated by their Schur complement (:func:`solve_bordered`); ``evaluated``: each block's columns and (with
    ``jacobian``) derivatives at its shape, as :meth:`Block.evaluate` gives them, when the caller has them already
    (:class:`estimation.estimators.variable_projection` keeps its latest)."""
    p0 = fixed.n_fixed
    slices = _layout(blocks, p0)
    p = slices[-1].stop if slices else p0
    normal = np.zeros((p, p))
    right = np.zeros(p)
    normal[:p0, :p0], right[:p0], power = fixed.weighted(weights)
    columns, derivatives = [], [] if jacobian else None
    for index, (block, shape) in enumerate(zip(blocks, shapes)):
        if evaluated is not None:
            values, derivative = evaluated[index]
            if jacobian:
                derivatives.append(derivative)
        elif jacobian:
            values, derivative = block.evaluate(states, shape, jacobian=True)
            derivatives.append(derivative)
        else:
            values = block.evaluate(states, shape)
        columns.append(values)
    for index, (block, values, where) in enumerate(zip(blocks, columns, slices)):
        kept = block.products(values)
        for position, row in enumerate(block.rows):
            w, C = weights[row], values[:, position, :]
            normal[:p0, where] += w * fixed.cross(row, C, None if kept is None else _stored_products(fixed, row, C,
                                                                                                    kept, position))
            normal[where, where] += w * (C.T @ C)
            right[where] += w * (C.T @ fixed.y[row])
            for other, other_values, other_where in zip(blocks[index + 1:], columns[index + 1:], slices[index + 1:]):
                if row in other.rows:
                    normal[where, other_where] += w * (C.T @ other_values[:, other.rows.index(row), :])
    normal = symmetric_upper(normal)
    solved = None if factored is None else solve_bordered(normal, right, factored)
    theta, factor = (solve_normal(normal, right), None) if solved is None else solved
    rss = float(power - 2 * theta @ right + theta @ normal @ theta)
    return LinearSolution(theta, max(rss, 0.0), normal, columns, derivatives, factor)


def _stored_products(fixed: FixedPart, row: int, C: NDArray[np.float64], kept: dict,
                     position: int) -> NDArray[np.float64]:
    """``own[row]ᵀ C`` of a block's kept evaluation (:meth:`Block.products`: ``kept``), computed once for each stored
    array: the parts of a diagnosis's rounds share the stored columns of every channel the effects adopted since do
    not reach (:meth:`FixedPart.extended`, :meth:`FixedPart.kept`), so a candidate screened at its last optimum, or
    refitted at other weights, reads them once, not at every solve. The same product of the same arrays."""
    own = fixed.own[row]
    known = kept.get((id(own), position))
    if known is not None and known[0]() is own:
        return known[1]
    products = own.T @ C
    kept[(id(own), position)] = (weakref.ref(own), products)
    return products


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
    if eigenvalues[0] < RANK_THRESHOLD * eigenvalues[-1]:
        raise np.linalg.LinAlgError("rank-deficient columns")
    # scipy.linalg.cho_factor and cho_solve's LAPACK calls, without their wrappers (the search's thousands of solves)
    factor, info = scipy.linalg.lapack.dpotrf(equilibrated, lower=False, clean=False)
    if info > 0:
        raise np.linalg.LinAlgError(f"{info}-th leading minor of the array is not positive definite")
    if info < 0:
        raise ValueError(f'LAPACK reported an illegal value in {-info}-th argument on entry to "POTRF".')
    return cholesky_solve(factor, right / scale) / scale


def residuals(fixed: FixedPart, blocks: Sequence[Block], solution: LinearSolution,
              rows: Sequence[int] | None = None) -> NDArray[np.float64]:
    """``y − A θ`` per channel, ``(m, N)``; with ``rows``, only those channels (the others zero)."""
    theta = solution.theta
    p0 = fixed.n_fixed
    if rows is None:
        values = np.subtract(fixed.y, (predicted := fixed.predict(theta[:p0])), out=predicted)  # in its own array
    else:
        values = np.zeros_like(fixed.y)
        for row in rows:
            values[row] = fixed.y[row] - fixed.predict(theta[:p0], row)
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
            information[:fixed.n_fixed, p + j] += w * fixed.cross(row, d[:, None])[:, 0]
            for block, columns, where in zip(blocks, solution.columns, slices):
                if row in block.rows:
                    information[where, p + j] += w * (columns[:, block.rows.index(row), :].T @ d)
            gradient[j] += -2.0 * w * (residual[row] @ d)
            for i, (other_rows, other) in enumerate(directions[: j + 1]):
                if row in other_rows:
                    information[p + i, p + j] += w * (other[:, other_rows.index(row)] @ d)
    information = symmetric_upper(information)
    return information, gradient


def consecutive_runs(places: NDArray[np.intp]) -> list[tuple[int, int, int]]:
    """The runs of consecutive values in ``places`` (increasing by one): ``(start, stop, first)`` for each, the run
    ``places[first:first + stop - start] == range(start, stop)``."""
    if places.size == 0:
        return []
    breaks = np.flatnonzero(np.diff(places) != 1) + 1
    firsts = [0, *breaks.tolist()]
    lasts = [*breaks.tolist(), int(places.size)]
    return [(int(places[first]), int(places[first]) + last - first, first) for first, last in zip(firsts, lasts)]


def sample_scores(fixed: FixedPart, blocks: Sequence[Block], solution: LinearSolution, weights: NDArray[np.float64],
                  residual: NDArray[np.float64]) -> NDArray[np.float64]:
    """Per sample ``s_t = Σ_c w_c r_{c,t} J_{c,t}``, ``(N, p + n_s)``, ``J = [A, (∂C/∂s) θ̂]``."""
    weighted = weights[:, None] * residual  # (m, N)
    # summed column by column, a channel after the other, as ``declared[:, places] += w_c r_c A_c`` sums them: here
    # transposed ((p0, N): a column's samples contiguous) and on each run of consecutive places as a slice, which
    # spares the gather and scatter of the indexed sum (~4x faster on the Panda; the same sums bit for bit)
    declared = np.zeros((fixed.n_fixed, fixed.n_samples))
    for channel, (own, where) in enumerate(zip(fixed.own, fixed.where)):
        kept = where >= 0
        product = (own if kept.all() else own[:, kept]).T * weighted[channel]  # (q_c, N)
        for start, stop, first in consecutive_runs(where[kept]):
            declared[start:stop] += product[first:first + stop - start]
    columns = [declared.T]
    for block, values in zip(blocks, solution.columns):
        columns.append(np.einsum("nr,nrk->nk", weighted[list(block.rows)].T, values))
    if solution.derivatives is not None:
        for rows, D in _shape_directions(fixed, blocks, solution):
            columns.append(np.einsum("nr,nr->n", weighted[list(rows)].T, D)[:, None])
    scores = np.empty((fixed.n_samples, sum(part.shape[1] for part in columns)))  # C order, as before
    return np.concatenate(columns, axis=1, out=scores)
