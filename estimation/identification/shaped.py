"""Identification of a model with shaped effects (``--friction viscous,coulomb:tanh``).

The base-parameter reduction of ``build_model`` is done once, with each shaped effect's columns at
its *reference* shape (a generic value inside its bounds, :attr:`ShapeParameter.reference`). A
shaped effect's columns are nonlinear functions of one joint's motion that no rigid-body column
spans, so each of its coefficients stays a base parameter of its own, for every shape value in
the bounds; this is checked (:class:`ShapeIdentifiabilityError` otherwise). The identification
then replaces those columns by ``C(s)`` and estimates ``s`` by variable projection
(:mod:`estimation.estimators.variable_projection`), the linear coefficients by channel-weighted least
squares inside, with the weights iterated as :class:`estimation.estimators.least_squares.WeightedLeastSquares`
does (a few rounds, each search starting from the last shapes).
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any, Literal

import numpy as np
from numpy.typing import NDArray

from dynamics.models import IdentificationModel
from dynamics.effects.shaped import ShapedPerJointEffect, is_shaped
from estimation.estimators.identification_problem import ResidualBand, in_band_variance
from estimation.estimators.least_squares import Estimate, channel_variance
from dynamics.measurements import Measurements
from estimation.data.passive import floored_variance
from estimation.data.segments import segment_slices
from estimation.identification.validation import Comparison
from estimation.estimators.effect_blocks import Block, States
from estimation.estimators.separable_least_squares import FixedPart, solve_linear
from estimation.estimators.variable_projection import ShapeFit, fit_shapes


class ShapeIdentifiabilityError(ValueError):
    """A shaped effect's coefficient is not a base parameter of its own (the model absorbs it)."""


@dataclass(frozen=True)
class ShapeValue:
    """One fitted shape parameter."""

    name: str
    effect: str
    value: float
    std: float
    lower: float
    upper: float

    @property
    def at_bound(self) -> bool:
        span = self.upper - self.lower
        return min(self.value - self.lower, self.upper - self.value) <= 1e-6 * span


def split_per_joint(effect: Any, robot) -> list[Any]:
    """A built-in per-joint shaped law on several joints as one effect per joint (independent blocks)."""
    if isinstance(effect, ShapedPerJointEffect):
        joints = effect.joints if effect.joints is not None else tuple(range(robot.n_joints))
        if len(joints) > 1:
            return [type(effect)(joints=(joint,), bounds=effect.bounds, starts=effect.starts) for joint in joints]
    return [effect]


def shaped_blocks(model: IdentificationModel) -> tuple[list[Block], list[int]]:
    """The shaped effects of ``model`` as blocks, and the base columns they replace."""
    blocks, replaced = [], []
    base_names = list(model.base.names)
    for effect in model.effects:
        if not is_shaped(effect, model.robot):
            continue
        for part in split_per_joint(effect, model.robot):
            block = Block(model.kind, model.robot, part, model.n_channels)
            for name in block.names:
                index = base_names.index(name) if name in base_names else -1
                if index < 0 or model.base.expressions[index].strip() != name:
                    raise ShapeIdentifiabilityError(
                        f"effect {getattr(part, 'spec', part.name)!r}: its coefficient {name} is not a base parameter of "
                        "its own in this model (the other columns absorb it): drop the effect or another that covers it")
                replaced.append(index)
            blocks.append(block)
    return blocks, replaced


@dataclass(frozen=True)
class ShapedFit:
    """A model with shaped effects fitted on one record: what predicts it elsewhere."""

    model: IdentificationModel
    blocks: tuple[Block, ...]
    kept: tuple[int, ...]  # base columns of the fixed part
    replaced: tuple[int, ...]  # base columns of the blocks, in block order
    fit: ShapeFit
    weights: np.ndarray

    def theta_base(self) -> np.ndarray:
        """The linear coefficients in the model's base order."""
        theta = np.empty(self.model.n_base)
        theta[list(self.kept)] = self.fit.theta[: len(self.kept)]
        theta[list(self.replaced)] = self.fit.theta[len(self.kept):]
        return theta

    def predict(self, measurements: Measurements, base: np.ndarray | None = None, *,
                overwrite: bool = False, rewritten: bool = False) -> np.ndarray:
        """``(N, m)`` predicted channels at the fitted shapes (``base``, ``overwrite``, ``rewritten``: see
        :meth:`regressor`)."""
        Y = self.regressor(measurements, base, overwrite=overwrite, rewritten=rewritten)
        return Y @ self.theta_base()

    def regressor(self, measurements: Measurements, base: np.ndarray | None = None, *,
                  overwrite: bool = False, rewritten: bool = False) -> np.ndarray:
        """The base regressor ``(N, m, r)`` with the shaped columns at the fitted shapes; ``base``: the model's base
        regressor along ``measurements`` when the caller has it (copied, not evaluated again). ``overwrite``: the
        shaped columns written into ``base`` itself when it is a writable C-ordered float array (the same values as
        the copy: only the shaped columns change, each call writes them all), which spares a copy of the whole
        regressor each round of :func:`fit_shaped_model`. ``rewritten``: ``base`` is the array an earlier call of
        this fit's blocks overwrote (a round of :func:`fit_shaped_model_predicting` after the first), whose shaped
        columns are zero already off their blocks' rows: only those rows are written again (the same values; the
        zeroing of a column reads and writes every sample of every channel, ~1.4 ms a column on the Panda)."""
        if base is None:  # a new array of its own, written in place
            Y = self.model.evaluate_base(measurements.q, measurements.dq, measurements.ddq)
        elif overwrite and isinstance(base, np.ndarray) and base.dtype == np.float64 and base.flags.c_contiguous \
                and base.flags.writeable:
            Y = base
        else:
            Y = np.array(base)
        states = States(measurements.q, measurements.dq, measurements.ddq)
        start, position = 0, 0
        for block in self.blocks:
            columns = block.evaluate(states, self.fit.shape[start:start + block.n_shape])
            start += block.n_shape
            indices = list(self.replaced[position:position + block.n_linear])
            position += block.n_linear
            if not (rewritten and Y is base):
                Y[:, :, indices] = 0.0
            for row_position, row in enumerate(block.rows):
                Y[:, row, indices] = columns[:, row_position, :]
        return Y

    def shape_values(self) -> tuple[ShapeValue, ...]:
        values, start = [], 0
        std = self.fit.shape_std
        for block in self.blocks:
            for parameter in block.parameters:
                values.append(ShapeValue(parameter.name, getattr(block.effect, "spec", block.effect.name),
                                         float(self.fit.shape[start]), float(std[start]), parameter.lower, parameter.upper))
                start += 1
        return tuple(values)


def fit_shaped_model(model: IdentificationModel, train: Measurements, *, weighted: bool = True,
                     rounds: int = 4, starts: dict[str, float] | None = None,
                     search: bool = True, covariance: Literal["hac", "white"] = "hac") -> tuple[ShapedFit, Estimate]:
    """Variable-projection fit of a model with shaped effects, and its :class:`Estimate` (base order).

    ``starts``: shape values by name to start from (the others at their reference), instead of the grid;
    without ``search`` the shapes stay there. ``covariance``: ``"hac"`` the batch-means sandwich
    (``cov_method="batch_means"``), ``"white"`` ``σ̂² (J_fᵀWJ_f)⁻¹`` (``cov_method="classical"``), both
    from the full Jacobian (:func:`estimation.estimators.variable_projection.fit_shapes`).
    """
    shaped, estimate, _ = fit_shaped_model_predicting(model, train, weighted=weighted, rounds=rounds, starts=starts,
                                                      search=search, covariance=covariance)
    return shaped, estimate


def fit_shaped_model_predicting(model: IdentificationModel, train: Measurements, *, weighted: bool = True,
                                rounds: int = 4, starts: dict[str, float] | None = None, search: bool = True,
                                covariance: Literal["hac", "white"] = "hac"
                                ) -> tuple[ShapedFit, Estimate, NDArray[np.float64]]:
    """:func:`fit_shaped_model`, and its prediction along ``train`` ``(N, m)``: the fit forms it for its residual,
    the very values :meth:`ShapedFit.predict` gives along ``train`` (the comparison on the training record takes it
    rather than evaluating the regressor again: :func:`shaped_comparison`'s ``predicted``)."""
    if covariance not in ("hac", "white"):
        raise ValueError(f"covariance must be 'hac' or 'white', got {covariance!r}")
    if train.dq is None or train.ddq is None:
        raise ValueError("the measurements lack dq/ddq: derive them first (estimation.preprocessing.differentiation.fill_derivatives)")
    blocks, replaced = shaped_blocks(model)
    kept = [index for index in range(model.n_base) if index not in set(replaced)]
    Y = model.evaluate_base(train.q, train.dq, train.ddq)
    y = train.channels(model.channels)
    fixed = FixedPart.from_arrays(np.take(Y, kept, axis=2), y)  # C-ordered (a fancy index's copy is strided)
    states = States(train.q, train.dq, train.ddq)
    weights = np.ones(model.n_channels)
    segments = [(piece.start, piece.stop) for piece in segment_slices(train)]
    band = ResidualBand.of(train)
    fit = None
    written = False  # whether Y's shaped columns were written by a round (then zero off their blocks' rows)
    first = None
    if starts is not None:
        first = np.array([[starts.get(parameter.name, parameter.reference) for block in blocks
                           for parameter in block.parameters]])
    # the rounds before the last use the shapes and θ only: the white covariance (the same singularity check)
    # rather than the batch-means sandwich, whose sample scores are the cost
    settling = "white" if weighted else covariance
    for _ in range(rounds if weighted else 1):
        start_points = first if fit is None else fit.shape[None, :]
        fit = fit_shapes(fixed, blocks, states, weights, starts=start_points, max_iter=60 if search else 0,
                         covariance=settling, segments=segments)
        shaped = ShapedFit(model, tuple(blocks), tuple(kept), tuple(replaced), fit, weights)
        # Y's shaped columns only are rewritten; from the second round on, on their blocks' rows alone
        residual = y - shaped.predict(train, Y, overwrite=True, rewritten=written)
        written = True
        mean_square = np.mean(y**2, axis=0)
        variance = floored_variance(in_band_variance(residual, model.n_base + len(fit.names), band),
                                    1e-14 * mean_square, mean_square == 0)  # the residual in the motion's band
        if not weighted:
            break
        updated = 1.0 / variance
        if np.max(np.abs(updated - weights) / updated) < 1e-4:
            weights = updated
            break
        weights = updated
    if weighted:  # the final fit at the settled weights
        fit = fit_shapes(fixed, blocks, states, weights, starts=fit.shape[None, :], max_iter=60 if search else 0,
                         covariance=covariance, segments=segments)
    shaped = ShapedFit(model, tuple(blocks), tuple(kept), tuple(replaced), fit, weights)
    predicted = shaped.predict(train, Y, overwrite=True, rewritten=written)
    residual = y - predicted
    order = list(kept) + list(replaced)
    n_linear = len(order)
    cov = np.empty((model.n_base, model.n_base))
    cov[np.ix_(order, order)] = fit.cov[:n_linear, :n_linear]
    theta = shaped.theta_base()
    std = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    with np.errstate(divide="ignore", invalid="ignore"):
        relative = np.where(theta != 0, 100.0 * std / np.abs(theta), np.inf)
    normal = solve_linear(fixed, blocks, states, [fit.shape[sum(b.n_shape for b in blocks[:i]):][:blk.n_shape]
                                                   for i, blk in enumerate(blocks)], weights).normal
    extremes = np.linalg.eigvalsh(normal)[[0, -1]]
    estimate = Estimate(
        values=theta, cov=cov, std=std, relative_std=relative,
        cond=float(np.sqrt(extremes[1] / max(extremes[0], np.finfo(float).tiny))), residuals=residual,
        channel_variance=channel_variance(residual, model.n_base + len(fit.names)), weights=weights,
        names=model.base.names, expressions=model.base.expressions, channels=model.channels,
        method="wls" if weighted else "ols", n_iterations=1,
        cov_method="batch_means" if covariance == "hac" else "classical",
    )
    return shaped, estimate, predicted


def shaped_comparison(shaped: ShapedFit, measurements: Measurements, label: str, *,
                      predicted: NDArray[np.float64] | None = None) -> Comparison:
    """Measured against predicted at the fitted shapes, against the channels **as recorded**
    (``measurements.recorded`` when preprocessing filtered or averaged them; the comparison with
    the filtered channels kept as ``filtered``), as :func:`estimation.identification.validation.compare`.
    ``predicted``: ``shaped.predict(measurements)`` when the caller has it (the fit's own along its training record,
    :func:`fit_shaped_model_predicting`), not formed again; the recorded samples' is formed here."""
    if predicted is not None and np.shape(predicted) != (measurements.n_samples, shaped.model.n_channels):
        raise ValueError(f"predicted has shape {np.shape(predicted)}, expected "
                         f"{(measurements.n_samples, shaped.model.n_channels)}")
    filtered = _comparison_as_is(shaped, measurements, label, predicted)
    if measurements.recorded is None:
        return filtered
    return replace(_comparison_as_is(shaped, measurements.recorded, label), filtered=filtered)


def _comparison_as_is(shaped: ShapedFit, measurements: Measurements, label: str,
                      predicted: NDArray[np.float64] | None = None) -> Comparison:
    return Comparison(measurements.t, measurements.channels(shaped.model.channels),
                      shaped.predict(measurements) if predicted is None else predicted,
                      shaped.model.channels, label, segments=tuple(segment_slices(measurements)))
