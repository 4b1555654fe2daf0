"""How a diagnosis confirms what it adds, and simplifies what it found.

* :func:`reweighted_comparison`: a candidate and the current model are compared at the channel
  weights the candidate's own training residuals give (``w_c = 1/σ̂_c²``, iterated as the weighted
  least squares of the final fit is). The declared model's weights down-weight exactly the channel
  an effect is missing from (its residual is large), so at those weights fixing that channel looks
  like a loss on the others (the KUKA LWR4+'s joint 1: Coulomb friction and an offset lower its
  validation MSE from 3.9 to 1.2 N²m², and every other channel's with it, once reweighted).
* :class:`HeldOutBlocks`: when the validation record repeats the training motion
  (:func:`estimation.identification.repeated_motion.repeated_motion`), another noise on the same motion
  cannot reject an effect fitted to that motion's own features. The comparison is then blocked: the
  motion cut into :data:`HELD_OUT_BLOCKS` stretches (of the period, when the records say it: every
  period's stretch left out together), each model trained on the training record without one stretch
  and its error taken on the validation record's same stretch, which its fit did not see.
* :func:`own_rows_gain`: a candidate's gain is judged on the channels it acts on (the torque equations its
  effects enter), at least ``min_improvement`` there, not on the sum over every channel.
* :func:`own_rows_gain`: a candidate's gain on the channels it acts on (the torque equations its effects
  enter): at least ``min_improvement`` there, and at least :data:`OWN_ROWS_SHARE` of the sum's gain, confirms it
  as on the sum over every channel.
* :func:`channels_made_worse`: a candidate is not confirmed when it raises the validation error of a
  channel it acts on (a pair acting on two rows must not trade one for the other).
* :func:`simplify_laws`: after the joint refit, a several-term law whose extra term the final fit does
  not support is replaced by its simpler law (a Stribeck law without a significant static term is
  Coulomb friction): a law of a shape the data do not ask for is not named.

Validation errors here are against the channels as recorded (:func:`estimation.diagnosis.search.diagnose`).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

import dataclasses
from collections.abc import Sequence
from dataclasses import dataclass

from dynamics.effects.linear import CoulombFriction, Effect
from dynamics.models import IdentificationModel, build_model
from dynamics.effects.shaped import ShapedStribeckFriction, shape_parameters
from estimation.diagnosis.candidates.trials import SIGNIFICANT_TERM, Trial, weighted_error
from estimation.identification.fit import IdentificationResult, identify
from estimation.data.passive import floored_variance
from estimation.estimators.identification_problem import in_band_variance
from estimation.estimators.effect_blocks import Block, ShapeSearchError, States
from estimation.estimators.separable_least_squares import FixedPart, residuals, solve_linear

#: reweighting passes of a candidate's linear coefficients (the weighted least squares settles in two)
REWEIGHTING_PASSES = 2
#: stretches of the motion left out in turn when the validation record repeats the training motion
HELD_OUT_BLOCKS = 5
#: the least share of the validation sum's gain that must lie on the channels an effect acts on for their
#: gain to confirm it (:func:`own_rows_gain`)
OWN_ROWS_SHARE = 0.5


@dataclass(frozen=True)
class HeldOutBlocks:
    """Which stretch of the motion each sample of the training and validation records is in (``0 …
    n_blocks − 1``): by the phase of the period when the records' ``frequency_hz`` is known, else by time."""

    train: NDArray[np.intp]
    validate: NDArray[np.intp]
    n_blocks: int = HELD_OUT_BLOCKS

    @classmethod
    def of(cls, train_t: NDArray[np.float64], validate_t: NDArray[np.float64], frequency_hz: float | None = None,
           n_blocks: int = HELD_OUT_BLOCKS) -> HeldOutBlocks:
        def labels(t: NDArray[np.float64]) -> NDArray[np.intp]:
            t = np.asarray(t, dtype=float) - t[0]
            if frequency_hz:  # the same stretch of every period, so that no other period shows it to the fit
                phase = np.mod(t * frequency_hz, 1.0)
            else:
                phase = np.arange(t.shape[0]) / max(t.shape[0], 1)
            return np.minimum((phase * n_blocks).astype(np.intp), n_blocks - 1)

        return cls(labels(train_t), labels(validate_t), n_blocks)

    def residual(self, train: FixedPart, validate: FixedPart, weights: NDArray[np.float64]) -> NDArray[np.float64]:
        """``(m, N)`` validation residuals, each stretch predicted by the fit without that stretch of training
        (its Gram matrices and moments taken out of the whole record's)."""
        residual = np.empty_like(validate.y)
        for block in range(self.n_blocks):
            gram, moment, power = _sums(train, self.train == block)
            fold = dataclasses.replace(train, gram=train.gram - gram, moment=train.moment - moment,
                                       power=train.power - power)
            theta = solve_linear(fold, [], None, [], weights).theta
            rows = self.validate == block
            residual[:, rows] = validate.y[:, rows] - validate.predict(theta)[:, rows]
        return residual


def _sums(fixed: FixedPart, samples: NDArray[np.bool_]
          ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """The per-channel Gram matrices, moments and powers of ``fixed`` on ``samples`` alone."""
    m, p0 = len(fixed.own), fixed.n_fixed
    gram, moment = np.zeros((m, p0, p0)), np.zeros((m, p0))
    y = fixed.y[:, samples]
    for channel, (own, where) in enumerate(zip(fixed.own, fixed.where)):
        kept = where >= 0
        stored = own[samples][:, kept]
        places = where[kept]
        gram[channel][np.ix_(places, places)] = stored.T @ stored
        moment[channel, places] = stored.T @ y[channel]
    return gram, moment, np.sum(y**2, axis=1)


def blocked_comparison(trial: Trial, fixed_train: FixedPart, fixed_validate: FixedPart, states_train: States,
                       states_validate: States, settled: NDArray[np.float64], blocks: HeldOutBlocks,
                       current: tuple[FixedPart, FixedPart] | None = None,
                       held_out: str = "the stretches of the repeated motion its fit did not see") -> CandidateComparison:
    """:func:`reweighted_comparison` on a validation record that repeats the training motion: both models trained
    at ``settled``, the weights the candidate's training residuals give (:func:`settled_weights`, as the
    comparison on the whole repeat found them), each stretch of the validation record predicted by the fits that
    did not see that stretch (:class:`HeldOutBlocks`)."""
    shapes = trial.shapes()
    candidate = blocks.residual(fixed_train.with_blocks(trial.blocks, states_train, shapes),
                                fixed_validate.with_blocks(trial.blocks, states_validate, shapes), settled)
    current_train, current_validate = (fixed_train, fixed_validate) if current is None else current
    current_residual = blocks.residual(current_train, current_validate, settled)
    return CandidateComparison(settled, float(settled @ np.mean(candidate**2, axis=1)), candidate,
                      float(settled @ np.mean(current_residual**2, axis=1)), current_residual, held_out)


@dataclass(frozen=True)
class CandidateComparison:
    """A candidate against the current model on held-out data, both trained at ``weights``."""

    weights: NDArray[np.float64]
    error: float  # the candidate's weighted validation MSE
    residual: NDArray[np.float64]  # (m, N)
    current_error: float
    current_residual: NDArray[np.float64]
    held_out: str = "the validation record"  # what the errors are on


def settled_weights(fixed: FixedPart, blocks, states: States, shapes, weights: NDArray[np.float64],
                    passes: int = REWEIGHTING_PASSES) -> NDArray[np.float64]:
    """Channel weights ``1/σ̂_c²`` from the training residuals of ``fixed`` plus ``blocks`` at
    ``shapes``, iterated ``passes`` times (PUMA paper, eq. 21, as :class:`WeightedLeastSquares`: the variances of
    the residual in ``fixed.band``, the motion's band, when it has one)."""
    n_parameters = fixed.n_fixed + sum(block.n_linear + block.n_shape for block in blocks)
    mean_square = np.mean(fixed.y**2, axis=1)
    floor = 1e-14 * mean_square + np.finfo(float).tiny
    for _ in range(passes):
        solution = solve_linear(fixed, blocks, states, shapes, weights)
        residual = residuals(fixed, blocks, solution)
        weights = 1.0 / floored_variance(in_band_variance(residual.T, n_parameters, fixed.band), floor,
                                         mean_square == 0)  # a passive joint's channel too
    return weights


def reweighted_comparison(trial: Trial, fixed_train: FixedPart, fixed_validate: FixedPart, states_train: States,
                          states_validate: States, weights: NDArray[np.float64],
                          current: tuple[FixedPart, FixedPart] | None = None) -> CandidateComparison:
    """The candidate and the current model, both trained at the weights the candidate's training
    residuals give (:func:`settled_weights`), and their weighted validation errors at those weights.
    ``fixed_train``, ``fixed_validate``: the columns the candidate joins; ``current``: the current
    model's (training, validation) columns when they differ (a replacement: the candidate joins the
    current model without the law it replaces)."""
    shapes = trial.shapes()
    settled = settled_weights(fixed_train, trial.blocks, states_train, shapes, weights)
    candidate = solve_linear(fixed_train, trial.blocks, states_train, shapes, settled)
    error, residual = weighted_error(fixed_validate, trial.blocks, states_validate, shapes, candidate.theta, settled)
    current_train, current_validate = (fixed_train, fixed_validate) if current is None else current
    return _against_current(settled, error, residual, current_train, current_validate)


def _against_current(settled: NDArray[np.float64], error: float, residual: NDArray[np.float64],
                     current_train: FixedPart, current_validate: FixedPart) -> CandidateComparison:
    current = solve_linear(current_train, [], None, [], settled)
    current_error, current_residual = weighted_error(current_validate, [], None, [], current.theta, settled)
    return CandidateComparison(settled, error, residual, current_error, current_residual)


def removal_comparison(reduced_train: FixedPart, reduced_validate: FixedPart, current_train: FixedPart,
                       current_validate: FixedPart, weights: NDArray[np.float64]) -> CandidateComparison:
    """The current model without an adopted effect (``reduced``) against the current model, both trained
    at the weights the reduced model's training residuals give, as :func:`reweighted_comparison`."""
    settled = settled_weights(reduced_train, [], None, [], weights)
    reduced = solve_linear(reduced_train, [], None, [], settled)
    error, residual = weighted_error(reduced_validate, [], None, [], reduced.theta, settled)
    return _against_current(settled, error, residual, current_train, current_validate)


def channels_made_worse(trial, current: NDArray[np.float64], candidate: NDArray[np.float64], tolerance: float,
                         model: IdentificationModel, replaced: Sequence[Block] = ()) -> str:
    """The channels a trial's effects (and those it replaces) act on whose validation MSE it raises by
    more than ``tolerance`` (relative), as ``"tau2 (1.08 -> 1.57)"``; empty when none. ``current``,
    ``candidate``: ``(m, N)`` validation residuals without and with the trial."""
    before, after = np.mean(current**2, axis=1), np.mean(candidate**2, axis=1)
    rows = sorted({row for block in tuple(trial.blocks) + tuple(replaced) for row in block.rows})
    return ", ".join(f"{model.channels[row]} ({before[row]:.4g} -> {after[row]:.4g})"
                     for row in rows if after[row] > (1.0 + tolerance) * before[row])


def own_rows_gain(trial, comparison: CandidateComparison, min_improvement: float, model: IdentificationModel,
                  replaced: Sequence[Block] = ()) -> str:
    """Why a trial's gain on the channels its effects (and those it replaces) act on falls short, or ``""``.

    An effect enters the torque equations of its rows only (a joint's friction law the equation of its joint);
    lowering their weighted validation MSE by at least ``min_improvement`` (relative) confirms it as lowering the
    sum over every channel by as much does, where the other channels' errors dilute its gain (a law that makes its
    joint 4 % better moves the sum of seven joints by 0.6 %).

    That holds when the gain is the effect's own: at least :data:`OWN_ROWS_SHARE` of the sum's gain must lie on
    those channels. A gain mostly on channels the effect does not enter comes through the parameters they share
    (the base parameters refitted), not from the effect explaining its joint, and is judged on the sum alone (a
    spring on a simulated PUMA's joint 1, whose truth holds none, lowered that joint's error by 1.2 % but held 29 %
    of the sum's 0.46 % gain)."""
    rows = sorted({row for block in tuple(trial.blocks) + tuple(replaced) for row in block.rows})
    weights = np.asarray(comparison.weights, dtype=float)[rows]
    before = float(weights @ np.mean(comparison.current_residual[rows] ** 2, axis=1))
    after = float(weights @ np.mean(comparison.residual[rows] ** 2, axis=1))
    channels = ", ".join(model.channels[row] for row in rows)
    total = comparison.current_error - comparison.error
    if after < (1.0 - min_improvement) * before:
        if before - after >= OWN_ROWS_SHARE * total:
            return ""
        return (f"lowers the validation error of the channels it acts on ({channels}: {before:.4g} -> {after:.4g}) "
                f"by under {100 * OWN_ROWS_SHARE:g} % of the sum's gain, the rest on channels it does not act on "
                f"(through the refitted shared parameters; {before - after:.4g} of {total:.4g}")
    change = "raises" if after > before else f"lowers by less than {100 * min_improvement:g} %"
    return f"{change} the validation error of the channels it acts on ({channels}: {before:.4g} -> {after:.4g}"


def weighted_validation(result: IdentificationResult, weights: NDArray[np.float64]) -> float:
    return float(np.dot(weights, list(result.validation.mse.values())))


def _simpler_law(effect: Effect, after: IdentificationResult, model: IdentificationModel) -> Effect | None:
    """The simpler law a found several-term law reduces to when its extra term is not significant in
    the final fit (a Stribeck law whose static term ``fs`` is within :data:`SIGNIFICANT_TERM`
    standard deviations of zero is Coulomb friction), else ``None``."""
    if not isinstance(effect, ShapedStribeckFriction):
        return None
    records = {record["name"]: record for record in after.estimate.records()}
    terms = [name for name in effect.parameter_names(model.robot) if name.startswith("fs")]
    if all(name in records and records[name]["value"] < SIGNIFICANT_TERM * records[name]["std"] for name in terms):
        return CoulombFriction(joints=effect.joints)
    return None


def simplify_laws(selected, after, model, train, validate, starts, weights, min_improvement):
    """One backward step after the joint refit: each found law whose extra terms the final fit does not
    support is replaced by its simpler law (:func:`_simpler_law`); the replacement is kept when the
    weighted validation error does not grow by more than ``min_improvement``. A law of a shape the
    data do not ask for is not named."""
    replacements = {id(effect): _simpler_law(effect, after, model) for effect, _, _ in selected}
    if not any(replacements.values()):
        return selected, after
    simplified = [(replacements[id(effect)] or effect, p_value, statistic) for effect, p_value, statistic in selected]
    current = build_model(model.robot, model.kind, model.effects + tuple(effect for effect, _, _ in simplified))
    kept = {name: value for name, value in starts.items()
            if any(name in {p.name for p in shape_parameters(effect, model.robot)} for effect, _, _ in simplified)}
    try:
        candidate = identify(current, train, validate, shape_starts=kept or None)
    except ShapeSearchError:
        return selected, after
    if weighted_validation(candidate, weights) <= (1.0 + min_improvement) * weighted_validation(after, weights):
        return simplified, candidate
    return selected, after


def unseen_veto(repeat: CandidateComparison, unseen: CandidateComparison) -> CandidateComparison:
    """The comparison on a repeat of the training motion, unless the candidate raises the error on the stretches
    of that motion its fit did not see (``unseen``: :func:`blocked_comparison`): then that one, which the search
    refuses. The size of the gain (``min_improvement``) is judged on the whole repeat: the stretches' errors also
    hold what a fit on four fifths of the motion misses of the rigid body, which is not the candidate's."""
    return unseen if unseen.error >= unseen.current_error else repeat
