"""How far to trust an estimate: covariance that holds for correlated residuals (batch means), Monte-Carlo coverage, residual whiteness, the noise floor, residual tracing.

Modules: :mod:`~estimation.uncertainty.batch_means`, :mod:`~estimation.uncertainty.covariance`, :mod:`~estimation.uncertainty.coverage`, :mod:`~estimation.uncertainty.noise_floor`, :mod:`~estimation.uncertainty.residual_tracing`, :mod:`~estimation.uncertainty.whiteness`.
"""
