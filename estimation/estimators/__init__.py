"""Estimators after scikit-learn's contract: (weighted) least squares, least squares from summed normal equations, recursive least squares, ARX/ARMAX and order selection, variable projection for shaped effects, fit metrics.

Modules: :mod:`~estimation.estimators.arx`, :mod:`~estimation.estimators.effect_blocks`, :mod:`~estimation.estimators.errors`, :mod:`~estimation.estimators.estimator`, :mod:`~estimation.estimators.identification_problem`, :mod:`~estimation.estimators.least_squares`, :mod:`~estimation.estimators.metrics`, :mod:`~estimation.estimators.normal_equations`, :mod:`~estimation.estimators.order_selection`, :mod:`~estimation.estimators.recursive`, :mod:`~estimation.estimators.summed_least_squares`, :mod:`~estimation.estimators.variable_projection`.
"""
