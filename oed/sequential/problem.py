"""The next experiment's design problem: the excitation design with a prior and a parameter focus.

:class:`SequentialDesign` is :class:`oed.design_problem.ExcitationDesign` (same Fourier parametrisation,
bounds, constraint refinement, IPOPT settings and multi-start) with another objective: the information
``P`` of the experiments already run (:mod:`oed.sequential.prior`) plus the new trajectory's,
``n · (1/N) Σ_k J_kᵀ J_k`` over ``N`` cost samples of one period (``n``: the samples the new experiment of
``duration_s`` records), scaled by ``D = diag(P)^{-1/2}`` (a constant shift of every log-determinant that keeps
the Cholesky factors well conditioned), under a D-, Ds- or worst-relative criterion (:mod:`oed.sequential.criteria`):

    J(x) = criterion(D (P/n + (1/N) Σ_k J_kᵀ J_k) D)

with ``J_k`` the model's noise-weighted Jacobian in all its parameters, shapes included
(:mod:`oed.sequential.jacobian`), differentiated exactly by CasADi through the sampled sum.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any

import casadi
import numpy as np
from numpy.typing import NDArray

from dynamics.runtime.memory import check_allocation
from oed.criteria import LogDet
from oed.design_problem import SUCCESS_STATUSES, ExcitationDesign, StartResult
from oed.design_solver import STACKED_ABOVE, stacked_information
from oed.sequential.criteria import scaled, symbolic_scaled
from oed.sequential.jacobian import ModelJacobian, SequentialDesignError
from oed.sequential.prior import PriorInformation
from oed.sequential.starts import SCREENED_CANDIDATES, screened_start

__all__ = ["ACCEPTED_STATUSES", "SEQUENTIAL_MAX_ITER", "STACKED_ABOVE", "SequentialDesign"]

#: IPOPT iterations a start of a sequential design (the information's sign(dq) terms make it stall, not converge)
SEQUENTIAL_MAX_ITER = 150

#: IPOPT statuses whose trajectory (within the bounds) is kept: the information sums a Coulomb or Stribeck
#: law's sign(dq) over samples, so the objective jumps where a sample's velocity changes sign and IPOPT can
#: stall short of a KKT point (at the iteration limit or in a failed step) at a trajectory still much better
#: than its start
ACCEPTED_STATUSES = SUCCESS_STATUSES | {"Maximum_Iterations_Exceeded", "Error_In_Step_Computation",
                                        "Search_Direction_Becomes_Too_Small", "Restoration_Failed"}


@dataclass(frozen=True, eq=False)
class SequentialDesign(ExcitationDesign):
    """The excitation design of the next experiment (module docstring).

    Parameters
    ----------
    robot, model, bounds, criterion, effects, settings
        As :class:`ExcitationDesign`; ``criterion`` acts on the posterior information of the model's
        parameters (``LogDet``, :class:`oed.sequential.criteria.FocusedLogDet` or
        :class:`oed.sequential.criteria.WorstRelativeVariance`).
    jacobian
        The identified model's noise-weighted Jacobian.
    prior
        The information of the experiments already run.
    duration_s
        Length of the new experiment, s (whole periods of the trajectory or not).
    screening
        Candidates each start is chosen among (:func:`oed.sequential.starts.screened_start`; 1: the plain
        random start).
    """

    jacobian: ModelJacobian | None = None
    prior: PriorInformation | None = None
    duration_s: float = 0.0
    screening: int = SCREENED_CANDIDATES

    def __post_init__(self) -> None:
        super().__post_init__()
        if not isinstance(self.jacobian, ModelJacobian):
            raise TypeError("jacobian must be a ModelJacobian (oed.sequential.jacobian.model_jacobian)")
        if not isinstance(self.prior, PriorInformation):
            raise TypeError("prior must be a PriorInformation (oed.sequential.prior.prior_information)")
        if self.prior.information.shape != (self.jacobian.n_parameters,) * 2:
            raise SequentialDesignError(f"the prior holds {self.prior.information.shape[0]} parameters, the model "
                                        f"{self.jacobian.n_parameters}")
        if not (np.isfinite(self.duration_s) and self.duration_s > 0):
            raise SequentialDesignError(f"the new experiment's duration must be positive, got {self.duration_s} s")
        if self.jacobian.function.size1_in(0) != self.n_joints:
            raise SequentialDesignError(f"the model has {self.jacobian.function.size1_in(0)} joints, the robot "
                                        f"{self.n_joints}")

    @property
    def new_samples(self) -> float:
        """Samples the new experiment records."""
        return self.prior.samples_in(self.duration_s)

    @property
    def scale(self) -> NDArray[np.float64]:
        """``diag(D) = diag(P)^{-1/2}``."""
        return 1.0 / np.sqrt(np.diag(self.prior.information))

    def cost_function(self) -> casadi.Function:
        """``design_objective(x) -> J`` (module docstring), cached.

        Up to :data:`STACKED_ABOVE` parameters the sum is the compiled per-sample ``JᵀJ`` of the plain design
        (:func:`oed.design_solver.sampled_information`); above, the per-sample function is ``Jᵀ`` alone, mapped
        over the cost samples into one ``p x (m N)`` matrix ``S``, and ``Σ_k J_kᵀ J_k = S Sᵀ`` is one product
        (:func:`oed.design_solver.stacked_information`).
        Measured: for the 7-joint KUKA (``p = 50``) the stacked form compiles in 6 s against 64 s at about the
        same gradient time (55–60 ms); for the PUMA (``p = 21``) the per-sample form's gradient takes 0.6 ms
        against 5.8 ms.
        """
        if "cost" not in self._cache:
            n, H, N = self.n_joints, self.settings.harmonics, self.settings.cost_samples
            m, p = self.jacobian.function.size1_out(0), self.jacobian.n_parameters
            check_allocation(8.0 * N * (3 * (2 * H + 1) + 3 * n + 4 * m * p), f"cost_samples = {N}")
            x = casadi.MX.sym("x", self.n_variables)
            states = self.sampled_states(x)  # (n, N) each: q, dq, ddq
            own = stacked_information(self.jacobian.function, states, self.settings.jit) / N
            prior = casadi.DM(self.prior.information / self.new_samples)
            objective = self.criterion.expression(symbolic_scaled(prior + own, self.scale))
            self._cache["cost"] = casadi.Function("sequential_objective", [x], [objective], ["x"], ["J"])
        return self._cache["cost"]

    def random_start(self, generator: np.random.Generator) -> NDArray[np.float64]:
        """A screened start (:func:`oed.sequential.starts.screened_start`, :attr:`screening` candidates)."""
        return screened_start(self, generator, self.screening)

    def solve(self, x0: NDArray[np.float64], index: int = 0) -> StartResult:
        """One start as :meth:`ExcitationDesign.solve`; a start that ends within the bounds after the
        iteration limit or a failed step counts as a success (see :data:`ACCEPTED_STATUSES`)."""
        result = super().solve(x0, index)
        return replace(result, success=result.feasible and result.status in ACCEPTED_STATUSES)

    def information(self, q, dq, ddq) -> NDArray[np.float64]:
        """``Σ_k J_kᵀ J_k`` of the model's parameters at the given samples (the new experiment's own)."""
        return self.jacobian.information(q, dq, ddq)

    def designed_information(self, x: NDArray[np.float64],
                             samples: tuple[NDArray[np.float64], ...] | None = None) -> NDArray[np.float64]:
        """The information the new experiment adds: ``n`` times its per-sample mean over one period at ``rate_hz``;
        ``samples``: ``(q, dq, ddq)`` of ``x`` at ``rate_hz`` when already computed."""
        q, dq, ddq = self.sample(x)[1:] if samples is None else samples
        return self.information(q, dq, ddq) * (self.new_samples / q.shape[0])

    def evaluate(self, x: NDArray[np.float64], samples: tuple[NDArray[np.float64], ...] | None = None
                 ) -> dict[str, Any]:
        """``cost`` (−log det of the scaled posterior information), its ``cond`` and the criterion there,
        over one period at ``rate_hz`` (``samples`` as in :meth:`designed_information`)."""
        posterior = scaled(self.prior.information + self.designed_information(x, samples), self.scale)
        eigenvalues = np.linalg.eigvalsh((posterior + posterior.T) / 2)
        cond = float(np.sqrt(eigenvalues[-1] / eigenvalues[0])) if eigenvalues[0] > 0 else float("inf")
        return {"cost": LogDet().value(posterior), "cond": cond, "criterion": self.criterion.value(posterior)}


