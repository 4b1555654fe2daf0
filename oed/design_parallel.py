"""Design starts as picklable units of work for any ``concurrent.futures.Executor``.

A process pool or a ``dask.distributed`` client receives the problem's definition as bytes
(:func:`payload_of`) and a start; each worker rebuilds the problem once (JIT included) and keeps it
for the starts that follow (:func:`solve_start`).
"""

from __future__ import annotations

import functools
import pickle
import threading

import numpy as np
from numpy.typing import NDArray

from oed.design_problem import ExcitationDesign, StartResult


@functools.lru_cache(maxsize=8)
def _problem_from_payload(payload: bytes, thread: int) -> ExcitationDesign:
    """One problem per definition and thread: a CasADi solver must not run in two threads at once."""
    robot, model, bounds, criterion, effects, settings, constraints, rest = pickle.loads(payload)
    return ExcitationDesign(robot, model, bounds, criterion, effects, settings, constraints=constraints, rest=rest)


def solve_start(payload: bytes, x0: NDArray[np.float64], index: int) -> StartResult:
    """Picklable unit of work for an executor: rebuild (once per worker) the problem and solve one start."""
    return _problem_from_payload(payload, threading.get_ident()).solve(x0, index)


def payload_of(problem: ExcitationDesign) -> bytes:
    """The problem's definition as bytes a worker process can rebuild it from."""
    return pickle.dumps((problem.robot, problem.model.value, problem.bounds, problem.criterion,
                         problem.effects, problem.settings, problem.constraints, problem.rest))
