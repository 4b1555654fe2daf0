"""One-shot identification: estimate base parameters on one experiment, validate on another.

::

    result = identify(build_model(robot, "combined"), train, validate, weighted=True)
    result.estimate.values, result.train.mse, result.validation.mse
    stream.write(json_text(result.to_dict()))   # the ``oed identify`` document (estimation.output_files)

For repeated use (several estimators, extra columns) work with
:func:`estimation.least_squares.stack` and the estimators directly.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from dynamics.models import IdentificationModel
from dynamics.threads import single_threaded_blas
from estimation.least_squares import Estimate, LeastSquares, WeightedLeastSquares, stack
from estimation.measurements import Measurements
from estimation.validation import Comparison, compare


@dataclass(frozen=True)
class IdentificationResult:
    """Estimates with their fit on the training data and, if given, on validation data.

    Attributes
    ----------
    model
        The identification model (robot, kind, effects).
    estimate
        Base-parameter estimates, covariance, condition number, residuals.
    train
        Measured vs predicted on the identification experiment.
    validation
        The same on the validation experiment, or ``None``.
    """

    model: IdentificationModel
    estimate: Estimate
    train: Comparison
    validation: Comparison | None = None

    def to_dict(self) -> dict[str, Any]:
        """The JSON document of ``oed identify``::

            {robot, model, effects, method, n_samples, parameters: [{name, expression, value, std,
             relative_std}], cond, channel_std: {channel: σ}, train: {mse: {channel: value}},
             validation: {mse: {channel: value}} | null}
        """
        return {
            "robot": self.model.robot.name,
            "model": self.model.kind.value,
            "effects": [effect.name for effect in self.model.effects],
            "method": self.estimate.method,
            "n_samples": int(self.train.t.shape[0]),
            "parameters": [_finite(record) for record in self.estimate.records()],
            "cond": float(self.estimate.cond),
            "channel_std": dict(zip(self.estimate.channels, map(float, np.sqrt(self.estimate.channel_variance)))),
            "train": {"mse": self.train.mse},
            "validation": None if self.validation is None else {"mse": self.validation.mse},
        }


@single_threaded_blas()
def identify(
    model: IdentificationModel,
    train: Measurements,
    validate: Measurements | None = None,
    *,
    weighted: bool = True,
    estimator: LeastSquares | None = None,
) -> IdentificationResult:
    """Estimate the base parameters of ``model`` from ``train`` and compare with ``validate``.

    Parameters
    ----------
    model
        The identification model (internal, external or combined, with its effects).
    train, validate
        Measurements with ``q, dq, ddq`` and the model's channels (see
        :func:`estimation.preprocessing.fill_derivatives` when ``dq``/``ddq`` are missing).
    weighted
        Channel-weighted least squares (default) rather than ordinary (PUMA paper, eq. 20).
    estimator
        A configured estimator instead (overrides ``weighted``); it is fitted in place.
    """
    if estimator is None:
        estimator = WeightedLeastSquares() if weighted else LeastSquares()
    estimate = estimator.fit(stack(model, train)).estimate_
    train_comparison = compare(model, estimate.values, train, label="identification")
    validation = None if validate is None else compare(model, estimate.values, validate, label="validation")
    return IdentificationResult(model, estimate, train_comparison, validation)


def _finite(record: dict[str, Any]) -> dict[str, Any]:
    """JSON has no infinity: a parameter estimated as exactly 0 gets ``relative_std`` null."""
    return {key: (None if isinstance(value, float) and not np.isfinite(value) else value) for key, value in record.items()}
