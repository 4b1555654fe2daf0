"""How an excitation design is discretised and solved (:class:`DesignSettings`), checked on creation."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from dynamics.codegen.compiled import find_compiler

#: longest period checked sample by sample at rate_hz (about 3 h at 1 kHz)
MAX_PERIOD_SAMPLES = 10_000_000


@dataclass(frozen=True)
class DesignSettings:
    """How the excitation problem is discretised and solved.

    Parameters
    ----------
    frequency_hz, harmonics
        ``f`` and ``N`` of eq. 18 (paper: 0.2 Hz, 5 harmonics; period ``1/f``).
    cost_samples
        Samples per period at which the criterion is evaluated during optimisation (the reported
        cost always uses the full ``rate_hz`` grid).
    constraint_points
        Equidistant points per period where the bounds are imposed (more are added where the
        ``rate_hz`` check fails).
    rate_hz
        Sampling rate of the executed trajectory (paper: 1 kHz).
    max_iter, tol, acceptable_tol, acceptable_iter, lbfgs_memory
        IPOPT settings (L-BFGS Hessian approximation; IPOPT stops early once ``acceptable_tol`` holds
        on ``acceptable_iter`` consecutive iterations). The defaults end a PUMA start about 15 %
        sooner than ``tol=1e-6`` at a cost within 0.02 of it (8 starts, combined and internal model).
    sqp_after
        IPOPT iterations after which an SQP method (:func:`oed.design_solver.sqp_solver`: dense
        damped BFGS, one small QP an iteration) takes over the start from IPOPT's point and also
        runs the refinement rounds; ``None``: IPOPT alone, to convergence (the former behaviour).
        IPOPT's barrier keeps the early iterates off the bounds, which leads to better optima than
        an active-set method from the same start; its late iterations, each a sparse factorisation of
        the KKT system with every constraint row and a curvature update that is mostly skipped, are
        the slow part. On the PUMA (8 seeds of 8 starts, combined and internal model) the starts take
        a third less CPU time, the best of 8 starts as good or better on 14 of the 16 seeds (worse by
        0.001 and 0.07 in −log det on the other two) and the single starts the same in the median
        (``benchmarks/README.md``). A start that IPOPT finishes within
        ``sqp_after`` iterations is not handed over, nor are starts of a criterion that is not smooth
        (``cond``, ``mineig``: their kinks defeat the BFGS model), nor any when ``max_iter`` is at most
        ``sqp_after``.
    refinements
        Rounds of "add the violated points and re-solve" (with torque, floor or self-collision constraints
        at least ``oed.design_problem.CONSTRAINED_REFINEMENTS``, 10).
    jit
        Compile the per-sample regressor and its reverse derivative with the system C compiler
        (about 3x faster objective gradients for a one-time build of about 1 s); default: when a
        compiler (``cc``/``gcc``) is on the ``PATH``.
    verbose
        Print IPOPT's (and the SQP method's) iteration log.
    ipopt_options
        Further IPOPT options as ``(name, value)`` pairs, over the above (e.g.
        ``(("mu_strategy", "monotone"),)``; ``benchmarks/bench_design.py --ipopt NAME=VALUE``).
    """

    frequency_hz: float = 0.2
    harmonics: int = 5
    cost_samples: int = 250
    constraint_points: int = 60
    rate_hz: float = 1000.0
    max_iter: int = 500
    tol: float = 1e-4
    acceptable_tol: float = 1e-3
    acceptable_iter: int = 2
    lbfgs_memory: int = 20
    sqp_after: int | None = 20
    refinements: int = 3
    jit: bool = field(default_factory=lambda: find_compiler() is not None)
    verbose: bool = False
    ipopt_options: tuple[tuple[str, Any], ...] = ()

    def __post_init__(self) -> None:
        options = tuple(tuple(pair) for pair in self.ipopt_options)
        if not all(len(pair) == 2 and isinstance(pair[0], str) for pair in options):
            raise ValueError(f"ipopt_options must be (name, value) pairs, got {self.ipopt_options!r}")
        object.__setattr__(self, "ipopt_options", options)
        for name in ("frequency_hz", "rate_hz", "tol", "acceptable_tol"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
                raise TypeError(f"{name} must be a number, got {value!r}")
        if not (np.isfinite(self.frequency_hz) and self.frequency_hz > 0):
            raise ValueError(f"frequency_hz must be positive, got {self.frequency_hz}")
        if not (np.isfinite(self.rate_hz) and self.rate_hz > 0):
            raise ValueError(f"rate_hz must be positive, got {self.rate_hz}")
        for name in ("harmonics", "cost_samples", "constraint_points", "max_iter", "lbfgs_memory", "acceptable_iter"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 1:
                raise ValueError(f"{name} must be a positive integer, got {value!r}")
        if self.sqp_after is not None and (isinstance(self.sqp_after, bool) or not isinstance(self.sqp_after, (int, np.integer))
                                           or self.sqp_after < 0):
            raise ValueError(f"sqp_after must be a non-negative integer or None, got {self.sqp_after!r}")
        if isinstance(self.refinements, bool) or not isinstance(self.refinements, (int, np.integer)) or self.refinements < 0:
            raise ValueError(f"refinements must be a non-negative integer, got {self.refinements!r}")
        for name in ("tol", "acceptable_tol"):
            if not getattr(self, name) > 0:
                raise ValueError(f"{name} must be positive, got {getattr(self, name)}")
        if self.rate_hz / self.frequency_hz < 2 * self.harmonics + 1:
            raise ValueError(f"rate_hz {self.rate_hz} is too low for {self.harmonics} harmonics of {self.frequency_hz} Hz")
        if self.rate_hz / self.frequency_hz > MAX_PERIOD_SAMPLES:
            raise ValueError(f"one period of {self.frequency_hz:g} Hz at {self.rate_hz:g} Hz is "
                             f"{self.rate_hz / self.frequency_hz:.3g} samples, more than the {MAX_PERIOD_SAMPLES:.0e} "
                             "checked at most: raise the frequency or lower rate_hz")
        samples_per_period = self.rate_hz / self.frequency_hz
        if abs(samples_per_period - round(samples_per_period)) > 1e-6 * samples_per_period:
            raise ValueError(f"one period of {self.frequency_hz:g} Hz is {samples_per_period:.6g} samples at "
                             f"{self.rate_hz:g} Hz: it must be a whole number, or the bounds checked on one "
                             "period do not hold on the next")
        if self.constraint_points < 2 * self.harmonics + 1:
            raise ValueError(f"constraint_points = {self.constraint_points} cannot bound {self.harmonics} harmonics: "
                             f"need at least 2 x harmonics + 1 = {2 * self.harmonics + 1}")
        if self.constraint_points > self.period_samples:
            raise ValueError(f"constraint_points = {self.constraint_points} is more than the {self.period_samples} samples "
                             f"of one period at {self.rate_hz:g} Hz (every sample is checked then): give at most "
                             f"{self.period_samples}")
        if self.cost_samples < 2 * self.harmonics + 1:
            raise ValueError(f"cost_samples = {self.cost_samples} cannot resolve {self.harmonics} harmonics: "
                             f"need at least 2 x harmonics + 1 = {2 * self.harmonics + 1}")

    @property
    def period_samples(self) -> int:
        """Samples of one period on the ``rate_hz`` grid (5 000 for the paper)."""
        return int(round(self.rate_hz / self.frequency_hz))
