"""Least squares from :class:`~estimation.estimators.normal_equations.NormalEquations` (sums over samples).

:class:`SummedLeastSquares` is :class:`estimation.estimators.least_squares.WeightedLeastSquares` (weights
``1/σ_c²`` iterated, Gautier's weighting) or :class:`~estimation.estimators.least_squares.LeastSquares`
(PUMA paper, eq. 20) with the data given as sums; :func:`solve_sums` solves one weighted problem
from the per-channel TSQR factors (see :mod:`estimation.estimators.normal_equations` for the accuracy).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np
import scipy.linalg
from numpy.typing import NDArray

from dynamics.runtime.threads import single_threaded_blas
from estimation.data.passive import floored_variance
from estimation.estimators.estimator import Estimator
from estimation.estimators.least_squares import IDENTIFIABILITY_TOLERANCE, IdentifiabilityError, ParameterRecords, freeze_arrays
from estimation.estimators.normal_equations import NormalEquations, stacked_factor

__all__ = ["SHAPED_ROUNDS", "SHAPED_TOL", "SummedEstimate", "SummedLeastSquares", "solve_sums", "summed_estimator"]


def solve_sums(sums: NormalEquations, weights: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64], float]:
    """``θ̂``, ``(YᵀWY)⁻¹`` and ``cond(W^½ Y)`` for channel weights ``(m,)`` — the counterpart of
    :func:`estimation.estimators.least_squares.solve` from the sums.

    The weighted factor is the R of ``[√w_c R_c]`` stacked over channels (TSQR); the parameters
    follow by back substitution. Columns are equilibrated (unit norms) for the rank test, which
    uses the same tolerance as the in-memory solve (on eigenvalues of the equilibrated ``YᵀWY``,
    i.e. squared singular values of the equilibrated factor).
    """
    theta, R_theta = _solved(sums, weights)
    k = sums.n_columns
    inverse_factor = scipy.linalg.solve_triangular(R_theta, np.eye(k), check_finite=False)
    inverse = inverse_factor @ inverse_factor.T
    extremes = np.linalg.svd(R_theta, compute_uv=False)[[0, -1]]
    return theta, inverse, float(extremes[0] / max(extremes[1], np.finfo(float).tiny))


def _solved(sums: NormalEquations, weights: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """``θ̂`` of :func:`solve_sums` (the same factor, rank test and back substitution) and the weighted factor
    ``R_θ``, without the inverse and the condition number: what each pass of the weight iteration needs."""
    weights = np.asarray(weights, dtype=float)
    k = sums.n_columns
    if not np.all(np.isfinite(sums.factor)):
        raise ValueError("the regressor or the measured channels overflow: check the units of the data")
    R = stacked_factor([np.sqrt(w) * R_c for w, R_c in zip(weights, sums.factor)], k + 1)
    R_theta = R[:k, :k]
    scale = np.linalg.norm(R_theta, axis=0)
    zero = np.flatnonzero(scale == 0)
    if zero.size:
        names = tuple(sums.names[i] for i in zero)
        raise IdentifiabilityError(
            f"parameter(s) {list(names)} have all-zero columns: these data do not excite them", names, unexcited=True)
    singular, right = np.linalg.svd(R_theta / scale, full_matrices=False)[1:]
    if singular[-1] ** 2 < IDENTIFIABILITY_TOLERANCE * singular[0] ** 2:
        direction = np.abs(right[-1])
        weak = [sums.names[i] for i in np.flatnonzero(direction > 0.3 * direction.max())]
        raise IdentifiabilityError(
            f"the data do not determine parameter(s) {weak}: the regressor is rank deficient "
            "(excite the robot more, or drop those columns)", tuple(weak))
    return scipy.linalg.solve_triangular(R_theta, R[:k, k], check_finite=False), R_theta


@dataclass(frozen=True)
class SummedEstimate(ParameterRecords):
    """Identified parameters from sums: :class:`estimation.estimators.least_squares.Estimate` without the
    per-sample residuals (``channel_rss`` and ``n_samples`` instead)."""

    values: NDArray[np.float64]
    cov: NDArray[np.float64]
    std: NDArray[np.float64]
    relative_std: NDArray[np.float64]
    cond: float
    channel_variance: NDArray[np.float64]
    channel_rss: NDArray[np.float64]
    weights: NDArray[np.float64]
    n_samples: int
    names: tuple[str, ...]
    expressions: tuple[str, ...]
    channels: tuple[str, ...]
    method: Literal["ols", "wls"]
    n_iterations: int
    #: how ``cov`` was had: ``"classical"`` (white residuals, from the sums) or ``"batch_means"`` (the sandwich of a
    #: pass over the files, :mod:`estimation.streaming.covariance`); no HAC lags (the in-memory estimate's field)
    cov_method: Literal["classical", "batch_means"] = "classical"
    hac_lags: None = None

    def __post_init__(self) -> None:
        freeze_arrays(self, ("values", "cov", "std", "relative_std", "channel_variance", "channel_rss", "weights"))

    def channel_rms(self) -> dict[str, float]:
        """Root-mean-square residual per channel."""
        return dict(zip(self.channels, map(float, np.sqrt(self.channel_rss / self.n_samples))))


class SummedLeastSquares(Estimator):
    """Ordinary or channel-weighted (iterated) least squares from :class:`NormalEquations`.

    The same estimator as :class:`estimation.estimators.least_squares.WeightedLeastSquares` (weights
    ``1/σ_c²`` iterated until no channel variance moves by more than ``tol``, variances floored at
    ``variance_floor`` times the channel's mean square) or, with ``method="ols"``,
    :class:`estimation.estimators.least_squares.LeastSquares`; only the data come as sums. The variances are those
    of the residual in the motion's band when the sums hold its sums (:attr:`NormalEquations.band`), as in memory.
    ``n_shape``: parameters fitted beside the columns (shaped laws' shape parameters, the columns summed at their
    fitted values) counted in each channel's degrees of freedom, ``N − (r + n_shape)/m``, as the in-memory
    variable-projection fit counts them (:func:`estimation.identification.shaped.fit_shaped_model`; with the
    weights iterated as there: :func:`summed_estimator`). ``passive``: the channels of passive joints
    (:mod:`estimation.data.passive`), whose zero is a measurement, weighted by their residual as in memory.
    ``fit(sums)`` returns ``self``; fitted attributes ``estimate_``, ``theta_``, ``cov_``, ``std_``.
    """

    def __init__(self, *, method: Literal["ols", "wls"] = "wls", max_iter: int = 20, tol: float = 1e-6,
                 variance_floor: float = 1e-14, n_shape: int = 0, passive: tuple[str, ...] = ()) -> None:
        self.method = method
        self.passive = passive
        self.max_iter = max_iter
        self.tol = tol
        self.variance_floor = variance_floor
        self.n_shape = n_shape

    @single_threaded_blas()
    def fit(self, sums: NormalEquations) -> SummedLeastSquares:
        self._forget_fit()
        if self.method not in ("ols", "wls"):
            raise ValueError(f"method must be 'ols' or 'wls', got {self.method!r}")
        if int(self.max_iter) != self.max_iter or self.max_iter < 1:
            raise ValueError(f"max_iter must be a positive integer, got {self.max_iter}")
        if not isinstance(sums, NormalEquations):
            raise TypeError(f"fit expects NormalEquations, got {type(sums).__name__}")
        N, m, r = sums.n_samples, sums.n_channels, sums.n_columns
        if N * m <= r:
            raise ValueError(f"{N * m} equations for {r} parameters: need more samples")
        n_shape = int(getattr(self, "n_shape", 0))
        if n_shape < 0:
            raise ValueError(f"n_shape must be a non-negative integer, got {self.n_shape}")
        samples = sums.samples  # each channel's valid samples (N when nothing was masked)
        dof_channel = samples - (r + n_shape) / m  # a shaped law's shape parameters counted, as in memory
        weights = np.ones(m)
        iterations = 1
        if self.method == "wls":
            dead = [c for c, value in zip(sums.channels, sums.power) if value == 0 and c not in self.passive]
            if dead:
                raise ValueError(f"channel(s) {', '.join(dead)} read zero in every sample (a dead sensor, or a column "
                                 "left empty?): weighted least squares cannot weight them; check the data, or use "
                                 "ordinary least squares (--method ols)")
            floor = self.variance_floor * sums.power / samples
            variance = None
            iterations = 0
            for _ in range(int(self.max_iter) + 1):
                theta = _solved(sums, weights)[0]  # only θ: the inverse and cond at the settled weights
                iterations += 1
                # the variances of the residual in the motion's band when the sums hold it (NormalEquations.band)
                updated = floored_variance(sums.in_band_rss(theta) / dof_channel, floor,
                                           sums.power == 0)  # a passive joint's channel too
                change = np.inf if variance is None else np.max(np.abs(updated - variance) / variance)
                variance = updated
                weights = 1.0 / variance
                if change < self.tol:
                    break
        theta, unscaled, cond = solve_sums(sums, weights)
        rss = sums.channel_rss(theta)
        scale = float(np.sum(rss * weights)) / (sums.n_equations - r)
        cov = scale * unscaled
        std = np.sqrt(np.clip(np.diag(cov), 0.0, None))
        with np.errstate(divide="ignore", invalid="ignore"):
            relative = np.where(theta != 0, 100.0 * std / np.abs(theta), np.inf)
        self.estimate_ = SummedEstimate(
            values=theta, cov=cov, std=std, relative_std=relative, cond=cond, channel_variance=rss / dof_channel,
            channel_rss=rss, weights=weights, n_samples=N, names=sums.names, expressions=sums.expressions,
            channels=sums.channels, method=self.method, n_iterations=iterations,
        )
        return self

    def _fitted(self) -> SummedEstimate:
        return self.estimate_  # before fit: NotFittedError from Estimator.__getattr__

    theta_ = property(lambda self: self._fitted().values, doc="Estimated parameters.")
    cov_ = property(lambda self: self._fitted().cov, doc="Covariance of the estimates.")
    std_ = property(lambda self: self._fitted().std, doc="Standard deviations.")


#: the in-memory fit of a model with shaped laws iterates its channel weights this many rounds at most, stopping when
#: no weight moves by more than :data:`SHAPED_TOL` (:func:`estimation.identification.shaped.fit_shaped_model`)
SHAPED_ROUNDS = 4
SHAPED_TOL = 1e-4


def summed_estimator(method: Literal["ols", "wls"], n_shape: int = 0, passive: tuple[str, ...] = ()
                     ) -> SummedLeastSquares:
    """The estimator from sums that fits as the in-memory ``identify`` fits the same model: without shaped laws
    (``n_shape == 0``) :class:`SummedLeastSquares` as :class:`~estimation.estimators.least_squares.
    WeightedLeastSquares`; with ``n_shape`` shape parameters held at their fitted values (the sums' columns at those
    shapes), the variable-projection fit's weighting (:data:`SHAPED_ROUNDS` rounds at most, :data:`SHAPED_TOL`, the
    shape parameters counted in the degrees of freedom), whose weights at the final solve may not have settled:
    the same estimate on the same samples. ``passive``: the channels of passive joints (their zero a measurement,
    :class:`SummedLeastSquares`)."""
    if n_shape:
        return SummedLeastSquares(method=method, max_iter=SHAPED_ROUNDS - 1, tol=SHAPED_TOL, n_shape=n_shape,
                                  passive=passive)
    return SummedLeastSquares(method=method, passive=passive)
