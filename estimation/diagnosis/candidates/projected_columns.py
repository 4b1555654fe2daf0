"""Candidate columns beyond a channel-weighted declared model, from per-channel Gram matrices.

The residual tracing (:func:`estimation.diagnosis.candidates.coupling.traced_pairs`) tests one column at a
time beyond the declared model ``Y`` and a few other candidate columns (a nested F test in the weighted least
squares ``W^½ y ≈ W^½ [Y E c] θ``, ``W`` the channel weights). Projected off ``W^½ Y``
(``P⊥ = I − W^½ Y (YᵀWY)⁻¹ YᵀW^½``), all it needs of the candidate columns ``C`` is

* ``S = CᵀW^½ P⊥ W^½ C = CᵀWC − (YᵀWC)ᵀ (YᵀWY)⁻¹ (YᵀWC)``, their projected Gram matrix: the Schur complement
  of ``YᵀWY`` in the bordered normal matrix (Golub & Van Loan, *Matrix Computations*, 4th ed., §3.2.10);
* ``s = CᵀW^½ r₀``, their products with the weighted residual ``r₀ = W^½ (y − Y θ̂)`` of the declared model
  (``P⊥ r₀ = r₀``: formed from the residual itself, no cancellation), and ``‖r₀‖²``.

A candidate column touches one or two channels (a joint's torque, a pair's two), so ``CᵀWC`` and ``YᵀWC``
cost ``O(N p_c)`` a column on the channels it touches (:class:`FixedPart` keeps the columns of ``Y`` each
channel has), and ``YᵀWY`` is summed from the per-channel Gram matrices: no QR factorisation of the
``N·m x p`` weighted regressor, no ``O(N m p)`` projection per column. ``θ̂`` (weighted, and the ordinary fit
that gives the weights) is solved by semi-normal equations with one step of iterative refinement on the
exact residual, as :func:`estimation.estimators.least_squares.solve` does.

Accuracy: ``S`` is formed by a difference, exact up to about ``eps`` times the column's own weighted norm
``‖W^½ c‖²`` (times the conditioning of the equilibrated ``YᵀWY``), where an explicit projection
``P⊥ W^½ c`` errs by ``eps ‖W^½ c‖`` only. A column the declared model absorbs (``S_cc = 0`` exactly, in
theory) is therefore told by its projected norm relative to its own: below :data:`ABSORBED` it has nothing
beyond the model (:meth:`ProjectedColumns.beyond`), and is never tested on its rounding noise.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from estimation.estimators.bordered_normal import RANK_THRESHOLD
from estimation.estimators.separable_least_squares import FixedPart

__all__ = ["ABSORBED", "ProjectedColumns", "Whitener", "weighted_fit"]

#: a column whose squared norm beyond the declared model is below this fraction of its own squared norm
#: (both weighted) is absorbed by the model: the projected Gram matrix cannot tell such a column from zero
ABSORBED = 1e-9


class Whitener:
    """``T`` with ``Tᵀ T = (YᵀWY)⁺`` from the equilibrated normal matrix's eigen-decomposition (directions below
    :data:`RANK_THRESHOLD` of the largest eigenvalue left out, as the identification's rank test)."""

    def __init__(self, normal: NDArray[np.float64]) -> None:
        scale = np.sqrt(np.diag(normal))
        scale = np.where(scale > 0, scale, 1.0)
        eigenvalues, eigenvectors = np.linalg.eigh(normal / np.outer(scale, scale))
        kept = eigenvalues > RANK_THRESHOLD * max(eigenvalues[-1], 0.0)
        self.matrix = (eigenvectors[:, kept] / np.sqrt(eigenvalues[kept])).T / scale  # (rank, p)

    def apply(self, right: NDArray[np.float64]) -> NDArray[np.float64]:
        """``T right``."""
        return self.matrix @ right

    def solve(self, right: NDArray[np.float64]) -> NDArray[np.float64]:
        """``(YᵀWY)⁺ right``."""
        return self.matrix.T @ (self.matrix @ right)


def weighted_fit(fixed: FixedPart, weights: NDArray[np.float64]) -> tuple[NDArray[np.float64], Whitener]:
    """The residual ``y − Y θ̂`` ``(m, N)`` of the least squares of ``fixed`` at channel weights ``(m,)``
    (``W = diag(weights)``, ``θ̂ = (YᵀWY)⁻¹ YᵀW y``; one refinement step on the exact residual), and the
    whitener of ``YᵀWY``."""
    whitener = Whitener(np.tensordot(weights, fixed.gram, axes=1))
    theta = whitener.solve(weights @ fixed.moment)
    residual = fixed.y - fixed.predict(theta)
    theta = theta + whitener.solve(weights @ fixed.moments(residual))
    return fixed.y - fixed.predict(theta), whitener


@dataclass(frozen=True)
class ProjectedColumns:
    """Candidate columns beyond a weighted declared model (module docstring).

    Attributes
    ----------
    gram
        ``(k, k)`` ``S``, their projected weighted Gram matrix.
    own
        ``(k,)`` ``‖W^½ c‖²``, each column's own weighted squared norm.
    moment
        ``(k,)`` ``s = CᵀW^½ r₀``.
    rss
        ``‖r₀‖²``, the weighted residual sum of squares of the declared model.
    n_rows, n_fixed
        Rows (samples x channels) and columns of the declared model.
    """

    gram: NDArray[np.float64]
    own: NDArray[np.float64]
    moment: NDArray[np.float64]
    rss: float
    n_rows: int
    n_fixed: int

    @classmethod
    def of(cls, fixed: FixedPart, root: NDArray[np.float64],
           columns: Sequence[NDArray[np.float64]]) -> ProjectedColumns:
        """From the declared model ``fixed``, the channel weights' square roots ``root (m,)`` and candidate
        columns ``(N, m)`` each (zero off the channels they touch)."""
        shape = (fixed.n_samples, len(fixed.own))
        if any(np.shape(column) != shape for column in columns):
            raise ValueError(f"candidate columns must be {shape} (samples, channels) each, got "
                             f"{sorted({np.shape(column) for column in columns})}")
        weights = root**2
        residual, whitener = weighted_fit(fixed, weights)
        k = len(columns)
        own, border, moment = np.zeros((k, k)), np.zeros((fixed.n_fixed, k)), np.zeros(k)
        support = np.array([np.any(column, axis=0) for column in columns]).reshape(k, -1)  # (k, m)
        for channel in range(len(fixed.own)):
            touching = list(np.flatnonzero(support[:, channel]))
            if not touching:
                continue
            values = np.stack([columns[index][:, channel] for index in touching], axis=1)  # (N, k_c)
            own[np.ix_(touching, touching)] += weights[channel] * (values.T @ values)
            border[:, touching] += weights[channel] * fixed.cross(channel, values)
            moment[touching] += weights[channel] * (values.T @ residual[channel])
        eliminated = whitener.apply(border)
        gram = own - eliminated.T @ eliminated
        # the residual's rounding along the model (YᵀW r ≠ 0), taken off the products as a projection would
        left = whitener.apply(weights @ fixed.moments(residual))
        moment = moment - eliminated.T @ left
        rss = float(weights @ np.sum(residual**2, axis=1)) - float(left @ left)
        return cls((gram + gram.T) / 2, np.diag(own).copy(), moment, rss, fixed.n_rows, fixed.n_fixed)

    def beyond(self, index: int) -> bool:
        """Whether column ``index`` has anything beyond the declared model (:data:`ABSORBED`)."""
        return bool(self.gram[index, index] > ABSORBED * self.own[index])

    def f_statistic(self, base: Sequence[int], column: int) -> float | None:
        """The F statistic (1 and ``n_rows − n_fixed − len(base) − 1`` degrees of freedom) of column ``column``
        beyond the declared model and the columns ``base``, or ``None`` when it has nothing beyond them
        (absorbed: its squared norm beyond both at most ``1e-12`` of the residual sum of squares left by them,
        or :data:`ABSORBED` of its own). Base columns the declared model absorbs are left out."""
        kept = [index for index in base if self.beyond(index)]
        rss, norm, product = self.rss, float(self.gram[column, column]), float(self.moment[column])
        if kept:
            block = self.gram[np.ix_(kept, kept)]
            scale = np.sqrt(np.diag(block))
            inverse = np.linalg.pinv(block / np.outer(scale, scale), hermitian=True) / np.outer(scale, scale)
            cross, moments = self.gram[kept, column], self.moment[kept]
            rss -= float(moments @ inverse @ moments)
            norm -= float(cross @ inverse @ cross)
            product -= float(cross @ inverse @ moments)
        if norm <= max(1e-12 * max(rss, 1e-300), ABSORBED * self.own[column]):
            return None
        gain = product**2 / norm
        dof = self.n_rows - self.n_fixed - len(base) - 1
        return gain / ((rss - gain) / dof)
