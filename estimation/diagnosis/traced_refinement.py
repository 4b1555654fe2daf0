"""Residual tracing ranks the candidates whose shapes are searched again in a round of the diagnosis.

After the first round a diagnosis screens every shaped candidate at its last optimum (one linear
solve) and searches the shapes again only for the best few by BIC
(:data:`estimation.diagnosis.rules.selection_rules.SCREEN_REFINED`). A law whose last optimum is far from where the
current residual wants it can rank low at that stale shape although its variable is what the residual
follows. The tracing (:mod:`estimation.uncertainty.residual_tracing`: binned conditional means fitted on the
training residual, their share confirmed on the validation residual) names that variable; the
candidate whose variables explain most of its channel's validation residual is searched again too,
when that share is at least :data:`estimation.uncertainty.residual_tracing.MIN_SHARE`. Adoption stays with the F
test, BIC and the validation record, which judge the fitted law itself.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from dynamics.measurements import Measurements
from estimation.uncertainty.residual_tracing import (
    DEFAULT_BINS,
    MIN_SHARE,
    ResidualTrace,
    rank_candidates,
    trace_residuals,
)


def current_trace(channels: Sequence[str], train: Measurements, validate: Measurements,
                  train_residual: NDArray[np.float64], validate_residual: NDArray[np.float64]) -> ResidualTrace | None:
    """The tracing of the current model's ``(m, N)`` residuals on both records (``None``: the records are too
    short to trace)."""
    if train.n_samples < 5 * DEFAULT_BINS or validate.n_samples < DEFAULT_BINS:
        return None
    return trace_residuals(train_residual.T, train, validate_residual.T, validate, list(channels))


def traced_first(trials: Sequence, trace: ResidualTrace | None, n_joints: int) -> tuple[int, ...] | None:
    """The group of the shaped trial the tracing of the current residuals (:func:`current_trace`) ranks first
    (``None``: none explains :data:`MIN_SHARE` of its channel's validation residual, or there was no tracing)."""
    shaped = [trial for trial in trials if trial.fit.shape.size]
    if not shaped or trace is None:
        return None
    ranked = rank_candidates(trace, [trial.blocks[0].effect for trial in shaped], n_joints)
    effect, share, _ = ranked[0]
    if share < MIN_SHARE:
        return None
    return next(trial.group for trial in shaped if trial.blocks[0].effect is effect)
