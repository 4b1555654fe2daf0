"""A free gain on each joint's torque channel, fitted with ``θ``: the bilinear least squares ``τ_j = s_j Y_j θ``.

Torques logged as motor currents (a torque constant per joint nobody gave), or a torque sensor's calibration, record
joint ``j``'s torque times its own gain ``s_j``. The per-joint columns (friction, offsets) absorb their joint's gain;
the rigid body's columns are shared between the joints' rows, so a gain that differs from joint to joint is a fault
of the log that a linear fit of ``θ`` alone cannot take up, and that other per-joint faults of the log's conventions
(a joint's zero off the description's, :mod:`estimation.identification.joint_zeros`) may take up in its place. The
overall scale is not determined (``(c s, θ / c)`` predict the same torques): the first gain is held at 1.

:func:`fit_channel_gains` minimises ``Σ_j w_j² ‖τ_j − s_j Y_j θ‖²`` by Levenberg–Marquardt on the channels' Gram
sums ``G_j = Y_jᵀ Y_j``, ``b_j = Y_jᵀ τ_j`` (the normal equations of the Gauss–Newton step in ``(θ, s)``; the gains
may take either sign). The weights ``w_j`` are given and fixed (every candidate scored alike). This is the fit of
:mod:`estimation.consistent.torque_gains` (PUMA paper eq. 20's weighting left to the caller), on the few thinned
samples of a check, without the description's scale: only the gains relative to each other matter here.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

__all__ = ["ChannelGains", "fit_channel_gains"]

#: Levenberg–Marquardt iterations at most, and the relative fall of the cost below which it stops
MAX_ITERATIONS = 100
TOLERANCE = 1e-10


@dataclass(frozen=True)
class ChannelGains:
    """What :func:`fit_channel_gains` found.

    Attributes
    ----------
    theta
        ``(r,)`` the parameters in the scale of the first free gain held at 1.
    gains
        ``(m,)`` one gain a channel (1 on the channels not given a gain).
    cost
        ``Σ_j w_j² ‖τ_j − s_j Y_j θ‖² / (N m)``: the mean of the weighted squared residuals.
    """

    theta: NDArray[np.float64]
    gains: NDArray[np.float64]
    cost: float

    def predicted(self, Y: NDArray) -> NDArray:
        """``s_j Y_j θ`` for ``Y (N, m, r)``: ``(N, m)``."""
        return (Y @ self.theta) * self.gains


def fit_channel_gains(Y: NDArray, target: NDArray, weights: NDArray, gained: NDArray[np.bool_]) -> ChannelGains:
    """Fit ``θ`` and a gain on each channel where ``gained`` (module docstring).

    Parameters
    ----------
    Y
        ``(N, m, r)`` the base regressor.
    target
        ``(N, m)`` the recorded channels.
    weights
        ``(m,)`` each channel's residual weight (fixed).
    gained
        ``(m,)`` the channels given a free gain (joint torques); the first of them is held at 1 (the scale), the
        others at 1.

    Returns
    -------
    ChannelGains
        With fewer than two gained channels, the linear least-squares fit (gains all 1).
    """
    N, m, r = Y.shape
    w2 = np.asarray(weights, dtype=float) ** 2
    by_channel = np.ascontiguousarray(Y.transpose(1, 0, 2))  # (m, N, r)
    G = (by_channel.transpose(0, 2, 1) @ by_channel) * w2[:, None, None]
    b = np.einsum("mnr,nm->mr", by_channel, target, optimize=True) * w2[:, None]
    c = np.einsum("nm,nm->m", target, target) * w2
    free = np.flatnonzero(gained)[1:]  # the first gained channel holds the scale
    s = _divided_start(G, b, c, gained, free)
    theta = _theta(G, b, s)
    cost = _cost(G, b, c, s, theta)
    damping = 1e-3
    for _ in range(MAX_ITERATIONS if free.size else 0):
        if cost <= 0.0:  # the model holds exactly
            break
        Gt = np.einsum("mrs,s->mr", G, theta)  # G_j θ
        # residual e_j = τ_j − s_j Y_j θ: d/dθ = −s_j Y_j, d/ds_j = −Y_j θ; H = JᵀJ, g = −Jᵀe
        H_tt = np.einsum("m,mrs->rs", s**2, G)
        H_ts = s[:, None] * Gt
        H_ss = Gt @ theta
        g_t = s @ b - H_tt @ theta
        g_s = b @ theta - s * H_ss
        H = np.block([[H_tt, H_ts[free].T], [H_ts[free], np.diag(H_ss[free])]])
        g = np.r_[g_t, g_s[free]]
        scale = np.sqrt(np.maximum(np.diag(H), 1e-300))
        while True:
            A = H / np.outer(scale, scale)
            step = np.linalg.lstsq(A + damping * np.eye(A.shape[0]), g / scale, rcond=None)[0] / scale
            trial_s = s.copy()
            trial_s[free] += step[r:]
            trial_theta = theta + step[:r]
            trial = _cost(G, b, c, trial_s, trial_theta)
            if trial <= cost or damping > 1e12:
                break
            damping *= 10.0
        if trial > cost:
            break
        done = cost - trial <= TOLERANCE * cost
        s, theta, cost, damping = trial_s, trial_theta, trial, max(damping / 10.0, 1e-12)
        if done:
            break
    return ChannelGains(theta, s, float(cost / (N * m)))


def _divided_start(G: NDArray, b: NDArray, c: NDArray, gained: NDArray[np.bool_], free: NDArray) -> NDArray:
    """The gains of the linear fit of the divided torques, ``h_j τ_j = Y_j θ`` with ``h_j = 1 / s_j`` (the first
    gained channel's ``h`` and the others' held at 1): one least-squares solve in ``(θ, h)`` whose residual is
    in the model's units rather than the recorded ones; exact when the model holds exactly, so the start from which
    Levenberg–Marquardt takes the recorded units' least squares in a few steps (from ``s = 1`` it creeps along the
    valley of the gains the rigid body hardly determines, and cannot reach a gain of the other sign)."""
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


def _theta(G: NDArray, b: NDArray, s: NDArray) -> NDArray:
    """``θ`` at the gains ``s``: the normal equations ``Σ s_j² G_j θ = Σ s_j b_j`` of the scaled columns."""
    A = np.einsum("m,mrs->rs", s**2, G)
    scale = np.sqrt(np.maximum(np.diag(A), 1e-300))
    return np.linalg.lstsq(A / np.outer(scale, scale), (s @ b) / scale, rcond=1e-12)[0] / scale


def _cost(G: NDArray, b: NDArray, c: NDArray, s: NDArray, theta: NDArray) -> float:
    return float(np.sum(c - 2.0 * s * (b @ theta) + s**2 * np.einsum("r,mrs,s->m", theta, G, theta)))
