"""The experiment that best tells two rival models apart: T-optimality with the records already run.

Two identified models ``A`` (``--from``) and ``B`` (``--rival``, or the runner-up ``--from``'s report kept) fit
the records almost equally well. If ``A`` is true, a new experiment separates them by the noise-weighted distance between ``A``'s prediction and the best
approximation ``B`` can make of it (Atkinson and Fedorov, "The design of experiments for discriminating between
two rival models", *Biometrika* 62(1), 1975): ``B`` refits its parameters to all the data. Linearised at ``B``'s
estimate, with ``d_k = (ŷ_A − ŷ_B)(x_k)/σ`` and ``J_k`` ``B``'s weighted Jacobian over the new experiment's ``n``
samples and ``P_B`` ``B``'s information from the records (which ``B`` already fits at its estimate), the refit
``δ`` minimises ``Σ‖d_k − J_k δ‖² + δᵀ P_B δ``, leaving

    Δ_AB = Σ d_kᵀ d_k − g ᵀ (H + P_B)⁻¹ g,      g = Σ J_kᵀ d_k,  H = Σ J_kᵀ J_k,

the expected increase of ``B``'s χ² over ``A``'s (twice the expected log-likelihood ratio, the noise apart).
``Δ_BA`` is the same with the roles swapped. Not knowing which is true, the design maximises
``log Δ_AB + log Δ_BA`` (both must grow) under the bounds of :class:`oed.design_problem.ExcitationDesign`,
with exact derivatives. Both models are weighted by ``A``'s channel noise. The expected BIC difference in
favour of the true model adds the penalty of the parameter counts, ``Δ + (p_other − p_true) ln N`` over the
``N`` channel samples of all the records.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field, replace
from typing import Any, ClassVar

import casadi
import numpy as np
from numpy.typing import NDArray

from dynamics.measurements import Measurements
from estimation.identification.identified_model import IdentifiedModel
from oed.bounds import JointBounds
from oed.criteria import Criterion
from oed.excitation import DesignResult, DesignSettings, design_excitation
from oed.design_problem import ExcitationDesign, StartResult
from oed.design_solver import jit_options
from oed.sequential.jacobian import ModelJacobian, SequentialDesignError, model_jacobian
from oed.sequential.next_experiment import check_bounds
from oed.sequential.prior import PriorInformation, prior_information
from oed.sequential.problem import ACCEPTED_STATUSES, SEQUENTIAL_MAX_ITER
from oed.sequential.starts import DISCRIMINATION_SHARE, SCREENED_CANDIDATES, screened_start

__all__ = ["DiscriminatingDesign", "Discrimination", "Rivalry", "TOptimality", "rivalry_of", "check_rivals", "design_discriminating", "separation"]


def check_rivals(model: IdentifiedModel, rival: IdentifiedModel) -> None:
    """Refuse rivals that are the same model, or models of different robots or channels."""
    if model.robot.name != rival.robot.name or list(model.file.joint_names) != list(rival.file.joint_names):
        raise SequentialDesignError(f"the rival model is of another robot ({rival.robot.name}) than --from "
                                    f"({model.robot.name})")
    if model.channels != rival.channels:
        raise SequentialDesignError(f"the rival model predicts channels {', '.join(rival.channels)}, --from "
                                    f"{', '.join(model.channels)}")
    if model.file.model == rival.file.model and model.file.effects == rival.file.effects:
        raise SequentialDesignError(f"the rival model is the same model as --from ({model.file.model}, "
                                    f"{model.file.effects}): nothing to discriminate")


def _pair_sums(truth: ModelJacobian, rival: ModelJacobian) -> casadi.Function:
    """Per sample ``(q, dq, ddq) -> [dᵀd; vec(J_Bᵀ d); vec(J_BᵀJ_B)]`` with ``d = y_A − y_B``."""
    n = truth.function.size1_in(0)
    q, dq, ddq = (casadi.SX.sym(name, n) for name in ("q", "dq", "ddq"))
    d = truth.prediction(q, dq, ddq) - rival.prediction(q, dq, ddq)
    J = rival.function(q, dq, ddq)
    terms = casadi.vertcat(casadi.dot(d, d), casadi.mtimes(J.T, d), casadi.vec(casadi.mtimes(J.T, J)))
    return casadi.Function("separation_terms", [q, dq, ddq], [terms], ["q", "dq", "ddq"], ["terms"])


def _separation(sums: Any, n_samples: float, prior: Any, p: int, scale: NDArray[np.float64]) -> Any:
    """``Δ = n s̄ − n² ḡᵀ (n H̄ + P)⁻¹ ḡ`` from the per-sample means ``[s̄; ḡ; vec H̄]`` (CasADi or numpy)."""
    symbolic = isinstance(sums, (casadi.MX, casadi.SX))
    s, g, H = sums[0], sums[1:1 + p], sums[1 + p:1 + p + p * p]
    if symbolic:
        D = casadi.diag(casadi.DM(scale))
        H = casadi.reshape(H, p, p)
        A = casadi.mtimes(casadi.mtimes(D, n_samples * H + casadi.DM(prior)), D)
        b = n_samples * casadi.mtimes(D, g)
        return n_samples * s - casadi.dot(b, casadi.solve(A, b))
    H = np.reshape(H, (p, p), order="F")
    A = scale[:, None] * (n_samples * H + prior) * scale[None, :]
    b = n_samples * scale * g
    return float(n_samples * s - b @ np.linalg.solve(A, b))


@dataclass(frozen=True)
class Rivalry:
    """One direction of the comparison: the per-sample separation terms of a supposed truth and its rival
    (:func:`rivalry_of`), and the rival's information from the records."""

    terms: casadi.Function
    prior: PriorInformation
    n_parameters: int

    @property
    def scale(self) -> NDArray[np.float64]:
        return 1.0 / np.sqrt(np.diag(self.prior.information))

    def separation(self, q, dq, ddq, n_samples: float) -> float:
        mean = np.asarray(self.terms.map(q.shape[0])(q.T, dq.T, ddq.T)).mean(axis=1)
        return _separation(mean, n_samples, self.prior.information, self.n_parameters, self.scale)


def rivalry_of(truth: IdentifiedModel, rival: IdentifiedModel, noise_std: NDArray, records: Measurements) -> Rivalry:
    """The :class:`Rivalry` of ``rival`` approximating ``truth``, both weighted by ``noise_std``."""
    truth_jacobian = model_jacobian(truth, noise_std)
    rival_jacobian = model_jacobian(rival, noise_std)
    return Rivalry(_pair_sums(truth_jacobian, rival_jacobian), prior_information(rival_jacobian, records),
                    rival_jacobian.n_parameters)


@dataclass(frozen=True)
class TOptimality(Criterion):
    """The name of the discriminating criterion in the design file: it acts on two models' predictions
    (:class:`DiscriminatingDesign`), not on one information matrix."""

    name: ClassVar[str] = "t-optimal"

    def expression(self, M):
        raise TypeError("T-optimality compares two models' predictions: see DiscriminatingDesign.cost_function")

    def value(self, M) -> float:
        raise TypeError("T-optimality compares two models' predictions: see DiscriminatingDesign.separations")


@dataclass(frozen=True, eq=False)
class DiscriminatingDesign(ExcitationDesign):
    """The excitation design maximising ``log Δ_AB + log Δ_BA`` (module docstring); ``criterion`` is unused;
    half of the starts are chosen among ``screening`` candidates (:func:`oed.sequential.starts.screened_start`)."""

    rivalries: tuple[Rivalry, ...] = ()
    duration_s: float = 0.0
    screening: int = SCREENED_CANDIDATES

    def __post_init__(self) -> None:
        super().__post_init__()
        if not self.rivalries or not all(isinstance(rivalry, Rivalry) for rivalry in self.rivalries):
            raise TypeError("rivalries must be Rivalry objects (rivalry_of), one for each model supposed true")
        if not (np.isfinite(self.duration_s) and self.duration_s > 0):
            raise SequentialDesignError(f"the new experiment's duration must be positive, got {self.duration_s} s")

    @property
    def new_samples(self) -> float:
        return self.rivalries[0].prior.samples_in(self.duration_s)

    def cost_function(self) -> casadi.Function:
        if "cost" not in self._cache:
            N = self.settings.cost_samples
            x = casadi.MX.sym("x", self.n_variables)
            states = self.sampled_states(x)  # (n, N) each: q, dq, ddq
            objective = 0
            for rivalry in self.rivalries:
                terms = rivalry.terms
                if self.settings.jit:  # compiled with its derivatives, as the information sum of the plain design
                    inputs = terms.sx_in()
                    terms = casadi.Function("separation_terms_compiled", inputs, terms.call(inputs),
                                            ["q", "dq", "ddq"], ["terms"], jit_options())
                summed = terms.map("separation_sum", "serial", N, [], [0])(*states) / N
                separation = _separation(summed, self.new_samples, rivalry.prior.information, rivalry.n_parameters,
                                         rivalry.scale)
                objective -= casadi.log(casadi.fmax(separation, 1e-12))
            self._cache["cost"] = casadi.Function("discrimination_objective", [x], [objective], ["x"], ["J"])
        return self._cache["cost"]

    def separations(self, x: NDArray[np.float64], samples: tuple[NDArray[np.float64], ...] | None = None
                    ) -> tuple[float, ...]:
        """``(Δ_AB, Δ_BA)`` of the trajectory ``x`` over one period at ``rate_hz``, for the new experiment's samples
        (``samples``: ``(q, dq, ddq)`` of ``x`` at ``rate_hz`` when already computed)."""
        q, dq, ddq = self.sample(x)[1:] if samples is None else samples
        return tuple(rivalry.separation(q, dq, ddq, self.new_samples) for rivalry in self.rivalries)

    def evaluate(self, x: NDArray[np.float64], samples: tuple[NDArray[np.float64], ...] | None = None
                 ) -> dict[str, Any]:
        """``cost`` and ``criterion``: −Σ log of the separations (:meth:`separations`); ``cond`` is not defined."""
        values = self.separations(x, samples)
        criterion = -float(sum(np.log(max(value, 1e-12)) for value in values))
        return {"cost": criterion, "cond": float("nan"), "criterion": criterion}

    def random_start(self, generator: np.random.Generator) -> NDArray[np.float64]:
        """A screened start (:func:`oed.sequential.starts.screened_start`, ``screening`` candidates) for half of
        the starts (:data:`oed.sequential.starts.DISCRIMINATION_SHARE`), a plain one for the others."""
        return screened_start(self, generator, self.screening, DISCRIMINATION_SHARE)

    def solve(self, x0: NDArray[np.float64], index: int = 0) -> StartResult:
        """As :meth:`oed.sequential.problem.SequentialDesign.solve` (the same statuses accepted)."""
        result = super().solve(x0, index)
        return replace(result, success=result.feasible and result.status in ACCEPTED_STATUSES)


@dataclass(frozen=True)
class Discrimination:
    """The discriminating experiment and the separations it is predicted to give."""

    design: DesignResult
    models: tuple[str, str]
    separation: dict[str, float]
    separation_after_repeat: dict[str, float]
    delta_bic: dict[str, float]
    duration_s: float
    prior: PriorInformation = field(repr=False)

    def to_dict(self) -> dict[str, Any]:
        """The design as ``oed design`` writes it, plus ``discrimination``."""
        document = self.design.trajectory.to_dict()
        document["discrimination"] = {
            "from": self.models[0], "rival": self.models[1], "duration_s": self.duration_s,
            "periods": self.duration_s * self.design.trajectory.frequency_hz,
            "prior_duration_s": self.prior.duration_s,
            "separation": self.separation, "separation_after_repeat": self.separation_after_repeat,
            "expected_delta_bic": self.delta_bic,
        }
        return document

    def summary(self) -> str:
        return (f"discriminating {self.models[0]} from {self.models[1]}: expected separation (chi-square) "
                f"{self.separation['if_from_true']:.3g} if --from is true, {self.separation['if_rival_true']:.3g} if "
                f"the rival is (repeating the records: {self.separation_after_repeat['if_from_true']:.3g}, "
                f"{self.separation_after_repeat['if_rival_true']:.3g}); expected BIC difference "
                f"{self.delta_bic['if_from_true']:.3g}, {self.delta_bic['if_rival_true']:.3g}")


def separation(problem: DiscriminatingDesign, records: Measurements, duration_s: float) -> tuple[float, ...]:
    """``(Δ_AB, Δ_BA)`` had the records' motion been run again for ``duration_s``."""
    n_samples = problem.rivalries[0].prior.samples_in(duration_s)
    return tuple(rivalry.separation(records.q, records.dq, records.ddq, n_samples) for rivalry in problem.rivalries)


def design_discriminating(model: IdentifiedModel, rival: IdentifiedModel, records: Measurements, *,
                          bounds: JointBounds, settings: DesignSettings | None = None, duration_s: float | None = None,
                          starts: int = 8, seed: int | None = 0,
                          progress: Callable[[StartResult, int], None] | None = None,
                          constraints: tuple = ()) -> Discrimination:
    """The T-optimal experiment between ``model`` and ``rival`` after ``records`` (module docstring);
    ``constraints``: torque limits, a floor, self-collision (:mod:`oed.design_constraints`)."""
    check_rivals(model, rival)
    check_bounds(bounds, model)
    noise_std = np.sqrt(np.asarray(model.file.channel_variance, dtype=float))
    rivalries = (rivalry_of(model, rival, noise_std, records), rivalry_of(rival, model, noise_std, records))
    prior = rivalries[0].prior
    duration = prior.duration_s if duration_s is None else float(duration_s)
    problem = DiscriminatingDesign(model.robot, model.model.kind, bounds, TOptimality(), model.model.effects,
                                   settings or DesignSettings(max_iter=SEQUENTIAL_MAX_ITER, sqp_after=None),
                                   constraints=tuple(constraints), rivalries=rivalries, duration_s=duration)
    result = design_excitation(model.robot, starts=starts, seed=seed, progress=progress, problem=problem)
    best = next(start for start in result.starts if start.index == result.best)
    designed = problem.separations(best.x)
    repeated = separation(problem, records, duration)
    n_total = (prior.n_samples + prior.samples_in(duration)) * len(model.channels)
    p_from, p_rival = rivalries[1].n_parameters, rivalries[0].n_parameters
    keys = ("if_from_true", "if_rival_true")
    bic = (designed[0] + (p_rival - p_from) * np.log(n_total), designed[1] + (p_from - p_rival) * np.log(n_total))
    return Discrimination(result, (model.file.effects, rival.file.effects), dict(zip(keys, map(float, designed))),
                          dict(zip(keys, map(float, repeated))), dict(zip(keys, map(float, bic))), duration, prior)
