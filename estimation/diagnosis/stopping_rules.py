"""When the diagnosis's forward selection stops: what the rule sees before each round, and the rules.

The noise floor is the yardstick (:mod:`estimation.uncertainty.noise_floor`): :func:`floor_stopping_rule`
keeps :func:`estimation.diagnosis.search.diagnose` searching while some channel's validation MSE, against
the channels as recorded, is significantly above its floor; without a floor
:func:`provisional_stopping_rule` lets the search run until nothing is significant and confirmed.
A user's own rule is any ``rule(SearchState) -> bool``.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from estimation.diagnosis.statistics import FLOOR_ALPHA
from dynamics.measurements import Measurements
from estimation.uncertainty.noise_floor import NoiseFloor, above_floor


@dataclass(frozen=True)
class SearchState:
    """What the stopping rule sees before each round of the search.

    Attributes
    ----------
    channels
        Channel names.
    train_residuals, validate_residuals
        ``(N, m)`` residuals of the current model (fitted on training) on each record.
    train, validate
        The measurements.
    added
        Effects added so far.
    """

    channels: tuple[str, ...]
    train_residuals: NDArray[np.float64]
    validate_residuals: NDArray[np.float64]
    train: Measurements
    validate: Measurements
    added: tuple[str, ...]


def provisional_stopping_rule(state: SearchState) -> bool:
    """The rule without a noise floor: always ``True`` (keep searching); the search then stops when
    no candidate is significant on training and confirmed on validation."""
    return True


def floor_stopping_rule(floor: NoiseFloor, *, alpha: float = FLOOR_ALPHA) -> Callable[[SearchState], bool]:
    """The noise floor as the stopping rule: ``True`` (keep searching) while some channel's
    validation MSE against the channels as recorded is significantly above its floor
    (:func:`estimation.uncertainty.noise_floor.above_floor`, an F test at ``alpha``)."""
    def rule(state: SearchState) -> bool:
        residual = state.validate_residuals  # (N, m)
        mse = {channel: float(np.mean(residual[:, index] ** 2)) for index, channel in enumerate(state.channels)}
        return any(above_floor(mse, floor, residual.shape[0], alpha=alpha).values())
    return rule
