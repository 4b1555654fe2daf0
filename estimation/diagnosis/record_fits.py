"""The in-memory diagnosis's fits (:class:`estimation.diagnosis.forward_selection.Fits` on the records).

The current model's columns on each record are a :class:`~estimation.estimators.variable_projection.FixedPart`
(per-channel Gram matrices), extended by each adopted block at its shape. A candidate is fitted
against them by :func:`estimation.diagnosis.candidates.trials.fit_or_reason` (the linear solve, or
variable projection for a shaped law): in the first round every shape is searched from its grid,
later rounds screen it at its last optimum and search again only the :data:`SCREEN_REFINED` best and
the one the residual tracing ranks first (:mod:`estimation.diagnosis.traced_refinement`). The delay
between torques and motion is a candidate here too (:class:`estimation.diagnosis.candidates.delay_search.DelaySearch`):
once adopted, the records move by it.
"""

from __future__ import annotations

import functools
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from dynamics.measurements import Measurements
from dynamics.models import IdentificationModel
from estimation.diagnosis.candidates.trials import Trial, fit_or_reason, weighted_error
from estimation.diagnosis.confirmation import Comparison, reweighted_comparison
from estimation.diagnosis.candidates.delay import DelayComparison, DelayTrial, Regressor
from estimation.diagnosis.candidates.delay_search import DelaySearch
from estimation.diagnosis.forward_selection import AdoptedEffect
from estimation.diagnosis.selection_rules import SCREEN_REFINED, refine_best
from estimation.diagnosis.stopping_rules import SearchState
from estimation.diagnosis.traced_refinement import traced_first
from estimation.estimators.effect_blocks import Block, States
from estimation.estimators.separable_least_squares import FixedPart, residuals, solve_linear
from estimation.estimators.variable_projection import ShapeFit
from estimation.identification.fit import IdentificationResult
from estimation.preprocessing.delay import DelayBounds

__all__ = ["RecordFit", "RecordFits", "declared_regressor"]


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
    """

    def __init__(self, model: IdentificationModel, regressor: Regressor, train: Measurements, recorded: Measurements,
                 delay: DelayBounds | None, stopping_rule: Callable[[SearchState], bool]) -> None:
        self.model, self.stopping_rule = model, stopping_rule
        self.fixed_train = FixedPart.from_arrays(regressor(train), train.channels(model.channels))
        self.fixed_validate = FixedPart.from_arrays(regressor(recorded), recorded.channels(model.channels))
        self._move(train, recorded)
        self.delay = DelaySearch(train, recorded, regressor, delay)  # the delay and, once adopted, the moved records
        self.previous: dict[tuple[int, ...], ShapeFit] = {}  # each group's last optimum

    def _move(self, train: Measurements, recorded: Measurements) -> None:
        self.train, self.recorded = train, recorded
        self.states_train = States(train.q, train.dq, train.ddq)
        self.states_validate = States(recorded.q, recorded.dq, recorded.ddq)

    def fit_current(self, weights: NDArray[np.float64]) -> RecordFit:
        solution = solve_linear(self.fixed_train, [], self.states_train, [], weights)
        validation_error, validate_residual = weighted_error(self.fixed_validate, [], self.states_validate, [],
                                                             solution.theta, weights)
        return RecordFit(solution.rss, validation_error, residuals(self.fixed_train, [], solution), validate_residual)

    def keep_searching(self, current: RecordFit, added: tuple[str, ...]) -> bool:
        return self.stopping_rule(SearchState(self.model.channels, current.train_residual.T,
                                              current.validate_residual.T, self.train, self.recorded, added))

    def trial(self, group: tuple[int, ...], members: Sequence[Block], weights: NDArray[np.float64],
              rss: float) -> Trial | str:
        """The group fitted against the current columns (a shape screened at its last optimum once it has one)."""
        outcome = fit_or_reason(group, members, self.fixed_train, self.states_train, weights, rss,
                                self.previous.get(group), search=False)
        if not isinstance(outcome, str):
            self.previous[group] = outcome.fit
        return outcome

    def refine(self, trials: list[Trial], current: RecordFit, weights: NDArray[np.float64],
               first_round: bool) -> list[Trial]:
        """The best screened shapes, and the one the residual tracing ranks first, searched again
        (the first round searched every shape from its grid: no tracing needed)."""
        traced = None if first_round else traced_first(
            trials, self.model.channels, self.model.robot.n_joints, self.train, self.recorded, current.train_residual,
            current.validate_residual)
        return refine_best(trials, self.fixed_train, self.states_train, weights, current.rss, self.previous,
                           SCREEN_REFINED, traced)

    def compare(self, trial: Trial, weights: NDArray[np.float64]) -> Comparison:
        return reweighted_comparison(trial, self.fixed_train, self.fixed_validate, self.states_train,
                                     self.states_validate, weights)

    def extend(self, adopted: Sequence[AdoptedEffect]) -> None:
        for item in adopted:
            self.fixed_train = self.fixed_train.extended(item.block.evaluate(self.states_train, item.shape),
                                                         item.block.rows)
            self.fixed_validate = self.fixed_validate.extended(item.block.evaluate(self.states_validate, item.shape),
                                                               item.block.rows)

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

    def adopt_delay(self, trial: DelayTrial, outcome: DelayComparison) -> Comparison:
        """The records moved by the adopted delay, and its comparison."""
        self.fixed_train, self.fixed_validate = outcome.fixed_train, outcome.fixed_validate
        self._move(*self.delay.adopt(trial))
        return outcome.comparison
