"""The bilinear least squares of a free gain on each channel: ``τ_j = s_j Y_j θ``, from the channels' Gram sums.

A channel recorded with its own unknown gain (a torque logged as a motor current, a sensor's calibration) makes the
model bilinear: the gains times ``Y θ``. With the channels' sums ``G_j = w_j Y_jᵀ Y_j``, ``b_j = w_j Y_jᵀ τ_j``,
``c_j = w_j τ_jᵀ τ_j`` (each weighted by ``w_j``, the inverse of its residual variance or any fixed weight), the cost
``Σ_j w_j ‖τ_j − s_j Y_j θ‖² = Σ_j c_j − 2 s_j b_jᵀ θ + s_j² θᵀ G_j θ`` and its Gauss–Newton normal equations in
``(θ, s)`` need no sample (Nocedal & Wright, *Numerical Optimization*, 2nd ed., §10.3, Levenberg–Marquardt).

:func:`fit_channel_gains_on_sums` is the one Levenberg–Marquardt loop of the two callers:

- :mod:`estimation.consistent.torque_gains` (the default answer's candidate): the gains kept positive (steps in
  ``log s``, ``sign="held"``), started at 1, the weights iterated outside (as WLS), the scale then fixed by the robot
  description's bodies;
- :mod:`estimation.identification.channel_gains` (the joint-zero check's test): the gains of either sign
  (``sign="free"``), started from :func:`divided_start`, the weights fixed, the first gain the scale.

The overall scale is not determined (``(c s, θ / c)`` predict the same): the caller holds at least one gain
(``free`` lists those that move).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np
from numpy.typing import NDArray

__all__ = ["DETERMINED_RELATIVE_STD", "GainSign", "GainsFit", "channel_residuals", "determined_gains", "divided_start",
           "fit_channel_gains_on_sums", "gains_normal", "gains_theta", "weighted_channel_sums"]

#: a gain whose standard error exceeds this fraction of it is not determined by the record (a sensor's calibration
#: error is of this order: such a value measures nothing; on a PUMA's wrist the spread of the estimates over noise
#: draws is then up to three times the linearised standard error, tests/test_torque_gains.py)
DETERMINED_RELATIVE_STD = 0.1

#: how a gain moves: ``"free"`` by additive steps (either sign), ``"held"`` by steps in its logarithm (its sign kept)
GainSign = Literal["free", "held"]


@dataclass(frozen=True)
class GainsFit:
    """What :func:`fit_channel_gains_on_sums` found.

    Attributes
    ----------
    theta
        ``(r,)`` the parameters at ``gains``.
    gains
        ``(m,)`` one gain a channel (the held ones as started).
    cost
        ``Σ_j c_j − 2 s_j b_jᵀ θ + s_j² θᵀ G_j θ``: the weighted residual sum of squares.
    iterations
        The Levenberg–Marquardt iterations taken.
    """

    theta: NDArray[np.float64]
    gains: NDArray[np.float64]
    cost: float
    iterations: int


def weighted_channel_sums(Y: NDArray, target: NDArray, weights: NDArray) -> tuple[NDArray, NDArray, NDArray]:
    """``(G, b, c)`` of ``Y (N, m, r)`` and ``target (N, m)``, channel ``j``'s sums times ``weights[j]``."""
    weights = np.asarray(weights, dtype=float)
    by_channel = np.ascontiguousarray(Y.transpose(1, 0, 2))  # (m, N, r)
    G = (by_channel.transpose(0, 2, 1) @ by_channel) * weights[:, None, None]
    b = np.einsum("mnr,nm->mr", by_channel, target, optimize=True) * weights[:, None]
    c = np.einsum("nm,nm->m", target, target) * weights
    return G, b, c


def channel_residuals(G: NDArray, b: NDArray, c: NDArray, gains: NDArray, theta: NDArray) -> NDArray:
    """``(m,)`` each channel's (weighted) residual sum of squares ``c_j − 2 s_j b_jᵀ θ + s_j² θᵀ G_j θ``."""
    return c - 2.0 * gains * (b @ theta) + gains**2 * np.einsum("r,mrs,s->m", theta, G, theta)


def gains_theta(G: NDArray, b: NDArray, gains: NDArray) -> NDArray:
    """``θ`` at the gains ``s``: the normal equations ``Σ s_j² G_j θ = Σ s_j b_j`` of the scaled columns."""
    A = np.einsum("m,mrs->rs", gains**2, G)
    scale = np.sqrt(np.maximum(np.diag(A), 1e-300))
    return np.linalg.lstsq(A / np.outer(scale, scale), (gains @ b) / scale, rcond=1e-12)[0] / scale


def divided_start(G: NDArray, b: NDArray, c: NDArray, free: NDArray) -> NDArray:
    """The gains of the linear fit of the divided channels, ``h_j τ_j = Y_j θ`` with ``h_j = 1 / s_j`` (the channels
    not in ``free`` held at ``h = 1``): one least-squares solve in ``(θ, h)`` whose residual is in the model's units
    rather than the recorded ones; exact when the model holds exactly, so a start from which Levenberg–Marquardt
    takes the recorded units' least squares in a few steps (from ``s = 1`` it creeps along the valley of the gains the
    regressor hardly determines, and cannot reach a gain of the other sign)."""
    m, r = b.shape
    s = np.ones(m)
    if free.size == 0:
        return s
    held = np.setdiff1d(np.arange(m), free)
    A = np.zeros((r + free.size, r + free.size))
    A[:r, :r] = G.sum(axis=0)
    A[:r, r:] = -b[free].T
    A[r:, :r] = -b[free]
    A[r:, r:] = np.diag(c[free])
    rhs = np.r_[b[held].sum(axis=0), np.zeros(free.size)]
    scale = np.sqrt(np.maximum(np.diag(A), 1e-300))
    h = (np.linalg.lstsq(A / np.outer(scale, scale), rhs / scale, rcond=1e-12)[0] / scale)[r:]
    usable = np.isfinite(h) & (np.abs(h) > 1e-6 * np.max(np.abs(h), initial=0.0))
    s[free[usable]] = 1.0 / h[usable]
    return s


def gains_normal(G: NDArray, b: NDArray, gains: NDArray, theta: NDArray, free: NDArray, sign: GainSign
                 ) -> tuple[NDArray, NDArray]:
    """The Gauss–Newton normal equations ``(JᵀJ, −Jᵀe)`` in ``(θ, s_free)`` (``sign="held"``: in ``log s_free``) of
    the residuals ``e_j = τ_j − s_j Y_j θ`` from the weighted sums (``d/dθ = −s_j Y_j``, ``d/ds_j = −Y_j θ``,
    ``d/dlog s_j = s_j d/ds_j``)."""
    s = gains
    Gt = np.einsum("mrs,s->mr", G, theta)  # G_j θ
    H_tt = np.einsum("m,mrs->rs", s**2, G)
    H_ts = s[:, None] * Gt
    H_ss = Gt @ theta
    g_t = s @ b - H_tt @ theta
    g_s = b @ theta - s * H_ss
    if sign == "held":
        H_ts, H_ss, g_s = s[:, None] * H_ts, s**2 * H_ss, s * g_s
    r, k = H_tt.shape[0], free.size
    H = np.zeros((r + k, r + k))  # the blocks copied in place (np.block's values, without its checks)
    H[:r, :r] = H_tt
    H[:r, r:] = H_ts[free].T
    H[r:, :r] = H_ts[free]
    H[r + np.arange(k), r + np.arange(k)] = H_ss[free]
    return H, np.concatenate((g_t, g_s[free]))


def determined_gains(sums: tuple[NDArray, NDArray, NDArray], fitted: GainsFit, free: NDArray, n_residuals: int
                     ) -> NDArray[np.bool_]:
    """Which gains of ``free`` (at ``fitted``, the least squares of ``sums``) the record determines: the standard
    error of ``log s_j`` from the Gauss–Newton covariance ``σ² (JᵀJ)⁻¹`` (``σ²`` the weighted residual variance over
    the ``n_residuals`` residuals less the parameters) within :data:`DETERMINED_RELATIVE_STD`; ``(free.size,)``. A
    gain that is not wanders along a valley of the cost (a PUMA's wrist, whose torques are at the noise: gains of
    100 and more for a fall of the cost of a few per cent)."""
    G, b, _ = sums
    H, _ = gains_normal(G, b, fitted.gains, fitted.theta, free, "held")
    variance = fitted.cost / max(n_residuals - H.shape[0], 1)
    std = np.sqrt(np.clip(np.diag(np.linalg.pinv(H))[b.shape[1]:] * variance, 0.0, None))
    return std <= DETERMINED_RELATIVE_STD


def fit_channel_gains_on_sums(sums: tuple[NDArray, NDArray, NDArray], gains: NDArray, free: NDArray, *,
                              sign: GainSign = "free", max_iterations: int = 100, tolerance: float = 1e-10
                              ) -> GainsFit:
    """Minimise ``Σ_j w_j ‖τ_j − s_j Y_j θ‖²`` over ``θ`` and the gains of ``free`` (module docstring).

    Parameters
    ----------
    sums
        ``(G, b, c)`` the channels' weighted sums (:func:`weighted_channel_sums`, or summed over a record's blocks).
    gains
        ``(m,)`` the start; the channels not in ``free`` keep theirs.
    free
        The indices of the gains fitted (the scale: at least one gain is held).
    sign
        ``"free"``: additive steps, a gain may change sign; ``"held"``: steps in ``log s`` (the start's signs kept).
    max_iterations, tolerance
        At most ``max_iterations`` steps; stop when a step lowers the cost by at most ``tolerance`` of it.

    Returns
    -------
    GainsFit
        Without a free gain, the linear least-squares fit at ``gains`` (no iteration).
    """
    if sign not in ("free", "held"):
        raise ValueError(f"sign must be 'free' or 'held', not {sign!r}")
    G, b, c = sums
    free = np.asarray(free, dtype=int)
    r = b.shape[1]
    s = np.asarray(gains, dtype=float).copy()
    theta = gains_theta(G, b, s)
    cost = float(np.sum(channel_residuals(G, b, c, s, theta)))
    damping = 1e-3
    iterations = 0
    for _ in range(max_iterations if free.size else 0):
        if cost <= 0.0:  # the model holds exactly
            break
        iterations += 1
        H, g = gains_normal(G, b, s, theta, free, sign)
        scale = np.sqrt(np.maximum(np.diag(H), 1e-300))
        A, rhs = H / np.outer(scale, scale), g / scale  # the same at each damping tried
        identity = np.eye(A.shape[0])
        while True:
            step = np.linalg.lstsq(A + damping * identity, rhs, rcond=None)[0] / scale
            trial_s = s.copy()
            if sign == "held":
                trial_s[free] *= np.exp(step[r:])
            else:
                trial_s[free] += step[r:]
            trial_theta = theta + step[:r]
            trial = float(np.sum(channel_residuals(G, b, c, trial_s, trial_theta)))
            if trial <= cost or damping > 1e12:
                break
            damping *= 10.0
        if trial > cost:
            break
        done = cost - trial <= tolerance * cost
        s, theta, cost, damping = trial_s, trial_theta, trial, max(damping / 10.0, 1e-12)
        if done:
            break
    return GainsFit(theta, s, cost, iterations)
