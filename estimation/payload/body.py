"""A rigid payload's ten standard parameters as a body: mass, centre of mass, inertia about it, with uncertainties.

The ten standard parameters of a body fixed to link ``k`` are, in the link frame ``F_k`` (:mod:`dynamics.robot`),

    π = (m, mx, my, mz, Ixx, Ixy, Iyy, Ixz, Iyz, Izz),      h = m c,   I_O = I_C + m (|c|² 1 − c cᵀ),

``c`` the centre of mass and ``I_C`` the inertia about it (link-frame axes). :func:`body_values` maps ``π`` to
``(m, cx, cy, cz, ixx, iyy, izz, ixy, ixz, iyz)`` of ``I_C``; the standard deviations of these follow from the
covariance of ``π`` through the map's Jacobian (first order, exact derivatives by CasADi).
"""

from __future__ import annotations

import functools
from dataclasses import dataclass
from typing import Any

import casadi
import numpy as np
from numpy.typing import ArrayLike, NDArray

from dynamics.robot import LINK_PARAMETER_NAMES

__all__ = ["BODY_NAMES", "INERTIA_KEYS", "PayloadBody", "body_values"]

#: the body's values in :func:`body_values` order
BODY_NAMES: tuple[str, ...] = ("mass", "cx", "cy", "cz", "ixx", "iyy", "izz", "ixy", "ixz", "iyz")
#: the keys of ``payload.inertia`` (about the centre of mass, link-frame axes)
INERTIA_KEYS: tuple[str, ...] = ("ixx", "iyy", "izz", "ixy", "ixz", "iyz")


@functools.lru_cache(maxsize=1)
def _body_function() -> casadi.Function:
    """``payload_body(pi) -> (values, jacobian)``: :data:`BODY_NAMES` of the standard parameters and their Jacobian."""
    pi = casadi.SX.sym("pi", 10)
    m, h = pi[0], pi[1:4]
    c = h / m
    ixx, ixy, iyy, ixz, iyz, izz = (pi[k] for k in range(4, 10))
    # I_C = I_O − m (|c|² 1 − c cᵀ) = I_O − (|h|² 1 − h hᵀ)/m
    values = casadi.vertcat(
        m, c,
        ixx - m * (c[1] ** 2 + c[2] ** 2), iyy - m * (c[0] ** 2 + c[2] ** 2), izz - m * (c[0] ** 2 + c[1] ** 2),
        ixy + m * c[0] * c[1], ixz + m * c[0] * c[2], iyz + m * c[1] * c[2],
    )
    return casadi.Function("payload_body", [pi], [values, casadi.jacobian(values, pi)], ["pi"], ["body", "J"])


def body_values(parameters: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """``(values, J)``: the :data:`BODY_NAMES` of ten standard parameters (mass > 0) and the ``10 x 10`` Jacobian."""
    parameters = np.asarray(parameters, dtype=float).reshape(-1)
    if parameters.shape != (10,):
        raise ValueError(f"a body has 10 standard parameters {LINK_PARAMETER_NAMES}, got {parameters.shape[0]}")
    if not parameters[0] > 0:
        raise ValueError(f"a body needs a positive mass, got {parameters[0]:g} kg")
    values, jacobian = _body_function()(parameters)
    return np.asarray(values, dtype=float).reshape(-1), np.asarray(jacobian, dtype=float)


@dataclass(frozen=True)
class PayloadBody:
    """A body from standard parameters ``π`` and their covariance (module docstring).

    Attributes
    ----------
    parameters
        ``π`` (link frame, inertia about the link-frame origin).
    cov
        ``10 x 10`` covariance of ``π``.
    """

    parameters: NDArray[np.float64]
    cov: NDArray[np.float64]

    @property
    def values(self) -> NDArray[np.float64]:
        """:data:`BODY_NAMES` values."""
        return body_values(self.parameters)[0]

    @property
    def values_cov(self) -> NDArray[np.float64]:
        """Covariance of the :data:`BODY_NAMES` values (first order)."""
        _, jacobian = body_values(self.parameters)
        return jacobian @ self.cov @ jacobian.T

    @property
    def values_std(self) -> NDArray[np.float64]:
        return np.sqrt(np.clip(np.diag(self.values_cov), 0.0, None))

    @property
    def mass(self) -> float:
        return float(self.parameters[0])

    @property
    def com(self) -> NDArray[np.float64]:
        """Centre of mass, m, link frame."""
        return self.values[1:4]

    @property
    def inertia(self) -> NDArray[np.float64]:
        """``3 x 3`` inertia about the centre of mass, link-frame axes, kg·m²."""
        ixx, iyy, izz, ixy, ixz, iyz = self.values[4:]
        return np.array([[ixx, ixy, ixz], [ixy, iyy, iyz], [ixz, iyz, izz]])

    @property
    def principal_moments(self) -> NDArray[np.float64]:
        """Eigenvalues of :attr:`inertia`, ascending."""
        return np.linalg.eigvalsh(self.inertia)

    def described(self, values: NDArray[np.float64]) -> dict[str, Any]:
        """``{mass, com, inertia}`` of a :data:`BODY_NAMES` vector (values or standard deviations) for JSON."""
        return {"mass": float(values[0]), "com": [float(v) for v in values[1:4]],
                "inertia": {key: float(v) for key, v in zip(INERTIA_KEYS, values[4:])}}

    def to_dict(self) -> dict[str, Any]:
        """``mass`` (kg), ``com`` ([x, y, z] m), ``inertia`` ({ixx…iyz} kg·m², about the centre of mass), ``std``
        (the same keys), ``parameters`` (the standard ones by name) and ``principal_moments``."""
        return {**self.described(self.values), "std": self.described(self.values_std),
                "parameters": dict(zip(LINK_PARAMETER_NAMES, map(float, self.parameters))),
                "principal_moments": self.principal_moments.tolist()}
