"""Fit metrics of the servo-arm paper (Paiva et al.): cost V (eq. 18), RMSE Ω (eq. 20), adjusted R² (eq. 21).

All functions take a measured signal and a model output of the same length (one joint), and return floats.
Whether ``predicted`` is a one-step-ahead prediction or a free-run simulation is the caller's business; the
protocol in :mod:`estimation.servo.protocol` reports both, labelled, because one-step R² flatters a model.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from dynamics.signal_checks import single_channel


def _pair(measured: ArrayLike, predicted: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
    """One channel each (``(N,)``, ``(N, 1)`` or ``(1, N)``), of equal length: several channels are
    scored one by one, never pooled (a pooled R² mixes the channels' means into "explained" variance)."""
    y, y_hat = single_channel(measured, "measured"), single_channel(predicted, "predicted")
    if y.shape != y_hat.shape:
        raise ValueError(f"measured has {y.size} samples but predicted {y_hat.size}")
    if y.size == 0:
        raise ValueError("metrics need at least one sample")
    if not (np.all(np.isfinite(y)) and np.all(np.isfinite(y_hat))):
        raise ValueError("measured or predicted holds NaN/inf")
    return y, y_hat


def cost_v(measured: ArrayLike, predicted: ArrayLike) -> float:
    """Mean squared prediction error V (paper eq. 18), in the signal's unit squared (rad²).

    ``V = 1/N_E Σ (q(n) − q̂(n|θ))²``.
    """
    y, y_hat = _pair(measured, predicted)
    return float(np.mean((y - y_hat) ** 2))


def rmse(measured: ArrayLike, predicted: ArrayLike) -> float:
    """Root mean square error Ω (paper eq. 20), in the signal's unit (rad)."""
    return float(np.sqrt(cost_v(measured, predicted)))


def r2_adjusted(measured: ArrayLike, predicted: ArrayLike, n_parameters: int) -> float:
    """Adjusted coefficient of determination R²_aj (paper eq. 21).

    ``R²_aj = 1 − (N − 1)/(N − p) · Σ(q − q̂)² / Σ(q − q̄)²`` with ``q̄`` the mean of the measured signal.

    Notes
    -----
    The paper prints the factor as ``(N_V − p)/(N_V − 1)``, which is upside down: it would make the
    adjusted value *larger* than the plain R² for ``p > 1``. The usual (Theil) correction is used here.
    The value is not bounded below by 0 (a model worse than the mean gives a negative value).
    """
    y, y_hat = _pair(measured, predicted)
    n = y.size
    if not isinstance(n_parameters, (int, np.integer)) or isinstance(n_parameters, bool):
        raise TypeError(f"n_parameters must be an integer, got {type(n_parameters).__name__}")
    if n_parameters < 0:
        raise ValueError(f"n_parameters must be non-negative, got {n_parameters}")
    if n - n_parameters < 1:
        raise ValueError(f"adjusted R² needs more samples ({n}) than parameters ({n_parameters})")
    total = float(np.sum((y - y.mean()) ** 2))
    if total == 0.0:
        raise ValueError("adjusted R² is undefined for a constant measured signal")
    residual = float(np.sum((y - y_hat) ** 2))
    return 1.0 - (n - 1) / (n - n_parameters) * residual / total
