"""The in-memory diagnosis's fits (:class:`estimation.diagnosis.search_fits.Fits` on the records).

The current model's columns on each record are a :class:`~estimation.estimators.variable_projection.FixedPart`
(per-channel Gram matrices): the declared model's columns and each adopted block at its shape; the
model without an adopted effect (a replacement's or a removal's) is built the same way. A candidate is
fitted against them by :func:`estimation.diagnosis.candidates.trials.fit_or_reason` (the linear solve, or
variable projection for a shaped law): in the first round every shape is searched from its grid,
later rounds screen it at its last optimum and search again only the :data:`SCREEN_REFINED` best and
the one the residual tracing ranks first (:mod:`estimation.diagnosis.traced_refinement`). The delay
between torques and motion is a candidate here too (:class:`estimation.diagnosis.candidates.delay_search.DelaySearch`):
once adopted, the records move by it. The Wald tests of the search are from the HAC covariance of the
declared columns plus the blocks at their shapes, shape directions included
(:func:`estimation.diagnosis.rules.robust_test.fit_covariance`).
"""

from __future__ import annotations

import dataclasses
import functools
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import TypeVar

import numpy as np
from numpy.typing import NDArray

from dynamics.measurements import Measurements
from dynamics.models import IdentificationModel
from dynamics.runtime.processes import run_tasks, worker_count
from estimation.diagnosis.candidates.trials import Trial, fit_or_reason, weighted_error
from estimation.diagnosis.confirmation import (CandidateComparison, HeldOutBlocks, blocked_comparison, unseen_veto,
                                               removal_comparison, reweighted_comparison)
from estimation.diagnosis.candidates.delay import DelayComparison, DelayTrial, Regressor
from estimation.diagnosis.candidates.delay_search import DelaySearch
from estimation.diagnosis.search_fits import AdoptedEffect, TrialRequest, TrialTest
from estimation.diagnosis.rules.robust_test import WaldTest, fit_covariance, wald_test
from estimation.diagnosis.rules.selection_rules import SCREEN_REFINED, refine_best
from estimation.diagnosis.rules.stopping_rules import SearchState
from estimation.diagnosis.traced_refinement import current_trace, traced_first
from estimation.estimators.identification_problem import ResidualBand
from estimation.estimators.effect_blocks import Block, States
from estimation.estimators.separable_least_squares import FixedPart, residuals, solve_linear
from estimation.estimators.variable_projection import ShapeFit
from estimation.identification.fit import IdentificationResult
from estimation.identification.repeated_motion import REPEAT_FRACTION, repeated_motion, still_motion
from estimation.preprocessing.delay import DelayBounds

__all__ = ["MIN_PARALLEL_SEARCHES", "RecordFit", "RecordFits", "declared_regressor"]

T = TypeVar("T")

#: fewest shape searches from their grids (tens of ms each) in a round for its fits to run in a process pool; a
#: round of screens at the last optimum (~1 ms a fit) runs in turn: the fork and its copied pages cost more
MIN_PARALLEL_SEARCHES = 4


@dataclass(frozen=True)
class RecordFit:
    """The current model fitted on training: weighted RSS, weighted validation MSE and the ``(m, N)``
    residuals on each record."""

    rss: float
    validation_error: float
    train_residual: NDArray[np.float64]
    validate_residual: NDArray[np.float64]


def _base_regressor(model: IdentificationModel, data: Measurements) -> NDArray[np.float64]:
    return model.evaluate_base(data.q, data.dq, data.ddq)


def declared_regressor(model: IdentificationModel, before: IdentificationResult) -> Regressor:
    """The declared model's columns along a record (its shaped laws at the shapes ``before`` found)."""
    if before.shaped_fit is not None:
        return before.shaped_fit.regressor
    return functools.partial(_base_regressor, model)


class RecordFits:
    """Fits of column blocks on the training record and errors on the validation record (as recorded).

    Parameters
    ----------
    model
        The declared model.
    regressor
        Its columns along a record (:func:`declared_regressor`).
    train, recorded
        The training record and the validation record as recorded, along the derived motion.
    delay
        Where the delay candidate is searched (``None``: not tried).
    stopping_rule
        ``rule(SearchState) -> bool``: keep searching while ``True``.
    shaped
        Whether the declared model has shaped laws (the final fit's covariance is then the batch-means
        sandwich: :mod:`estimation.diagnosis.rules.robust_test`).
    jobs
        Processes that fit a round's candidates side by side (``None``: the available cores;
        :func:`dynamics.runtime.processes.worker_count`).
    unseen_stretches
        When the validation record repeats the training motion
        (:func:`estimation.identification.repeated_motion.repeated_motion`), refuse a candidate that raises the
        error on the stretches of the motion its fit did not see (:func:`estimation.diagnosis.confirmation.unseen_veto`).
    """

    def __init__(self, model: IdentificationModel, regressor: Regressor, train: Measurements, recorded: Measurements,
                 delay: DelayBounds | None, stopping_rule: Callable[[SearchState], bool], shaped: bool = False,
                 jobs: int | None = 1, unseen_stretches: bool = False) -> None:
        self.model, self.stopping_rule, self.regressor, self.shaped = model, stopping_rule, regressor, shaped
        self.jobs, self.unseen_stretches = jobs, unseen_stretches
        self.adopted: tuple[AdoptedEffect, ...] = ()
        self._move(train, recorded)
        self.delay = DelaySearch(train, recorded, regressor, delay)  # the delay and, once adopted, the moved records
        self.previous: dict[tuple[int, ...], ShapeFit] = {}  # each group's last optimum

    def _move(self, train: Measurements, recorded: Measurements) -> None:
        """The records (moved by an adopted delay) and the declared model's columns along them."""
        self.train, self.recorded = train, recorded
        # each candidate's block keeps its latest columns along them: a plain candidate's, or one screened at its last
        # optimum, are the same round after round
        self.states_train = States(train.q, train.dq, train.ddq, kept=True)
        self.states_validate = States(recorded.q, recorded.dq, recorded.ddq, kept=True)
        self.declared = FixedPart.from_arrays(self.regressor(train), train.channels(self.model.channels),
                                              ResidualBand.of(train))  # the weights from the residual in the band
        self.declared_validate = FixedPart.from_arrays(self.regressor(recorded), recorded.channels(self.model.channels))
        # a validation record that repeats the training motion confirms on stretches of it the fits did not see
        self.held_out = HeldOutBlocks.of(train.t, recorded.t, train.metadata.get("frequency_hz")) \
            if self.unseen_stretches and repeated_motion(train, recorded) <= REPEAT_FRACTION else None
        # a validation record at rest measures little of the dynamics: a candidate is judged on the stretches of the
        # training record its fit did not see
        self.own_stretches = HeldOutBlocks.of(train.t, train.t, train.metadata.get("frequency_hz")) \
            if still_motion(train, recorded) else None
        self.set_model(self.adopted)

    @property
    def n_rows(self) -> int:
        return self.fixed_train.n_rows

    def _columns(self, without: tuple[int, ...] = ()) -> tuple[FixedPart, FixedPart]:
        """The (training, validation) columns of the current model without the adopted ``without`` (the
        current model's columns, their Gram matrices and moments with those of ``without`` left out)."""
        if without not in self.reduced:
            keep, start = list(range(self.declared.n_fixed)), self.declared.n_fixed
            for item in self.adopted:
                if item.index not in without:
                    keep.extend(range(start, start + item.block.n_linear))
                start += item.block.n_linear
            self.reduced[without] = tuple(fixed.kept(keep) for fixed in self.reduced[()])
        return self.reduced[without]

    @staticmethod
    def _fixed(declared: FixedPart, states: States, adopted: Sequence[AdoptedEffect]) -> FixedPart:
        """The declared columns extended by each adopted block at its shape (its channels' products alone)."""
        return declared.with_blocks([item.block for item in adopted], states, [item.shape for item in adopted])

    def set_model(self, adopted: Sequence[AdoptedEffect]) -> None:
        """The current model: the declared columns and the adopted blocks at their shapes."""
        self.adopted = tuple(adopted)
        self.fixed_train, self.fixed_validate = (self._fixed(self.declared, self.states_train, self.adopted),
                                                 self._fixed(self.declared_validate, self.states_validate, self.adopted))
        self.reduced: dict[tuple[int, ...], tuple[FixedPart, FixedPart]] = {(): (self.fixed_train, self.fixed_validate)}

    def fit_current(self, weights: NDArray[np.float64], without: tuple[int, ...] = ()) -> RecordFit:
        fixed_train, fixed_validate = self._columns(without)
        solution = solve_linear(fixed_train, [], self.states_train, [], weights)
        validation_error, validate_residual = weighted_error(fixed_validate, [], self.states_validate, [],
                                                             solution.theta, weights)
        return RecordFit(solution.rss, validation_error, residuals(fixed_train, [], solution), validate_residual)

    def keep_searching(self, current: RecordFit, added: tuple[str, ...]) -> bool:
        return self.stopping_rule(SearchState(self.model.channels, current.train_residual.T,
                                              current.validate_residual.T, self.train, self.recorded, added))

    def trial(self, group: tuple[int, ...], members: Sequence[Block], weights: NDArray[np.float64],
              rss: float, without: tuple[int, ...] = ()) -> Trial | str:
        """The group fitted against the current columns (without the adopted ``without``; a shape
        screened at its last optimum once it has one)."""
        outcome = fit_or_reason(group, members, self._columns(without)[0], self.states_train, weights, rss,
                                self.previous.get(group), search=False)
        if isinstance(outcome, str):
            return outcome
        self.previous[group] = outcome.fit
        return dataclasses.replace(outcome, without=without)

    def trials(self, requests: Sequence[TrialRequest], weights: NDArray[np.float64], current: RecordFit
               ) -> list[Trial | str]:
        """:meth:`trial` of each request, the round's first delay step before them
        (:meth:`~estimation.diagnosis.candidates.delay_search.DelaySearch.ahead_task`: it depends on no candidate's
        fit), side by side in ``jobs`` processes when the round has at least :data:`MIN_PARALLEL_SEARCHES` costly fits
        (:func:`dynamics.runtime.processes.run_tasks`: the same results, in order): the shapes searched from their
        grids and the delay's search on its whole grid, the longest (a later round's screens, ~1 ms each, run in
        turn: a fork's copied pages cost more than the second core gives back)."""
        blocks, shapes = [item.block for item in self.adopted], [item.shape for item in self.adopted]
        start = (current.rss, self.fixed_train.n_fixed)
        delay_task = self.delay.ahead_task(blocks, shapes, self.model, weights, *start)
        ahead = [] if delay_task is None else [delay_task]
        tasks = ahead + [self._trial_task(request, weights) for request in requests]
        searches = sum(self._searches(request) for request in requests) + self.delay.searching_grid()
        workers = worker_count(self.jobs, len(tasks)) if searches >= MIN_PARALLEL_SEARCHES else 1
        outcomes = run_tasks(tasks, workers, shared=[block for request in requests for block in request.members])
        if delay_task is not None:
            self.delay.keep_ahead(outcomes[0], blocks, shapes, weights, *start)
        return [self._kept(request, outcome) for request, outcome in zip(requests, outcomes[len(ahead):])]

    def side_by_side(self, tasks: Sequence[Callable[[], T]]) -> list[T]:
        """``[task() for task in tasks]`` in ``jobs`` processes (:func:`dynamics.runtime.processes.run_tasks`: the same
        results, in order): the confirmations of a round on the validation record
        (:meth:`~estimation.diagnosis.forward_selection.DiagnosisSearch.confirmed_ahead`, ~15 ms each on the Panda)."""
        return run_tasks(tasks, worker_count(self.jobs, len(tasks)))

    def _trial_task(self, request: TrialRequest, weights: NDArray[np.float64]) -> Callable[[], Trial | str]:
        """The request's fit against the current columns, as a task (:meth:`trial`'s, run anywhere)."""
        return functools.partial(fit_or_reason, request.group, request.members, self._columns(request.without)[0],
                                 self.states_train, weights, request.rss, self.previous.get(request.group),
                                 search=False)

    def _searches(self, request: TrialRequest) -> bool:
        """Whether the request searches a shape from its grid (no last optimum yet): a costly fit."""
        return self.previous.get(request.group) is None and any(block.n_shape for block in request.members)

    def _kept(self, request: TrialRequest, outcome: Trial | str) -> Trial | str:
        """A task's outcome as :meth:`trial` gives it: the shape kept as the group's last optimum."""
        if isinstance(outcome, str):
            return outcome
        self.previous[request.group] = outcome.fit
        return dataclasses.replace(outcome, without=request.without)

    def refine(self, trials: list[Trial], current: RecordFit, weights: NDArray[np.float64],
               first_round: bool) -> list[Trial]:
        """The best screened shapes, and the one the residual tracing ranks first, searched again
        (the first round searched every shape from its grid: no tracing needed)."""
        shaped = any(trial.fit.shape.size for trial in trials)
        traced = None if first_round or not shaped else traced_first(
            trials, current_trace(self.model.channels, self.train, self.recorded, current.train_residual,
                                  current.validate_residual), self.model.robot.n_joints)
        rss = {(): current.rss}

        def reference(trial: Trial) -> float:
            if trial.without not in rss:
                rss[trial.without] = self.fit_current(weights, trial.without).rss
            return rss[trial.without]

        return refine_best(trials, lambda trial: self._columns(trial.without)[0], self.states_train, weights,
                           reference, self.previous, SCREEN_REFINED, traced)

    def _robust(self, blocks: Sequence[Block], shapes: Sequence[NDArray[np.float64]], weights: NDArray[np.float64]
                ) -> tuple[NDArray[np.float64], NDArray[np.float64], int]:
        """``(θ, cov θ, n_declared)`` of the declared columns plus ``blocks`` at ``shapes``, the HAC
        covariance of the final fit (the shape directions of every shaped block included)."""
        shaped = self.shaped or any(block.n_shape for block in blocks)
        theta, cov = fit_covariance(self.declared, blocks, self.states_train, shapes, weights, shaped=shaped)
        return theta, cov, self.declared.n_fixed

    def test(self, trial: Trial, weights: NDArray[np.float64]) -> TrialTest:
        """The Wald test of the trial's block from the HAC covariance of its model's fit."""
        kept = [item for item in self.adopted if item.index not in trial.without]
        theta, cov, _ = self._robust([item.block for item in kept] + list(trial.blocks),
                                     [item.shape for item in kept] + trial.shapes(), weights)
        block = slice(theta.shape[0] - sum(block.n_linear for block in trial.blocks), theta.shape[0])
        return TrialTest(wald_test(theta[block], cov[block, block]), np.sqrt(np.clip(np.diag(cov)[block], 0.0, None)))

    def current_tests(self, weights: NDArray[np.float64]) -> dict[int, WaldTest]:
        """Each adopted effect's Wald test in the current model (HAC covariance)."""
        theta, cov, start = self._robust([item.block for item in self.adopted], [item.shape for item in self.adopted],
                                         weights)
        tests = {}
        for item in self.adopted:
            block = slice(start, start + item.block.n_linear)
            tests[item.index] = wald_test(theta[block], cov[block, block])
            start = block.stop
        return tests

    def compare(self, trial: Trial, weights: NDArray[np.float64]) -> CandidateComparison:
        fixed_train, fixed_validate = self._columns(trial.without)
        repeat = reweighted_comparison(trial, fixed_train, fixed_validate, self.states_train, self.states_validate,
                                       weights, current=(self.fixed_train, self.fixed_validate))
        if self.own_stretches is not None:
            return blocked_comparison(trial, fixed_train, fixed_train, self.states_train, self.states_train,
                                      repeat.weights, self.own_stretches, current=(self.fixed_train, self.fixed_train),
                                      held_out="the stretches of the training record its fit did not see (the "
                                               "validation record hardly moves)")
        if self.held_out is None:
            return repeat
        return unseen_veto(repeat, blocked_comparison(trial, fixed_train, fixed_validate, self.states_train,
                                                      self.states_validate, repeat.weights, self.held_out,
                                                      current=(self.fixed_train, self.fixed_validate)))

    def removal(self, without: tuple[int, ...], weights: NDArray[np.float64]) -> CandidateComparison:
        return removal_comparison(*self._columns(without), self.fixed_train, self.fixed_validate, weights)

    @property
    def delay_adopted(self) -> bool:
        return self.delay.adopted is not None

    def delay_trials(self, adopted: Sequence[AdoptedEffect], weights: NDArray[np.float64], rss: float,
                     others: Sequence[Trial]) -> list[DelayTrial]:
        return self.delay.trials([a.block for a in adopted], [a.shape for a in adopted], self.model, weights, rss,
                                 self.fixed_train.n_fixed, others)

    def confirm_delay(self, trial: DelayTrial, adopted: Sequence[AdoptedEffect], weights: NDArray[np.float64],
                      min_improvement: float) -> DelayComparison | None:
        return self.delay.confirm(trial, [a.block for a in adopted], [a.shape for a in adopted], self.model,
                                  self.fixed_train, self.fixed_validate, weights, min_improvement)

    def adopt_delay(self, trial: DelayTrial, outcome: DelayComparison) -> CandidateComparison:
        """The records moved by the adopted delay, and its comparison."""
        self._move(*self.delay.adopt(trial))
        return outcome.comparison
