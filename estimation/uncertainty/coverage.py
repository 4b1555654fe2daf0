"""Monte-Carlo check that confidence intervals hold: do ``level`` intervals cover the truth that often?

A standard deviation is honest when ``θ̂ ± z σ̂`` covers the true ``θ`` about ``level`` of the time
over repeated experiments. :func:`monte_carlo_coverage` draws ``realisations`` noisy records
(``realise(seed)``), runs an estimator on each (``estimate(measurements)`` returning names, values
and standard deviations: any estimator can be checked, e.g. one that also estimates shape
parameters), and counts, per parameter, how often the interval covers the truth. Realisations run
through a :class:`concurrent.futures.Executor` (threads by default: the work is in BLAS and
CasADi; a process pool needs picklable callables).

:func:`identification_draw` turns an :func:`estimation.identification.fit.identify` result into a draw:
the base parameters and, for a model with shaped effects, the shape parameters (smoothing
velocities…) with their standard deviations.

With ``R`` realisations and a true coverage ``p`` the counted fraction has standard deviation
``√(p(1−p)/R)`` (1.5 % at ``p = 0.95``, ``R = 200``).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from concurrent.futures import Executor, ThreadPoolExecutor
from dataclasses import dataclass
from typing import Any, NamedTuple

import numpy as np
import scipy.stats
from numpy.typing import NDArray

from dynamics.measurements import Measurements


class EstimateDraw(NamedTuple):
    """What an estimator gives for one realisation."""

    names: tuple[str, ...]
    values: NDArray[np.float64]
    std: NDArray[np.float64]


@dataclass(frozen=True)
class CoverageResult:
    """Estimates and standard deviations of every realisation, with the truth.

    Attributes
    ----------
    names
        Parameters checked.
    truth
        ``(r,)`` true values.
    values, std
        ``(R, r)`` estimates and standard deviations per realisation.
    level
        Nominal coverage of the intervals (0.95).
    """

    names: tuple[str, ...]
    truth: NDArray[np.float64]
    values: NDArray[np.float64]
    std: NDArray[np.float64]
    level: float

    @property
    def realisations(self) -> int:
        return self.values.shape[0]

    def covered(self) -> NDArray[np.bool_]:
        """``(R, r)``: the interval of realisation ``i`` covers parameter ``j``."""
        z = scipy.stats.norm.ppf(0.5 + self.level / 2)
        return np.abs(self.values - self.truth) <= z * self.std

    def coverage(self) -> dict[str, float]:
        """Fraction of realisations whose interval covers the truth, per parameter."""
        return dict(zip(self.names, map(float, self.covered().mean(axis=0))))

    def overall(self) -> float:
        """Coverage over every parameter and realisation."""
        return float(self.covered().mean())

    def std_ratio(self) -> dict[str, float]:
        """Mean reported standard deviation over the spread of the estimates (1: honest)."""
        spread = self.values.std(axis=0, ddof=1)
        with np.errstate(divide="ignore", invalid="ignore"):
            return dict(zip(self.names, map(float, self.std.mean(axis=0) / spread)))

    def bias_sigmas(self) -> dict[str, float]:
        """Mean error over the spread (a bias the standard deviations cannot cover)."""
        spread = self.values.std(axis=0, ddof=1)
        with np.errstate(divide="ignore", invalid="ignore"):
            return dict(zip(self.names, map(float, (self.values.mean(axis=0) - self.truth) / spread)))

    def to_dict(self) -> dict[str, Any]:
        return {"level": self.level, "realisations": self.realisations, "overall": self.overall(),
                "coverage": self.coverage(), "std_ratio": self.std_ratio(), "bias_sigmas": self.bias_sigmas()}


def identification_draw(result: Any) -> EstimateDraw:
    """The base parameters of an :class:`estimation.identification.fit.IdentificationResult` and its shape
    parameters (``result.shapes``: smoothing velocities…), with their standard deviations."""
    estimate = result.estimate
    names = tuple(estimate.names) + tuple(value.name for value in result.shapes)
    values = np.concatenate([estimate.values, [value.value for value in result.shapes]])
    std = np.concatenate([estimate.std, [value.std for value in result.shapes]])
    return EstimateDraw(names, values, std)


def monte_carlo_coverage(
    realise: Callable[[int], Measurements],
    estimate: Callable[[Measurements], EstimateDraw],
    truth: Mapping[str, float],
    *,
    realisations: int = 200,
    level: float = 0.95,
    executor: Executor | None = None,
    seed: int = 0,
    names: Sequence[str] | None = None,
) -> CoverageResult:
    """Coverage of ``level`` intervals over ``realisations`` noisy records.

    Parameters
    ----------
    realise
        ``seed -> Measurements``: one noisy record (seeds ``seed, seed+1, …``).
    estimate
        ``Measurements -> EstimateDraw`` (names, values, standard deviations).
    truth
        True value of each parameter checked, by name.
    names
        Parameters checked (default: every name in ``truth``); each must be in every draw.
    executor
        Runs the realisations (default: a thread pool of two workers).
    """
    if isinstance(realisations, bool) or int(realisations) != realisations or realisations < 2:
        raise ValueError(f"realisations must be an integer of at least 2, got {realisations}")
    if not 0 < level < 1:
        raise ValueError(f"level must lie in (0, 1), got {level}")
    names = tuple(truth if names is None else names)
    missing = [name for name in names if name not in truth]
    if missing:
        raise ValueError(f"no true value for {missing}")

    def one(index: int) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        draw = estimate(realise(seed + index))
        lookup = {name: i for i, name in enumerate(draw.names)}
        absent = [name for name in names if name not in lookup]
        if absent:
            raise ValueError(f"the estimator gives no {absent}")
        picks = [lookup[name] for name in names]
        return np.asarray(draw.values, dtype=float)[picks], np.asarray(draw.std, dtype=float)[picks]

    own = executor is None
    pool = ThreadPoolExecutor(max_workers=2) if own else executor
    try:
        futures = [pool.submit(one, index) for index in range(int(realisations))]
        try:
            results = [future.result() for future in futures]
        except BaseException:
            for future in futures:
                future.cancel()
            raise
    finally:
        if own:
            pool.shutdown(wait=True)
    values = np.array([values for values, _ in results])
    std = np.array([std for _, std in results])
    return CoverageResult(names, np.array([truth[name] for name in names], dtype=float), values, std, float(level))
