"""One statistic for adopting an effect and for reporting it: the Wald test of its coefficients from the
covariance that gives its standard deviations.

An effect is adopted when its linear coefficients ``θ_b`` (a block of ``k``) are far from zero for the
noise of the fit, measured by the same heteroskedasticity- and autocorrelation-consistent (HAC)
covariance the reported standard deviations come from (Newey & West, Econometrica 1987)::

    W = θ_bᵀ C_bb⁻¹ θ_b ~ χ²_k  (no effect),   p = P(χ²_k > W),

the robust form of the nested F test (``W / k`` is reported as the F statistic). The F test on residual
sums of squares assumes white residuals; residuals correlated in time (derivative errors, filtered
noise, an effect not yet modelled) make it far too confident: an armature of ``67 ± 62`` adopted at
``p = 5e-16``. With ``W`` from the HAC covariance an effect whose coefficients are within their
standard deviations is never significant, and p-values, standard deviations and adoption say the same.

The covariance is that of the final fit (:func:`estimation.identification.fit.identify` with
``covariance="hac"``): for a model without shape parameters the prewhitened Newey–West sandwich
(:func:`estimation.uncertainty.covariance.hac_covariance`), for a model with shaped laws the batch-means
sandwich of the full Jacobian, never below the white-noise value on its diagonal
(:func:`estimation.estimators.variable_projection.fit_shapes`). :func:`fit_covariance` computes it for a
candidate fitted against fixed columns (:class:`~estimation.estimators.separable_least_squares.FixedPart`),
:func:`estimate_test` reads the test of a found effect from a final estimate.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from estimation.estimators.effect_blocks import Block, States
from estimation.estimators.least_squares import Estimate
from estimation.estimators.separable_least_squares import (
    FixedPart,
    full_information,
    residuals,
    sample_scores,
    solve_linear,
)
from estimation.uncertainty.batch_means import batch_length, batch_means
from estimation.uncertainty.covariance import prewhitened_long_run_covariance
from estimation.uncertainty.wald import WaldTest, wald_test

__all__ = ["WaldTest", "estimate_test", "fit_covariance", "wald_test"]


def _inverse(matrix: NDArray[np.float64]) -> NDArray[np.float64]:
    scale = np.sqrt(np.clip(np.diag(matrix), np.finfo(float).tiny, None))
    return np.linalg.pinv(matrix / np.outer(scale, scale), hermitian=True) / np.outer(scale, scale)


def fit_covariance(fixed: FixedPart, blocks: Sequence[Block], states: States | None,
                   shapes: Sequence[NDArray[np.float64]], weights: NDArray[np.float64], *,
                   shaped: bool) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """``(θ, cov θ)`` of the fixed columns plus ``blocks`` at ``shapes``, the HAC covariance of the final
    fit (module docstring): ``shaped`` the batch-means sandwich of the full Jacobian (shape directions
    included), else the prewhitened Newey–West sandwich. The covariance returned is that of the linear
    coefficients ``θ = (θ₀, θ_b…)``."""
    with_shapes = shaped and any(block.n_shape for block in blocks)
    solution = solve_linear(fixed, blocks, states, shapes, weights, jacobian=with_shapes)
    residual = residuals(fixed, blocks, solution)
    if with_shapes:
        information, _ = full_information(fixed, blocks, solution, weights, residual)
    else:
        information = solution.normal
    scores = sample_scores(fixed, blocks, solution, weights, residual)
    inverse = _inverse(information)
    n_parameters = information.shape[0]
    if shaped:
        meat = batch_means(scores, batch_length(residual, weights))
        cov = inverse @ meat @ inverse * fixed.n_samples / max(fixed.n_samples - n_parameters, 1)
        sigma2 = solution.rss / max(fixed.n_rows - n_parameters, 1)
        diagonal = np.maximum(np.diag(cov), sigma2 * np.diag(inverse))  # never below the white-noise value
        white = sigma2 * inverse
        scale = np.sqrt(diagonal / np.clip(np.diag(white), np.finfo(float).tiny, None))
        cov = white * np.outer(scale, scale)
    else:
        meat, _ = prewhitened_long_run_covariance(scores)
        cov = fixed.n_rows / max(fixed.n_rows - n_parameters, 1) * inverse @ meat @ inverse
    n_linear = solution.theta.shape[0]
    cov = 0.5 * (cov + cov.T)
    return solution.theta, cov[:n_linear, :n_linear]


def estimate_test(estimate: Estimate, parameters: Sequence[str]) -> WaldTest:
    """The Wald test of the named coefficients from an estimate's own covariance (its ``cov_method``):
    the p-value a report gives beside those standard deviations."""
    names = list(estimate.names)
    indices = [names.index(name) for name in parameters]
    return wald_test(np.asarray(estimate.values)[indices], np.asarray(estimate.cov)[np.ix_(indices, indices)])
