"""Covariance of estimates when the residuals are correlated in time: the batch-means sandwich.

For a least-squares fit with per-sample scores ``s_t = Σ_c w_c r_{c,t} J_{c,t}`` (gradient rows of the
weighted residual), the covariance ``H⁻¹ M H⁻¹`` with ``H = JᵀWJ`` and ``M = Σ_b S_b S_bᵀ``, ``S_b``
the sum of the scores over batch ``b`` of consecutive samples, holds when the residuals are
correlated within a batch length (non-overlapping batch means, a Bartlett-type long-run variance
estimate; Newey & West, Econometrica 55, 1987; batch length by Andrews' AR(1) plug-in rule,
Econometrica 59, 1991). With white residuals and ``W = 1/σ²`` it reduces to ``H⁻¹``.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray


def batch_length(residual: NDArray[np.float64], weights: NDArray[np.float64]) -> int:
    """Samples per batch for :func:`batch_means`: Andrews' (1991) AR(1) plug-in bandwidth
    ``1.1447 (α N)^{1/3}``, ``α = 4ρ²/(1−ρ)⁴``, ``ρ`` the weighted mean lag-1 autocorrelation of the
    residuals, at least 1 and at most ``N/20`` (twenty batches)."""
    n_samples = residual.shape[1]
    centred = residual - residual.mean(axis=1, keepdims=True)
    variance = np.sum(centred**2, axis=1)
    rho_c = np.sum(centred[:, 1:] * centred[:, :-1], axis=1) / np.where(variance > 0, variance, 1.0)
    rho = float(np.clip(np.sum(weights * variance * rho_c) / max(np.sum(weights * variance), 1e-300), 0.0, 0.999))
    alpha = 4 * rho**2 / (1 - rho) ** 4
    return int(np.clip(round(1.1447 * (alpha * n_samples) ** (1 / 3)), 1, max(1, n_samples // 20)))


def batch_means(scores: NDArray[np.float64], length: int) -> NDArray[np.float64]:
    """``Σ_b S_b S_bᵀ`` with ``S_b`` the sum of the scores over batch ``b`` of ``length`` consecutive samples."""
    n_samples = scores.shape[0]
    edges = np.arange(0, n_samples, max(1, length))
    sums = np.add.reduceat(scores, edges, axis=0)
    return sums.T @ sums
