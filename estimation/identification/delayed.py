"""Identification with a delay between torques and motion (:mod:`estimation.preprocessing.delay`).

The delay enters every column at once (it moves the motion the whole regressor is evaluated
along), so it is searched outside the linear least squares, as the shape parameters are
(variable projection, :mod:`estimation.estimators.variable_projection`): the projected weighted residual
``f(d) = min_θ ‖W^½ (y − Y(d) θ)‖²`` on the grid of :class:`DelayBounds`, then Brent's bounded
search around the best grid point. Its standard deviation is the Gauss–Newton one of the full
problem: with ``D = ∂(Y(d) θ̂)/∂d`` (central differences of the prediction in ``d``, the columns at
their fitted shapes) projected off the model's columns, ``D̃``,
``var(d) = Σ_b S_b² / (D̃ᵀ W D̃)²`` with ``S_b`` the batch sums of the scores ``Σ_c w_c r_c D̃_c``
(batch means, as the shapes' HAC; never below the white-noise value ``σ̂²/(D̃ᵀWD̃)``), and the
linear coefficients' covariance gets ``var(d) g gᵀ`` with ``g = ∂θ̂/∂d``.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
import scipy.optimize
from numpy.typing import NDArray

from estimation.uncertainty.batch_means import batch_length, batch_means
from dynamics.measurements import Measurements
from estimation.preprocessing.delay import DELAY, DelayBounds, delayed, longest_piece
from estimation.estimators.separable_least_squares import FixedPart, residuals, solve_linear
from estimation.identification.shaped import ShapeValue

Columns = Callable[[Measurements], NDArray[np.float64]]


@dataclass(frozen=True)
class DelayFit:
    """A fitted delay: value and standard deviation (s), the weighted residual sums of squares at
    the delay and at zero, ``∂θ̂/∂d`` (base order), and the search's grid profile."""

    delay: float
    std: float
    rss: float
    rss_zero: float
    theta_slope: NDArray[np.float64]
    grid: NDArray[np.float64]
    profile: NDArray[np.float64]


def _fixed(columns: Columns, record: Measurements, delay: float, channels: tuple[str, ...]) -> FixedPart:
    # the columns and the channels of the moved record are all a fixed part reads: its recorded samples
    # (``Measurements.recorded``, moved too by ``delayed``, piece by piece) are left out, not moved for nothing
    moved = delayed(dataclasses.replace(record, recorded=None), delay)
    return FixedPart.from_arrays(np.asarray(columns(moved)), moved.channels(list(channels)))


@dataclass
class _Profile:
    """The projected residual ``f(d)`` of :func:`fit_delay`, remembering the fixed part at the lowest value met
    (where the search ends, formed once) and the value at ``d = 0`` when met (the grid holds it)."""

    columns: Columns
    record: Measurements
    channels: tuple[str, ...]
    weights: NDArray[np.float64]
    best: tuple[float, float, FixedPart] | None = None
    zero: float | None = None

    def __call__(self, delay: float) -> float:
        try:
            fixed = _fixed(self.columns, self.record, delay, self.channels)
            rss = solve_linear(fixed, [], None, [], self.weights).rss
        except (np.linalg.LinAlgError, FloatingPointError):
            rss = np.inf
            fixed = None
        if delay == 0.0:
            self.zero = rss
        if fixed is not None and (self.best is None or rss < self.best[1]):
            self.best = (float(delay), rss, fixed)
        return rss

    def fixed(self, delay: float) -> FixedPart:
        """The fixed part at ``delay``: the one kept when it is the lowest met there, else formed."""
        if self.best is not None and self.best[0] == delay:
            return self.best[2]
        return _fixed(self.columns, self.record, delay, self.channels)

    def at_zero(self) -> float:
        return self(0.0) if self.zero is None else self.zero


def fit_delay(columns: Columns, train: Measurements, channels: tuple[str, ...], weights: NDArray[np.float64],
              bounds: DelayBounds = DelayBounds()) -> DelayFit:
    """The delay minimising the projected weighted residual of the columns ``columns(record)``
    (``(N, m, p)``, at fixed shapes) on ``train``, with its standard deviation (module docstring)."""
    bounds = bounds.within(longest_piece(train))
    grid = bounds.grid()
    rss = _Profile(columns, train, channels, weights)
    profile = np.array([rss(value) for value in grid])
    if not np.any(np.isfinite(profile)):
        raise np.linalg.LinAlgError("the columns are singular at every delay of the grid")
    best = int(np.nanargmin(np.where(np.isfinite(profile), profile, np.nan)))
    step = grid[1] - grid[0]
    low, high = max(grid[best] - step, bounds.lower), min(grid[best] + step, bounds.upper)
    resolution = 1e-3 * float(np.median(np.diff(train.t)))
    search = scipy.optimize.minimize_scalar(rss, bounds=(low, high), method="bounded", options={"xatol": resolution})
    delay = float(search.x) if search.fun <= profile[best] else float(grid[best])
    fixed = rss.fixed(delay)
    solution = solve_linear(fixed, [], None, [], weights)
    residual = residuals(fixed, [], solution)
    h = max(0.5 * float(np.median(np.diff(train.t))), 1e-6)
    plus, minus = _fixed(columns, train, delay + h, channels), _fixed(columns, train, delay - h, channels)
    # D: the prediction's derivative in d at fixed θ; D̃: D off the columns (the Schur complement)
    D = (plus.predict(solution.theta) - minus.predict(solution.theta)) / (2 * h)  # (m, N)
    projected_solution = solve_linear(dataclasses.replace(fixed, y=D, moment=fixed.moments(D),
                                                          power=np.sum(D**2, axis=1)), [], None, [], weights)
    D_tilde = D - fixed.predict(projected_solution.theta)
    information = float(np.sum(weights[:, None] * D_tilde**2))
    n_rows = fixed.n_rows
    sigma2 = solution.rss / max(n_rows - fixed.n_fixed - 1, 1)
    white = sigma2 / information if information > 0 else np.inf
    scores = np.sum(weights[:, None] * residual * D_tilde, axis=0)[:, None]  # (N, 1)
    hac = float(batch_means(scores, batch_length(residual, weights))[0, 0]) / information**2 if information > 0 else np.inf
    variance = max(white, hac)
    theta_slope = (solve_linear(plus, [], None, [], weights).theta - solve_linear(minus, [], None, [], weights).theta) / (2 * h)
    return DelayFit(delay, float(np.sqrt(variance)), float(solution.rss), rss.at_zero(),
                    theta_slope, grid, profile)


def identify_delayed(model, train: Measurements, validate: Measurements | None, *, identify: Callable[..., Any],
                     bounds: DelayBounds, weighted: bool = True, covariance="hac",
                     shape_starts: dict[str, float] | None = None, shape_search: bool = True):
    """``identify`` (:func:`estimation.identification.fit.identify`, which dispatches here and passes
    itself) with the delay searched too (module docstring).

    The model is identified at no delay (its weights and, for shaped effects, its shapes), the delay
    fitted on those columns, and the model identified again along the delayed motion (shapes searched
    again from where they were). The validation record is compared along its motion moved by the same
    delay (one measurement chain), against its torques as recorded.
    """
    initial = identify(model, train, weighted=weighted, covariance=covariance, shape_starts=shape_starts,
                       shape_search=shape_search)
    estimate = initial.estimate
    weights = estimate.weights if estimate.method == "wls" else 1.0 / estimate.channel_variance
    if initial.shaped_fit is not None:
        columns = initial.shaped_fit.regressor
    else:
        def columns(record: Measurements) -> NDArray[np.float64]:
            return model.evaluate_base(record.q, record.dq, record.ddq)
    fit = fit_delay(columns, train, tuple(model.channels), weights, bounds)
    starts = {value.name: value.value for value in initial.shapes} or None
    result = identify(model, delayed(train, fit.delay), None if validate is None else delayed(validate, fit.delay),
                      weighted=weighted, covariance=covariance, shape_starts=starts, shape_search=shape_search)
    cov = result.estimate.cov + fit.std**2 * np.outer(fit.theta_slope, fit.theta_slope)
    std = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    with np.errstate(divide="ignore", invalid="ignore"):
        relative = np.where(result.estimate.values != 0, 100.0 * std / np.abs(result.estimate.values), np.inf)
    estimate = dataclasses.replace(result.estimate, cov=cov, std=std, relative_std=relative)
    window = bounds.within(longest_piece(train))
    value = ShapeValue(DELAY, DELAY, fit.delay, fit.std, window.lower, window.upper)
    return dataclasses.replace(result, estimate=estimate, shapes=tuple(result.shapes) + (value,), delay=value)
