"""Physically consistent parameters: the log-Cholesky map of Rucker & Wensing (2022).

A link's ten standard parameters ``m, mx, my, mz, Ixx, Ixy, Iyy, Ixz, Iyz, Izz`` (mass, first
moments ``h = m c``, inertia ``I`` about the link-frame origin; :mod:`dynamics.robot`) are a real
rigid body exactly when the **pseudo-inertia**

.. math::  J = \\begin{pmatrix} Σ & h \\\\ h^T & m \\end{pmatrix}, \\qquad Σ = \\tfrac12 \\operatorname{tr}(I)\\, 1 - I

is positive definite (Wensing, Kim & Slotine 2017): positive mass, and the inertia about the
centre of mass positive definite with the triangle inequalities. Rucker & Wensing ("Smooth
parameterization of rigid-body inertia", IEEE RA-L 2022) write ``J = U Uᵀ`` with

.. math::  U = e^{α} \\begin{pmatrix} e^{d_1} & s_{12} & s_{13} & t_1 \\\\ 0 & e^{d_2} & s_{23} & t_2 \\\\
           0 & 0 & e^{d_3} & t_3 \\\\ 0 & 0 & 0 & 1 \\end{pmatrix},

a smooth bijection from ``φ = (α, d1, d2, d3, s12, s23, s13, t1, t2, t3) ∈ R¹⁰`` onto the set of
positive-definite pseudo-inertias. Two of its coordinates are physical: ``m = e^{2α}`` and the
centre of mass ``c = t``, so mass ranges and a box on the centre of mass are plain bounds on ``φ``.

Effect parameters that physics makes non-negative (friction, armature;
:data:`dynamics.effects.linear.POSITIVE_EFFECTS`) are squares, ``θ = z²``; the others (offsets,
springs, plate offsets) are free, ``θ = z``. :class:`PhysicalParametrisation` builds the whole
map ``φ → θ`` of a model as a named ``casadi.Function``.

An effect is looked up by its ``physical_kind`` when it has one (friction and inertia of motors and of
joint combinations: ``coulomb[q5+q6]``, ``motor_viscous[m6]``), else by its name; the shaped laws of
:mod:`dynamics.effects.shaped` (their shapes held fixed) by theirs (``coulomb``, ``stribeck``, ``sigmoid``).
Extension point: a new law adds its own entry in :data:`PARAMETER_MAPS`;
:meth:`PhysicalParametrisation.of_model` is the only place that reads it.
"""

from __future__ import annotations

import functools
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Literal

import casadi
import numpy as np
from numpy.typing import ArrayLike, NDArray

from dynamics.effects.linear import POSITIVE_EFFECTS
from dynamics.robot import N_LINK_PARAMETERS

PHI_NAMES: tuple[str, ...] = ("alpha", "d1", "d2", "d3", "s12", "s23", "s13", "t1", "t2", "t3")
ParameterKind = Literal["nonnegative", "free"]
#: how each effect's parameters are mapped (effects not listed: free)
PARAMETER_MAPS: dict[str, ParameterKind] = {name: "nonnegative" for name in POSITIVE_EFFECTS}


class InconsistentBodyError(ValueError):
    """Standard parameters that are not a rigid body (pseudo-inertia not positive definite)."""


class ConsistencyBoundsError(ValueError):
    """User bounds on masses or centres of mass that no consistent body (or no prior) can meet."""


# ---------------------------------------------------------------------------------------------
# one link, numpy

def pseudo_inertia(theta: ArrayLike) -> NDArray[np.float64]:
    """The 4x4 pseudo-inertia ``J`` of one link's ten standard parameters (Wensing et al. 2017)."""
    m, mx, my, mz, ixx, ixy, iyy, ixz, iyz, izz = np.asarray(theta, dtype=float).reshape(N_LINK_PARAMETERS)
    inertia = np.array([[ixx, ixy, ixz], [ixy, iyy, iyz], [ixz, iyz, izz]])
    J = np.zeros((4, 4))
    J[:3, :3] = 0.5 * np.trace(inertia) * np.eye(3) - inertia
    J[:3, 3] = J[3, :3] = (mx, my, mz)
    J[3, 3] = m
    return J


def from_pseudo_inertia(J: ArrayLike) -> NDArray[np.float64]:
    """Ten standard parameters from a pseudo-inertia (inverse of :func:`pseudo_inertia`)."""
    J = np.asarray(J, dtype=float)
    sigma = 0.5 * (J[:3, :3] + J[:3, :3].T)
    inertia = np.trace(sigma) * np.eye(3) - sigma
    return np.array([J[3, 3], *J[:3, 3], inertia[0, 0], inertia[0, 1], inertia[1, 1], inertia[0, 2],
                     inertia[1, 2], inertia[2, 2]])


def consistency_margin(theta: ArrayLike) -> float:
    """Smallest eigenvalue of the pseudo-inertia divided by its largest (> 0: consistent)."""
    eigenvalues = np.linalg.eigvalsh(pseudo_inertia(theta))
    return float(eigenvalues[0] / max(abs(eigenvalues[-1]), np.finfo(float).tiny))


def is_consistent(theta: ArrayLike, tolerance: float = 0.0) -> bool:
    """Whether one link's parameters are a rigid body: ``λ_min(J) > −tolerance · λ_max(J)``."""
    return consistency_margin(theta) > -tolerance


def project_link(theta: ArrayLike, floor: float = 1e-6) -> NDArray[np.float64]:
    """The nearest strictly consistent body (Frobenius norm on ``J``): eigenvalues of the
    pseudo-inertia clipped at ``floor · λ_max`` (or ``floor`` kg·m² when ``J`` has none positive)."""
    eigenvalues, vectors = np.linalg.eigh(pseudo_inertia(theta))
    smallest = floor * eigenvalues[-1] if eigenvalues[-1] > 0 else floor
    clipped = np.maximum(eigenvalues, smallest)
    return from_pseudo_inertia((vectors * clipped) @ vectors.T)


def log_cholesky_from_link(theta: ArrayLike) -> NDArray[np.float64]:
    """``φ`` of a strictly consistent link (the inverse of the map): ``J = U Uᵀ``, ``U`` upper
    triangular, from the Cholesky factor of ``J`` with rows and columns reversed."""
    J = pseudo_inertia(theta)
    reverse = J[::-1, ::-1]
    try:
        lower = np.linalg.cholesky(reverse)
    except np.linalg.LinAlgError:
        raise InconsistentBodyError(
            f"the parameters {np.round(np.asarray(theta, dtype=float), 6).tolist()} are not a rigid body "
            "(pseudo-inertia not positive definite); project them first (project_link)") from None
    U = lower[::-1, ::-1]
    scale = U[3, 3]
    unit = U / scale
    return np.array([np.log(scale), np.log(unit[0, 0]), np.log(unit[1, 1]), np.log(unit[2, 2]),
                     unit[0, 1], unit[1, 2], unit[0, 2], unit[0, 3], unit[1, 3], unit[2, 3]])


# ---------------------------------------------------------------------------------------------
# one link, CasADi

def _upper_factor(psi: casadi.SX) -> casadi.SX:
    """``U`` from the exponential coordinates ``ψ = (e^α, e^d1, e^d2, e^d3, s12, s23, s13, t1, t2, t3)``."""
    scale, e1, e2, e3, s12, s23, s13, t1, t2, t3 = (psi[k] for k in range(10))
    zero = casadi.SX(0)
    U = casadi.vertcat(
        casadi.horzcat(e1, s12, s13, t1),
        casadi.horzcat(zero, e2, s23, t2),
        casadi.horzcat(zero, zero, e3, t3),
        casadi.horzcat(zero, zero, zero, casadi.SX(1)),
    )
    return scale * U


def exponential_coordinates(phi: casadi.SX) -> casadi.SX:
    """``ψ(φ)``: ``α, d1, d2, d3`` replaced by their exponentials (the plain Cholesky factor's
    diagonal); ``ψ_k > 0`` for those four is the consistent set, ``ψ_k ≥ 0`` its closure."""
    return casadi.vertcat(casadi.exp(phi[0:4]), phi[4:10])


def _link_expression(phi: casadi.SX) -> tuple[casadi.SX, casadi.SX]:
    """Standard parameters and pseudo-inertia of one link from its ``φ``."""
    return link_from_psi(exponential_coordinates(phi))


def link_from_psi(psi: casadi.SX) -> tuple[casadi.SX, casadi.SX]:
    """Standard parameters and pseudo-inertia of one link from its exponential coordinates ``ψ``."""
    U = _upper_factor(psi)
    J = casadi.mtimes(U, U.T)
    sigma = J[:3, :3]
    trace = sigma[0, 0] + sigma[1, 1] + sigma[2, 2]
    inertia = trace * casadi.SX.eye(3) - sigma
    theta = casadi.vertcat(J[3, 3], J[0, 3], J[1, 3], J[2, 3], inertia[0, 0], inertia[0, 1], inertia[1, 1],
                           inertia[0, 2], inertia[1, 2], inertia[2, 2])
    return theta, J


@functools.lru_cache(maxsize=1)
def log_cholesky_link() -> casadi.Function:
    """``log_cholesky_link(phi) -> (theta, J)``: one link's standard parameters and pseudo-inertia."""
    phi = casadi.SX.sym("phi", 10)
    theta, J = _link_expression(phi)
    return casadi.Function("log_cholesky_link", [phi], [theta, J], ["phi"], ["theta", "J"])


def log_det_divergence(phi: casadi.SX, J_prior: NDArray[np.float64]) -> casadi.SX:
    """Entropic (log-det / Bregman) divergence ``tr(J₀⁻¹J) − log det(J₀⁻¹J) − 4`` of a link's
    pseudo-inertia from a prior one (Lee & Park 2018; Rucker & Wensing 2022, eq. 21). Zero only at
    ``J = J₀``; invariant to the choice of frame and units. ``log det J = 8α + 2(d1 + d2 + d3)``."""
    _, J = _link_expression(phi)
    prior_inverse = np.linalg.inv(J_prior)
    log_det_J = 8 * phi[0] + 2 * (phi[1] + phi[2] + phi[3])
    return casadi.sum1(casadi.sum2(casadi.SX(prior_inverse) * J)) - log_det_J + np.linalg.slogdet(J_prior)[1] - 4


# ---------------------------------------------------------------------------------------------
# a whole model

@dataclass(frozen=True)
class LinkBounds:
    """Bounds a user puts on one link: a mass range (kg), a box for the centre of mass (m, link frame).

    ``None`` or an infinite entry: no bound there.
    """

    mass: tuple[float, float] = (0.0, np.inf)
    com_lower: tuple[float, float, float] = (-np.inf, -np.inf, -np.inf)
    com_upper: tuple[float, float, float] = (np.inf, np.inf, np.inf)

    def __post_init__(self) -> None:
        try:
            mass = tuple(float(value) for value in self.mass)
            lower = tuple(float(value) for value in self.com_lower)
            upper = tuple(float(value) for value in self.com_upper)
        except (TypeError, ValueError):
            raise TypeError("link bounds must be numbers: mass [min, max], com_lower and com_upper [x, y, z]") from None
        if len(mass) != 2 or len(lower) != 3 or len(upper) != 3:
            raise ConsistencyBoundsError("link bounds: mass takes [min, max], com_lower/com_upper [x, y, z]")
        if any(np.isnan(mass + lower + upper)):
            raise ConsistencyBoundsError("link bounds hold NaN")
        if not mass[1] > 0:
            raise ConsistencyBoundsError(f"mass range {list(mass)} lies at or below zero: no rigid body has that mass")
        if mass[0] > mass[1]:
            raise ConsistencyBoundsError(f"mass range {list(mass)}: the minimum is above the maximum")
        if any(low > high for low, high in zip(lower, upper)):
            raise ConsistencyBoundsError(f"centre-of-mass box {list(lower)}..{list(upper)} is empty")
        object.__setattr__(self, "mass", mass)
        object.__setattr__(self, "com_lower", lower)
        object.__setattr__(self, "com_upper", upper)

    def phi_bounds(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Bounds on the link's ``φ``: ``α ∈ [½ ln m_min, ½ ln m_max]``, ``t ∈ box``."""
        lower, upper = np.full(10, -np.inf), np.full(10, np.inf)
        with np.errstate(divide="ignore"):
            lower[0] = 0.5 * np.log(self.mass[0]) if self.mass[0] > 0 else -np.inf
            upper[0] = 0.5 * np.log(self.mass[1])
        lower[7:], upper[7:] = self.com_lower, self.com_upper
        return lower, upper

    def contains(self, theta: ArrayLike) -> bool:
        """Whether a link's parameters meet the bounds (centre of mass ``h / m``)."""
        theta = np.asarray(theta, dtype=float)
        if not self.mass[0] <= theta[0] <= self.mass[1] or theta[0] <= 0:
            return False
        com = theta[1:4] / theta[0]
        return bool(np.all(com >= np.array(self.com_lower)) and np.all(com <= np.array(self.com_upper)))


@dataclass(frozen=True, eq=False)
class PhysicalParametrisation:
    """The map ``φ → θ`` of a model's standard parameters (``10 n`` link values, then effects).

    Parameters
    ----------
    n_links
        Links of the chain.
    effect_kinds
        ``nonnegative`` (``θ = z²``) or ``free`` (``θ = z``) for each effect parameter, in model order.
    link_names
        A name per link (reports).
    bounds
        Optional :class:`LinkBounds` per link name.
    """

    n_links: int
    effect_kinds: tuple[ParameterKind, ...]
    link_names: tuple[str, ...]
    bounds: Mapping[str, LinkBounds] = field(default_factory=dict)

    def __post_init__(self) -> None:
        unknown = sorted(set(self.bounds) - set(self.link_names))
        if unknown:
            raise ConsistencyBoundsError(f"bounds for unknown link(s) {unknown}; the links are {list(self.link_names)}")

    @classmethod
    def of_model(cls, model, bounds: Mapping[str, LinkBounds] | None = None) -> PhysicalParametrisation:
        """The parametrisation of an :class:`dynamics.models.IdentificationModel`."""
        kinds: list[ParameterKind] = []
        for effect in model.effects:
            kind = PARAMETER_MAPS.get(getattr(effect, "physical_kind", effect.name), "free")
            kinds.extend([kind] * len(effect.parameter_names(model.robot)))
        return cls(model.robot.n_joints, tuple(kinds), tuple(model.robot.joint_names), dict(bounds or {}))

    @property
    def n_phi(self) -> int:
        return 10 * self.n_links + len(self.effect_kinds)

    @property
    def n_theta(self) -> int:
        return self.n_phi

    @functools.cached_property
    def function(self) -> casadi.Function:
        """``physical_parameters(phi) -> theta``: the named CasADi map (exact derivatives)."""
        phi = casadi.SX.sym("phi", self.n_phi)
        return casadi.Function("physical_parameters", [phi], [self.expression(phi)], ["phi"], ["theta"])

    def expression(self, phi: casadi.SX | casadi.MX) -> casadi.SX:
        link = log_cholesky_link()
        parts = [link(phi[10 * k : 10 * (k + 1)])[0] for k in range(self.n_links)]
        for index, kind in enumerate(self.effect_kinds):
            z = phi[10 * self.n_links + index]
            parts.append(z * z if kind == "nonnegative" else z)
        return casadi.vertcat(*parts)

    def psi_expression(self, psi: casadi.SX) -> casadi.SX:
        """``θ`` from the solver's coordinates ``ψ``: per link the exponential coordinates
        (:func:`exponential_coordinates`), per non-negative effect its value ``z²`` itself."""
        parts = [link_from_psi(psi[10 * k : 10 * (k + 1)])[0] for k in range(self.n_links)]
        parts.append(psi[10 * self.n_links :])
        return casadi.vertcat(*parts)

    def psi_from_phi(self, phi: ArrayLike) -> NDArray[np.float64]:
        psi = np.array(phi, dtype=float).reshape(-1)
        for k in range(self.n_links):
            psi[10 * k : 10 * k + 4] = np.exp(psi[10 * k : 10 * k + 4])
        for index, kind in enumerate(self.effect_kinds):
            if kind == "nonnegative":
                psi[10 * self.n_links + index] **= 2
        return psi

    def phi_from_psi(self, psi: ArrayLike) -> NDArray[np.float64]:
        """``φ`` of solver coordinates (their exponential coordinates must be positive)."""
        phi = np.array(psi, dtype=float).reshape(-1)
        for k in range(self.n_links):
            with np.errstate(divide="ignore"):
                phi[10 * k : 10 * k + 4] = np.log(phi[10 * k : 10 * k + 4])
        for index, kind in enumerate(self.effect_kinds):
            if kind == "nonnegative":
                phi[10 * self.n_links + index] = np.sqrt(max(phi[10 * self.n_links + index], 0.0))
        return phi

    def psi_bounds(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Bounds on ``ψ``: the exponential coordinates and the non-negative effects at or above
        zero, and the user's bounds (mass: ``e^α ∈ [√m_min, √m_max]``; centre of mass: ``t``)."""
        lower, upper = self.phi_bounds()
        for k in range(self.n_links):
            lower[10 * k : 10 * k + 4] = np.exp(lower[10 * k : 10 * k + 4])
            upper[10 * k : 10 * k + 4] = np.exp(upper[10 * k : 10 * k + 4])
        for index, kind in enumerate(self.effect_kinds):
            if kind == "nonnegative":
                lower[10 * self.n_links + index] = 0.0
        return lower, upper

    def __call__(self, phi: ArrayLike) -> NDArray[np.float64]:
        """``θ(φ)`` as a numpy vector."""
        return np.asarray(self.function(np.asarray(phi, dtype=float).reshape(-1))).reshape(-1)

    def inverse(self, theta: ArrayLike) -> NDArray[np.float64]:
        """``φ`` of standard parameters whose links are strictly consistent and whose non-negative
        effects are non-negative (raises :class:`InconsistentBodyError` otherwise)."""
        theta = np.asarray(theta, dtype=float).reshape(-1)
        if theta.shape != (self.n_theta,):
            raise ValueError(f"expected {self.n_theta} parameters, got {theta.shape[0]}")
        phi = [log_cholesky_from_link(theta[10 * k : 10 * (k + 1)]) for k in range(self.n_links)]
        effects = theta[10 * self.n_links :]
        for value, kind in zip(effects, self.effect_kinds):
            if kind == "nonnegative" and value < 0:
                raise InconsistentBodyError(f"a non-negative effect parameter is {value}")
        phi.append(np.array([np.sqrt(v) if kind == "nonnegative" else v for v, kind in zip(effects, self.effect_kinds)]))
        return np.concatenate(phi)

    def project(self, theta: ArrayLike, *, floor: float = 1e-6, effect_floor: float = 0.0) -> NDArray[np.float64]:
        """Standard parameters moved onto the consistent set: each link's pseudo-inertia with its
        eigenvalues clipped (:func:`project_link`), then into its bounds (mass clipped, centre of mass
        clipped into its box, keeping ``I_C``), non-negative effects clipped at ``effect_floor``."""
        theta = np.array(theta, dtype=float).reshape(-1)
        for k, name in enumerate(self.link_names):
            block = slice(10 * k, 10 * (k + 1))
            link = project_link(theta[block], floor)
            if name in self.bounds:
                link = _into_bounds(link, self.bounds[name])
            theta[block] = link
        effects = theta[10 * self.n_links :]
        for index, kind in enumerate(self.effect_kinds):
            if kind == "nonnegative":
                effects[index] = max(effects[index], effect_floor)
        return theta

    def phi_bounds(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Lower and upper bounds on ``φ`` (infinite where there is none)."""
        lower, upper = np.full(self.n_phi, -np.inf), np.full(self.n_phi, np.inf)
        for k, name in enumerate(self.link_names):
            if name in self.bounds:
                lower[10 * k : 10 * (k + 1)], upper[10 * k : 10 * (k + 1)] = self.bounds[name].phi_bounds()
        return lower, upper

    def phi_names(self) -> list[str]:
        names = [f"{name}[{k + 1}]" for k in range(self.n_links) for name in PHI_NAMES]
        return names + [f"z{index}" for index in range(len(self.effect_kinds))]


def _into_bounds(theta: NDArray[np.float64], bounds: LinkBounds) -> NDArray[np.float64]:
    """Mass clipped into its range and centre of mass into its box, the inertia about the centre kept."""
    mass = theta[0]
    com = theta[1:4] / mass
    inertia = _inertia(theta)
    inertia_com = inertia - mass * (com @ com * np.eye(3) - np.outer(com, com))
    mass = float(np.clip(mass, max(bounds.mass[0], 1e-9), bounds.mass[1]))
    com = np.clip(com, bounds.com_lower, bounds.com_upper)
    inertia = inertia_com + mass * (com @ com * np.eye(3) - np.outer(com, com))
    return np.array([mass, *(mass * com), inertia[0, 0], inertia[0, 1], inertia[1, 1], inertia[0, 2],
                     inertia[1, 2], inertia[2, 2]])


def _inertia(theta: NDArray[np.float64]) -> NDArray[np.float64]:
    _, _, _, _, ixx, ixy, iyy, ixz, iyz, izz = theta
    return np.array([[ixx, ixy, ixz], [ixy, iyy, iyz], [ixz, iyz, izz]])


def link_summary(theta: ArrayLike) -> dict[str, object]:
    """``{mass, com, inertia, inertia_com}`` of one link (inertia about the link-frame origin, and
    about the centre of mass), as plain lists for JSON."""
    theta = np.asarray(theta, dtype=float)
    mass = float(theta[0])
    com = theta[1:4] / mass if mass > 0 else np.zeros(3)
    inertia = _inertia(theta)
    inertia_com = inertia - mass * (com @ com * np.eye(3) - np.outer(com, com))
    return {"mass": mass, "com": com.tolist(), "inertia": inertia.tolist(), "inertia_com": inertia_com.tolist()}


__all__: Sequence[str] = [
    "ConsistencyBoundsError", "InconsistentBodyError", "LinkBounds", "PARAMETER_MAPS", "PHI_NAMES",
    "PhysicalParametrisation", "consistency_margin", "from_pseudo_inertia", "is_consistent", "link_summary",
    "log_cholesky_from_link", "log_cholesky_link", "log_det_divergence", "project_link", "pseudo_inertia",
]
