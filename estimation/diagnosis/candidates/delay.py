"""The delay between torques and motion as a candidate of the diagnosis (:mod:`estimation.preprocessing.delay`).

A delay is not a column block: it moves the motion every column is evaluated along. In a round of
the diagnosis it is fitted on the current columns (the base regressor and the effects already
added, at their shapes; :func:`estimation.identification.delayed.fit_delay`) and competes with the
column candidates on the same terms: the nested F test with one parameter, BIC, and confirmation on
the held-out record moved by the same delay (one measurement chain), both models trained and compared
at the weights the candidate's own residuals give. Once adopted, the search goes on along the
delayed motion.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from estimation.diagnosis.candidates.trials import nested_test, weighted_error
from estimation.diagnosis.confirmation import CandidateComparison, settled_weights
from estimation.identification.delayed import DelayFit, fit_delay
from dynamics.measurements import Measurements
from estimation.preprocessing.delay import DELAY, DelayBounds, delayed
from estimation.estimators.effect_blocks import Block, States
from estimation.estimators.separable_least_squares import FixedPart, solve_linear

Regressor = Callable[[Measurements], NDArray[np.float64]]


def current_columns(regressor: Regressor, blocks: Sequence[Block], shapes: Sequence[NDArray[np.float64]],
                    n_channels: int) -> Regressor:
    """The current model's columns along a record: the regressor and each added block at its shape."""

    def columns(record: Measurements) -> NDArray[np.float64]:
        Y = np.asarray(regressor(record))
        if not blocks:  # the declared columns alone: no copy of them
            return Y
        states = States(record.q, record.dq, record.ddq)
        parts = [Y]
        for block, shape in zip(blocks, shapes):
            extra = np.zeros((record.n_samples, n_channels, block.n_linear))
            extra[:, list(block.rows), :] = block.evaluate(states, shape)
            parts.append(extra)
        return np.concatenate(parts, axis=2)

    return columns


@dataclass(frozen=True)
class DelayTrial:
    """The delay fitted against the current columns, with the statistics the ranking needs."""

    fit: DelayFit
    rss: float
    f_statistic: float
    p_value: float
    bic: float
    group: tuple[str, ...] = (DELAY,)

    @property
    def delay(self) -> float:
        return self.fit.delay


def search_delay(columns: Regressor, train: Measurements, channels: tuple[str, ...], weights: NDArray[np.float64],
                 bounds: DelayBounds) -> DelayFit | str:
    """The delay fitted in ``bounds`` against the current columns (:func:`estimation.identification.delayed.fit_delay`),
    or why it cannot be fitted here."""
    try:
        return fit_delay(columns, train, channels, weights, bounds)
    except (np.linalg.LinAlgError, FloatingPointError, ValueError) as error:
        return f"delay search failed: {error}"


def delay_trial(fit: DelayFit | str, train: Measurements, channels: tuple[str, ...], rss: float,
                n_fixed: int) -> DelayTrial | str:
    """The trial of a searched delay: its nested F test and BIC against the current model's weighted RSS
    ``rss`` with ``n_fixed`` columns (the reason passed on when the search failed)."""
    if isinstance(fit, str):
        return fit
    return DelayTrial(fit, fit.rss, *nested_test(rss, fit.rss, 1, train.n_samples * len(channels), n_fixed))


def try_delay(columns: Regressor, train: Measurements, channels: tuple[str, ...], weights: NDArray[np.float64],
              rss: float, n_fixed: int, bounds: DelayBounds) -> DelayTrial | str:
    """The delay trial searched in ``bounds``, or why it cannot be fitted here."""
    return delay_trial(search_delay(columns, train, channels, weights, bounds), train, channels, rss, n_fixed)


@dataclass(frozen=True)
class DelayComparison:
    """The delayed model against the current one on held-out data (:class:`CandidateComparison`), and the
    delayed records' fixed parts, should it be adopted."""

    comparison: CandidateComparison
    fixed_train: FixedPart
    fixed_validate: FixedPart


def compare_delay(trial: DelayTrial, columns: Regressor, train: Measurements, recorded: Measurements,
                  channels: tuple[str, ...], fixed_train: FixedPart, fixed_validate: FixedPart,
                  weights: NDArray[np.float64]) -> DelayComparison:
    """Both models trained at the weights the delayed model's residuals give; validation errors against
    the validation channels as recorded, along the validation motion moved by the same delay."""
    moved_train, moved_validate = delayed(train, trial.delay), delayed(recorded, trial.delay)
    candidate_train = FixedPart.from_arrays(columns(moved_train), moved_train.channels(list(channels)),
                                            fixed_train.band)
    candidate_validate = FixedPart.from_arrays(columns(moved_validate), moved_validate.channels(list(channels)))
    settled = settled_weights(candidate_train, [], None, [], weights)
    candidate = solve_linear(candidate_train, [], None, [], settled)
    error, residual = weighted_error(candidate_validate, [], None, [], candidate.theta, settled)
    current = solve_linear(fixed_train, [], None, [], settled)
    current_error, current_residual = weighted_error(fixed_validate, [], None, [], current.theta, settled)
    return DelayComparison(CandidateComparison(settled, error, residual, current_error, current_residual),
                           candidate_train, candidate_validate)


def channels_made_worse(comparison: CandidateComparison, tolerance: float, channels: Sequence[str]) -> str:
    """Every channel whose validation MSE the delay raises by more than ``tolerance`` (it acts on all)."""
    before = np.mean(comparison.current_residual**2, axis=1)
    after = np.mean(comparison.residual**2, axis=1)
    return ", ".join(f"{channel} ({b:.4g} -> {a:.4g})" for channel, b, a in zip(channels, before, after)
                     if a > (1.0 + tolerance) * b)


@dataclass(frozen=True)
class MovedColumns:
    """The declared columns along the training motion moved by one delay, and the moved states: what the screens
    of that delay share while it stays the last optimum (only the adopted blocks are evaluated again)."""

    delay: float
    states: States
    declared: FixedPart

    @classmethod
    def along(cls, regressor: Regressor, train: Measurements, channels: tuple[str, ...], delay: float
              ) -> MovedColumns | str:
        """The columns along the motion moved by ``delay``, or why they cannot be had."""
        moved = delayed(train, delay)
        try:
            declared = FixedPart.from_arrays(np.asarray(regressor(moved)), moved.channels(list(channels)))
        except (np.linalg.LinAlgError, FloatingPointError) as error:
            return f"delay search failed: {error}"
        return cls(delay, States(moved.q, moved.dq, moved.ddq), declared)


def screen_delay(moved: MovedColumns | str, blocks: Sequence[Block], shapes: Sequence[NDArray[np.float64]],
                 weights: NDArray[np.float64], rss: float, n_rows: int, n_fixed: int) -> DelayTrial | str:
    """The delay trial at its last optimum (one evaluation: a screening, as for the shaped candidates): the adopted
    ``blocks`` at their ``shapes`` evaluated along the moved motion beside the declared columns kept for it."""
    if isinstance(moved, str):
        return moved
    try:
        value = solve_linear(moved.declared.with_blocks(blocks, moved.states, shapes), [], None, [], weights).rss
    except (np.linalg.LinAlgError, FloatingPointError) as error:
        return f"delay search failed: {error}"
    empty = np.zeros(0)
    fit = DelayFit(moved.delay, float("nan"), float(value), float("nan"), empty, empty, empty)
    return DelayTrial(fit, float(value), *nested_test(rss, float(value), 1, n_rows, n_fixed))


def around(delay: float, bounds: DelayBounds, duration: float) -> DelayBounds:
    """A local search window: two grid steps either side of ``delay``, within ``bounds``."""
    window = bounds.within(duration)
    step = (window.upper - window.lower) / (window.points - 1)
    lower, upper = max(window.lower, delay - 2 * step), min(window.upper, delay + 2 * step)
    return DelayBounds(lower, upper, 5)


def at_bound(trial: DelayTrial, bounds: DelayBounds, duration: float) -> bool:
    window = bounds.within(duration)
    return min(trial.delay - window.lower, window.upper - trial.delay) <= 1e-4 * (window.upper - window.lower)
