"""A free gain on each joint's torque channel, fitted with ``θ``: the bilinear least squares ``τ_j = s_j Y_j θ``.

Torques logged as motor currents (a torque constant per joint nobody gave), or a torque sensor's calibration, record
joint ``j``'s torque times its own gain ``s_j``. The per-joint columns (friction, offsets) absorb their joint's gain;
the rigid body's columns are shared between the joints' rows, so a gain that differs from joint to joint is a fault
of the log that a linear fit of ``θ`` alone cannot take up, and that other per-joint faults of the log's conventions
(a joint's zero off the description's, :mod:`estimation.identification.joint_zeros`) may take up in its place. The
overall scale is not determined (``(c s, θ / c)`` predict the same torques): the first gain is held at 1.

:func:`fit_channel_gains` minimises ``Σ_j w_j² ‖τ_j − s_j Y_j θ‖²`` by Levenberg–Marquardt on the channels' Gram
sums ``G_j = Y_jᵀ Y_j``, ``b_j = Y_jᵀ τ_j`` (:func:`estimation.estimators.channel_gains.fit_channel_gains_on_sums`,
the loop :mod:`estimation.consistent.torque_gains` runs too; here the gains may take either sign and start from the
divided torques' linear fit). The weights ``w_j`` are given and fixed (every candidate scored alike), on the few
thinned samples of a check, without the description's scale: only the gains relative to each other matter here.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from estimation.estimators.channel_gains import GainSign, GainsFit, determined_gains, divided_start, fit_channel_gains_on_sums, weighted_channel_sums

__all__ = ["ChannelGains", "determined_channels", "fit_channel_gains"]

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


def fit_channel_gains(Y: NDArray, target: NDArray, weights: NDArray, gained: NDArray[np.bool_], *,
                      sign: GainSign = "free", max_iterations: int = MAX_ITERATIONS) -> ChannelGains:
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
    sign
        ``"free"``: a gain may take either sign (a reversed torque is one); ``"held"``: the gains stay positive (a
        reversed torque is not taken up: the joint-zero check's directions say it).
    max_iterations
        Levenberg–Marquardt's iterations at most.

    Returns
    -------
    ChannelGains
        With fewer than two gained channels, the linear least-squares fit (gains all 1).
    """
    N, m, _ = Y.shape
    sums = weighted_channel_sums(Y, target, np.asarray(weights, dtype=float) ** 2)
    free = np.flatnonzero(gained)[1:]  # the first gained channel holds the scale
    start = divided_start(*sums, free)
    fitted = fit_channel_gains_on_sums(sums, start if sign == "free" else np.abs(start), free, sign=sign,
                                       max_iterations=max_iterations, tolerance=TOLERANCE)
    return ChannelGains(fitted.theta, fitted.gains, float(fitted.cost / (N * m)))


def determined_channels(Y: NDArray, target: NDArray, weights: NDArray, gained: NDArray[np.bool_],
                        fitted: ChannelGains) -> NDArray[np.bool_]:
    """``gained`` less the channels whose gain ``fitted`` (:func:`fit_channel_gains` of the same arguments) the
    samples do not determine (:func:`estimation.estimators.channel_gains.determined_gains`; the first gained channel,
    the scale, kept): a gain left free there wanders along a valley of the cost, and the costs of candidates scored
    with it differ by how far each fit crept."""
    N, m, _ = Y.shape
    sums = weighted_channel_sums(Y, target, np.asarray(weights, dtype=float) ** 2)
    free = np.flatnonzero(gained)[1:]
    known = determined_gains(sums, GainsFit(fitted.theta, fitted.gains, fitted.cost * N * m, 0), free, N * m)
    kept = np.asarray(gained, dtype=bool).copy()
    kept[free[~known]] = False
    return kept
