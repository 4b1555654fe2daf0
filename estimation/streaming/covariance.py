"""The batch-means covariance of a streamed estimate, accumulated chunk by chunk (bounded memory).

The in-memory estimators hold their standard deviations when the residuals are correlated in time
(derivative errors near velocity reversals, an effect the model lacks) by a sandwich
(:mod:`estimation.uncertainty.batch_means`): ``cov = H⁻¹ M H⁻¹ · N/(N − p)`` with ``H = JᵀWJ``,
``M = Σ_b S_b S_bᵀ`` and ``S_b`` the sum of the scores ``s_t = Σ_c w_c r_{c,t} J_{c,t}`` over batch
``b`` of consecutive samples, the batch length by Andrews' AR(1) plug-in rule
(:func:`estimation.uncertainty.batch_means.batch_length`). Both need the residuals at the final estimate: a
third pass over the files (:class:`BatchScores`, one a file). The batch length needs the residuals'
lag-1 autocorrelation, itself a sum; so that one pass suffices, ``M`` is accumulated at every batch
length ``2^k`` (:data:`BATCH_LENGTHS`) and the one nearest (in ratio) to Andrews' length is used.
Batches do not straddle files (each file's last, partial batch is one batch). As in memory, the
standard deviations are never below the white-noise ones (:func:`sandwich`).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from dynamics.models import IdentificationModel
from estimation.streaming.diagnosis_sums import ColumnLayout
from dynamics.measurements import Measurements
from estimation.estimators.effect_blocks import Block, States

__all__ = ["BATCH_LENGTHS", "BatchScores", "chunk_scores", "lag_one_correlation", "sandwich"]

#: batch lengths at which the meat is accumulated (1 to 65 536 samples)
BATCH_LENGTHS: tuple[int, ...] = tuple(2**k for k in range(17))


def chunk_scores(model: IdentificationModel, layout: ColumnLayout, blocks: Sequence[Block],
                 shapes: Sequence[NDArray[np.float64]], chunk: Measurements, theta: NDArray[np.float64],
                 weights: NDArray[np.float64], *, Y: NDArray[np.float64] | None = None
                 ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Scores ``(N, p)`` and residuals ``(m, N)`` (prepared channels) of ``θ`` on all of ``layout``'s columns
    (``Y``: the chunk's base regressor when already evaluated)."""
    Y = model.evaluate_base(chunk.q, chunk.dq, chunk.ddq) if Y is None else Y
    measured = chunk.channels(model.channels)
    masked = np.isnan(measured)  # a masked sample's equation left out: its residual 0, as memory's zeroed equation
    if not masked.any():
        masked = None
    if not blocks and len(layout.names) == Y.shape[2]:  # the base columns alone, on every channel: one product each
        residual = measured - np.einsum("ncp,p->nc", Y, theta, optimize=True)
        if masked is not None:
            residual[masked] = 0.0
        return np.einsum("nc,ncp->np", residual * weights, Y, optimize=True), np.ascontiguousarray(residual.T)
    states = States(chunk.q, chunk.dq, chunk.ddq)
    columns = [block.evaluate(states, shape) for block, shape in zip(blocks, shapes)]
    scores = np.zeros((chunk.n_samples, len(layout.names)))
    residual = np.empty((layout.n_channels, chunk.n_samples))
    for c in range(layout.n_channels):
        where = list(layout.channel_columns(c))
        X = np.concatenate([Y[:, c, :]] + [values[:, rows.index(c), :] for values, rows in zip(columns, layout.rows)
                                           if c in rows], axis=1)
        residual[c] = measured[:, c] - X @ theta[where]
        if masked is not None:
            residual[c][masked[:, c]] = 0.0
        scores[:, where] += (weights[c] * residual[c])[:, None] * X
    return scores, residual


@dataclass
class BatchScores:
    """Running ``Σ_b S_b S_bᵀ`` at each of :data:`BATCH_LENGTHS`, and the residual sums Andrews' rule needs."""

    meat: NDArray[np.float64]  # (L, p, p)
    partial: NDArray[np.float64]  # (L, p): the open batch's sum
    n_samples: int
    total: NDArray[np.float64]  # (m,) Σ r
    square: NDArray[np.float64]  # (m,) Σ r²
    lagged: NDArray[np.float64]  # (m,) Σ r_t r_{t−1}
    first: NDArray[np.float64]  # (m,)
    last: NDArray[np.float64]  # (m,)

    @classmethod
    def empty(cls, n_parameters: int, n_channels: int) -> BatchScores:
        zeros = np.zeros(n_channels)
        return cls(np.zeros((len(BATCH_LENGTHS), n_parameters, n_parameters)),
                   np.zeros((len(BATCH_LENGTHS), n_parameters)), 0, zeros.copy(), zeros.copy(), zeros.copy(),
                   np.full(n_channels, np.nan), zeros.copy())

    def add(self, scores: NDArray[np.float64], residual: NDArray[np.float64]) -> None:
        """The next consecutive samples of the file."""
        n = scores.shape[0]
        if n == 0:
            return
        index = self.n_samples + np.arange(n)
        for k, length in enumerate(BATCH_LENGTHS):
            ids = index // length
            edges = np.flatnonzero(np.r_[True, ids[1:] != ids[:-1]])
            sums = np.add.reduceat(scores, edges, axis=0)
            if self.n_samples % length:  # the first batch continues the open one
                sums[0] += self.partial[k]
            closed = sums[:-1]
            self.meat[k] += closed.T @ closed
            self.partial[k] = sums[-1]
            if (self.n_samples + n) % length == 0:  # the last batch is complete too
                self.meat[k] += np.outer(sums[-1], sums[-1])
                self.partial[k] = 0.0
        if self.n_samples == 0:
            self.first = residual[:, 0].copy()
        else:
            self.lagged += self.last * residual[:, 0]
        self.lagged += np.sum(residual[:, 1:] * residual[:, :-1], axis=1)
        self.total += residual.sum(axis=1)
        self.square += np.sum(residual**2, axis=1)
        self.last = residual[:, -1].copy()
        self.n_samples += n

    def closed(self) -> BatchScores:
        """At the file's end: its last, partial batch counted as one."""
        meat = self.meat + np.einsum("kp,kq->kpq", self.partial, self.partial)
        return BatchScores(meat, np.zeros_like(self.partial), self.n_samples, self.total, self.square, self.lagged,
                           self.first, self.last)


def lag_one_correlation(parts: Sequence[BatchScores], weights: NDArray[np.float64]) -> tuple[float, int]:
    """The weighted mean lag-1 autocorrelation of the centred residuals (as
    :func:`estimation.uncertainty.batch_means.batch_length`, each file's mean removed) and the sample count."""
    variance = np.zeros_like(weights)
    covariance = np.zeros_like(weights)
    count = 0
    for part in parts:
        n = part.n_samples
        mean = part.total / n
        variance += part.square - n * mean**2
        covariance += part.lagged - mean * (2 * part.total - part.first - part.last) + (n - 1) * mean**2
        count += n
    rho = float(np.clip(np.sum(weights * covariance) / max(np.sum(weights * variance), 1e-300), 0.0, 0.999))
    return rho, count


def sandwich(parts: Sequence[BatchScores], normal: NDArray[np.float64], classical: NDArray[np.float64],
             weights: NDArray[np.float64]) -> tuple[NDArray[np.float64], int]:
    """The batch-means covariance (never below ``classical`` on the diagonal, its correlations kept
    at the sandwich's diagonal, as :func:`estimation.estimators.variable_projection.fit_shapes`) and the batch length used."""
    rho, n_samples = lag_one_correlation(parts, weights)
    alpha = 4 * rho**2 / (1 - rho) ** 4
    length = int(np.clip(round(1.1447 * (alpha * n_samples) ** (1 / 3)), 1, max(1, n_samples // 20)))
    allowed = [candidate for candidate in BATCH_LENGTHS if candidate <= max(1, n_samples // 20)]  # twenty batches
    k = int(np.argmin([abs(np.log(candidate / length)) for candidate in allowed]))
    meat = sum(part.meat[k] for part in parts)
    scale = np.sqrt(np.diag(normal))
    inverse = np.linalg.inv(normal / np.outer(scale, scale)) / np.outer(scale, scale)  # equilibrated
    p = normal.shape[0]
    cov = inverse @ meat @ inverse * n_samples / max(n_samples - p, 1)
    diagonal = np.maximum(np.diag(cov), np.diag(classical))
    scale = np.sqrt(np.clip(diagonal, 0.0, None) / np.clip(np.diag(classical), np.finfo(float).tiny, None))
    return classical * np.outer(scale, scale), BATCH_LENGTHS[k]
