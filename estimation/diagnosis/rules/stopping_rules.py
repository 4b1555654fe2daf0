"""When the diagnosis's search stops early: what a stopping rule sees before each round, and the rules.

By default (:func:`provisional_stopping_rule`) :func:`estimation.diagnosis.search.diagnose` searches
until no move is significant and confirmed. The noise floor (:mod:`estimation.uncertainty.noise_floor`)
as a stopping rule, :func:`floor_stopping_rule`, keeps the search going only while some channel's
validation MSE, against the channels as recorded, is significantly above its floor: sooner, but blind
to an effect smaller than a test of the whole channel's error sees (an offset twelve standard
deviations from zero that leaves its channel 1.04 times its floor). A user's own rule is any
``rule(SearchState) -> bool``.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from estimation.diagnosis.statistics import FLOOR_ALPHA
from dynamics.measurements import Measurements
from estimation.uncertainty.noise_floor import NoiseFloor
from estimation.uncertainty.floor_comparison import above_floor


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
    """The default rule: always ``True`` (keep searching); the search then stops when no move is
    significant on training and confirmed on validation."""
    return True


def floor_stopping_rule(floor: NoiseFloor, *, alpha: float = FLOOR_ALPHA) -> Callable[[SearchState], bool]:
    """The noise floor as the stopping rule: ``True`` (keep searching) while some channel's
    validation MSE against the channels as recorded is significantly above its floor
    (:func:`estimation.uncertainty.floor_comparison.above_floor`, an F test at ``alpha``)."""
    def rule(state: SearchState) -> bool:
        residual = state.validate_residuals  # (N, m)
        mse = {channel: float(np.mean(residual[:, index] ** 2)) for index, channel in enumerate(state.channels)}
        return any(above_floor(mse, floor, residual.shape[0], alpha=alpha).values())
    return rule
