"""ARX and ARMAX model structures: regressors, batch least squares, predictors, free-run, order selection.

Convention (Ljung; the servo paper's eqs. 22–25)::

    A(z) y(n) = B(z) u(n) + C(z) e(n)
    A = 1 + a1 z⁻¹ + … + a_na z⁻ⁿᵃ,  B = z⁻ⁿᵏ (b1 + b2 z⁻¹ + … + b_nb z⁻ⁿᵇ⁺¹),  C = 1 + c1 z⁻¹ + … + c_nc z⁻ⁿᶜ

The parameter vector is ``θ = [a1 … a_na, b1 … b_nb, c1 … c_nc]`` (eq. 24) and the regressor
``φ(n) = [−y(n−1) … −y(n−na), u(n−nk) … u(n−nk−nb+1), ε(n−1) … ε(n−nc)]`` (eq. 25, with a general delay).

Examples
--------
>>> import numpy as np
>>> from estimation.estimators.arx import ARXEstimator
>>> rng = np.random.default_rng(0)
>>> u = rng.standard_normal(2000)
>>> y = ARXEstimator.simulate_structure(a=[-1.5, 0.7], b=[0.5], nk=1, u=u)
>>> model = ARXEstimator(na=2, nb=1, nk=1).fit(u, y)
>>> np.round(model.theta_, 6).tolist()
[-1.5, 0.7, 0.5]
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np
import scipy.signal
from numpy.typing import ArrayLike

from estimation.estimators.errors import NotFittedError
from estimation.estimators.estimator import Estimator
from dynamics.signal_checks import check_informative, single_channel


def check_orders(na: int, nb: int, nk: int, nc: int = 0) -> None:
    """Validate model orders (``na, nc ≥ 0``, ``nb ≥ 1``, ``nk ≥ 1``), naming the offending one."""
    for name, value, low in (("na", na, 0), ("nb", nb, 1), ("nk", nk, 1), ("nc", nc, 0)):
        if not isinstance(value, (int, np.integer)) or isinstance(value, bool):
            raise TypeError(f"{name} must be an integer, got {value!r}")
        if value < low:
            raise ValueError(f"{name} must be >= {low}, got {value}")


def as_signal_pair(u: ArrayLike, y: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
    """Return ``u, y`` as finite 1-D float arrays of equal length, or raise ``ValueError`` naming the problem."""
    u, y = single_channel(u, "u"), single_channel(y, "y")
    if u.size != y.size:
        raise ValueError(f"input u has {u.size} samples but output y has {y.size}")
    for name, signal in (("u", u), ("y", y)):
        if not np.all(np.isfinite(signal)):
            raise ValueError(f"signal {name} holds NaN/inf at sample {int(np.flatnonzero(~np.isfinite(signal))[0])}")
    return u, y


def arx_regressors(u: np.ndarray, y: np.ndarray, na: int, nb: int, nk: int) -> tuple[np.ndarray, np.ndarray]:
    """Regressor matrix ``Φ`` (rows ``φ(n)ᵀ`` of eq. 25 without the noise terms) and targets ``y(n)``.

    Rows start at ``n0 = max(na, nk + nb − 1)`` so that every entry is a measured sample.
    """
    n0 = max(na, nk + nb - 1)
    rows = np.arange(n0, y.size)
    columns = [-y[rows - i] for i in range(1, na + 1)] + [u[rows - nk - j] for j in range(nb)]
    return np.column_stack(columns), y[rows]


@dataclass(frozen=True)
class Polynomials:
    """``A, B, C`` as coefficient arrays in powers of ``z⁻¹`` (``B`` includes the leading ``nk`` zeros)."""

    a: np.ndarray
    b: np.ndarray
    c: np.ndarray

    @classmethod
    def from_theta(cls, theta: ArrayLike, na: int, nb: int, nk: int, nc: int = 0) -> Polynomials:
        theta = np.asarray(theta, dtype=float).reshape(-1)
        if theta.size != na + nb + nc:
            raise ValueError(f"theta has {theta.size} entries, orders need na+nb+nc = {na + nb + nc}")
        a = np.concatenate(([1.0], theta[:na]))
        b = np.concatenate((np.zeros(nk), theta[na : na + nb]))
        c = np.concatenate(([1.0], theta[na + nb :]))
        return cls(a=a, b=b, c=c)

    def one_step_prediction(self, u: np.ndarray, y: np.ndarray) -> np.ndarray:
        """One-step-ahead predictor ``ŷ(n|n−1) = y(n) − ε(n)``, ``C ε = A y − B u`` (zero initial state)."""
        eps = scipy.signal.lfilter(self.a, self.c, y) - scipy.signal.lfilter(self.b, self.c, u)
        return y - eps

    def free_run(self, u: np.ndarray, y_past: np.ndarray, u_past: np.ndarray) -> np.ndarray:
        """Simulate ``A y = B u`` (noise-free) from measured past samples (oldest first) — never reset to data."""
        zi = scipy.signal.lfiltic(self.b, self.a, y_past[::-1], u_past[::-1])
        out, _ = scipy.signal.lfilter(self.b, self.a, u, zi=zi)
        return out


class ARXEstimator(Estimator):
    """ARX model ``A(z) y = B(z) u + e`` by batch least squares (the servo paper's eqs. 17–19 with ``nc = 0``).

    Parameters
    ----------
    na, nb, nk
        Orders of ``A``, ``B`` and the input delay in samples.
    """

    def __init__(self, *, na: int = 2, nb: int = 1, nk: int = 1) -> None:
        self.na = na
        self.nb = nb
        self.nk = nk

    def fit(self, u: ArrayLike, y: ArrayLike) -> ARXEstimator:
        """Least-squares estimate ``θ̂ = argmin V`` (eq. 19); sets ``theta_``, ``cov_``, ``noise_variance_``, ``residuals_``."""
        self._forget_fit()
        check_orders(self.na, self.nb, self.nk)
        u, y = as_signal_pair(u, y)
        check_informative(u, y)
        phi, target = arx_regressors(u, y, self.na, self.nb, self.nk)
        p = phi.shape[1]
        if target.size <= p:
            raise ValueError(f"{target.size} usable samples for {p} parameters: need more data")
        theta, _, rank, _ = np.linalg.lstsq(phi, target, rcond=None)
        if rank < p:
            raise ValueError(f"regressor matrix has rank {rank} < {p}: input not persistently exciting for these orders")
        residuals = target - phi @ theta
        noise_variance = float(residuals @ residuals) / (target.size - p)
        self.theta_ = theta
        self.noise_variance_ = noise_variance
        self.cov_ = noise_variance * np.linalg.inv(phi.T @ phi)
        self.residuals_ = residuals
        self.n_parameters_ = p
        return self

    def _fitted(self) -> Polynomials:
        if not hasattr(self, "theta_"):
            raise NotFittedError(f"{type(self).__name__} is not fitted yet: call fit(u, y) first")
        return Polynomials.from_theta(self.theta_, self.na, self.nb, self.nk)

    def predict(self, u: ArrayLike, y: ArrayLike) -> np.ndarray:
        """One-step-ahead prediction ``ŷ(n|n−1)`` over a record (first ``max(na, nk+nb−1)`` samples are transient)."""
        polys = self._fitted()
        u, y = as_signal_pair(u, y)
        return polys.one_step_prediction(u, y)

    def simulate(self, u: ArrayLike, y_past: ArrayLike, u_past: ArrayLike) -> np.ndarray:
        """Free-run output for input ``u`` given the measured samples just before it (oldest first)."""
        polys = self._fitted()
        return polys.free_run(np.asarray(u, float), np.asarray(y_past, float), np.asarray(u_past, float))

    @staticmethod
    def simulate_structure(*, a: ArrayLike, b: ArrayLike, nk: int, u: ArrayLike, c: ArrayLike = (), e: ArrayLike | None = None) -> np.ndarray:
        """Output of ``A y = B u + C e`` from rest (to make test data with known parameters)."""
        a_poly = np.concatenate(([1.0], np.asarray(a, float)))
        b_poly = np.concatenate((np.zeros(nk), np.asarray(b, float)))
        y = scipy.signal.lfilter(b_poly, a_poly, np.asarray(u, float))
        if e is not None:
            y = y + scipy.signal.lfilter(np.concatenate(([1.0], np.asarray(c, float))), a_poly, np.asarray(e, float))
        return y


@dataclass(frozen=True)
class OrderCandidate:
    """One ``(na, nb, nc)`` tried by :func:`select_orders` and its score (lower is better)."""

    na: int
    nb: int
    nc: int
    score: float


@dataclass(frozen=True)
class OrderSelection:
    """Result of :func:`select_orders`: the best orders and every candidate's score."""

    na: int
    nb: int
    nc: int
    criterion: str
    candidates: tuple[OrderCandidate, ...]


def information_criterion(loss: float, n_samples: int, n_parameters: int, criterion: Literal["aic", "bic", "fpe"]) -> float:
    """Akaike/Bayesian information criterion or final prediction error of a fit with mean squared error ``loss``."""
    if criterion == "aic":
        return n_samples * np.log(loss) + 2 * n_parameters
    if criterion == "bic":
        return n_samples * np.log(loss) + n_parameters * np.log(n_samples)
    if criterion == "fpe":
        return loss * (n_samples + n_parameters) / (n_samples - n_parameters)
    raise ValueError(f"criterion must be 'aic', 'bic' or 'fpe', got {criterion!r}")
