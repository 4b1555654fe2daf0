"""The diagnosis's linear candidate tests from accumulated sums (bounded memory).

:func:`estimation.diagnosis.search.diagnose` compares nested linear models with fixed channel weights
``w_c``: the F statistic ``F = ((RSS₀ − RSS₁)/k) / (RSS₁/(N m − p₁))`` on weighted residual sums of
squares (training), and the weighted validation MSE ``Σ_c w_c ‖y_c − Y_c θ‖² / N``. Every
quantity is a function of the sums of the problem with **all** candidate columns appended,
``[Y_base | C_1 | … | C_J]`` (:func:`accumulate_candidates`, one pass over the samples): a nested
model is a subset of its columns (:meth:`NormalEquations.select`), its weighted fit the TSQR of the
weighted per-channel factors (:func:`weighted_fit`). Peak memory is that of one chunk; the
forward-selection loop then costs ``O(m k³)`` a trial, whatever the record's length.

Wiring (for the diagnosis loop, not done here): accumulate ``train`` and ``validate`` once with
:func:`accumulate_candidates`; the base columns are ``range(model.n_base)``, candidate ``j`` the
block :attr:`CandidateSums.blocks` ``[j]``; ``_weighted_fit(Y, y, w)`` becomes
``weighted_fit(train, columns, w)`` and ``_weighted_mse(...)`` ``weighted_mse(validate, columns, θ, w)``,
with ``columns`` growing by a block when an effect is added; :func:`f_tests` gives a round's trials.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import scipy.linalg
import scipy.stats
from numpy.typing import NDArray

from dynamics.effects.linear import Effect
from dynamics.models import IdentificationModel
from dynamics.runtime.threads import single_threaded_blas
from dynamics.measurements import Measurements
from estimation.diagnosis.search import candidate_columns  # the diagnosis's own columns
from estimation.estimators.normal_equations import DEFAULT_CHUNK_SIZE, NormalEquations, check_chunk_size, stacked_factor

__all__ = ["CandidateSums", "CandidateTest", "accumulate_candidates", "f_tests", "weighted_fit", "weighted_mse"]


@dataclass(frozen=True)
class CandidateSums:
    """Sums of ``[Y_base | C_1 | … | C_J]`` and where each candidate's columns are."""

    sums: NormalEquations
    n_base: int
    blocks: tuple[tuple[int, ...], ...]
    candidates: tuple[Effect, ...]


@dataclass(frozen=True)
class CandidateTest:
    """One nested-model F test: the base (plus ``columns``) against it plus one candidate."""

    index: int
    name: str
    f_statistic: float
    p_value: float
    rss: float
    rss_augmented: float
    theta: NDArray[np.float64]


@single_threaded_blas()
def accumulate_candidates(model: IdentificationModel, measurements: Measurements, candidates: Sequence[Effect], *,
                          chunk_size: int = DEFAULT_CHUNK_SIZE) -> CandidateSums:
    """One pass over ``measurements``: the sums of the base regressor with every candidate's columns."""
    if measurements.dq is None or measurements.ddq is None:
        raise ValueError("the measurements lack dq/ddq: derive them first (estimation.preprocessing.differentiation.fill_derivatives)")
    counts = [len(candidate.parameter_names(model.robot)) for candidate in candidates]
    chunk_size = check_chunk_size(chunk_size, model, sum(counts))
    names = list(model.base.names)
    blocks = []
    for index, (candidate, count) in enumerate(zip(candidates, counts)):
        blocks.append(tuple(range(len(names), len(names) + count)))
        names += [f"{parameter}#{index}" for parameter in candidate.parameter_names(model.robot)]
    sums = NormalEquations.empty(model.channels, tuple(names))
    measured = measurements.channels(model.channels)
    for start in range(0, measurements.n_samples, chunk_size):
        chunk = measurements.select(slice(start, min(start + chunk_size, measurements.n_samples)))
        Y = [model.evaluate_base(chunk.q, chunk.dq, chunk.ddq)]
        Y += [candidate_columns(model, candidate, chunk) for candidate in candidates]
        sums = sums.add_block(np.concatenate(Y, axis=2), measured[start:start + chunk.n_samples])
    return CandidateSums(sums, model.n_base, tuple(blocks), tuple(candidates))


def weighted_fit(sums: NormalEquations, columns: Sequence[int], weights: NDArray[np.float64]
                 ) -> tuple[NDArray[np.float64], float]:
    """``(θ, weighted RSS)`` of least squares on ``columns`` with fixed channel weights, from the
    factors: the R of ``[√w_c R_c(columns, y)]`` stacked over channels; RSS its last diagonal²."""
    selected = sums.select(columns)
    k = len(columns)
    R = stacked_factor([np.sqrt(w) * factor for w, factor in zip(np.asarray(weights, dtype=float), selected.factor)], k + 1)
    theta = scipy.linalg.solve_triangular(R[:k, :k], R[:k, k], check_finite=False)
    return theta, float(R[k, k] ** 2)


def weighted_mse(sums: NormalEquations, columns: Sequence[int], theta: NDArray[np.float64],
                 weights: NDArray[np.float64]) -> float:
    """``Σ_c w_c ‖y_c − Y_c θ‖² / N`` on ``columns`` (the diagnosis's weighted validation error)."""
    return float(np.asarray(weights, dtype=float) @ sums.select(columns).channel_rss(theta) / sums.n_samples)


def f_tests(screen: CandidateSums, weights: NDArray[np.float64], *, columns: Sequence[int] | None = None,
            indices: Sequence[int] | None = None) -> tuple[CandidateTest, ...]:
    """The F test of each candidate (``indices``, default all not in ``columns``) added to ``columns``
    (default the base columns), as in :func:`estimation.diagnosis.search.diagnose`."""
    columns = list(range(screen.n_base)) if columns is None else list(columns)
    taken = set(columns)
    indices = [j for j in range(len(screen.blocks)) if not taken & set(screen.blocks[j])] if indices is None else indices
    rss = weighted_fit(screen.sums, columns, weights)[1]
    rows = screen.sums.n_samples * screen.sums.n_channels
    tests = []
    for index in indices:
        block = list(screen.blocks[index])
        theta, rss_augmented = weighted_fit(screen.sums, columns + block, weights)
        dof = rows - len(columns) - len(block)
        statistic = ((rss - rss_augmented) / len(block)) / (rss_augmented / dof)
        tests.append(CandidateTest(index, screen.candidates[index].name, float(statistic),
                                   float(scipy.stats.f.sf(statistic, len(block), dof)), rss, rss_augmented, theta))
    return tuple(tests)
