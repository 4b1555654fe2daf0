"""Standard deviations of an output-error fit whose residual is coloured (issue 17).

The free-run residual ``r = q − q̂`` of a joint whose angle comes from a Kalman fusion is not white: the filter
low-passes the sensor noise, so neighbouring samples share it. The plain Gauss–Newton covariance
``σ_e² (JᵀJ)⁻¹`` then understates the spread of the estimates (several-fold for a filter of long memory).
The sandwich covariance of a least-squares estimate with correlated errors is used instead (Ljung,
*System Identification*, 2nd ed., sec. 9.3; the "HAC" estimator of Newey & West 1987 with the residual's
pooled autocovariance)::

    Cov θ̂ = (JᵀJ)⁻¹ (Σ_{|ℓ|≤L} w_ℓ γ(ℓ) Σ_n J_n J_{n+ℓ}ᵀ) (JᵀJ)⁻¹,    w_ℓ = 1 − |ℓ|/(L + 1)   (Bartlett)

``J`` (N × p) the sensitivity of the simulated angle to the parameters at the optimum, ``γ(ℓ)`` the residual's
sample autocovariance. For white residuals (``L = 0``) it is ``σ_e² (JᵀJ)⁻¹``. The window ``L`` is where
the residual's autocorrelation has died out: twice the first lag at which it falls below ``2/√N``
(at least 1, at most ``N/4``). The ratio of the sandwich variances to the plain ones is reported
(``variance_inflation``) so that a user sees how much the colouring mattered.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class SandwichCovariance:
    """``covariance`` (p × p), the window ``lags`` used, and ``variance_inflation`` (p,), the ratio of each
    variance to the white-noise Gauss–Newton one."""

    covariance: np.ndarray
    lags: int
    variance_inflation: np.ndarray


def correlation_window(residual: np.ndarray) -> int:
    """Bartlett window ``L`` for :func:`sandwich_covariance` (module docstring)."""
    r = np.asarray(residual, dtype=float).reshape(-1)
    r = r - r.mean()
    n = r.size
    spectrum = np.fft.rfft(r, 2 * n)
    autocovariance = np.fft.irfft(spectrum * np.conj(spectrum))[:n] / n
    if autocovariance[0] <= 0:
        return 0
    rho = autocovariance / autocovariance[0]
    below = np.flatnonzero(np.abs(rho[1:]) < 2 / np.sqrt(n))
    first = int(below[0]) + 1 if below.size else n
    return int(min(max(2 * first, 1), n // 4))


def sandwich_covariance(jacobian: np.ndarray, residual: np.ndarray, *, lags: int | None = None) -> SandwichCovariance:
    """Covariance of a least-squares estimate from its sensitivity ``jacobian`` (N × p) and ``residual`` (N,).

    Parameters
    ----------
    lags
        Bartlett window ``L``; default :func:`correlation_window` of the residual.

    Raises
    ------
    numpy.linalg.LinAlgError
        If ``JᵀJ`` is singular (a parameter the data do not determine).
    """
    j = np.asarray(jacobian, dtype=float)
    r = np.asarray(residual, dtype=float).reshape(-1)
    n, p = j.shape
    if lags is None:
        lags = correlation_window(r)
    centred = r - r.mean()
    gamma = np.array([centred[: n - ell] @ centred[ell:] / n for ell in range(lags + 1)])
    information = j.T @ j
    inverse = np.linalg.inv(information)
    middle = gamma[0] * information
    for ell in range(1, lags + 1):
        cross = j[: n - ell].T @ j[ell:]
        middle += (1 - ell / (lags + 1)) * gamma[ell] * (cross + cross.T)
    covariance = inverse @ middle @ inverse
    covariance = 0.5 * (covariance + covariance.T)
    plain = np.diag(inverse) * float(r @ r) / max(n - p, 1)
    return SandwichCovariance(covariance=covariance, lags=int(lags), variance_inflation=np.diag(covariance) / plain)
