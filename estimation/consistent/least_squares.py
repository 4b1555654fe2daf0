"""Physically consistent least squares: every link a rigid body, friction that dissipates.

The weighted least-squares cost of the base parameters is a quadratic form,

.. math::  ‖W^{½}(y − Y_b θ_b)‖² = χ²(\\hat θ_b) + (θ_b − \\hat θ_b)^T G (θ_b − \\hat θ_b),
           \\qquad G = Σ_c w_c Y_c^T Y_c ,

with ``θ̂_b`` the unconstrained weighted estimate and ``w_c = 1/σ_c²`` its channel weights
(:class:`estimation.estimators.least_squares.WeightedLeastSquares`). Writing the standard parameters through
the log-Cholesky map ``θ = θ(φ)`` (:mod:`dynamics.physical_parameters`, Rucker & Wensing 2022)
and ``θ_b = K θ`` (:attr:`dynamics.base_parameters.BaseParameters.K`), IPOPT minimises

.. math::  f(φ) = ½ (K θ(φ) − \\hat θ_b)^T G (K θ(φ) − \\hat θ_b) + w Σ_i D(J_i(φ), J_{0,i})

over ``φ`` with exact derivatives from CasADi: an ``r x r`` problem whatever the number of samples.
In practice IPOPT works on the lifted problem ``(θ, ψ)``: ``ψ`` the exponential coordinates of ``φ``
(the plain Cholesky factor, diagonal ≥ 0 as bounds), each link tied by ``θ_k = θ_k(ψ_k)`` (see
:class:`estimation.consistent.solver.ConsistentProblem` for why; same optimum, tens to hundreds of iterations where ``φ`` took thousands).
``D`` is the entropic (log-det) divergence of each link's pseudo-inertia from a prior one
(Lee & Park 2018): with ``prior_weight = w > 0`` the prior is the URDF's/DH table's nominal bodies
(or a user's), a Bayesian prior worth ``w`` in units of ``½χ²``. With ``w = 0`` a pull of weight
``regularisation`` (default 1e-6) towards the nominal bodies fixes the directions of the standard
parameters the data do not see (their base parameters move by less than the solver tolerance).
Non-negative effects (friction, armature) are bounded at zero; active bounds are reported.

Weight 0: the data term plus the pull ``regularisation`` of the divergence, reached along the path of the weight
from 0.1 down (each step started at the optimum before and certified with the pull's term), so that the answer is
that problem's unique optimum and not where a start stopped on the cone's boundary; the cold starts, with the data
term's certificate, only when no point of the path is certified.

Starts: the projection of the unconstrained estimate onto the consistent set (the minimum-norm
standard parameters reproducing ``θ̂_b`` around the nominal ones, each link's pseudo-inertia with
its eigenvalues clipped, friction clipped at zero), the nominal bodies, and random perturbations
of the first (``starts``); the best solution wins. A ``warm_start`` (the optimum at a neighbouring prior
weight) is tried first, and alone when its solution is certified. Each solution is certified by the convex
problem's optimality condition in the pseudo-inertias (:func:`estimation.consistent.solver.escape`): with a prior
(``prior_weight > 0``) that of the whole cost, which is then convex and strictly inside the cone, so that a
certified point is the one every start reaches; without, the data term's.

Uncertainty (``uncertainty_method = "reduced Hessian"``): the Gauss–Newton Hessian of ``f`` in the
coordinates ``ψ`` that are not at a user bound (mass, centre of mass) plus the prior's exact
Hessian, ``cov(θ_b) = s J (JᵀGJ + w ∇²D)⁺ Jᵀ`` with ``J = K ∂θ/∂ψ`` and ``s`` the residual scale of
the unconstrained fit. Coordinates at zero by consistency (a friction, a degenerate body) stay free,
so their uncertainty is not understated. Without a prior this is the unconstrained covariance; a
prior shrinks it. Standard deviations of the link parameters themselves are given only with a prior
(the data alone do not determine them). Both, and the bounds met, in :mod:`estimation.consistent.reduced_hessian`.

Effects with shape parameters (nonlinear in them) fit the quadratic form once their shapes are held
fixed: give the problem at those shapes (:func:`estimation.consistent.fixed_shapes.fixed_problem`, from the
variable-projection fit); measurements alone would be evaluated at the laws' reference shapes, so
:func:`check_linear_effects` refuses them.
"""

from __future__ import annotations

import functools
import time
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from dynamics.effects.shaped import is_shaped
from dynamics.models import IdentificationModel
from dynamics.physical_parameters import (
    ConsistencyBoundsError, LinkBounds, PhysicalParametrisation, consistency_margin, is_consistent, project_link,
    pseudo_inertia,
)
from dynamics.runtime.threads import single_threaded_blas
from estimation.estimators.estimator import Estimator
from estimation.estimators.identification_problem import IdentificationProblem, stack
from estimation.estimators.least_squares import Estimate, WeightedLeastSquares, channel_gram
from estimation.estimators.normal_equations import NormalEquations
from estimation.consistent.effect_prior import EffectPrior, effect_prior
from estimation.consistent.reduced_hessian import active_bounds, at_user_bounds, reduced_hessian_covariance
from estimation.consistent.solver import compiled_problem, escape, inside, variable_scales
from dynamics.measurements import Measurements

#: IPOPT return statuses accepted as a solution
ACCEPTED_STATUSES = frozenset({"Solve_Succeeded", "Solved_To_Acceptable_Level"})
UNCERTAINTY_METHOD = "reduced Hessian"
#: most restarts from a certified non-optimal stationary point (per start)
MAX_ESCAPES = 5
#: IPOPT's iteration limit after an escape, and at each step of the weight-0 path after its first (a warm start near
#: the optimum; a longer run is a failure: on the 7-joint 14 000-sample log of benchmarks/bench_diagnose.py the
#: path's last step ran 3000 iterations, 1.5 s, to fail all the same, where the steps that converge take 9-140)
ESCAPE_ITERATIONS = 300
#: weight 0: the prior's weights followed down to ``regularisation``, each fit started at the one before
#: (:meth:`ConsistentLeastSquares._regularised_path`)
ZERO_WEIGHT_PATH = (0.1, 1e-2, 1e-3, 1e-4, 1e-5)


class ConsistentSolverError(RuntimeError, ValueError):
    """IPOPT found no consistent estimate from any start."""


@dataclass(frozen=True)
class ConsistentEstimate:
    """A physically consistent estimate.

    Attributes
    ----------
    theta
        ``(p,)`` standard parameters (``10 n`` link values, then the effects), consistent.
    phi
        ``(p,)`` the log-Cholesky coordinates of ``theta``.
    values, cov, std
        ``(r,)`` base parameters ``K θ``, their covariance and standard deviations.
    theta_std
        ``(p,)`` standard deviations of ``theta`` (with a prior only, else ``None``).
    uncertainty_method
        How ``cov`` was computed.
    names, expressions
        Base-parameter names and groupings.
    parameter_names
        Standard-parameter names.
    link_names
        One name per link.
    margins
        ``(n,)`` smallest over largest eigenvalue of each link's pseudo-inertia (> 0: a rigid body).
    active_bounds
        User bounds met with equality and non-negative parameters at zero (``"fv5 >= 0"``,
        ``"joint3 mass <= 4"``…).
    prior_weight
        ``w`` of the prior (0: none).
    excess_chi2
        ``(θ_b − θ̂_b)ᵀ G (θ_b − θ̂_b)``: what consistency costs in weighted squared residuals.
    solver
        ``status``, ``iterations``, ``time_s``, ``best``, ``certified`` (every link's pseudo-inertia
        gradient positive semidefinite: the convex problem's optimum, up to the prior's pull), ``starts``
        (per start: ``name, status, iterations, escapes, certified, cost``); at weight 0, when the answer is the
        end of the path down to the regularisation (certified), ``regularisation``: the pull's weight it holds.
    """

    theta: NDArray[np.float64]
    phi: NDArray[np.float64]
    values: NDArray[np.float64]
    cov: NDArray[np.float64]
    std: NDArray[np.float64]
    theta_std: NDArray[np.float64] | None
    uncertainty_method: str
    names: tuple[str, ...]
    expressions: tuple[str, ...]
    parameter_names: tuple[str, ...]
    link_names: tuple[str, ...]
    margins: NDArray[np.float64]
    active_bounds: tuple[str, ...]
    prior_weight: float
    excess_chi2: float
    solver: dict[str, Any]
    #: the description's values the effect parameters were pulled toward (:mod:`estimation.consistent.effect_prior`;
    #: empty: none)
    effect_prior: Mapping[str, float] = field(default_factory=dict)

    def link_parameters(self) -> NDArray[np.float64]:
        """``(n, 10)`` standard parameters link by link."""
        return self.theta[: 10 * len(self.link_names)].reshape(-1, 10)

    def effect_values(self) -> dict[str, float]:
        """Effect parameters by name (``fv1``, ``fc1``, ``off1``…)."""
        start = 10 * len(self.link_names)
        return dict(zip(self.parameter_names[start:], map(float, self.theta[start:])))

    def records(self) -> list[dict[str, Any]]:
        """One dict per base parameter: ``name, expression, value, std``."""
        return [{"name": name, "expression": expression, "value": float(value), "std": float(std)}
                for name, expression, value, std in zip(self.names, self.expressions, self.values, self.std)]


def check_linear_effects(model: IdentificationModel) -> None:
    """Refuse effects with shape parameters when the columns would be evaluated from measurements (at the
    laws' reference shapes, not fitted ones): such a model is fitted on the problem at its fitted shapes."""
    nonlinear = [getattr(effect, "spec", effect.name) for effect in model.effects if is_shaped(effect, model.robot)]
    if nonlinear:
        raise NotImplementedError(
            f"effects {nonlinear} have shape parameters: fit them first (estimation.identification.fit.identify) and "
            "give the problem at the fitted shapes (estimation.consistent.fixed_shapes.fixed_problem), or use "
            "estimation.consistent.identification.consistent_fit")


class ConsistentLeastSquares(Estimator):
    """Weighted least squares under the log-Cholesky map, solved with IPOPT (module docstring).

    Parameters
    ----------
    prior_weight
        ``w ≥ 0``: strength of the log-det prior towards ``prior`` (units of ``½χ²``; 0: no prior).
    prior
        Standard parameters of the links (``10 n``) the prior pulls towards; default the robot
        description's. Every link must be a rigid body (slightly inconsistent ones are projected).
    bounds
        :class:`dynamics.physical_parameters.LinkBounds` by link (joint) name.
    starts
        Number of starts: projection, nominal, then random perturbations of the projection.
    regularisation
        Weight of the pull towards the prior when ``prior_weight`` is 0.
    seed
        Seed of the random starts.
    max_iter
        IPOPT's iteration limit per start.
    warm_start
        ``(p,)`` log-Cholesky coordinates ``φ`` to start from first (:attr:`ConsistentEstimate.phi` of a fit of the
        same problem at a neighbouring prior weight, say: a homotopy). When its solution is certified (the convex
        problem's optimum; with a prior the whole cost's, :func:`estimation.consistent.solver.escape`) no other
        start is run; otherwise the usual starts follow and the best solution wins.
    """

    def __init__(self, *, prior_weight: float = 0.0, prior: ArrayLike | None = None,
                 bounds: Mapping[str, LinkBounds] | None = None, starts: int = 2, regularisation: float = 1e-6,
                 seed: int = 0, max_iter: int = 3000, warm_start: ArrayLike | None = None) -> None:
        self.prior_weight = prior_weight
        self.prior = prior
        self.bounds = bounds
        self.starts = starts
        self.regularisation = regularisation
        self.seed = seed
        self.max_iter = max_iter
        self.warm_start = warm_start

    @single_threaded_blas()
    def fit(self, model: IdentificationModel, data: IdentificationProblem | Measurements | NormalEquations, *,
            unconstrained: Estimate | None = None, shapes_fixed: bool = False,
            gram: NDArray[np.float64] | None = None) -> ConsistentLeastSquares:
        """Fit ``model`` on ``data`` (a stacked problem, measurements, or the sums of the problem over its samples,
        :class:`~estimation.estimators.normal_equations.NormalEquations`: the cost needs the per-channel Gram
        matrices only, so a record read in blocks is fitted as the whole one), from ``unconstrained`` (a weighted or
        ordinary estimate of the same problem; fitted here when not given, but from sums, whose estimate is
        :class:`~estimation.estimators.summed_least_squares.SummedLeastSquares`'s). ``shapes_fixed``: the sums were
        evaluated at the shaped laws' fitted shapes (the streamed diagnosis's adopted model,
        :mod:`estimation.streaming.diagnosis_selection`), as a problem from
        :func:`~estimation.consistent.fixed_shapes.fixed_problem` is. ``gram``: the per-channel Gram matrices
        ``(m, r, r)`` of ``data`` (a problem or measurements) when the caller has them
        (:func:`~estimation.estimators.least_squares.channel_gram`: a search over the prior's weight fits one problem
        at every weight), not formed again."""
        self._forget_fit()
        started = time.perf_counter()
        if not isinstance(model, IdentificationModel):
            raise TypeError(f"model must be an IdentificationModel, got {type(model).__name__}")
        if not isinstance(data, IdentificationProblem) and not (shapes_fixed and isinstance(data, NormalEquations)):
            check_linear_effects(model)
        weight = self._check_settings()
        if isinstance(data, NormalEquations):
            if data.n_columns != model.n_base or unconstrained is None:
                raise ValueError(f"sums of {data.n_columns} columns for {model.n_base} base parameters, and the "
                                 "unconstrained estimate fitted from them, are needed")
            gram = data.gram
        else:
            problem = data if isinstance(data, IdentificationProblem) else stack(model, data)
            if problem.n_parameters != model.n_base:
                raise ValueError(f"the problem has {problem.n_parameters} parameters, the model {model.n_base} base parameters")
            if unconstrained is None:
                unconstrained = WeightedLeastSquares().fit(problem).estimate_
            if gram is None:
                gram, _ = channel_gram(problem)
            elif np.shape(gram) != (problem.n_channels, problem.n_parameters, problem.n_parameters):
                raise ValueError(f"gram has shape {np.shape(gram)}, expected "
                                 f"{(problem.n_channels, problem.n_parameters, problem.n_parameters)}")
        G = np.tensordot(unconstrained.weights, gram, axes=1)
        G = 0.5 * (G + G.T)
        parametrisation = PhysicalParametrisation.of_model(model, self.bounds)
        prior = self._prior(model, parametrisation, weight)
        if weight == 0:
            path = self._regularised_path(model, parametrisation, G, unconstrained, prior)
            if path is not None:
                solves, best, results = path
                self.estimate_ = _estimate(solves, best, results, unconstrained, weight, started)
                return self
        solves = _Solves(model, parametrisation, G, unconstrained.values, prior, int(self.max_iter),
                         prior_in_certificate=weight > 0, effects=effect_prior(model) if weight > 0 else None)
        effective = weight if weight > 0 else float(self.regularisation)
        results = []
        if self.warm_start is not None:
            results.append(solves.solve("warm", self._warm_phi(parametrisation), effective))
        if not (results and results[0]["certified"]):  # a certified warm start is the optimum: no cold start needed
            # the extra starts are only for when no configured one reached a certified optimum
            results = self._cold(solves, model, parametrisation, unconstrained.values, prior, effective, results)
        accepted = [result for result in results if result["status"] in ACCEPTED_STATUSES and np.isfinite(result["cost"])]
        if not accepted:
            raise ConsistentSolverError(
                "IPOPT found no consistent estimate: " + "; ".join(f"start {r['name']}: {r['status']}" for r in results))
        best = min([r for r in accepted if r["certified"]] or accepted, key=lambda result: result["cost"])
        self.estimate_ = _estimate(solves, best, results, unconstrained, weight, started)
        return self

    def _cold(self, solves: _Solves, model, parametrisation, values, prior, weight: float,
              results: list[dict[str, Any]]) -> list[dict[str, Any]]:
        """The cold starts at ``weight`` (the configured ones, then the fallbacks while none is certified)."""
        for count, (name, phi0) in enumerate(self._starts(model, parametrisation, values, prior)):
            if count >= self.starts and any(r["certified"] for r in results):
                break
            results.append(solves.solve(name, phi0, weight))
        return results

    def _regularised_path(self, model, parametrisation, G, unconstrained, prior):
        """Weight 0: ``(solves, best, results)`` at the end of the homotopy :data:`ZERO_WEIGHT_PATH` down to
        ``regularisation``, or ``None`` when no point of it is certified (the cold starts then, as before).

        Without a prior the optimum lies on the boundary of the consistent set, where cold starts stop at different
        points (KUKA LWR4+: six starts from ½χ² = 8199 to 10846, none certified). The problem solved at weight 0 is
        the data term plus the pull ``regularisation`` of the prior's divergence; with that pull in the certificate
        its cost is convex in the pseudo-inertias and strictly inside the cone, so its certified optimum is unique
        and every start reaches it. IPOPT gets there along the path the weight follows down from
        :data:`ZERO_WEIGHT_PATH`'s first value (each step started at the optimum before and given :data:`ESCAPE_ITERATIONS`,
        each certified by the whole cost's condition). Where the certificate fails before the path's end (numerically, the pull being
        tiny), the answer is the last certified point, and ``solver["regularisation"]`` the weight it holds (the
        answer depends on the data and that weight only, never on a start)."""
        solves = _Solves(model, parametrisation, G, unconstrained.values, prior, int(self.max_iter),
                         prior_in_certificate=True)
        regularisation = float(self.regularisation)
        weights = [w for w in ZERO_WEIGHT_PATH if w > regularisation] + [regularisation]
        results: list[dict[str, Any]] = []
        if self.warm_start is not None:
            results.append(solves.solve("warm", self._warm_phi(parametrisation), weights[0]))
        if not (results and results[0]["certified"]):
            results = self._cold(solves, model, parametrisation, unconstrained.values, prior, weights[0], results)
        certified = [r for r in results if r["certified"] and r["status"] in ACCEPTED_STATUSES]
        if not certified:
            return None
        best = dict(min(certified, key=lambda r: r["cost"]), weight=weights[0])
        for weight in weights[1:]:
            result = solves.solve(f"path {weight:g}", parametrisation.phi_from_psi(best["psi"]), weight, short=True)
            results.append(result)
            if not (result["certified"] and result["status"] in ACCEPTED_STATUSES):
                break
            best = dict(result, weight=weight)
        best["iterations"] = sum(r["iterations"] for r in results)
        return solves, best, results

    theta_ = property(lambda self: self._fitted().theta, doc="Consistent standard parameters (links, then effects).")
    base_ = property(lambda self: self._fitted().values, doc="Base parameters K θ of the consistent estimate.")

    def _fitted(self) -> ConsistentEstimate:
        return self.estimate_

    def _check_settings(self) -> float:
        weight = self.prior_weight
        if isinstance(weight, bool) or not isinstance(weight, (int, float, np.integer, np.floating)):
            raise TypeError(f"prior_weight must be a number, got {type(weight).__name__}")
        if not (np.isfinite(weight) and weight >= 0):
            raise ValueError(f"prior_weight must be a finite non-negative number, got {weight}")
        if not (isinstance(self.starts, (int, np.integer)) and not isinstance(self.starts, bool) and 1 <= self.starts <= 1000):
            raise ValueError(f"starts must be an integer from 1 to 1000, got {self.starts!r}")
        if isinstance(self.max_iter, bool) or not isinstance(self.max_iter, (int, np.integer)) or self.max_iter < 1:
            raise ValueError(f"max_iter must be a positive integer, got {self.max_iter!r}")
        if not (np.isfinite(self.regularisation) and self.regularisation > 0):
            raise ValueError(f"regularisation must be positive, got {self.regularisation}")
        return float(weight)

    def _prior(self, model: IdentificationModel, parametrisation: PhysicalParametrisation, weight: float) -> NDArray:
        """The prior's link parameters, each made strictly consistent; with a prior, each bounded
        link's prior must meet its bounds (else no body is near both)."""
        n = model.robot.n_joints
        given = model.robot.standard_parameters if self.prior is None else np.asarray(self.prior, dtype=float).reshape(-1)
        if given.shape != (10 * n,) or not np.all(np.isfinite(given)):
            raise ValueError(f"the prior must hold {10 * n} finite link parameters (10 per link), got {given.shape}")
        prior = np.concatenate([project_link(given[10 * k : 10 * (k + 1)], 1e-4) for k in range(n)])
        if weight > 0:
            for k, name in enumerate(parametrisation.link_names):
                bounds = parametrisation.bounds.get(name)
                if bounds is not None and not bounds.contains(given[10 * k : 10 * (k + 1)]):
                    raise ConsistencyBoundsError(
                        f"link {name}: the prior's mass {given[10 * k]:.4g} kg or centre of mass "
                        f"{np.round(given[10 * k + 1 : 10 * k + 4] / max(given[10 * k], 1e-300), 4).tolist()} m lies "
                        f"outside its bounds (mass {list(bounds.mass)}, box {list(bounds.com_lower)}..{list(bounds.com_upper)}): "
                        "the prior pulls towards a body the bounds exclude")
        return prior

    def _warm_phi(self, parametrisation: PhysicalParametrisation) -> NDArray[np.float64]:
        phi = np.asarray(self.warm_start, dtype=float).reshape(-1)
        if phi.shape != (parametrisation.n_phi,) or not np.all(np.isfinite(phi)):
            raise ValueError(f"warm_start must hold {parametrisation.n_phi} finite log-Cholesky coordinates, "
                             f"got shape {phi.shape}")
        return phi

    def _starts(self, model, parametrisation, values, prior):
        """(name, φ₀): the projection of the unconstrained estimate, the nominal bodies, random
        perturbations of the projection (``starts`` in all), then up to five fallbacks (nominal and
        random ones) tried only when no configured start reached a certified optimum."""
        K = model.base.K
        reference = np.concatenate([prior, np.zeros(K.shape[1] - prior.shape[0])])
        lifted = reference + np.linalg.lstsq(K, values - K @ reference, rcond=None)[0]
        scale = np.abs(lifted[10 * model.robot.n_joints :]).max(initial=1.0)
        projected = parametrisation.project(lifted, floor=1e-6, effect_floor=1e-6 * scale)
        first = parametrisation.inverse(projected)
        nominal = parametrisation.inverse(parametrisation.project(
            np.concatenate([prior, projected[prior.shape[0]:]]), floor=1e-6, effect_floor=1e-6 * scale))
        generator = np.random.default_rng(self.seed)
        yield "projection", first
        if self.starts >= 2:
            yield "nominal", nominal
        for index in range(2, self.starts):
            yield f"random{index - 1}", first + generator.normal(0.0, 0.3, parametrisation.n_phi)
        if self.starts < 2:
            yield "nominal", nominal
        for index in range(4):
            yield f"fallback{index + 1}", first + generator.normal(0.0, 0.3, parametrisation.n_phi)


class _Solves:
    """What every start of one fit shares: the quadratic form ``G, θ̂_b``, the prior's terms, IPOPT's
    bounds and scales, the compiled problem and the shorter one run after an escape."""

    def __init__(self, model: IdentificationModel, parametrisation: PhysicalParametrisation, G: NDArray[np.float64],
                 target: NDArray[np.float64], prior: NDArray[np.float64], max_iter: int, *,
                 prior_in_certificate: bool = False, effects: EffectPrior | None = None) -> None:
        n = model.robot.n_joints
        self.model, self.parametrisation, self.G, self.target = model, parametrisation, G, target
        self.prior_in_certificate = prior_in_certificate
        self.effects = effects  # the description's prior on the effect parameters (with a prior weight only)
        J0 = [pseudo_inertia(prior[10 * k : 10 * (k + 1)]) for k in range(n)]
        self.inverses = np.concatenate([np.linalg.inv(J).reshape(-1, order="F") for J in J0])
        self.log_dets = np.array([np.linalg.slogdet(J)[1] for J in J0])
        self.compiled = compiled_problem(model, max_iter, effects is not None)
        self.lower, self.upper = parametrisation.psi_bounds()
        self.scales = variable_scales(prior, n, model.n_parameters - 10 * n)
        self.max_iter = max_iter

    @functools.cached_property
    def escape_solver(self):
        """The shorter solver run after an escape, built on first use (a certified first solve needs none)."""
        return compiled_problem(self.model, min(self.max_iter, ESCAPE_ITERATIONS), self.effects is not None)

    def parameters(self, prior_weight: float) -> NDArray[np.float64]:
        """The compiled problem's parameter vector at ``prior_weight``."""
        effects = () if self.effects is None else (self.effects.mean, self.effects.precision)
        return np.concatenate([self.G.reshape(-1, order="F"), self.target, [prior_weight], self.inverses, self.log_dets,
                               *effects])

    def _prior_terms(self, prior_weight: float) -> dict[str, Any]:
        """The prior's terms of the certificate: with a prior (``prior_weight > 0`` given by the user) the whole
        cost's; without, the data term's alone (the vanishing pull of ``regularisation`` left out)."""
        if not self.prior_in_certificate:
            return {}
        return {"prior_inverses": self.inverses, "prior_weight": prior_weight}

    def solve(self, name: str, phi0: NDArray[np.float64], prior_weight: float, *, short: bool = False) -> dict[str, Any]:
        """IPOPT from ``phi0``, then certified or escaped along a descent direction and solved again
        (at most :data:`MAX_ESCAPES` times); the solver's result with ``name, escapes, certified``. ``short``: the
        first solve too within :data:`ESCAPE_ITERATIONS` (``phi0`` the optimum of a neighbouring problem)."""
        lower, upper = self.lower, self.upper
        psi0 = np.clip(self.parametrisation.psi_from_phi(phi0), inside(lower, +1e-9), inside(upper, -1e-9))
        first = self.escape_solver if short else self.compiled
        result = first.solve(psi0, self.parameters(prior_weight), lower, upper, *self.scales)
        escapes, certified = 0, False
        while result["status"] in ACCEPTED_STATUSES and escapes <= MAX_ESCAPES:
            # a stationary point of the factorised problem need not be the convex problem's optimum
            # (Burer–Monteiro): certify it, or leave it along a descent direction and solve again
            escaped = escape(self.model, self.parametrisation, self.compiled, result["psi"], self.G, self.target,
                             **self._prior_terms(prior_weight))
            if escaped is None:
                certified = True
                break
            if escapes == MAX_ESCAPES:
                break
            escapes += 1
            again = self.escape_solver.solve(np.clip(escaped, inside(lower, +1e-9), inside(upper, -1e-9)),
                                             self.parameters(prior_weight), lower, upper, *self.scales)
            again["iterations"] += result["iterations"]
            if again["status"] not in ACCEPTED_STATUSES or again["cost"] > result["cost"]:
                result["iterations"] = again["iterations"]
                break
            result = again
        return {"name": name, "escapes": escapes, "certified": certified, **result}


def _estimate(solves: _Solves, best: dict[str, Any], results: list[dict[str, Any]], unconstrained: Estimate,
              weight: float, started: float) -> ConsistentEstimate:
    """The consistent estimate at the best start's solution, with its reduced-Hessian covariance."""
    model, parametrisation, G = solves.model, solves.parametrisation, solves.G
    n = model.robot.n_joints
    psi = best["psi"]
    theta, dtheta = (np.asarray(value) for value in solves.compiled.mapping(psi))
    theta = theta.reshape(-1)
    values = model.base.K @ theta
    prior_hessian = np.asarray(solves.compiled.prior_hessian(psi, solves.parameters(weight))) if weight > 0 else None
    residual_scale = float(np.trace(unconstrained.cov @ G)) / model.n_base
    cov, theta_std = reduced_hessian_covariance(model.base.K, dtheta, G, at_user_bounds(parametrisation, psi),
                                                residual_scale, weight, prior_hessian)
    deviation = values - unconstrained.values
    return ConsistentEstimate(
        theta=theta, phi=parametrisation.phi_from_psi(psi), values=values, cov=cov,
        std=np.sqrt(np.clip(np.diag(cov), 0.0, None)),
        theta_std=theta_std, uncertainty_method=UNCERTAINTY_METHOD, names=model.base.names,
        expressions=model.base.expressions, parameter_names=model.parameter_names,
        link_names=tuple(model.robot.joint_names),
        margins=np.array([consistency_margin(theta[10 * k : 10 * (k + 1)]) for k in range(n)]),
        active_bounds=active_bounds(parametrisation, psi, theta, unconstrained, model),
        prior_weight=weight, excess_chi2=float(deviation @ G @ deviation),
        solver={"status": best["status"], "iterations": best["iterations"], "best": best["name"],
                "time_s": time.perf_counter() - started,
                "certified": bool(best["certified"]),
                **({"regularisation": best["weight"]} if "weight" in best else {}),
                "starts": [{key: r[key] for key in ("name", "status", "iterations", "escapes", "certified", "cost")}
                           for r in results]},
        effect_prior={} if solves.effects is None else dict(solves.effects.values),
    )


__all__ = ["ConsistentEstimate", "ConsistentLeastSquares", "ConsistentSolverError", "check_linear_effects",
           "is_consistent"]
