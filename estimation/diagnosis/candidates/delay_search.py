"""The delay candidate's state through the rounds of a diagnosis (:mod:`estimation.diagnosis.candidates.delay`).

First round: the delay searched on its whole grid; later rounds: screened at its last optimum (one evaluation)
and searched again near it only when it ranks among the best candidates, as the shaped candidates are
(:data:`estimation.diagnosis.rules.selection_rules.SCREEN_REFINED`). The search on the grid and the screen depend on
no other candidate's fit: they may run ahead, beside the round's other fits (:meth:`DelaySearch.ahead_task`). Once
adopted, the training and validation motions are moved by it for the rest of the search.
"""

from __future__ import annotations

import dataclasses
import functools
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from estimation.diagnosis.candidates.delay import (
    DelayComparison,
    DelayTrial,
    MovedColumns,
    Regressor,
    around,
    at_bound,
    channels_made_worse,
    compare_delay,
    current_columns,
    delay_trial,
    screen_delay,
    search_delay,
    try_delay,
)
from dynamics.measurements import Measurements
from dynamics.models import IdentificationModel
from estimation.preprocessing.delay import DELAY, DelayBounds, delayed, longest_piece
from estimation.identification.delayed import DelayFit
from estimation.identification.shaped import ShapeValue
from estimation.estimators.effect_blocks import Block
from estimation.estimators.separable_least_squares import FixedPart

#: a screened delay is searched again when fewer than this many candidates rank above it
REFINED_RANK = 2


@dataclass(frozen=True)
class SearchedAhead:
    """A round's first delay step run ahead (:meth:`DelaySearch.ahead_task`), the search on the whole grid or the
    screen at the last optimum: its outcome, the current model's blocks, shapes and weights it was run at, and
    the last optimum, RSS and column count it started from."""

    blocks: tuple[Block, ...]
    shapes: tuple[NDArray[np.float64], ...]
    weights: NDArray[np.float64]
    start: tuple[float | None, float, int]  # (last optimum, current RSS, current columns)
    outcome: DelayFit | DelayTrial | str

    def searched_at(self, blocks: Sequence[Block], shapes: Sequence[NDArray[np.float64]],
                    weights: NDArray[np.float64], start: tuple[float | None, float, int]) -> bool:
        """Whether it was run at these very objects (the round's current model and weights) from this start."""
        given, kept = (*blocks, *shapes, weights), (*self.blocks, *self.shapes, self.weights)
        return (len(given) == len(kept) and all(first is second for first, second in zip(given, kept))
                and start == self.start)


class DelaySearch:
    """The delay candidate of one diagnosis: its last optimum, why it was not adopted, or the adopted trial."""

    def __init__(self, train: Measurements, recorded: Measurements, regressor: Regressor,
                 bounds: DelayBounds | None) -> None:
        self.train, self.recorded, self.regressor, self.bounds = train, recorded, regressor, bounds
        self.duration = longest_piece(train)
        self.previous: float | None = None
        self.reason: str | None = None
        self.adopted: DelayTrial | None = None
        self.tried = False
        self.ahead: SearchedAhead | None = None  # the round's first step run ahead, until the round's trial takes it
        self.moved: MovedColumns | str | None = None  # the declared columns along the last optimum's moved motion

    def _columns(self, blocks: Sequence[Block], shapes: Sequence[NDArray[np.float64]], model) -> Regressor:
        return current_columns(self.regressor, blocks, shapes, model.n_channels)

    def searching(self) -> bool:
        """Whether a round tries the delay: asked for, not adopted, and its search never failed."""
        return (self.bounds is not None and self.adopted is None
                and not (self.reason or "").startswith("delay search failed"))

    def searching_grid(self) -> bool:
        """Whether this round's first step is the search on the whole grid (the first round's: costly)."""
        return self.searching() and self.previous is None

    def ahead_task(self, blocks: Sequence[Block], shapes: Sequence[NDArray[np.float64]], model: IdentificationModel,
                   weights: NDArray[np.float64], rss: float, n_fixed: int) -> Callable[[], DelayFit | DelayTrial | str] | None:
        """The first step of this round's :meth:`trials` as a task to run ahead (it depends on no other candidate's
        fit; its outcome goes to :meth:`keep_ahead`); ``None`` when this round tries no delay."""
        if not self.searching():
            return None
        return self._first_step(blocks, shapes, model, weights, rss, n_fixed)

    def keep_ahead(self, outcome: DelayFit | DelayTrial | str, blocks: Sequence[Block],
                   shapes: Sequence[NDArray[np.float64]], weights: NDArray[np.float64], rss: float, n_fixed: int) -> None:
        """Keep an :meth:`ahead_task`'s outcome for this round's :meth:`trials` (at the same model, weights and start)."""
        self.ahead = SearchedAhead(tuple(blocks), tuple(shapes), weights, (self.previous, rss, n_fixed), outcome)

    def _first_step(self, blocks: Sequence[Block], shapes: Sequence[NDArray[np.float64]], model: IdentificationModel,
                    weights: NDArray[np.float64], rss: float, n_fixed: int) -> Callable[[], DelayFit | DelayTrial | str]:
        """A round's first step as a task: the search on the whole grid (first round), else the screen at the
        last optimum (from the declared columns along its moved motion, made once for that delay)."""
        channels = tuple(model.channels)
        if self.previous is None:
            return functools.partial(search_delay, self._columns(blocks, shapes, model), self.train, channels,
                                     weights, self.bounds)
        if not isinstance(self.moved, MovedColumns) or self.moved.delay != self.previous:
            self.moved = MovedColumns.along(self.regressor, self.train, channels, self.previous)
        return functools.partial(screen_delay, self.moved, tuple(blocks), tuple(shapes), weights, rss,
                                 self.train.n_samples * len(channels), n_fixed)

    def trials(self, blocks, shapes, model, weights, rss: float, n_fixed: int, others) -> list[DelayTrial]:
        """This round's delay trial (none once adopted, failed, or not asked for): its first step as run ahead at this
        model, these weights and this start, else now."""
        if not self.searching():
            return []
        self.tried = True
        columns, channels = self._columns(blocks, shapes, model), tuple(model.channels)
        ahead, self.ahead = self.ahead, None
        outcome = (ahead.outcome if ahead is not None and ahead.searched_at(blocks, shapes, weights,
                                                                            (self.previous, rss, n_fixed))
                   else self._first_step(blocks, shapes, model, weights, rss, n_fixed)())
        if self.previous is None:
            trial = delay_trial(outcome, self.train, channels, rss, n_fixed)
        else:
            trial = outcome
            if not isinstance(trial, str) and sum(other.bic < trial.bic for other in others) < REFINED_RANK:
                trial = try_delay(columns, self.train, channels, weights, rss, n_fixed,
                                  around(self.previous, self.bounds, self.duration))
        if isinstance(trial, str):
            self.reason = trial
            return []
        self.previous = trial.delay
        return [trial]

    def confirm(self, trial: DelayTrial, blocks, shapes, model, fixed_train: FixedPart, fixed_validate: FixedPart,
                weights: NDArray[np.float64], min_improvement: float) -> DelayComparison | None:
        """The comparison on held-out data when the delay is confirmed, else ``None`` (the reason kept)."""
        text = f"significant on training (p = {trial.p_value:.2g}) but "
        if at_bound(trial, self.bounds, self.duration):
            self.reason = text + f"it stopped at a bound of the search ({trial.delay:.4g} s): the data ask for another effect"
            return None
        outcome = compare_delay(trial, self._columns(blocks, shapes, model), self.train, self.recorded,
                                tuple(model.channels), fixed_train, fixed_validate, weights)
        comparison = outcome.comparison
        if comparison.error >= (1.0 - min_improvement) * comparison.current_error:
            change = ("raises the validation error" if comparison.error > comparison.current_error else
                      f"lowers the validation error by less than {100 * min_improvement:g} %")
            self.reason = text + f"{change} ({comparison.current_error:.4g} -> {comparison.error:.4g})"
            return None
        worse = channels_made_worse(comparison, min_improvement, model.channels)
        if worse:
            self.reason = text + f"raises the validation error of {worse}"
            return None
        return outcome

    def adopt(self, trial: DelayTrial) -> tuple[Measurements, Measurements]:
        """Adopt the delay: the training and validation records along the moved motion."""
        self.adopted, self.moved = trial, None  # the search goes on along the moved records: no screens left
        return delayed(self.train, trial.delay), delayed(self.recorded, trial.delay)

    def final_bounds(self) -> DelayBounds | None:
        """What the final fit searches the delay in (``None``: no delay adopted)."""
        return None if self.adopted is None else self.bounds

    def adopted_value(self) -> ShapeValue | None:
        if self.adopted is None:
            return None
        window = self.bounds.within(self.duration)
        return ShapeValue(DELAY, DELAY, self.adopted.delay, self.adopted.fit.std, window.lower, window.upper)

    def not_adopted_reason(self, untested: str) -> str | None:
        """Why the delay is not in the model (``None`` when adopted or not asked for); ``untested``: what
        to say when no round tried it."""
        if self.bounds is None or self.adopted is not None:
            return None
        if not self.tried:
            return untested
        return self.reason or "not significant"


def with_delay(result, value: ShapeValue | None):
    """``result`` carrying the delay ``value`` (when the fit that made it ran along moved records)."""
    if value is None or result.delay is not None:
        return result
    return dataclasses.replace(result, delay=value, shapes=tuple(result.shapes) + (value,))
