"""How far to trust an estimate: covariance that holds for correlated residuals (batch means), Monte-Carlo coverage, residual whiteness, the noise floor, residual tracing.

Modules: :mod:`~estimation.uncertainty.batch_means`, :mod:`~estimation.uncertainty.covariance`, :mod:`~estimation.uncertainty.coverage`, :mod:`~estimation.uncertainty.noise_floor`, :mod:`~estimation.uncertainty.residual_tracing`, :mod:`~estimation.uncertainty.wald`, :mod:`~estimation.uncertainty.whiteness`.
"""

from __future__ import annotations

from dynamics.runtime.lazy import lazy_exports

#: each name users import from this package and the module that defines it; the modules behind may move,
#: these names stay (imported on first use, PEP 562, so that importing the package stays light)
_EXPORTS: dict[str, str] = {
    "CovarianceLabel": "estimation.uncertainty.covariance",
    "CovarianceMethod": "estimation.uncertainty.covariance",
    "DEFAULT_BINS": "estimation.uncertainty.residual_tracing",
    "EstimateDraw": "estimation.uncertainty.coverage",
    "FloorComparison": "estimation.uncertainty.floor_comparison",
    "MIN_SHARE": "estimation.uncertainty.residual_tracing",
    "NoiseFloor": "estimation.uncertainty.noise_floor",
    "NoiseFloorError": "estimation.uncertainty.noise_floor",
    "ResidualChecks": "estimation.uncertainty.whiteness",
    "ResidualTrace": "estimation.uncertainty.residual_tracing",
    "above_floor": "estimation.uncertainty.floor_comparison",
    "autocorrelation": "estimation.uncertainty.whiteness",
    "bandwidth": "estimation.uncertainty.covariance",
    "batch_length": "estimation.uncertainty.batch_means",
    "check_method": "estimation.uncertainty.covariance",
    "compare_with_floor": "estimation.uncertainty.floor_comparison",
    "cross_correlation": "estimation.uncertainty.whiteness",
    "WaldTest": "estimation.uncertainty.wald",
    "wald_test": "estimation.uncertainty.wald",
    "difference_variance": "estimation.uncertainty.noise_floor",
    "fourier_residual_variance": "estimation.uncertainty.noise_floor",
    "hac_covariance": "estimation.uncertainty.covariance",
    "identification_draw": "estimation.uncertainty.coverage",
    "long_run_covariance": "estimation.uncertainty.covariance",
    "monte_carlo_coverage": "estimation.uncertainty.coverage",
    "plot_residual_trace": "estimation.uncertainty.residual_tracing",
    "pooled_floor": "estimation.uncertainty.noise_floor",
    "prepared_floor": "estimation.uncertainty.noise_floor",
    "prewhitened_long_run_covariance": "estimation.uncertainty.covariance",
    "rank_candidates": "estimation.uncertainty.residual_tracing",
    "residual_checks": "estimation.uncertainty.whiteness",
    "residual_statements": "estimation.uncertainty.residual_tracing",
    "segment_bounds": "estimation.uncertainty.covariance",
    "trace_residuals": "estimation.uncertainty.residual_tracing",
}

__all__ = sorted(_EXPORTS)

__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)
