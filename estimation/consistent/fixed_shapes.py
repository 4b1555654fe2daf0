"""The consistent refit of a model with the diagnosed effects: shaped laws and a delay held at their fitted values.

A shaped law (``coulomb:tanh``, ``stribeck:velocity``, ``sigmoid``, ``ripple``, ``coulomb:tanh[q5+q6]``;
:mod:`dynamics.effects.shaped`) is linear in its coefficients once its shape ``s`` is fixed, and a delay
``d`` between torques and motion (:mod:`estimation.preprocessing.delay`) only moves the motion the
columns are evaluated along. Held at the unconstrained (variable-projection) fit's ``ŝ`` and ``d̂``, the
model is again ``y = Y_b(q(t − d̂), …; ŝ) θ_b``, a linear problem in the base parameters, and the
weighted least-squares cost keeps the quadratic form that
:class:`estimation.consistent.least_squares.ConsistentLeastSquares` minimises under the log-Cholesky map:

.. math::  ‖W^{½}(y − Y_b(ŝ, d̂) θ_b)‖² = χ²(\\hat θ_b) + (θ_b − \\hat θ_b)^T G(ŝ, d̂) (θ_b − \\hat θ_b),

with ``θ̂_b`` the variable-projection estimate (the inner linear solve at ``ŝ``, the channel weights
settled there). The shapes are not refined under consistency: the consistent coefficients move from
``θ̂_b`` by what the bodies' consistency costs, and the shapes that fit ``θ̂_b`` best are kept (the profile
of ``s`` is flat where the fit is good; refining it is a further step of the same form).

The linear effects (offsets, springs, armature, motor-side friction and inertia of a transmission, laws
on joint combinations) enter as before; each effect's parameters are non-negative by physics when its
kind is (:data:`dynamics.effects.linear.POSITIVE_EFFECTS` through the effect's ``physical_kind``).

The prediction of the refit along another record is ``Y_b(q(t − d̂), …; ŝ) θ_b^{cons}``: the same columns as
the unconstrained model's (:class:`estimation.identification.identified_model.IdentifiedModel` with
``estimate="consistent"`` reads it from the model file).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace

import numpy as np
from numpy.typing import ArrayLike, NDArray

from dynamics.measurements import Measurements
from estimation.data.channel_mask import masked_equations
from estimation.data.passive import passive_channels
from estimation.data.segments import concatenate, segment_slices
from estimation.estimators.identification_problem import IdentificationProblem
from estimation.identification.fit import IdentificationResult
from estimation.identification.validation import Comparison
from estimation.preprocessing.delay import delayed

__all__ = ["comparisons", "fixed_comparison", "fixed_problem", "fixed_regressor", "has_fixed_effects"]


def has_fixed_effects(result: IdentificationResult) -> bool:
    """Whether ``result`` has shaped laws or a delay (held fixed by the consistent refit)."""
    # a fit from sums (the streamed diagnosis's SummedFit) has no shaped_fit: its shaped columns were summed at
    # their fixed shapes
    return getattr(result, "shaped_fit", None) is not None or result.delay is not None


def _moved(result: IdentificationResult, measurements: Measurements) -> Measurements:
    if measurements.dq is None or measurements.ddq is None:
        raise ValueError("the measurements lack dq/ddq: derive them first (estimation.preprocessing.plan.prepare)")
    if measurements.n_joints != result.model.robot.n_joints:
        raise ValueError(f"the data have {measurements.n_joints} joints, the robot {result.model.robot.n_joints}")
    return measurements if result.delay is None else delayed(measurements, float(result.delay.value))


def fixed_regressor(result: IdentificationResult, measurements: Measurements) -> NDArray[np.float64]:
    """``(N, m, r)``: ``result``'s base regressor along ``measurements`` (motion moved by the fitted delay, if
    any), the shaped columns at the fitted shapes, in the model's base order."""
    record = _moved(result, measurements)
    if result.shaped_fit is not None:
        return np.asarray(result.shaped_fit.regressor(record), dtype=float)
    return np.asarray(result.model.evaluate_base(record.q, record.dq, record.ddq), dtype=float)


def fixed_problem(result: IdentificationResult, measurements: Measurements) -> IdentificationProblem:
    """The linear base-parameter problem of ``result``'s model on ``measurements``, shapes and delay held at
    ``result``'s values (module docstring): what :class:`ConsistentLeastSquares` fits."""
    measurements = concatenate(measurements)
    model = result.model
    Y = fixed_regressor(result, measurements)
    pieces = segment_slices(measurements)
    bounds = tuple((piece.start, piece.stop) for piece in pieces) if len(pieces) > 1 else ()
    Y, measured, mask = masked_equations(Y, measurements.channels(model.channels))  # masked samples: out
    return IdentificationProblem(Y, measured, model.channels, model.base.names, model.base.expressions, bounds,
                                 passive=passive_channels(model), mask=mask)


def fixed_comparison(result: IdentificationResult, values: ArrayLike, measurements: Measurements, *,
                     label: str = "") -> Comparison:
    """Base parameters ``values`` of ``result``'s model at its shapes and delay, against the channels **as
    recorded** (``measurements.recorded`` when preprocessing filtered them; the filtered comparison kept as
    ``filtered``), as :func:`estimation.identification.validation.compare` for a linear model."""
    theta = np.asarray(values, dtype=float).reshape(-1)
    filtered = _comparison(result, theta, measurements, label)
    if measurements.recorded is None:
        return filtered
    return replace(_comparison(result, theta, measurements.recorded, label), filtered=filtered)


def _comparison(result: IdentificationResult, theta: NDArray[np.float64], measurements: Measurements,
                label: str) -> Comparison:
    channels = result.model.channels
    predicted = fixed_regressor(result, measurements) @ theta
    return Comparison(measurements.t, measurements.channels(channels), predicted, channels, label,
                      segments=tuple(segment_slices(measurements)))


def comparisons(result: IdentificationResult, values: Sequence[ArrayLike], measurements: Measurements, *,
                label: str = "", regressor: NDArray[np.float64] | None = None) -> list[Comparison]:
    """The comparisons of several base-parameter vectors ``values`` of ``result``'s model on ``measurements``, each
    the one :func:`fixed_comparison` (shaped laws or a delay) or
    :func:`estimation.identification.validation.compare` (a linear model) makes, with the regressor of each record
    (the filtered one, then the recording) evaluated once for all the vectors and released before the next: the
    same predictions ``Y θ``, bit for bit (the prior-weight search, :func:`estimation.consistent.identification.
    consistent_fit`). ``regressor``: the regressor along ``measurements`` itself, already evaluated (the training
    problem's)."""
    thetas = [np.asarray(value, dtype=float).reshape(-1) for value in values]
    filtered = _comparisons(result, thetas, measurements, label, regressor)
    if measurements.recorded is None:
        return filtered
    recorded = _comparisons(result, thetas, measurements.recorded, label, None)
    return [replace(on_record, filtered=on_filtered) for on_record, on_filtered in zip(recorded, filtered)]


def _comparisons(result: IdentificationResult, thetas: Sequence[NDArray[np.float64]], measurements: Measurements,
                 label: str, regressor: NDArray[np.float64] | None) -> list[Comparison]:
    channels = result.model.channels
    Y = _regressor(result, measurements) if regressor is None else regressor
    measured, segments = measurements.channels(channels), tuple(segment_slices(measurements))
    return [Comparison(measurements.t, measured, Y @ theta, channels, label, segments=segments) for theta in thetas]


def _regressor(result: IdentificationResult, measurements: Measurements) -> NDArray[np.float64]:
    """The regressor ``fixed_comparison`` (shaped laws or a delay) or ``compare`` (``model.predict`` of base
    values) multiplies by the base parameters."""
    if has_fixed_effects(result):
        return fixed_regressor(result, measurements)
    model = result.model
    if measurements.dq is None or measurements.ddq is None:
        raise ValueError("the measurements lack dq/ddq: derive them first (estimation.preprocessing.plan.prepare)")
    states = (measurements.q, measurements.dq, measurements.ddq)
    # model.predict takes a vector as long as the standard parameters as standard values
    return model.evaluate(*states) if model.n_parameters == model.n_base else model.evaluate_base(*states)
