"""Errors shared by the estimators."""

from __future__ import annotations


class NotFittedError(RuntimeError, AttributeError):
    """An estimator was used before ``fit``.

    Also an ``AttributeError``, as in scikit-learn: ``hasattr(estimator, "theta_")`` is ``False``
    before ``fit`` instead of raising.
    """
