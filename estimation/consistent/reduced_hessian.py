"""Where a consistent estimate meets its bounds, and its covariance by the reduced Hessian.

The estimate of :class:`estimation.consistent.least_squares.ConsistentLeastSquares` is a solution in
the exponential coordinates ``ψ`` of the log-Cholesky map (Rucker & Wensing 2022). Its covariance
(``uncertainty_method = "reduced Hessian"``) is that of a Gauss–Newton step in the coordinates not at
a user bound (mass, centre of mass), plus the prior's exact Hessian::

    cov(θ_b) = s J (JᵀGJ + w ∇²D)⁺ Jᵀ,        J = K ∂θ/∂ψ  (free coordinates)

with ``s`` the residual scale of the unconstrained fit. Coordinates at zero by consistency (a
friction, a degenerate body) stay free, so their uncertainty is not understated.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from dynamics.models import IdentificationModel
from dynamics.physical_parameters import PhysicalParametrisation, consistency_margin
from estimation.consistent.solver import pseudo_inverse
from estimation.estimators.least_squares import Estimate

__all__ = ["active_bounds", "at_user_bounds", "reduced_hessian_covariance"]


def at_user_bounds(parametrisation: PhysicalParametrisation, psi: NDArray[np.float64]) -> NDArray[np.bool_]:
    """Which coordinates of ``psi`` sit at a bound the user set (a link's mass or centre of mass):
    those are fixed in the reduced Hessian."""
    lower, upper = parametrisation.psi_bounds()
    fixed_lower, fixed_upper = parametrisation.phi_bounds()  # the user's bounds
    user_bound = np.zeros(psi.shape[0], dtype=bool)
    for k in range(parametrisation.n_links):
        block = slice(10 * k, 10 * (k + 1))
        for offset in (0, 7, 8, 9):
            value = psi[block][offset]
            low, high = lower[block][offset], upper[block][offset]
            user_bound[10 * k + offset] = bool(
                (np.isfinite(fixed_lower[block][offset]) and value <= low + 1e-7 * (1 + abs(low)))
                or (np.isfinite(fixed_upper[block][offset]) and value >= high - 1e-7 * (1 + abs(high))))
    return user_bound


def reduced_hessian_covariance(K: NDArray[np.float64], dtheta: NDArray[np.float64], G: NDArray[np.float64],
                               user_bound: NDArray[np.bool_], residual_scale: float, prior_weight: float = 0.0,
                               prior_hessian: NDArray[np.float64] | None = None
                               ) -> tuple[NDArray[np.float64], NDArray[np.float64] | None]:
    """``cov(θ_b)`` (module docstring) and, with a prior (``prior_weight > 0`` and its Hessian in
    ``ψ``), the standard deviations of ``θ`` itself (else ``None``: the data alone do not determine them).

    ``dtheta`` is ``∂θ/∂ψ`` at the solution, ``user_bound`` the coordinates held fixed."""
    free = ~user_bound
    J = K @ dtheta[:, free]
    hessian = J.T @ G @ J
    if prior_weight > 0:
        hessian = hessian + prior_weight * prior_hessian[np.ix_(free, free)]
    inverse = pseudo_inverse(hessian)  # equilibrated inside: ψ mixes scales (a degenerate link's a → 0)
    cov = residual_scale * J @ inverse @ J.T
    theta_std = None
    if prior_weight > 0:
        theta_cov = residual_scale * dtheta[:, free] @ inverse @ dtheta[:, free].T
        theta_std = np.sqrt(np.clip(np.diag(theta_cov), 0.0, None))
    return cov, theta_std


def active_bounds(parametrisation: PhysicalParametrisation, psi: NDArray[np.float64], theta: NDArray[np.float64],
                  unconstrained: Estimate, model: IdentificationModel) -> tuple[str, ...]:
    """Bounds met with equality: non-negative effects at zero, degenerate bodies (pseudo-inertia
    singular: the estimate is on the boundary of the consistent set), the user's mass and
    centre-of-mass bounds."""
    active = []
    start = 10 * parametrisation.n_links
    reference = max(1.0, float(np.abs(unconstrained.values).max()))
    for index, kind in enumerate(parametrisation.effect_kinds):
        if kind == "nonnegative" and theta[start + index] <= 1e-8 * reference:
            active.append(f"{model.parameter_names[start + index]} >= 0")
    lower, upper = parametrisation.psi_bounds()
    user_lower, user_upper = parametrisation.phi_bounds()
    for k, name in enumerate(parametrisation.link_names):
        block = slice(10 * k, 10 * (k + 1))
        if consistency_margin(theta[block]) < 1e-8:
            active.append(f"{name} pseudo-inertia singular (degenerate body)")
        for offset, label in ((0, "mass"), (7, "com x"), (8, "com y"), (9, "com z")):
            value, low, high = psi[block][offset], lower[block][offset], upper[block][offset]
            shown = (lambda v: float(v * v)) if offset == 0 else float
            if np.isfinite(user_lower[block][offset]) and value <= low + 1e-6 * (1 + abs(low)):
                active.append(f"{name} {label} >= {shown(low):.6g}")
            if np.isfinite(user_upper[block][offset]) and value >= high - 1e-6 * (1 + abs(high)):
                active.append(f"{name} {label} <= {shown(high):.6g}")
    return tuple(active)
