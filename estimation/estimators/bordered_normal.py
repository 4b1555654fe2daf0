"""Normal equations of fixed columns bordered by a few more: the fixed block factored once, each border by
its Schur complement.

A search over candidate columns solves ``N θ = r`` with ``N = [[N₀₀, N₀₁], [N₁₀, N₁₁]]`` many times over:
``N₀₀ = Σ_c w_c A_cᵀA_c`` of the fixed columns (the declared model and the effects adopted so far) is the
same in every solve of a round, the border ``N₀₁, N₁₁`` of the ``k`` columns tried (one shaped law at one
shape) changes. :func:`estimation.estimators.separable_least_squares.solve_normal` equilibrates ``N`` to a
unit diagonal, ``E = D⁻¹ N D⁻¹``, tests its rank from its eigenvalues and factors it: ``O(p³)`` each time.
Here the equilibrated fixed block ``E₀₀`` is factored once (:class:`FixedFactor`) and each solve eliminates
the border through the ``k × k`` Schur complement ``S = E₁₁ − E₁₀ X``, ``X = E₀₀⁻¹ E₀₁``: ``O(p₀² k)``
(Golub & Van Loan, *Matrix Computations*, 4th ed., §3.2.10, block elimination).

The rank test is the same (the smallest eigenvalue of ``E`` below ``1e-13`` of its largest: rank-deficient
columns), decided from bounds while they are far from it: ``λ_min(E) ≥ 1 / tr(E⁻¹)`` with
``tr(E⁻¹) = tr(E₀₀⁻¹) + tr(S⁻¹ (I + XᵀX))`` (the inverse of a partitioned matrix) and
``λ_max(E) ≤ ‖E‖_F``. When ``1 / (tr(E⁻¹) ‖E‖_F)`` is within :data:`MARGIN` of the threshold, or ``S`` is not
positive definite, :func:`solve_bordered` hands over to ``solve_normal`` (the eigenvalues computed): the
same verdict on every matrix, the solution to rounding (``κ(E)·eps``) the same.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np
import scipy.linalg
from numpy.typing import NDArray

__all__ = ["BorderedFactor", "FixedFactor", "MARGIN", "RANK_THRESHOLD", "cholesky_solve", "solve_bordered",
           "symmetric_upper"]

#: rank-deficient: the smallest eigenvalue of the equilibrated normal matrix below this fraction of its largest
RANK_THRESHOLD = 1e-13
#: the bound decides only when it clears the threshold by this factor; the eigenvalues decide otherwise
MARGIN = 1e3


@functools.lru_cache(maxsize=64)
def _lower_masks(size: int) -> tuple[NDArray[np.bool_], NDArray[np.bool_]]:
    """``np.tri(size, size, -1)`` and ``np.tri(size, size, 0)`` as booleans (what ``np.triu(·, 0)`` and
    ``np.triu(·, 1)`` zero), read-only."""
    masks = tuple(np.tri(size, size, k, dtype=bool) for k in (-1, 0))
    for mask in masks:
        mask.flags.writeable = False
    return masks  # type: ignore[return-value]


def symmetric_upper(matrix: NDArray[np.float64]) -> NDArray[np.float64]:
    """The symmetric matrix of ``matrix``'s upper triangle: ``np.triu(matrix) + np.triu(matrix, 1).T``, the same
    operations (``np.where`` with ``np.triu``'s masks) with the masks made once a size (the searches assemble
    thousands of small normal matrices)."""
    strict, with_diagonal = _lower_masks(matrix.shape[0])
    zero = np.zeros(1, matrix.dtype)
    return np.where(strict, zero, matrix) + np.where(with_diagonal, zero, matrix).T


def cholesky_solve(factor: NDArray[np.float64], right: NDArray[np.float64]) -> NDArray[np.float64]:
    """``scipy.linalg.cho_solve((factor, False), right, check_finite=False)`` for float64 arrays: the same LAPACK
    call (``dpotrs``), without the wrapper's batch and array-API handling (~50 µs a call, 9 000 calls a Panda
    diagnosis's search)."""
    if right.size == 0:
        return np.empty_like(right, dtype=float)
    solution, info = scipy.linalg.lapack.dpotrs(factor, right, lower=False)
    if info != 0:
        raise ValueError(f"illegal value in {-info}th argument of internal potrs")
    return solution


@dataclass(frozen=True)
class FixedFactor:
    """The equilibrated fixed block ``E₀₀ = D₀⁻¹ N₀₀ D₀⁻¹`` factored (upper Cholesky), with ``D₀``,
    ``tr(E₀₀⁻¹)`` and ``‖E₀₀‖_F²``."""

    scale: NDArray[np.float64]
    factor: NDArray[np.float64]
    trace_inverse: float
    frobenius2: float

    @classmethod
    def of(cls, gram: NDArray[np.float64], weights: NDArray[np.float64]) -> FixedFactor | None:
        """From per-channel Gram matrices ``(m, p₀, p₀)`` at channel weights ``(m,)``, or ``None`` when the
        block is not finite and positive definite (the solves then take the eigenvalue path)."""
        normal = np.tensordot(weights, gram, axes=1)
        normal = symmetric_upper(normal)
        scale = np.sqrt(np.diag(normal))
        if not (np.all(np.isfinite(normal)) and np.all(scale > 0)):
            return None
        equilibrated = normal / np.outer(scale, scale)
        factor, info = scipy.linalg.lapack.dpotrf(equilibrated, lower=False, clean=True)
        if info != 0:
            return None
        inverse_factor, info = scipy.linalg.lapack.dtrtri(factor, lower=False)
        if info != 0:
            return None
        return cls(scale, factor, float(np.sum(inverse_factor**2)), float(np.sum(equilibrated**2)))

    @property
    def n_fixed(self) -> int:
        return self.scale.shape[0]

    def solve(self, right: NDArray[np.float64]) -> NDArray[np.float64]:
        """``E₀₀⁻¹ right``."""
        return cholesky_solve(self.factor, right)


@dataclass(frozen=True)
class BorderedFactor:
    """One bordered matrix factored by blocks: ``D``, ``X = E₀₀⁻¹ E₀₁``, ``E₀₁`` and the Schur complement's
    Cholesky factor (:meth:`solve` solves ``N Z = R`` for other right-hand sides)."""

    fixed: FixedFactor
    scale: NDArray[np.float64]
    border: NDArray[np.float64]
    eliminated: NDArray[np.float64]
    schur: NDArray[np.float64]

    def solve(self, right: NDArray[np.float64]) -> NDArray[np.float64]:
        """``N⁻¹ right`` for ``right (p,)`` or ``(p, r)``."""
        p0 = self.fixed.n_fixed
        scale = self.scale if right.ndim == 1 else self.scale[:, None]
        equilibrated = right / scale
        z0 = self.fixed.solve(equilibrated[:p0])
        if self.schur.shape[0] == 0:
            return z0 / scale
        second = cholesky_solve(self.schur, equilibrated[p0:] - self.border.T @ z0)
        return np.concatenate([z0 - self.eliminated @ second, second]) / scale


def solve_bordered(normal: NDArray[np.float64], right: NDArray[np.float64],
                   fixed: FixedFactor) -> tuple[NDArray[np.float64], BorderedFactor] | None:
    """``θ`` of ``normal θ = right`` (symmetric, its leading block the one ``fixed`` factored) and its
    factorisation, or ``None`` when the bounds do not decide the rank test (module docstring) or the matrix
    is not finite, has an all-zero column or a Schur complement that is not positive definite: the caller
    then solves it whole (``solve_normal``), which raises where it must."""
    if not (np.all(np.isfinite(normal)) and np.all(np.isfinite(right))):
        return None
    p0 = fixed.n_fixed
    diagonal = np.diag(normal)
    if np.any(diagonal[p0:] <= 0):
        return None
    scale = np.concatenate([fixed.scale, np.sqrt(diagonal[p0:])])
    border = normal[:p0, p0:] / np.outer(fixed.scale, scale[p0:])
    corner = normal[p0:, p0:] / np.outer(scale[p0:], scale[p0:])
    eliminated = fixed.solve(border)
    complement = corner - border.T @ eliminated
    schur, info = scipy.linalg.lapack.dpotrf((complement + complement.T) / 2, lower=False, clean=True)
    if info != 0:
        return None
    k = corner.shape[0]
    trace_inverse = fixed.trace_inverse + float(np.trace(cholesky_solve(
        schur, np.eye(k) + eliminated.T @ eliminated))) if k else fixed.trace_inverse
    frobenius = np.sqrt(fixed.frobenius2 + 2 * np.sum(border**2) + np.sum(corner**2))
    if not trace_inverse * frobenius * RANK_THRESHOLD * MARGIN <= 1.0:
        return None
    factor = BorderedFactor(fixed, scale, border, eliminated, schur)
    return factor.solve(right), factor
