"""Estimators after scikit-learn's contract: (weighted) least squares, least squares from summed normal equations, recursive least squares, ARX/ARMAX and order selection, variable projection for shaped effects, fit metrics.

Modules: :mod:`~estimation.estimators.arx`, :mod:`~estimation.estimators.channel_gains`, :mod:`~estimation.estimators.effect_blocks`, :mod:`~estimation.estimators.errors`, :mod:`~estimation.estimators.estimator`, :mod:`~estimation.estimators.identification_problem`, :mod:`~estimation.estimators.least_squares`, :mod:`~estimation.estimators.metrics`, :mod:`~estimation.estimators.normal_equations`, :mod:`~estimation.estimators.order_selection`, :mod:`~estimation.estimators.recursive`, :mod:`~estimation.estimators.separable_least_squares`, :mod:`~estimation.estimators.summed_least_squares`, :mod:`~estimation.estimators.variable_projection`.
"""

from __future__ import annotations

from dynamics.runtime.lazy import lazy_exports

#: each name users import from this package and the module that defines it; the modules behind may move,
#: these names stay (imported on first use, PEP 562, so that importing the package stays light)
_EXPORTS: dict[str, str] = {
    "ARXEstimator": "estimation.estimators.arx",
    "BATCH": "estimation.estimators.shape_starts",
    "Backend": "estimation.estimators.recursive",
    "Block": "estimation.estimators.effect_blocks",
    "CovarianceBlowUpWarning": "estimation.estimators.recursive",
    "DEFAULT_CHUNK_SIZE": "estimation.estimators.normal_equations",
    "Estimate": "estimation.estimators.least_squares",
    "GainSign": "estimation.estimators.channel_gains",
    "GainsFit": "estimation.estimators.channel_gains",
    "Estimator": "estimation.estimators.estimator",
    "ExtendedRecursiveLeastSquares": "estimation.estimators.recursive",
    "FixedFactor": "estimation.estimators.bordered_normal",
    "FixedPart": "estimation.estimators.separable_least_squares",
    "IdentifiabilityError": "estimation.estimators.least_squares",
    "IdentificationProblem": "estimation.estimators.identification_problem",
    "LeastSquares": "estimation.estimators.least_squares",
    "LinearSolution": "estimation.estimators.separable_least_squares",
    "NoRowsError": "estimation.estimators.effect_blocks",
    "NormalEquations": "estimation.estimators.normal_equations",
    "NotFittedError": "estimation.estimators.errors",
    "OrderAtEdgeWarning": "estimation.estimators.order_selection",
    "Polynomials": "estimation.estimators.arx",
    "RANK_THRESHOLD": "estimation.estimators.bordered_normal",
    "RecursionDivergedError": "estimation.estimators.recursive",
    "RecursiveLeastSquares": "estimation.estimators.recursive",
    "ShapeFit": "estimation.estimators.variable_projection",
    "ShapeSearchError": "estimation.estimators.effect_blocks",
    "States": "estimation.estimators.effect_blocks",
    "SummedEstimate": "estimation.estimators.summed_least_squares",
    "SummedLeastSquares": "estimation.estimators.summed_least_squares",
    "WeightedLeastSquares": "estimation.estimators.least_squares",
    "accumulate": "estimation.estimators.normal_equations",
    "channel_gram": "estimation.estimators.least_squares",
    "channel_residuals": "estimation.estimators.channel_gains",
    "channel_variance": "estimation.estimators.least_squares",
    "check_chunk_size": "estimation.estimators.normal_equations",
    "cost_v": "estimation.estimators.metrics",
    "divided_start": "estimation.estimators.channel_gains",
    "effect_columns": "estimation.estimators.effect_blocks",
    "effect_rows": "estimation.estimators.effect_blocks",
    "fit_channel_gains_on_sums": "estimation.estimators.channel_gains",
    "fit_shapes": "estimation.estimators.variable_projection",
    "gains_theta": "estimation.estimators.channel_gains",
    "full_information": "estimation.estimators.separable_least_squares",
    "grid_costs": "estimation.estimators.shape_starts",
    "r2_adjusted": "estimation.estimators.metrics",
    "reduce_sums": "estimation.estimators.normal_equations",
    "residuals": "estimation.estimators.separable_least_squares",
    "rmse": "estimation.estimators.metrics",
    "sample_scores": "estimation.estimators.separable_least_squares",
    "select_orders": "estimation.estimators.order_selection",
    "solve": "estimation.estimators.least_squares",
    "solve_bordered": "estimation.estimators.bordered_normal",
    "solve_linear": "estimation.estimators.separable_least_squares",
    "solve_normal": "estimation.estimators.separable_least_squares",
    "solve_sums": "estimation.estimators.summed_least_squares",
    "stack": "estimation.estimators.identification_problem",
    "stacked_factor": "estimation.estimators.normal_equations",
    "valley_floors": "estimation.estimators.shape_starts",
    "weighted_channel_sums": "estimation.estimators.channel_gains",
}

__all__ = sorted(_EXPORTS)

__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)
