"""The IPOPT problem behind :mod:`estimation.consistent.least_squares`, compiled once per model.

:func:`compiled_problem` builds the lifted, scaled NLP (:class:`ConsistentProblem`);
:func:`escape` certifies a solution by the convex problem's optimality condition and, when it
fails, returns a start along a descent direction; :func:`variable_scales`, :func:`pseudo_inverse`
and :func:`inside` are the numerical helpers of the estimator.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass
from typing import Any

import casadi
import numpy as np
from numpy.typing import NDArray

from dynamics.codegen.solver_cache import cached_nlpsol
from dynamics.models import IdentificationModel
from dynamics.physical_parameters import PhysicalParametrisation, from_pseudo_inertia, link_from_psi, pseudo_inertia


#: a descent step gaining less than this (units of ½χ², far below a standard deviation's 0.5) certifies the point
CERTIFICATE_GAIN = 1e-6


@dataclass(frozen=True, eq=False)
class ConsistentProblem:
    """The compiled pieces of one model's consistent problem (built once per model, cached).

    ``solver``: IPOPT on ``x = (θ, ψ_links)``: the convex cost ``½(Kθ − θ̂_b)ᵀG(Kθ − θ̂_b)`` in the
    standard parameters plus the prior, each link tied to its Cholesky coordinates ``ψ_k`` (the
    exponential coordinates of the log-Cholesky map, diagonal ≥ 0) by 10 equalities
    ``θ_k = θ_k(ψ_k)``; non-negative effects bounded at zero; variables scaled per link by the
    prior's mass and radius of gyration. Measured on the KUKA (viscous
    friction, no prior): 130 iterations, against thousands, not converged, for IPOPT on ``φ``
    directly (the log coordinates put the optimum, a degenerate body on the boundary of the
    consistent set, at infinity) and hundreds with heavy Hessian regularisation on ``ψ`` alone
    (the data residual times the map's curvature makes that Hessian indefinite; lifted, the
    curvature in ``ψ`` is the multipliers', as in Burer–Monteiro factorisations). The triangular
    factor has spurious stationary points (a degenerate body whose factor cannot turn towards the
    optimum): :func:`escape` detects them and restarts (short noisy PUMA records: about one start in
    two needs one to three escapes).
    NLP parameters: ``G`` (r²), ``θ̂_b`` (r), ``w``, per link ``J₀⁻¹`` (16) and ``log det J₀``; with the effect prior
    its means and precisions (``p − 10 n`` each).
    """

    solver: casadi.Function
    mapping: casadi.Function
    prior_hessian: casadi.Function
    n_links: int
    n_phi: int

    def solve(self, psi0: NDArray, parameters: NDArray, lower: NDArray, upper: NDArray,
              scale_theta: NDArray, scale_psi: NDArray) -> dict[str, Any]:
        """One IPOPT solve from ``ψ₀``; variables scaled (``θ = s_θ θ̃``, ``ψ = s_ψ ψ̃``) to order one."""
        n = 10 * self.n_links
        theta0 = np.asarray(self.mapping(psi0)[0]).reshape(-1)
        scale = np.concatenate([scale_theta, scale_psi])
        with np.errstate(invalid="ignore"):
            solution = self.solver(
                x0=np.concatenate([theta0, psi0[:n]]) / scale, p=np.concatenate([parameters, scale_theta, scale_psi]),
                lbg=0, ubg=0,
                lbx=np.concatenate([np.full(n, -np.inf), lower[n:], lower[:n]]) / scale,
                ubx=np.concatenate([np.full(n, np.inf), upper[n:], upper[:n]]) / scale)
        x = np.asarray(solution["x"]).reshape(-1) * scale
        stats = self.solver.stats()
        psi = np.concatenate([x[self.n_phi :], x[n : self.n_phi]])
        psi = np.clip(psi, lower, upper)  # IPOPT relaxes bounds by 1e-8: friction of -1e-8 is zero
        positive = np.zeros(psi.shape[0], dtype=bool)
        for k in range(self.n_links):
            positive[10 * k : 10 * k + 4] = True
        psi[positive] = np.maximum(psi[positive], np.finfo(float).tiny ** 0.25)  # the Cholesky diagonal stays > 0
        return {"status": stats["return_status"], "iterations": int(stats["iter_count"]), "cost": float(solution["f"]),
                "psi": psi}


def links_and_divergence(psi_links: casadi.SX, n: int, prior_inverse: casadi.SX, prior_log_det: casadi.SX):
    """Each link's standard parameters from its Cholesky coordinates, and ``Σ_k D(J_k, J₀_k)``."""
    divergence = 0
    links = []
    for k in range(n):
        link = psi_links[10 * k : 10 * (k + 1)]
        theta_k, J = link_from_psi(link)
        links.append(theta_k)
        inverse = casadi.reshape(prior_inverse[16 * k : 16 * (k + 1)], 4, 4)
        log_det = 8 * casadi.log(link[0]) + 2 * (casadi.log(link[1]) + casadi.log(link[2]) + casadi.log(link[3]))
        divergence = divergence + casadi.sum1(casadi.sum2(inverse * J)) - log_det + prior_log_det[k] - 4
    return casadi.vertcat(*links), divergence


@dataclass(frozen=True, eq=False)
class _Symbolic:
    """One model's consistent NLP as CasADi expressions (``nlp``: ``x, p, f, g``), its mapping and prior Hessian, and
    the derivative functions IPOPT evaluates (``derivatives``: ``grad_f``, ``jac_g``, ``hess_lag``), kept from the first
    solver built on it: they do not depend on IPOPT's options, and generating them is most of a build (the Panda's
    7 links: 0.2 s, against 0.02 s for a solver given them)."""

    nlp: dict[str, casadi.SX]
    mapping: casadi.Function
    prior_hessian: casadi.Function
    n_links: int
    n_phi: int
    derivatives: dict[str, casadi.Function]


#: the derivative functions IPOPT generates (``nlpsol``'s options) and their names in a built solver
_DERIVATIVES = {"grad_f": "nlp_grad_f", "jac_g": "nlp_jac_g", "hess_lag": "nlp_hess_l"}


@functools.lru_cache(maxsize=16)
def _symbolic(model: IdentificationModel, effect_prior: bool = False) -> _Symbolic:
    """``effect_prior``: the cost also holds ``w · ½ Σ λ_e (θ_e − μ_e)²`` on the effect parameters, ``μ`` and ``λ``
    (``p − 10 n`` each) two more NLP parameters (:mod:`estimation.consistent.effect_prior`)."""
    parametrisation = PhysicalParametrisation.of_model(model)
    n, r, p = model.robot.n_joints, model.n_base, parametrisation.n_phi
    G = casadi.SX.sym("G", r, r)
    target = casadi.SX.sym("theta_hat", r)
    weight = casadi.SX.sym("w")
    prior_inverse = casadi.SX.sym("J0_inv", 16 * n)
    prior_log_det = casadi.SX.sym("log_det_J0", n)
    parameters = casadi.vertcat(casadi.vec(G), target, weight, prior_inverse, prior_log_det)
    effect_mean = casadi.SX.sym("effect_mean", p - 10 * n)
    effect_precision = casadi.SX.sym("effect_precision", p - 10 * n)
    if effect_prior:
        parameters = casadi.vertcat(parameters, effect_mean, effect_precision)

    def with_effect_term(divergence: casadi.SX, effects: casadi.SX) -> casadi.SX:
        """The prior's divergence, plus the effect prior's term when there is one (else the very expression)."""
        if not effect_prior:
            return divergence
        return divergence + 0.5 * casadi.dot(effect_precision, (effects - effect_mean) ** 2)
    scale_theta = casadi.SX.sym("scale_theta", p)
    scale_psi = casadi.SX.sym("scale_psi", 10 * n)
    # IPOPT's variables, scaled to order one: θ = s_θ θ̃, ψ = s_ψ ψ̃ (per link: m, m·ℓ, m·ℓ²; √m, ℓ)
    theta_scaled = casadi.SX.sym("theta_scaled", p)
    psi_scaled = casadi.SX.sym("psi_scaled", 10 * n)
    theta = scale_theta * theta_scaled
    links, divergence = links_and_divergence(scale_psi * psi_scaled, n, prior_inverse, prior_log_det)
    error = casadi.mtimes(casadi.DM(model.base.K), theta) - target
    cost = 0.5 * casadi.dot(error, casadi.mtimes(G, error)) + weight * with_effect_term(divergence, theta[10 * n :])
    nlp = {"x": casadi.vertcat(theta_scaled, psi_scaled), "p": casadi.vertcat(parameters, scale_theta, scale_psi),
           "f": cost, "g": (theta[: 10 * n] - links) / scale_theta[: 10 * n]}
    psi = casadi.SX.sym("psi", p)
    _, divergence = links_and_divergence(psi[: 10 * n], n, prior_inverse, prior_log_det)
    theta_psi = parametrisation.psi_expression(psi)
    mapping = casadi.Function("consistent_theta", [psi], [theta_psi, casadi.jacobian(theta_psi, psi)],
                              ["psi"], ["theta", "dtheta_dpsi"])
    prior_hessian = casadi.Function(
        "prior_hessian", [psi, parameters], [casadi.hessian(with_effect_term(divergence, theta_psi[10 * n :]), psi)[0]],
        ["psi", "p"], ["hessian"])
    return _Symbolic(nlp, mapping, prior_hessian, n, p, {})


@functools.lru_cache(maxsize=16)
def compiled_problem(model: IdentificationModel, max_iter: int = 3000, effect_prior: bool = False) -> ConsistentProblem:
    """The model's :class:`ConsistentProblem` with IPOPT stopped at ``max_iter`` iterations (``effect_prior``: with the
    description's prior on the effect parameters, :func:`_symbolic`). The solvers of one model
    (the escape's shorter one beside the full one) share their derivative functions: the first built generates them,
    the others are given them (the same functions, so the same iterates bit for bit)."""
    symbolic = _symbolic(model, effect_prior)
    solver = cached_nlpsol(
        "consistent_least_squares", "ipopt", symbolic.nlp,
        {"print_time": False, "show_eval_warnings": False, "ipopt.print_level": 0, "ipopt.sb": "yes",
         "ipopt.tol": 1e-8, "ipopt.acceptable_tol": 1e-7, "ipopt.acceptable_iter": 5, "ipopt.max_iter": int(max_iter),
         "ipopt.bound_relax_factor": 0.0,  # the log-det prior needs the Cholesky diagonal > 0 at every trial point
         **symbolic.derivatives},
    )
    if not symbolic.derivatives:
        symbolic.derivatives.update({option: solver.get_function(name) for option, name in _DERIVATIVES.items()})
    return ConsistentProblem(solver, symbolic.mapping, symbolic.prior_hessian, symbolic.n_links, symbolic.n_phi)


def link_gradients(model: IdentificationModel, theta: NDArray, G: NDArray, target: NDArray) -> list[NDArray]:
    """Per link, the data cost's gradient with respect to its pseudo-inertia ``J_k`` (4x4, symmetric):
    ``⟨Γ_k, H⟩ = ∇_θk f · θ(H)`` for every symmetric ``H``. The convex problem's optimum has every
    ``Γ_k ⪰ 0`` (the multiplier of ``J_k ⪰ 0``; with ``⟨Γ_k, J_k⟩ = 0``)."""
    gradient = model.base.K.T @ (G @ (model.base.K @ theta - target))
    gradients = []
    for k in range(model.robot.n_joints):
        g = gradient[10 * k : 10 * (k + 1)]
        Gamma = np.zeros((4, 4))
        for a in range(4):
            for b in range(a, 4):
                basis = np.zeros((4, 4))
                basis[a, b] = basis[b, a] = 1.0
                value = g @ from_pseudo_inertia(basis)
                Gamma[a, b] = Gamma[b, a] = value if a == b else 0.5 * value
        gradients.append(Gamma)
    return gradients


def escape(model, parametrisation, compiled, psi, G, target, *, prior_inverses: NDArray | None = None,
           prior_weight: float = 0.0) -> NDArray | None:
    """``None`` when every link's ``Γ_k`` is positive semidefinite (the point is the convex optimum,
    up to the prior's pull); otherwise ``ψ`` after the exact line search along ``J_k += α v vᵀ``, ``v``
    the eigenvector of the most negative eigenvalue of ``Γ_k`` (a descent direction the triangular
    factor could not follow).

    With ``prior_inverses`` (per link ``J₀⁻¹``, 16 values, column-major) the prior's term is part of the
    certificate: ``Γ_k + w (J₀⁻¹ − J_k⁻¹)`` is the whole cost's gradient in ``J_k`` (the entropic divergence
    ``tr(J₀⁻¹J) − log det J``, Lee & Park 2018), and the line search minimises the whole cost along the
    direction (:func:`prior_line_search`, exact). The cost is then convex in the pseudo-inertias and
    strictly inside the cone, so a stationary point the certificate passes is the global optimum: the point
    another start would reach, to the solver's tolerance. Without it (no prior: the vanishing pull of
    ``regularisation`` left out), the data term's certificate as before."""
    theta = np.asarray(compiled.mapping(psi)[0]).reshape(-1)
    gradients = link_gradients(model, theta, G, target)
    size = max(np.abs(np.linalg.eigvalsh(Gamma)).max() for Gamma in gradients)  # the data term's scale
    with_prior = prior_inverses is not None and prior_weight > 0
    pseudo = [pseudo_inertia(theta[10 * k : 10 * (k + 1)]) for k in range(len(gradients))] if with_prior else []
    if with_prior:
        for k, J in enumerate(pseudo):
            prior_gradient = prior_inverses[16 * k : 16 * (k + 1)].reshape(4, 4, order="F") - np.linalg.inv(J)
            gradients[k] = gradients[k] + prior_weight * 0.5 * (prior_gradient + prior_gradient.T)
    worst, link, direction = 0.0, None, None
    for k, Gamma in enumerate(gradients):
        eigenvalues, vectors = np.linalg.eigh(Gamma)
        if eigenvalues[0] < worst:
            worst, link, direction = eigenvalues[0], k, vectors[:, 0]
    if link is None or worst > -1e-6 * size:
        return None
    step = np.zeros_like(theta)
    step[10 * link : 10 * (link + 1)] = from_pseudo_inertia(np.outer(direction, direction))
    change = model.base.K @ step
    curvature = change @ G @ change
    error = model.base.K @ theta - target
    slope = change @ G @ error
    if with_prior:
        inverse_prior = prior_inverses[16 * link : 16 * (link + 1)].reshape(4, 4, order="F")
        alpha, gain = prior_line_search(slope, curvature, prior_weight, direction @ inverse_prior @ direction,
                                         direction @ np.linalg.solve(pseudo[link], direction))
    else:
        if not (curvature > 0 and slope < 0):
            return None
        alpha, gain = -slope / curvature, slope * slope / (2 * curvature)
    if not alpha > 0 or gain < CERTIFICATE_GAIN + 1e-9 * 0.5 * (error @ G @ error):
        return None  # the best step along the direction gains nothing measurable (in units of ½χ²)
    moved = parametrisation.project(theta + alpha * step, floor=1e-6)
    return parametrisation.psi_from_phi(parametrisation.inverse(moved))


def prior_line_search(slope: float, curvature: float, weight: float, a: float, b: float) -> tuple[float, float]:
    """``(α*, gain)``: the minimiser over ``α ≥ 0`` of the whole cost along ``J += α v vᵀ``,
    ``f(α) = s α + ½ c α² + w (a α − log(1 + b α))`` (``s, c`` the data term's slope and curvature,
    ``a = vᵀJ₀⁻¹v``, ``b = vᵀJ⁻¹v > 0``), and ``f(0) − f(α*)``. ``f'(α) = 0`` is the quadratic
    ``c b α² + (c + (s + w a) b) α + (s + w a − w b) = 0``; ``f`` is convex, so its root ``> 0`` is the minimiser
    when ``f'(0) = s + w a − w b < 0`` (else ``α* = 0``)."""
    first = slope + weight * a - weight * b
    if not (first < 0 and b > 0):
        return 0.0, 0.0
    quadratic, linear, constant = curvature * b, curvature + (slope + weight * a) * b, first
    if quadratic > 0:
        root = np.sqrt(max(linear * linear - 4 * quadratic * constant, 0.0))
        alpha = (-linear + root) / (2 * quadratic) if linear <= 0 else -2 * constant / (linear + root)
    elif linear > 0:
        alpha = -constant / linear
    else:
        return 0.0, 0.0  # unbounded: not with G ⪰ 0 (no curvature means no slope) and J₀ ≻ 0 (a > 0)
    value = slope * alpha + 0.5 * curvature * alpha * alpha + weight * (a * alpha - np.log1p(b * alpha))
    return float(alpha), float(-value)


def variable_scales(prior: NDArray[np.float64], n_links: int, n_effects: int) -> tuple[NDArray, NDArray]:
    """Variable scales from the prior's bodies: per link a mass ``m`` and a length ``ℓ`` (radius of
    gyration about the frame origin), floored at a fraction of the largest so that a massless
    nominal link still gets a scale; ``θ``: ``m, mℓ (3), mℓ² (6)``, ``ψ``: ``√m, ℓ (9)``; effects 1."""
    masses, lengths = np.empty(n_links), np.empty(n_links)
    for k in range(n_links):
        link = prior[10 * k : 10 * (k + 1)]
        masses[k] = link[0]
        lengths[k] = np.sqrt(max(link[4] + link[6] + link[9], 0.0) / max(link[0], 1e-300))
    masses = np.maximum(masses, 1e-2 * masses.max(initial=0.0) + 1e-12)
    lengths = np.clip(lengths, 0.05 * lengths.max(initial=0.0) + 1e-6, None)
    scale_theta = np.concatenate([
        np.concatenate([[m], np.full(3, m * length), np.full(6, m * length * length)])
        for m, length in zip(masses, lengths)
    ] + [np.ones(n_effects)])
    scale_psi = np.concatenate([np.concatenate([[np.sqrt(m)], np.full(9, length)])
                                for m, length in zip(masses, lengths)])
    return scale_theta, scale_psi


def inside(bound: NDArray[np.float64], relative: float) -> NDArray[np.float64]:
    """``bound`` moved by ``relative (1 + |bound|)`` (infinite bounds unchanged)."""
    finite = np.isfinite(bound)
    moved = bound.copy()
    moved[finite] += relative * (1 + np.abs(bound[finite]))
    return moved


def pseudo_inverse(matrix: NDArray[np.float64], rcond: float = 1e-12) -> NDArray[np.float64]:
    """Pseudo-inverse of a symmetric PSD matrix, equilibrated by its diagonal first."""
    matrix = 0.5 * (matrix + matrix.T)
    diagonal = np.sqrt(np.clip(np.diag(matrix), 0.0, None))
    kept = diagonal > 1e-30 * max(diagonal.max(initial=0.0), np.finfo(float).tiny)  # no curvature at all: dropped
    scale = np.where(kept, 1.0 / np.where(kept, diagonal, 1.0), 0.0)
    eigenvalues, vectors = np.linalg.eigh(matrix * np.outer(scale, scale))
    keep = eigenvalues > rcond * max(eigenvalues[-1], 0.0)
    return scale[:, None] * ((vectors[:, keep] / eigenvalues[keep]) @ vectors[:, keep].T) * scale[None, :]
