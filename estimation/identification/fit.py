"""One-shot identification: estimate base parameters on one experiment, validate on another.

::

    result = identify(build_model(robot, "combined"), train, validate, weighted=True)
    result.estimate.values, result.train.mse, result.validation.mse
    stream.write(json_text(result.to_dict()))   # the ``oed identify`` document (dynamics.runtime.output_files)

For repeated use (several estimators, extra columns) work with
:func:`estimation.estimators.least_squares.stack` and the estimators directly.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field, replace
from collections.abc import Sequence
from typing import Any, Literal

import numpy as np

from dynamics.effects.linear import POSITIVE_EFFECTS
from dynamics.effects.shaped import is_shaped
from dynamics.models import IdentificationModel
from dynamics.runtime.threads import single_threaded_blas
from estimation.uncertainty.covariance import CovarianceMethod, check_method
from estimation.estimators.least_squares import Estimate, LeastSquares, WeightedLeastSquares, stack
from dynamics.measurements import Measurements
from estimation.data.segments import concatenate
from estimation.identification.delayed import identify_delayed
from estimation.identification.shaped import ShapeValue, fit_shaped_model_predicting, shaped_comparison
from estimation.identification.validation import Comparison, compare
from estimation.preprocessing.delay import DelayBounds, check_delay, delayed


#: an estimate this many standard deviations on the wrong side of zero is flagged
IMPLAUSIBLE_SIGMAS = 3.0


class ImplausibleEstimateWarning(UserWarning):
    """A parameter positive by physics (friction, armature) was estimated clearly negative."""


def implausible_estimates(model: IdentificationModel, estimate: Estimate,
                          sigmas: float = IMPLAUSIBLE_SIGMAS) -> tuple[str, ...]:
    """Messages for the base parameters that are one positive-by-physics effect parameter alone
    (``fv5``, ``fc2``, ``Ia3``…; :data:`dynamics.effects.linear.POSITIVE_EFFECTS`) and whose estimate lies
    more than ``sigmas`` standard deviations below zero.

    Such a value is not friction: it usually absorbs an effect the model lacks (or a torque-sign or
    unit error); :func:`estimation.diagnosis.search.diagnose` looks for the missing effect.
    """
    return tuple(f"{record['name']} = {record['value']:.4g} ± {record['std']:.2g} is negative "
                 f"({-record['value'] / record['std']:.0f} standard deviations), which no {effect} can be: "
                 f"{IMPLAUSIBLE_CAUSE}" for record, effect in implausible_records(model, estimate, sigmas))


#: what a positive-by-physics estimate far below zero usually means (:func:`implausible_estimates`)
IMPLAUSIBLE_CAUSE = ("the model probably lacks an effect (what `oed diagnose` looks for), or a sign or unit is "
                     "wrong")


def implausible_records(model: IdentificationModel, estimate: Estimate,
                        sigmas: float = IMPLAUSIBLE_SIGMAS) -> list[tuple[dict[str, Any], str]]:
    """The records (``estimate.records()``) of :func:`implausible_estimates`, each with the effect it belongs to
    in words (``viscous friction``, ``armature``)."""
    positive = {name for effect in model.effects if getattr(effect, "physical_kind", effect.name) in POSITIVE_EFFECTS
                for name in effect.parameter_names(model.robot)}
    return [(record, _effect_of(model, record["expression"])) for record in estimate.records()
            if record["expression"].strip() in positive and record["std"] > 0
            and record["value"] < -sigmas * record["std"]]


def _effect_of(model: IdentificationModel, parameter: str) -> str:
    for effect in model.effects:
        if parameter.strip() in effect.parameter_names(model.robot):
            return effect.name if effect.name == "armature" else f"{effect.name} friction"
    return "effect"


@dataclass(frozen=True)
class IdentificationResult:
    """Estimates with their fit on the training data and, if given, on validation data: of records held in memory
    (:func:`identify`) or read in blocks and summed (:func:`estimation.streaming.identification.identify_files`),
    the same fields on both paths.

    Attributes
    ----------
    model
        The identification model (robot, kind, effects).
    estimate
        Base-parameter estimates, covariance, condition number: an
        :class:`~estimation.estimators.least_squares.Estimate` (with the residuals) in memory, a
        :class:`~estimation.estimators.summed_least_squares.SummedEstimate` (no samples held) streamed.
    train
        Measured vs predicted on the identification experiment: a
        :class:`~estimation.identification.validation.Comparison` in memory, its errors only
        (:class:`~estimation.identification.validation.ChannelErrors`) streamed.
    validation
        The same on the validation experiment, or ``None``.
    warnings
        Physically implausible estimates (:func:`implausible_estimates`), also issued as
        :class:`ImplausibleEstimateWarning`.
    preprocessing
        How the motion was derived (``train.metadata["preprocessing"]``, set by
        :func:`estimation.preprocessing.plan.prepare`), or ``None``.
    """

    model: IdentificationModel
    estimate: Estimate
    train: Comparison
    validation: Comparison | None = None
    warnings: tuple[str, ...] = ()
    preprocessing: dict[str, Any] | None = None
    #: fitted shape parameters of shaped effects (:mod:`estimation.identification.shaped`), and the
    #: fit that predicts with them (``None`` for a linear model)
    shapes: tuple[Any, ...] = ()
    shaped_fit: Any = None
    #: the fitted delay between torques and motion (a shape value named ``delay``, also in
    #: ``shapes``; :mod:`estimation.preprocessing.delay`), or ``None``
    delay: Any = None
    #: ``"in-memory"`` or ``"streamed"`` (the document's ``identification_path``)
    path: Literal["in-memory", "streamed"] = "in-memory"
    #: what this path could not compute, by the document's key, and why (empty in memory)
    not_computed: dict[str, str] = field(default_factory=dict, repr=False)
    #: how the files were read, summed and estimated (the document's ``streaming``), or ``None`` in memory
    streaming: dict[str, Any] | None = field(default=None, repr=False)
    #: the validation errors of the trivial predictors (``zero_mse``, ``nominal_mse``:
    #: :mod:`estimation.identification.trivial_predictors`) where the fit had them at no cost (streamed: from the
    #: validation sums when they hold the recording), else ``None``
    trivial: dict[str, dict[str, float]] | None = field(default=None, repr=False)

    def predict(self, measurements: Measurements) -> np.ndarray:
        """``(N, m)`` predicted channels along ``measurements`` (at the fitted shapes, if any, and
        along the motion moved by the fitted delay, if any)."""
        if self.delay is not None:
            measurements = delayed(measurements, self.delay.value)
        if self.shaped_fit is not None:
            return self.shaped_fit.predict(measurements)
        return self.model.predict(self.estimate.values, measurements.q, measurements.dq, measurements.ddq)

    def to_dict(self) -> dict[str, Any]:
        """The JSON document of ``oed identify``::

            {robot, model, effects, method, n_samples, parameters: [{name, expression, value, std,
             relative_std}], cond, channel_std: {channel: σ}, train: {mse: {channel: value}
             [, mse_filtered: {…}]}, validation: {mse…} | null, warnings: [text],
             preprocessing: {method, cutoff_hz | frequency_hz, harmonics, trimmed_s, …} | null,
             cov_method, hac_lags}

        ``mse`` is measured against the torques/wrench as recorded (on the samples kept);
        ``mse_filtered``, present when preprocessing filtered or averaged them, against those.
        Both paths add ``identification_path``, ``streaming`` (how the streamed path read the files, else
        ``null``) and ``not_computed`` (what the path could not compute, and why; ``{}`` in memory).
        """
        return {
            "robot": self.model.robot.name,
            "model": self.model.kind.value,
            "effects": [effect.name for effect in self.model.effects],
            "method": self.estimate.method,
            "n_samples": int(self.train.n_samples),
            "parameters": [_finite(record) for record in self.estimate.records()],
            "cond": float(self.estimate.cond),
            "channel_std": dict(zip(self.estimate.channels, map(float, np.sqrt(self.estimate.channel_variance)))),
            "train": self.train.to_dict(),
            "validation": None if self.validation is None else self.validation.to_dict(),
            "warnings": list(self.warnings),
            "preprocessing": self.preprocessing,
            "cov_method": self.estimate.cov_method,
            "hac_lags": self.estimate.hac_lags,
            **({"shape": {value.name: value.value for value in self.shapes},
                "shape_std": {value.name: value.std for value in self.shapes}} if self.shapes else {}),
            **({"delay": {"value": self.delay.value, "std": self.delay.std, "unit": "s"}} if self.delay is not None else {}),
            "identification_path": self.path,
            "streaming": None if self.streaming is None else dict(self.streaming),
            "not_computed": dict(self.not_computed),
        }


@single_threaded_blas()
def identify(
    model: IdentificationModel,
    train: Measurements | Sequence[Measurements],
    validate: Measurements | Sequence[Measurements] | None = None,
    *,
    weighted: bool = True,
    estimator: LeastSquares | None = None,
    covariance: CovarianceMethod = "hac",
    shape_starts: dict[str, float] | None = None,
    shape_search: bool = True,
    delay: Any = None,
) -> IdentificationResult:
    """Estimate the base parameters of ``model`` from ``train`` and compare with ``validate``.

    Parameters
    ----------
    model
        The identification model (internal, external or combined, with its effects).
    train, validate
        Measurements with ``q, dq, ddq`` and the model's channels (see
        :func:`estimation.preprocessing.plan.prepare` when ``dq``/``ddq`` are missing), or a
        sequence of segments, each prepared on its own (stacked: :mod:`estimation.data.segments`).
        Errors are measured against the channels as recorded (``Measurements.recorded``).
    weighted
        Channel-weighted least squares (default) rather than ordinary (PUMA paper, eq. 20).
    estimator
        A configured estimator instead (overrides ``weighted`` and ``covariance``); it is fitted in place.
    covariance
        Standard deviations: ``"hac"`` (default; Newey–West, they hold when the residuals are
        correlated in time, and equal the classical ones within sampling error when they are white:
        :mod:`estimation.uncertainty.covariance`) or ``"classical"`` (white residuals assumed). With shaped
        effects ``"hac"`` is the batch-means sandwich (``cov_method="batch_means"``, the shapes'
        uncertainty included through the full Jacobian) and ``"classical"`` its white-noise form.
    shape_starts
        Start the shape search of shaped effects from these values (by shape-parameter name)
        instead of their declared grid (:mod:`estimation.identification.shaped`).
    shape_search
        ``False``: keep the shapes at ``shape_starts`` (the linear coefficients and the full
        covariance are still estimated).
    delay
        :class:`estimation.preprocessing.delay.DelayBounds`: estimate a delay between torques and motion
        too (:mod:`estimation.identification.delayed`); a number: the motion moved by that delay, s.

    Warns
    -----
    ImplausibleEstimateWarning
        For each friction or armature estimate more than :data:`IMPLAUSIBLE_SIGMAS` standard
        deviations below zero (also in ``result.warnings``).
    """
    train = concatenate(train)
    validate = None if validate is None else concatenate(validate)
    if delay is not None:
        if estimator is not None:
            raise TypeError("a delay is searched with the channel-weighted least squares: give weighted=, not estimator=")
        if isinstance(delay, DelayBounds):
            return identify_delayed(model, train, validate, identify=identify, bounds=delay, weighted=weighted,
                                    covariance=covariance, shape_starts=shape_starts, shape_search=shape_search)
        value = check_delay(delay)
        result = identify(model, delayed(train, value), None if validate is None else delayed(validate, value),
                          weighted=weighted, covariance=covariance, shape_starts=shape_starts, shape_search=shape_search)
        return replace(result, delay=ShapeValue("delay", "delay", value, 0.0, value, value))  # given, not estimated
    if any(is_shaped(effect, model.robot) for effect in model.effects):
        if estimator is not None:
            raise TypeError("a model with shaped effects is fitted by variable projection: give weighted=, not estimator=")
        return _identify_shaped(model, train, validate, weighted, shape_starts, shape_search, check_method(covariance))
    if estimator is None:
        estimator = WeightedLeastSquares(covariance=covariance) if weighted else LeastSquares(covariance=covariance)
    problem = stack(model, train)
    estimate = estimator.fit(problem).estimate_
    # the prediction along ``train`` from the fit's own regressor (the base one, which model.predict takes for base
    # values unless the model has as many standard parameters), not evaluated again
    base = estimate.values.shape[0] == model.n_base != model.n_parameters
    train_comparison = compare(model, estimate.values, train, label="identification",
                               predicted=problem.Y @ np.asarray(estimate.values, dtype=float) if base else None)
    validation = None if validate is None else compare(model, estimate.values, validate, label="validation")
    notes = implausible_estimates(model, estimate)
    for note in notes:
        warnings.warn(note, ImplausibleEstimateWarning, stacklevel=3)  # past the BLAS decorator
    return IdentificationResult(model, estimate, train_comparison, validation, notes,
                                train.metadata.get("preprocessing"))


def _identify_shaped(model, train, validate, weighted, shape_starts=None, shape_search=True,
                     covariance: CovarianceMethod = "hac") -> IdentificationResult:
    """Variable projection for shaped effects (:mod:`estimation.identification.shaped`); ``covariance``
    ``"hac"``: the batch-means sandwich, ``"classical"``: white residuals (both from the full Jacobian)."""
    shaped, estimate, fitted = fit_shaped_model_predicting(model, train, weighted=weighted, starts=shape_starts,
                                                           search=shape_search,
                                                           covariance="white" if covariance == "classical" else "hac")
    train_comparison = shaped_comparison(shaped, train, "identification", predicted=fitted)  # the fit's own
    validation = None if validate is None else shaped_comparison(shaped, validate, "validation")
    notes = implausible_estimates(model, estimate)
    for note in notes:
        warnings.warn(note, ImplausibleEstimateWarning, stacklevel=4)
    return IdentificationResult(model, estimate, train_comparison, validation, notes, train.metadata.get("preprocessing"),
                                shaped.shape_values(), shaped)


def _finite(record: dict[str, Any]) -> dict[str, Any]:
    """JSON has no infinity: a parameter estimated as exactly 0 gets ``relative_std`` null."""
    return {key: (None if isinstance(value, float) and not np.isfinite(value) else value) for key, value in record.items()}
