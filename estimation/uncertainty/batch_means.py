"""Covariance of estimates when the residuals are correlated in time: the batch-means sandwich.

For a least-squares fit with per-sample scores ``s_t = Σ_c w_c r_{c,t} J_{c,t}`` (gradient rows of the
weighted residual), the covariance ``H⁻¹ M H⁻¹`` with ``H = JᵀWJ`` and ``M = Σ_b S_b S_bᵀ``, ``S_b``
the sum of the scores over batch ``b`` of consecutive samples, holds when the residuals are
correlated within a batch length (non-overlapping batch means, a Bartlett-type long-run variance
estimate; Newey & West, Econometrica 55, 1987; batch length by Andrews' AR(1) plug-in rule,
Econometrica 59, 1991). With white residuals and ``W = 1/σ²`` it reduces to ``H⁻¹``.

A record stacked from segments (:func:`estimation.data.segments.segment_slices`) gets batches that
restart at each boundary, and the lag-1 autocorrelation of the rule uses pairs inside a segment
only: no batch or lag spans two pieces recorded apart.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

#: ``(start, stop)`` samples of each segment (``None``: one segment)
Segments = Sequence[tuple[int, int]] | None


def _inside(n_samples: int, segments: Segments) -> NDArray[np.bool_]:
    """``(N − 1,)``: sample ``t + 1`` follows sample ``t`` in the same segment."""
    inside = np.ones(max(n_samples - 1, 0), dtype=bool)
    for start, _ in segments or ():
        if 0 < start < n_samples:
            inside[start - 1] = False
    return inside


def batch_length(residual: NDArray[np.float64], weights: NDArray[np.float64], segments: Segments = None) -> int:
    """Samples per batch for :func:`batch_means`: Andrews' (1991) AR(1) plug-in bandwidth
    ``1.1447 (α N)^{1/3}``, ``α = 4ρ²/(1−ρ)⁴``, ``ρ`` the weighted mean lag-1 autocorrelation of the
    residuals (pairs inside a segment), at least 1 and at most ``N/20`` (twenty batches)."""
    n_samples = residual.shape[1]
    centred = residual - residual.mean(axis=1, keepdims=True)
    variance = np.sum(centred**2, axis=1)
    inside = _inside(n_samples, segments)
    products = (centred[:, 1:] * centred[:, :-1])[:, inside]
    rho_c = np.sum(products, axis=1) / np.where(variance > 0, variance, 1.0)
    rho = float(np.clip(np.sum(weights * variance * rho_c) / max(np.sum(weights * variance), 1e-300), 0.0, 0.999))
    alpha = 4 * rho**2 / (1 - rho) ** 4
    return int(np.clip(round(1.1447 * (alpha * n_samples) ** (1 / 3)), 1, max(1, n_samples // 20)))


def batch_means(scores: NDArray[np.float64], length: int, segments: Segments = None) -> NDArray[np.float64]:
    """``Σ_b S_b S_bᵀ`` with ``S_b`` the sum of the scores over batch ``b`` of ``length`` consecutive
    samples (restarting at each segment's first sample)."""
    n_samples = scores.shape[0]
    bounds = [(int(start), int(stop)) for start, stop in segments] if segments else [(0, n_samples)]
    edges = np.unique(np.concatenate([np.arange(start, stop, max(1, length)) for start, stop in bounds if stop > start]))
    sums = np.add.reduceat(scores, edges, axis=0)
    return sums.T @ sums
