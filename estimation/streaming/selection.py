"""The streamed diagnosis's fits from accumulated sums (:mod:`estimation.streaming.diagnosis_sums`).

:class:`SummedFits` is the :class:`estimation.diagnosis.search_fits.Fits` of the streamed
diagnosis: the search itself, its rules and their wording, are those of the in-memory
diagnosis (:class:`estimation.diagnosis.forward_selection.DiagnosisSearch`, the same object); only the
fits differ. A candidate's trial is the weighted least-squares solve on the summed per-channel Gram
matrices of the current columns (without the laws it replaces) and its own, with the nested F test and
BIC of :mod:`estimation.diagnosis.candidates.trials` (``F = ((RSS₀ − RSS₁)/q) / (RSS₁/(N m − p₁))``, ``q``
the candidate's linear and shape parameters); the confirmation compares both models on the validation
sums against the channels **as recorded**, trained at the weights the candidate's training residuals
give (:func:`estimation.diagnosis.confirmation.reweighted_comparison`'s rule, :data:`REWEIGHTING_PASSES`);
a removal compares the model without an effect the same way. The search runs until no move is
significant and confirmed (``stop_at_floor``: the noise floor as the stopping rule,
:func:`estimation.uncertainty.floor_comparison.above_floor` at :data:`~estimation.diagnosis.statistics.FLOOR_ALPHA`,
as :func:`~estimation.diagnosis.rules.stopping_rules.floor_stopping_rule`).

What this path does differently (said in the report's ``streaming.not_on_this_path``):

* shapes are fixed: each shaped law's shape parameters were searched once, against the declared
  model, on a subsample (:mod:`estimation.streaming.diagnosis`); the in-memory fits refine the two
  best-ranked shapes again in each round against the current model, and search a law paired with
  its offset jointly (here the pair uses the law's own shape);
* no delay candidate, and a joint combination's Coulomb and viscous laws are not one candidate
  (:attr:`SearchSettings.combinations <estimation.diagnosis.forward_selection.SearchSettings>` off);
* the Wald tests of the search use the batch-means covariance of the linear coefficients at the fixed shapes
  (``robust``: from the sums of consecutive stretches of the training record and its lag sums), where the in-memory
  search takes the prewhitened Newey–West covariance, or the batch-means one with the shape directions; without
  ``robust``, the classical covariance of the summed fit;
* the stopping rule is the noise floor or none (a user's ``rule(SearchState)`` needs per-sample residuals).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any, TypeVar

import numpy as np
from numpy.typing import NDArray

from dynamics.effects.linear import CoulombFriction, Effect
from dynamics.effects.shaped import ShapedStribeckFriction
from dynamics.models import IdentificationModel, build_model
from estimation.data.passive import floored_variance, passive_channels
from estimation.diagnosis.candidates.trials import SIGNIFICANT_TERM, Trial, nested_test
from estimation.diagnosis.confirmation import REWEIGHTING_PASSES, CandidateComparison
from estimation.diagnosis.candidates.delay import DelayTrial
from estimation.diagnosis.search_fits import AdoptedEffect, TrialRequest, TrialTest
from estimation.diagnosis.rules.robust_test import WaldTest, wald_test
from estimation.diagnosis.results import RunnerUp
from estimation.diagnosis.runner_up import RivalFit, RivalFitter, RunnerUpOutcome, fit_runner_up
from estimation.diagnosis.statistics import FLOOR_ALPHA
from estimation.estimators.effect_blocks import Block
from estimation.estimators.variable_projection import ShapeFit
from estimation.estimators.summed_least_squares import summed_estimator
from estimation.identification.fit import implausible_estimates
from estimation.streaming.diagnosis_sums import ChannelSums, normal_equations
from estimation.uncertainty.noise_floor import NoiseFloor
from estimation.uncertainty.floor_comparison import above_floor

#: what a candidate is compared on when the validation record is at rest (the in-memory wording)
STILL_HELD_OUT = "the stretches of the training record its fit did not see (the validation record hardly moves)"

__all__ = ["STILL_HELD_OUT", "SummedFit", "SummedFits", "simpler_laws", "summed_rival_fitter", "summed_runner_up"]

T = TypeVar("T")


@dataclass(frozen=True)
class SummedFit:
    """The current model fitted on the training sums: weighted RSS, weighted validation MSE and the
    validation MSE per channel (against the channels as recorded)."""

    rss: float
    validation_error: float
    validate_mse: NDArray[np.float64]


class SummedFits:
    """Fits of column blocks from the training and validation sums.

    Parameters
    ----------
    model
        The declared model.
    train, validate
        The sums of the base and every candidate's columns (:class:`ChannelSums`).
    columns
        Each candidate's columns in the sums, by candidate index.
    shapes
        Each candidate's fixed shape, by candidate index.
    floor
        The validation record's noise floor (``None``: none).
    robust
        ``robust(indices, weights) -> (θ, cov θ)``: the fit of the declared columns and the candidates ``indices``
        (in that order) with the covariance that holds for residuals correlated in time (the batch-means sandwich from
        sums, :func:`estimation.streaming.diagnosis.robust_covariance`), for the Wald tests
        of the search as in memory (the HAC covariance, :mod:`estimation.diagnosis.rules.robust_test`); ``None``: the
        classical covariance of the summed fit.
    stretches
        The training sums on each stretch of the training record
        (:func:`~estimation.streaming.diagnosis_passes.stretch_pass`): given when the validation record is at rest, a
        candidate is then compared with the current model on the stretches of the training record its fit did not
        see, each predicted by the fit on the others, as in memory
        (:class:`~estimation.diagnosis.confirmation.HeldOutBlocks` on the training record); ``None``: on the
        validation record.
    stop_at_floor
        Whether the floor is the stopping rule (:func:`~estimation.diagnosis.rules.stopping_rules.floor_stopping_rule`);
        by default the search runs until no move is significant and confirmed, as in memory.
    """

    def __init__(self, model: IdentificationModel, train: ChannelSums, validate: ChannelSums,
                 columns: Mapping[int, Sequence[int]], shapes: Mapping[int, NDArray[np.float64]],
                 floor: NoiseFloor | None, stop_at_floor: bool = False,
                 robust: Callable[[tuple[int, ...], NDArray[np.float64]],
                                  tuple[NDArray[np.float64], NDArray[np.float64]]] | None = None,
                 stretches: Sequence[ChannelSums] | None = None) -> None:
        self.model, self.train, self.validate, self.floor = model, train, validate, floor
        self.robust, self.stretches = robust, stretches
        self.stop_at_floor = stop_at_floor
        self.columns, self.shapes = columns, shapes
        self.adopted: tuple[int, ...] = ()
        self.selection = list(range(train.layout.n_base))  # the current model's columns

    @property
    def n_rows(self) -> int:
        return self.train.n_samples * self.train.layout.n_channels

    def _columns(self, indices: Sequence[int]) -> list[int]:
        return [column for index in indices for column in self.columns[index]]

    def _selection(self, without: tuple[int, ...] = ()) -> list[int]:
        """The current model's columns without the adopted ``without``."""
        return list(range(self.train.layout.n_base)) + self._columns([i for i in self.adopted if i not in without])

    def fit_current(self, weights: NDArray[np.float64], without: tuple[int, ...] = ()) -> SummedFit:
        selection = self._selection(without)
        theta, rss = self.train.solve(selection, weights)
        validate_mse = self.validate.channel_mse(selection, theta)
        return SummedFit(rss, float(weights @ validate_mse), validate_mse)

    def keep_searching(self, current: SummedFit, added: tuple[str, ...]) -> bool:
        """``stop_at_floor``: while some channel's validation MSE is significantly above the floor; else
        always (the in-memory default: until no move is significant and confirmed)."""
        if self.floor is None or not self.stop_at_floor:
            return True
        mse = dict(zip(self.model.channels, current.validate_mse))
        return any(above_floor(mse, self.floor, self.validate.n_samples, alpha=FLOOR_ALPHA).values())

    def trial(self, group: tuple[int, ...], members: Sequence[Block], weights: NDArray[np.float64],
              rss: float, without: tuple[int, ...] = ()) -> Trial | str:
        """A :class:`Trial` of ``group`` added to the current columns (without the adopted ``without``;
        the in-memory trial's statistics), or why not."""
        selection = self._selection(without)
        columns = selection + self._columns(group)
        try:
            theta, rss_augmented = self.train.solve(columns, weights)
        except np.linalg.LinAlgError:
            if all(block.n_shape == 0 for block in members):
                return "not identifiable: the base parameters already absorb it"
            return "not identifiable at the shape found on the subsample (its columns are absorbed or singular)"
        except FloatingPointError:
            return "its columns are non-finite"
        count = sum(block.n_linear + block.n_shape for block in members)
        statistic, p_value, bic = nested_test(rss, rss_augmented, count, self.n_rows, len(selection))
        shape = (np.concatenate([np.asarray(self.shapes[index], dtype=float) for index in group]) if group
                 else np.zeros(0))
        n_total = theta.shape[0] + shape.shape[0]
        fit = ShapeFit(shape, theta, np.full((n_total, n_total), np.nan), rss_augmented,
                       tuple(p.name for block in members for p in block.parameters), 0)
        return Trial(tuple(group), tuple(members), fit, rss_augmented, float(statistic), p_value, float(bic),
                     tuple(without))

    def trials(self, requests: Sequence[TrialRequest], weights: NDArray[np.float64], current: SummedFit
               ) -> list[Trial | str]:
        """:meth:`trial` of each request in turn (each a solve of summed normal equations: cheap)."""
        return [self.trial(request.group, request.members, weights, request.rss, request.without)
                for request in requests]

    def refine(self, trials: list[Trial], current: SummedFit, weights: NDArray[np.float64],
               first_round: bool) -> list[Trial]:
        return trials  # the shapes are fixed

    def _classical(self, columns: list[int], weights: NDArray[np.float64]) -> tuple[NDArray[np.float64],
                                                                                   NDArray[np.float64]]:
        """``(θ, σ̂² (XᵀWX)⁻¹)``: the sums hold no per-sample residuals, so no HAC covariance here (the
        final estimate's is the batch-means sandwich of a further pass)."""
        normal = self.train.normal_system(columns, weights)[0]
        theta, rss = self.train.solve(columns, weights)
        sigma2 = rss / max(self.n_rows - len(columns), 1)
        scale = np.sqrt(np.diag(normal))
        return theta, sigma2 * np.linalg.pinv(normal / np.outer(scale, scale), hermitian=True) / np.outer(scale, scale)

    def _covariance(self, indices: Sequence[int], weights: NDArray[np.float64]
                    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """``(θ, cov θ)`` of the declared columns and the candidates ``indices``: robust when ``robust`` is given."""
        if self.robust is not None:
            return self.robust(tuple(indices), np.asarray(weights, dtype=float))
        return self._classical(list(range(self.train.layout.n_base)) + self._columns(indices), weights)

    def test(self, trial: Trial, weights: NDArray[np.float64]) -> TrialTest:
        """The Wald test of the trial's block from the covariance of the summed fit (robust when ``robust`` is
        given, as the in-memory HAC test; else classical)."""
        kept = [index for index in self.adopted if index not in trial.without]
        theta, cov = self._covariance(kept + list(trial.group), weights)
        block = slice(theta.shape[0] - len(self._columns(trial.group)), theta.shape[0])
        return TrialTest(wald_test(theta[block], cov[block, block]), np.sqrt(np.clip(np.diag(cov)[block], 0.0, None)))

    def current_tests(self, weights: NDArray[np.float64]) -> dict[int, WaldTest]:
        theta, cov = self._covariance(self.adopted, weights)
        tests, start = {}, self.train.layout.n_base
        for index in self.adopted:
            block = slice(start, start + len(self.columns[index]))
            tests[index] = wald_test(theta[block], cov[block, block])
            start = block.stop
        return tests

    def _settled_weights(self, columns: Sequence[int], n_parameters: int, weights: NDArray[np.float64]
                         ) -> NDArray[np.float64]:
        """``1/σ̂_c²`` from the training residuals on ``columns``, iterated (as
        :func:`estimation.diagnosis.confirmation.settled_weights`: ``σ̂_c² = ‖ρ_c‖² / (N − r/m)``)."""
        m, n = self.train.layout.n_channels, self.train.n_samples
        floor = 1e-14 * self.train.power[:, 0] / n + np.finfo(float).tiny
        for _ in range(REWEIGHTING_PASSES):
            theta, _ = self.train.solve(columns, weights)
            weights = 1.0 / floored_variance(self.train.in_band_rss(columns, theta) / (n - n_parameters / m), floor,
                                             self.train.power[:, 0] == 0)  # a passive joint's channel too
        return weights

    def _comparison(self, columns: list[int], n_parameters: int, weights: NDArray[np.float64]) -> CandidateComparison:
        """The model on ``columns`` against the current one, both trained at the weights the former's
        training residuals give, compared on validation; the "residuals" are the per-channel root MSEs,
        ``(m, 1)`` (one "sample" whose square is the MSE, which is all
        :func:`~estimation.diagnosis.confirmation.channels_made_worse` needs)."""
        settled = self._settled_weights(columns, n_parameters, weights)
        if self.stretches is not None:
            candidate_mse, current_mse = (self._held_out_mse(selection, settled) for selection in (columns, self.selection))
            return CandidateComparison(settled, float(settled @ candidate_mse), np.sqrt(candidate_mse)[:, None],
                                       float(settled @ current_mse), np.sqrt(current_mse)[:, None], STILL_HELD_OUT)
        candidate_mse = self.validate.channel_mse(columns, self.train.solve(columns, settled)[0])
        current_mse = self.validate.channel_mse(self.selection, self.train.solve(self.selection, settled)[0])
        return CandidateComparison(settled, float(settled @ candidate_mse), np.sqrt(candidate_mse)[:, None],
                          float(settled @ current_mse), np.sqrt(current_mse)[:, None])

    def _held_out_mse(self, columns: list[int], weights: NDArray[np.float64]) -> NDArray[np.float64]:
        """The MSE per channel (prepared channels) of each stretch of the training record predicted by the fit on the
        others (:meth:`~estimation.diagnosis.confirmation.HeldOutBlocks.residual` from sums)."""
        rss = np.zeros(self.train.layout.n_channels)
        for stretch in self.stretches:
            fold = ChannelSums(self.train.layout, tuple(a - b for a, b in zip(self.train.gram, stretch.gram)),
                               tuple(a - b for a, b in zip(self.train.moment, stretch.moment)),
                               self.train.power - stretch.power, self.train.n_samples - stretch.n_samples)
            rss += stretch.channel_rss(columns, fold.solve(columns, weights)[0], target=0)
        return rss / self.train.n_samples

    def compare(self, trial: Trial, weights: NDArray[np.float64]) -> CandidateComparison:
        """The trial's model (the current one without what it replaces, with its group) against the current one."""
        selection = self._selection(trial.without)
        return self._comparison(selection + self._columns(trial.group), len(selection) + trial.n_parameters, weights)

    def removal(self, without: tuple[int, ...], weights: NDArray[np.float64]) -> CandidateComparison:
        columns = self._selection(without)
        return self._comparison(columns, len(columns), weights)

    def side_by_side(self, tasks: Sequence[Callable[[], T]]) -> list[T]:
        """``[task() for task in tasks]``, in turn: a comparison from sums is a few small solves."""
        return [task() for task in tasks]

    def set_model(self, adopted: Sequence[AdoptedEffect]) -> None:
        self.adopted = tuple(item.index for item in adopted)
        self.selection = self._selection()

    @property
    def delay_adopted(self) -> bool:
        return False  # no delay candidate on this path

    def delay_trials(self, adopted, weights, rss, others) -> list[DelayTrial]:
        return []

    def confirm_delay(self, trial, adopted, weights, min_improvement) -> None:
        raise ValueError("the streamed diagnosis has no delay candidate")

    def adopt_delay(self, trial, outcome) -> CandidateComparison:
        raise ValueError("the streamed diagnosis has no delay candidate")


def simpler_laws(chosen: Sequence[int], blocks: dict[int, Block], records: dict[str, dict], model: IdentificationModel
                 ) -> dict[int, int]:
    """``{chosen index: plain-Coulomb candidate index}`` for each found Stribeck law whose static
    terms the final fit does not support (within :data:`SIGNIFICANT_TERM` standard deviations of
    zero), when that joint's plain Coulomb candidate has columns in the sums (the rule of
    :func:`estimation.diagnosis.confirmation.simplify_laws`; the caller keeps the replacement only when the
    weighted validation error does not grow by more than ``min_improvement``)."""
    coulomb = {tuple(block.effect.joints): index for index, block in blocks.items()
               if type(block.effect) is CoulombFriction and block.effect.joints is not None}
    replacements = {}
    for index in chosen:
        effect: Effect = blocks[index].effect
        if not isinstance(effect, ShapedStribeckFriction) or effect.joints is None:
            continue
        terms = [name for name in effect.parameter_names(model.robot) if name.startswith("fs")]
        unsupported = all(name in records and records[name]["value"] < SIGNIFICANT_TERM * records[name]["std"]
                          for name in terms)
        if unsupported and tuple(effect.joints) in coulomb:
            replacements[index] = coulomb[tuple(effect.joints)]
    return replacements


def summed_rival_fitter(model: IdentificationModel, train: ChannelSums, validation: ChannelSums,
                        blocks: Mapping[int, Block], columns: Mapping[int, Sequence[int]],
                        shapes: Mapping[int, NDArray[np.float64]]) -> RivalFitter:
    """The streamed diagnosis's fit of its runner-up (:mod:`estimation.diagnosis.runner_up`): the declared model's
    columns and the candidates' (``columns`` by index, at their fixed ``shapes``) solved from the training sums,
    its MSE per channel from the sums against the channels as recorded (classical covariance)."""
    def fit(rival: IdentificationModel, indices: tuple[int, ...], starts: dict[str, float]) -> RivalFit:
        selection = list(range(model.n_base)) + [column for index in indices for column in columns[index]]
        names = list(model.base.names) + [name for index in indices for name in blocks[index].names]
        expressions = list(model.base.expressions) + names[model.n_base:]
        n_shape = sum(blocks[index].n_shape for index in indices)  # weighted as the in-memory fit of shaped laws
        estimate = summed_estimator("wls", n_shape, passive_channels(model)).fit(normal_equations(train, selection, names, expressions)).estimate_
        fixed = {parameter.name: float(value) for index in indices
                 for parameter, value in zip(blocks[index].parameters, shapes[index])}
        return RivalFit(estimate, dict(zip(model.channels, map(float, train.channel_mse(selection, estimate.values)))),
                        dict(zip(model.channels, map(float, validation.channel_mse(selection, estimate.values)))),
                        fixed, {}, estimate, tuple(implausible_estimates(rival, estimate)))
    return fit


def summed_runner_up(model: IdentificationModel, train: ChannelSums, validation: ChannelSums, found: Any,
                     outcome: RunnerUpOutcome, chosen: Sequence[int], after: Any) -> tuple[RunnerUp | None, str | None]:
    """The streamed diagnosis's runner-up, or why it has none (:func:`estimation.diagnosis.runner_up.fit_runner_up`):
    ``found`` the candidates with columns in the sums (their ``blocks``, ``columns``, fixed ``shapes``),
    ``chosen`` the candidates of the final estimate ``after``."""
    final = build_model(model.robot, model.kind, tuple(model.effects) + tuple(found.blocks[i].effect for i in chosen))
    fitter = summed_rival_fitter(model, train, validation, found.blocks, found.columns, found.shapes)
    return fit_runner_up(model, outcome, found.blocks, final, after, fitter)
