"""What the diagnosis's search (:class:`estimation.diagnosis.forward_selection.DiagnosisSearch`) asks of
its fits: an effect of the current model, the current model's fit, the robust test of a trial, and the
:class:`Fits` protocol that the in-memory and the streamed diagnosis implement
(:class:`estimation.diagnosis.record_fits.RecordFits`, :class:`estimation.streaming.selection.SummedFits`)."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any, Protocol, TypeVar

import numpy as np
from numpy.typing import NDArray

from dynamics.effects.linear import Effect
from estimation.diagnosis.candidates.delay import DelayTrial
from estimation.diagnosis.candidates.trials import Trial
from estimation.diagnosis.confirmation import CandidateComparison
from estimation.diagnosis.rules.robust_test import WaldTest
from estimation.estimators.effect_blocks import Block

__all__ = ["AdoptedEffect", "CurrentFit", "Fits", "TrialRequest", "TrialTest"]

T = TypeVar("T")


@dataclass(frozen=True)
class AdoptedEffect:
    """One effect of the current model: candidate ``index``, its column block at ``shape``, and the
    Wald test of the move that adopted it (p-value, ``W / k``)."""

    index: int
    block: Block
    shape: NDArray[np.float64]
    p_value: float
    f_statistic: float

    @property
    def effect(self) -> Effect:
        return self.block.effect


@dataclass(frozen=True)
class TrialRequest:
    """A group to fit against the current model without the adopted ``without``, whose weighted RSS is
    ``rss``; or, when ``reason`` is given, why it is not fitted."""

    group: tuple[int, ...]
    members: tuple[Block, ...]
    rss: float
    without: tuple[int, ...] = ()
    reason: str | None = None


class CurrentFit(Protocol):
    """The current model fitted on training: its weighted RSS and weighted validation MSE."""

    rss: float
    validation_error: float


@dataclass(frozen=True)
class TrialTest:
    """The Wald test of a trial's block from the HAC covariance of its fit
    (:mod:`estimation.diagnosis.rules.robust_test`), and the standard deviations of the block's linear
    coefficients from that covariance."""

    wald: WaldTest
    std: NDArray[np.float64]


class Fits(Protocol):
    """How a search fits column blocks: from the records in memory or from summed normal equations.

    ``without``: candidate indices of adopted effects left out of the current model (a replacement's
    or a removal's model)."""

    @property
    def n_rows(self) -> int: ...

    def fit_current(self, weights: NDArray[np.float64], without: tuple[int, ...] = ()) -> CurrentFit: ...

    def keep_searching(self, current: CurrentFit, added: tuple[str, ...]) -> bool: ...

    def trial(self, group: tuple[int, ...], members: Sequence[Block], weights: NDArray[np.float64],
              rss: float, without: tuple[int, ...] = ()) -> Trial | str: ...

    def trials(self, requests: Sequence[TrialRequest], weights: NDArray[np.float64], current: CurrentFit
               ) -> list[Trial | str]: ...

    def refine(self, trials: list[Trial], current: CurrentFit, weights: NDArray[np.float64],
               first_round: bool) -> list[Trial]: ...

    def test(self, trial: Trial, weights: NDArray[np.float64]) -> TrialTest: ...

    def current_tests(self, weights: NDArray[np.float64]) -> dict[int, WaldTest]: ...

    def compare(self, trial: Trial, weights: NDArray[np.float64]) -> CandidateComparison: ...

    def removal(self, without: tuple[int, ...], weights: NDArray[np.float64]) -> CandidateComparison: ...

    def set_model(self, adopted: Sequence[AdoptedEffect]) -> None: ...

    @property
    def delay_adopted(self) -> bool: ...

    def delay_trials(self, adopted: Sequence[AdoptedEffect], weights: NDArray[np.float64], rss: float,
                     others: Sequence[Trial]) -> list[DelayTrial]: ...

    def confirm_delay(self, trial: DelayTrial, adopted: Sequence[AdoptedEffect], weights: NDArray[np.float64],
                      min_improvement: float) -> Any: ...

    def adopt_delay(self, trial: DelayTrial, outcome: Any) -> CandidateComparison: ...

    def side_by_side(self, tasks: Sequence[Callable[[], T]]) -> list[T]:
        """``[task() for task in tasks]``, side by side where the fits may use several processes (the same results,
        in order)."""
        ...
