"""Screened starts for the next experiment's design problems: slow joints among the candidates, the best one kept.

The plain design's random start (:meth:`oed.design_problem.ExcitationDesign.random_start`) fills 30–90 % of every
joint's bounds. What a first experiment leaves uncertain is often a low-speed effect: a Stribeck velocity, the
smoothing of a Coulomb law, the difference between two friction laws near a velocity reversal. Their information
and their separation come from samples at speeds of the order of the effect's shape, which such starts cross in a
few milliseconds; the sampled objective is then flat or aliased there and IPOPT stalls close to its start (measured
on the discriminating design of a weak Stribeck bump: every one of 8 plain starts ended in a failed step with a
predicted separation below 8). A screened start draws ``candidates`` random starts, slows each joint down with
probability :data:`SLOW_SHARE` by a factor log-uniform in ``[SLOWEST, 1]`` (its oscillation about ``q0`` scaled,
then shrunk into the bounds), and keeps the candidate whose objective (the problem's ``cost_function``, on the
cost samples the solver sees) is lowest: a cheap global look before the local solver. The discriminating design screens half of its starts only
(``share = 0.5``, :data:`DISCRIMINATION_SHARE`): its objective, sampled on the cost grid, can alias the milliseconds
around a reversal where two laws differ, and the screen then prefers slowed candidates by a promise the solver does
not keep; measured, the plain starts found the strongest design for one case (``fs = 0.4``) and the screened ones
for another (``fs = 0.3``), where every plain start failed.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from oed.design_problem import ExcitationDesign

__all__ = ["DISCRIMINATION_SHARE", "SCREENED_CANDIDATES", "SLOWEST", "SLOW_SHARE", "screened_start", "slowed_start"]

#: candidates a screened start chooses among
SCREENED_CANDIDATES = 16
#: chance that a candidate's joint is slowed down
SLOW_SHARE = 0.5
#: the smallest factor a slowed joint's oscillation is scaled by
SLOWEST = 0.02
#: share of the discriminating design's starts that are screened (module docstring)
DISCRIMINATION_SHARE = 0.5


def slowed_start(problem: ExcitationDesign, generator: np.random.Generator) -> NDArray[np.float64]:
    """The plain random start with each joint's oscillation scaled, with probability :data:`SLOW_SHARE`, by a
    factor log-uniform in ``[SLOWEST, 1]`` (module docstring); within the bounds."""
    x = ExcitationDesign.random_start(problem, generator)
    width = 2 * problem.settings.harmonics + 1
    for joint in range(problem.n_joints):
        if generator.uniform() < SLOW_SHARE:
            factor = float(np.exp(generator.uniform(np.log(SLOWEST), 0.0)))
            x[joint * width + 1:(joint + 1) * width] *= factor
    return problem.shrink_to_bounds(x)


def screened_start(problem: ExcitationDesign, generator: np.random.Generator,
                   candidates: int = SCREENED_CANDIDATES, share: float = 1.0) -> NDArray[np.float64]:
    """The best of ``candidates`` :func:`slowed_start` draws by the problem's objective (lowest), with probability
    ``share`` (else, and with ``candidates = 1``, the plain random start)."""
    if isinstance(candidates, bool) or not isinstance(candidates, (int, np.integer)) or candidates < 1:
        raise ValueError(f"candidates must be a positive integer, got {candidates!r}")
    if not (np.isfinite(share) and 0 <= share <= 1):
        raise ValueError(f"share must be in [0, 1], got {share}")
    if candidates == 1 or (share < 1 and generator.uniform() >= share):
        return ExcitationDesign.random_start(problem, generator)
    pool = [slowed_start(problem, generator) for _ in range(candidates)]
    objective = problem.cost_function()
    values = np.array([float(objective(x)) for x in pool], dtype=float)
    values[~np.isfinite(values)] = np.inf
    return pool[int(np.argmin(values))]
