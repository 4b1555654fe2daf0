"""Least-squares identification of base parameters: ordinary and channel-weighted (iterated).

The problem (PUMA paper, section IV, eq. 20): stack the base regressor over the ``N`` samples
and the ``m`` channels of a model, ``y = Y_base θ_base + ε``, with ``Y_base`` ``(N·m) x r``.

* :class:`LeastSquares` — ``θ̂ = (YᵀY)⁻¹ Yᵀ y`` (eq. 20), one noise variance for every channel,
  ``cov = σ̂² (YᵀY)⁻¹``, ``σ̂² = ‖y − Yθ̂‖² / (N m − r)``.
* :class:`WeightedLeastSquares` — one variance per channel ``σ_c²`` estimated from that
  channel's residuals, ``θ̂ = (YᵀWY)⁻¹ YᵀW y`` with ``W = diag(1/σ_c²)``, iterated until the
  variances settle (Gautier's weighting). The combined model mixes ``N`` wrench rows in N and N·m
  with ``N`` joint rows: without weighting the largest channels dominate.

Both solve semi-normal equations with iterative refinement on the exact residuals (see
:func:`solve`), and report the relative standard deviation ``100 σ_θ / |θ|`` (%) and the
condition number of the (weighted) regressor. Estimators follow scikit-learn: settings in
``__init__``, ``fit`` returns ``self``, fitted attributes end in ``_``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np
import scipy.linalg
from numpy.typing import NDArray

from dynamics.models import IdentificationModel
from dynamics.runtime.threads import single_threaded_blas
from estimation.data.passive import floored_variance
from estimation.uncertainty.covariance import CovarianceLabel, CovarianceMethod, check_method, hac_covariance
from estimation.estimators.errors import NotFittedError
from estimation.estimators.estimator import Estimator
from estimation.estimators.identification_problem import IdentificationProblem, in_band_variance, stack
from dynamics.measurements import Measurements

__all__ = [
    "Estimate", "IdentifiabilityError", "IdentificationProblem", "LeastSquares", "NotFittedError", "ParameterRecords",
    "WeightedLeastSquares", "channel_gram", "channel_variance", "freeze_arrays", "solve", "stack",
]

#: smallest/largest eigenvalue of the equilibrated ``YᵀWY`` below this: a parameter is not excited
IDENTIFIABILITY_TOLERANCE = 1e-13


class IdentifiabilityError(ValueError):
    """The data do not determine every parameter (rank-deficient regressor); ``parameters``: those it names
    (empty when it names none); ``unexcited``: they are all-zero columns (the data hold nothing of them, e.g. the
    friction of a joint that never moves), not a combination of other columns."""

    def __init__(self, message: str, parameters: tuple[str, ...] = (), *, unexcited: bool = False) -> None:
        super().__init__(message)
        self.parameters = tuple(parameters)
        self.unexcited = unexcited




def freeze_arrays(instance: Any, names: tuple[str, ...]) -> None:
    """Store the named attributes of a frozen dataclass as read-only float arrays (frozen all the way
    down: ``estimator.theta_[0] = 0`` must not rewrite an estimate)."""
    for name in names:
        array = np.array(getattr(instance, name), dtype=float)
        array.flags.writeable = False
        object.__setattr__(instance, name, array)


class ParameterRecords:
    """``records()`` of an estimate with ``names, expressions, values, std, relative_std``."""

    def records(self) -> list[dict[str, Any]]:
        """One dict per parameter: ``name, expression, value, std, relative_std``."""
        return [
            {"name": name, "expression": expression, "value": float(value), "std": float(std), "relative_std": float(relative)}
            for name, expression, value, std, relative in zip(self.names, self.expressions, self.values, self.std, self.relative_std)
        ]


@dataclass(frozen=True)
class Estimate(ParameterRecords):
    """Identified parameters with their uncertainty and the fit's residuals.

    Attributes
    ----------
    values
        ``(r,)`` estimates ``θ̂``.
    cov
        ``(r, r)`` covariance of ``θ̂``.
    std
        ``(r,)`` standard deviations ``√diag(cov)``.
    relative_std
        ``(r,)`` ``100 σ / |θ̂|``, %.
    cond
        Condition number of the (weighted) stacked regressor.
    residuals
        ``(N, m)`` ``y − Y θ̂`` per sample and channel.
    channel_variance
        ``(m,)`` residual variance per channel (degrees of freedom shared: ``N − r/m`` each).
    weights
        ``(m,)`` weight of each channel in the final solve (all one for ordinary LS).
    names, expressions, channels
        Parameter names and groupings; channel names.
    method
        ``"ols"`` or ``"wls"``.
    n_iterations
        Weighted solves done (1 for ordinary LS).
    cov_method
        ``"classical"`` (white residuals) or ``"hac"`` (Newey–West, :mod:`estimation.uncertainty.covariance`).
    hac_lags
        Bandwidth of the HAC estimate (``None`` for the classical one).
    """

    values: NDArray[np.float64]
    cov: NDArray[np.float64]
    std: NDArray[np.float64]
    relative_std: NDArray[np.float64]
    cond: float
    residuals: NDArray[np.float64] = field(repr=False)
    channel_variance: NDArray[np.float64]
    weights: NDArray[np.float64]
    names: tuple[str, ...]
    expressions: tuple[str, ...]
    channels: tuple[str, ...]
    method: Literal["ols", "wls"]
    n_iterations: int
    cov_method: CovarianceLabel = "classical"
    hac_lags: int | None = None

    def __post_init__(self) -> None:
        freeze_arrays(self, ("values", "cov", "std", "relative_std", "residuals", "channel_variance", "weights"))

    def channel_rms(self) -> dict[str, float]:
        """Root-mean-square residual per channel."""
        return {channel: float(value) for channel, value in zip(self.channels, np.sqrt(np.mean(self.residuals**2, axis=0)))}


def channel_gram(problem: IdentificationProblem) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Per-channel ``Y_cᵀ Y_c`` ``(m, r, r)`` and ``Y_cᵀ y_c`` ``(m, r)``."""
    by_channel = problem.Y.transpose(1, 2, 0)  # (m, r, N)
    return np.matmul(by_channel, problem.Y.transpose(1, 0, 2)), np.matmul(by_channel, problem.y.T[:, :, None])[:, :, 0]


def solve(
    problem: IdentificationProblem,
    weights: NDArray[np.float64],
    gram: tuple[NDArray[np.float64], NDArray[np.float64]] | None = None,
) -> tuple[NDArray[np.float64], NDArray[np.float64], float]:
    """``θ̂``, ``(YᵀWY)⁻¹`` and ``cond(W^½ Y)`` for channel weights ``(m,)``.

    Semi-normal equations: Cholesky factor of the equilibrated ``YᵀWY`` (summed from the
    per-channel Gram matrices, so a change of weights costs ``O(m r²)``), then one step of
    iterative refinement on the exact residual ``y − Y θ̂`` — as accurate as a QR
    factorisation of ``W^½ Y`` for the condition numbers of identification (Björck), and
    several times faster on ``N·m x r`` regressors.
    """
    gram_matrices, moments = channel_gram(problem) if gram is None else gram
    normal = np.tensordot(weights, gram_matrices, axes=1)
    if not (np.all(np.isfinite(normal)) and np.all(np.isfinite(weights @ moments))):
        raise ValueError("the regressor or the measured channels overflow in YᵀY: check the units of the data")
    scale = np.sqrt(np.diag(normal))
    zero = np.flatnonzero(scale == 0)
    if zero.size:
        names = tuple(problem.names[i] for i in zero)
        raise IdentifiabilityError(
            f"parameter(s) {list(names)} have all-zero columns: these data do not excite them", names, unexcited=True)
    equilibrated = normal / np.outer(scale, scale)
    eigenvalues, eigenvectors = np.linalg.eigh(equilibrated)
    if eigenvalues[0] < IDENTIFIABILITY_TOLERANCE * eigenvalues[-1]:
        direction = np.abs(eigenvectors[:, 0])
        weak = [problem.names[i] for i in np.flatnonzero(direction > 0.3 * direction.max())]
        raise IdentifiabilityError(
            f"the data do not determine parameter(s) {weak}: the regressor is rank deficient "
            "(excite the robot more, or drop those columns)", tuple(weak)
        )
    factor = scipy.linalg.cho_factor(equilibrated, check_finite=False)
    theta = scipy.linalg.cho_solve(factor, (weights @ moments) / scale, check_finite=False) / scale
    residuals = problem.residuals(theta)
    correction = np.matmul(problem.Y.transpose(1, 2, 0), residuals.T[:, :, None])[:, :, 0]  # (m, r)
    theta = theta + scipy.linalg.cho_solve(factor, (weights @ correction) / scale, check_finite=False) / scale
    inverse = scipy.linalg.cho_solve(factor, np.eye(scale.shape[0]), check_finite=False) / np.outer(scale, scale)
    extremes = np.linalg.eigvalsh(normal)[[0, -1]]
    return theta, inverse, float(np.sqrt(extremes[1] / max(extremes[0], np.finfo(float).tiny)))


def channel_variance(residuals: NDArray[np.float64], n_parameters: int,
                     samples: NDArray[np.int_] | None = None) -> NDArray[np.float64]:
    """Residual variance per channel, ``‖ρ_c‖² / (N_c − r/m)`` (the ``N m − r`` degrees of freedom shared evenly;
    ``samples``: ``N_c``, each channel's valid samples when some are masked, their residual 0, else ``N``)."""
    n_samples, n_channels = residuals.shape
    dof = (n_samples if samples is None else np.asarray(samples, dtype=float)) - n_parameters / n_channels
    if np.any(dof <= 0):
        raise ValueError(f"{n_samples} samples leave no degrees of freedom for {n_parameters} parameters")
    return np.sum(residuals**2, axis=0) / dof


class LeastSquares(Estimator):
    """Ordinary least squares, eq. 20 of the PUMA paper: one noise variance for all channels.

    ``fit(problem)`` or ``fit(model, measurements)``; fitted attributes ``theta_``, ``cov_``,
    ``std_``, ``relative_std_``, ``cond_``, ``residuals_``, ``channel_variance_``,
    ``estimate_`` (an :class:`Estimate`).

    Parameters
    ----------
    covariance
        ``"classical"`` (``σ̂² (YᵀY)⁻¹``, white residuals) or ``"hac"`` (Newey–West sandwich, holds
        with residuals correlated in time: :mod:`estimation.uncertainty.covariance`).
    """

    method: Literal["ols", "wls"] = "ols"

    def __init__(self, *, covariance: CovarianceMethod = "classical") -> None:
        self.covariance = covariance

    @single_threaded_blas()
    def fit(self, problem: IdentificationProblem | IdentificationModel, measurements: Measurements | None = None):
        self._forget_fit()
        check_method(getattr(self, "covariance", "classical"))
        problem = _as_problem(problem, measurements)
        _check_size(problem)
        weights = np.ones(problem.n_channels)
        theta, unscaled, cond = solve(problem, weights)
        residuals = problem.residuals(theta)
        dof = problem.n_equations - problem.n_parameters
        sigma2 = float(np.sum(residuals**2)) / dof
        self._store(problem, theta, sigma2 * unscaled, cond, residuals, weights, 1, unscaled)
        return self

    def _store(self, problem, theta, cov, cond, residuals, weights, iterations, unscaled=None) -> None:
        cov_method, lags = check_method(getattr(self, "covariance", "classical")), None
        if cov_method == "hac":
            cov, lags = hac_covariance(problem.Y, residuals, weights, unscaled, segments=problem.segments or None)
        std = np.sqrt(np.clip(np.diag(cov), 0.0, None))
        with np.errstate(divide="ignore", invalid="ignore"):
            relative = np.where(theta != 0, 100.0 * std / np.abs(theta), np.inf)
        self.estimate_ = Estimate(
            values=theta, cov=cov, std=std, relative_std=relative, cond=cond, residuals=residuals,
            channel_variance=channel_variance(residuals, problem.n_parameters, problem.channel_samples),
            weights=weights,
            names=problem.names, expressions=problem.expressions, channels=problem.channels,
            method=self.method, n_iterations=iterations, cov_method=cov_method, hac_lags=lags,
        )

    def _fitted(self) -> Estimate:
        return self.estimate_  # before fit: NotFittedError from Estimator.__getattr__

    theta_ = property(lambda self: self._fitted().values, doc="Estimated parameters.")
    cov_ = property(lambda self: self._fitted().cov, doc="Covariance of the estimates.")
    std_ = property(lambda self: self._fitted().std, doc="Standard deviations.")
    relative_std_ = property(lambda self: self._fitted().relative_std, doc="Relative standard deviations, %.")
    cond_ = property(lambda self: self._fitted().cond, doc="Condition number of the (weighted) regressor.")
    residuals_ = property(lambda self: self._fitted().residuals, doc="Residuals (N, m).")
    channel_variance_ = property(lambda self: self._fitted().channel_variance, doc="Residual variance per channel.")

    def predict(self, problem: IdentificationProblem | IdentificationModel | NDArray[np.float64],
                measurements: Measurements | None = None) -> NDArray[np.float64]:
        """``Y θ̂`` for a problem, ``(model, measurements)`` as in :meth:`fit`, or a regressor ``(N, m, r)``."""
        theta = self._fitted().values
        if isinstance(problem, IdentificationModel):
            if not isinstance(measurements, Measurements) or measurements.dq is None or measurements.ddq is None:
                raise TypeError("predict(model, measurements): give measurements with q, dq and ddq "
                                "(estimation.preprocessing.differentiation.fill_derivatives derives them)")
            problem = problem.evaluate_base(measurements.q, measurements.dq, measurements.ddq)  # no measured channels needed
        Y = problem.Y if isinstance(problem, IdentificationProblem) else np.asarray(problem, dtype=float)
        if Y.ndim < 1 or Y.shape[-1] != theta.shape[0]:
            raise ValueError(f"the regressor has shape {Y.shape}; its last axis must hold the {theta.shape[0]} "
                             "fitted parameters")
        return Y @ theta


class WeightedLeastSquares(LeastSquares):
    """Channel-weighted least squares with weights ``1/σ_c²`` from the residuals, iterated.

    The variances are those of the residual in the problem's band (``problem.band``, the band the motion was
    low-passed to: :func:`estimation.estimators.identification_problem.in_band_variance`), else of the residual.

    Parameters
    ----------
    max_iter
        Most weighted solves after the ordinary one.
    tol
        Stop when no channel variance changes by more than this fraction.
    variance_floor
        Smallest channel variance, relative to the channel's mean square (keeps noise-free
        channels from taking infinite weight).
    covariance
        ``"classical"`` or ``"hac"``, as :class:`LeastSquares`.
    """

    method: Literal["ols", "wls"] = "wls"

    def __init__(self, *, max_iter: int = 20, tol: float = 1e-6, variance_floor: float = 1e-14,
                 covariance: CovarianceMethod = "classical") -> None:
        self.max_iter = max_iter
        self.tol = tol
        self.variance_floor = variance_floor
        self.covariance = covariance

    @single_threaded_blas()
    def fit(self, problem: IdentificationProblem | IdentificationModel, measurements: Measurements | None = None):
        self._forget_fit()
        check_method(getattr(self, "covariance", "classical"))
        if int(self.max_iter) != self.max_iter or self.max_iter < 1:
            raise ValueError(f"max_iter must be a positive integer, got {self.max_iter}")
        for name in ("tol", "variance_floor"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
                raise TypeError(f"{name} must be a number, got {type(value).__name__}")
        if not (np.isfinite(self.tol) and self.tol > 0):
            raise ValueError(f"tol must be positive, got {self.tol}")
        if not (np.isfinite(self.variance_floor) and self.variance_floor >= 0):
            raise ValueError(f"variance_floor must be a non-negative number, got {self.variance_floor}")
        problem = _as_problem(problem, measurements)
        _check_size(problem)
        samples = problem.channel_samples  # each channel's valid samples when some are masked (their y is 0)
        mean_square = np.mean(problem.y**2, axis=0) if samples is None else np.sum(problem.y**2, axis=0) / samples
        dead = [channel for channel, value in zip(problem.channels, mean_square)
                if value == 0 and channel not in problem.passive]
        if dead:
            raise ValueError(f"channel(s) {', '.join(dead)} read zero in every sample (a dead sensor, or a column "
                             "left empty?): weighted least squares cannot weight them; check the data, or use ordinary "
                             "least squares (--method ols)")
        # The weights are iterated on per-channel Gram matrices (r x r each, formed once): every
        # iteration costs O(m r²). The final solve refines on the exact residuals (see solve).
        floor = self.variance_floor * mean_square
        gram, moment = channel_gram(problem)  # (m, r, r), (m, r)
        power = np.sum(problem.y**2, axis=0)  # (m,)
        dof = (problem.n_samples if samples is None else samples) - problem.n_parameters / problem.n_channels
        weights = np.ones(problem.n_channels)
        variance = None
        iterations = 0
        for _ in range(int(self.max_iter) + 1):
            theta = _normal_solve(np.tensordot(weights, gram, axes=1), weights @ moment, problem.names)
            iterations += 1
            if problem.band is None:
                in_band = (power - 2 * moment @ theta + np.einsum("r,mrs,s->m", theta, gram, theta)) / dof
            else:  # the residual in the motion's band (problem.band): the (N, m) residual filtered at each
                # iteration, cheaper than the (N, m, r) regressor filtered once for the few iterations a fit takes
                in_band = in_band_variance(problem.residuals(theta), problem.n_parameters, problem.band,
                                           problem.channel_samples)
            updated = floored_variance(in_band, floor, mean_square == 0)  # a passive joint's channel too
            change = np.inf if variance is None else np.max(np.abs(updated - variance) / variance)
            variance = updated
            weights = 1.0 / variance
            if change < self.tol:
                break
        theta, unscaled, cond = solve(problem, weights, (gram, moment))
        residuals = problem.residuals(theta)
        dof = problem.n_equations - problem.n_parameters
        # ≈ 1 once the weights are the inverse variances; above 1 with a band, by the recording's out-of-band noise,
        # which the covariance of a fit to the recorded torques must hold
        scale = float(np.sum(residuals**2 * weights)) / dof
        self._store(problem, theta, scale * unscaled, cond, residuals, weights, iterations, unscaled)
        return self


def _normal_solve(normal: NDArray[np.float64], right: NDArray[np.float64],
                  names: tuple[str, ...] = ()) -> NDArray[np.float64]:
    """Solve the (symmetrically equilibrated) normal equations; used only to iterate weights. ``names``: the
    parameters' (an all-zero column's named in the error)."""
    scale = np.sqrt(np.diag(normal))
    if np.any(scale == 0):
        zero = tuple(names[i] for i in np.flatnonzero(scale == 0)) if names else ()
        raise IdentifiabilityError(f"parameter(s) {list(zero)} have all-zero columns: these data do not excite them"
                                   if zero else "a parameter has an all-zero column: these data do not excite it",
                                   zero, unexcited=True)
    return np.linalg.lstsq(normal / np.outer(scale, scale), right / scale, rcond=None)[0] / scale


def _as_problem(problem, measurements) -> IdentificationProblem:
    if isinstance(problem, IdentificationModel):
        if measurements is None:
            raise TypeError("fit(model, measurements): the measurements are missing")
        return stack(problem, measurements)
    if not isinstance(problem, IdentificationProblem):
        raise TypeError(f"fit expects an IdentificationProblem or (model, measurements), got {type(problem).__name__}")
    if measurements is not None:
        raise TypeError("fit(problem) takes no measurements: they are already stacked in the problem")
    return problem


def _check_size(problem: IdentificationProblem) -> None:
    rows = problem.n_samples * problem.n_channels
    if rows <= problem.n_parameters:
        raise ValueError(f"{rows} equations for {problem.n_parameters} parameters: need more samples")
