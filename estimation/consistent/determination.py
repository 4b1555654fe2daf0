"""Which bodies, and which directions of them, the data determined.

The unconstrained estimate's covariance ``Σ_b`` (classical or HAC: relative to the noise the
residuals show) is the inverse of the information the data hold on the base parameters. On the
standard parameters ``θ = (θ_links, θ_effects)`` of ``θ_b = K θ`` it is

.. math::  F = K^T Σ_b^{-1} K ,\\qquad
           F_{links} = F_{LL} − F_{LE} F_{EE}^{+} F_{EL}

(the effects' parameters unknown too: the Schur complement). Each link's ten parameters are
scaled by the nominal body (the prior): its mass ``m₀`` for ``m``, ``m₀ ℓ`` for the first moments
and ``m₀ ℓ²`` for the inertias, ``ℓ`` the link's reach
(:func:`estimation.identification.plausibility.link_reach`). An eigenvector ``v`` of the scaled
information ``S F_links S`` with eigenvalue ``λ`` is a direction of the bodies known to a
standard deviation ``1/√λ`` of their own size; it is **undetermined** when that exceeds
:data:`RELATIVE_STD_THRESHOLD`, and **structural** when ``λ`` is zero to rounding (no record
determines it: it is not in the span of the base parameters). There the consistent estimate
comes from the prior (``--prior-weight``), not from the data.

Each direction is named by its loadings ``v_i²`` (the parameters holding at least
:data:`LOADING_SHOWN` of it); a parameter is undetermined when more than half of it lies in the
undetermined subspace (``Σ v_i²`` over those directions, a property of the subspace, unlike the
directions themselves, which are arbitrary within a repeated eigenvalue).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from dynamics.models import IdentificationModel
from dynamics.robot import N_LINK_PARAMETERS
from estimation.identification.plausibility import link_reach

__all__ = ["LOADING_SHOWN", "RELATIVE_STD_THRESHOLD", "Determination", "UndeterminedDirection", "determination"]

#: a direction of the bodies known to a standard deviation above this fraction of its nominal size is
#: undetermined: there a prior of weight about 1 (units of ½χ²) weighs as much as the data
RELATIVE_STD_THRESHOLD = 1.0
#: loadings ``v_i²`` from this up name a direction's parameters
LOADING_SHOWN = 0.05
#: eigenvalues below this fraction of the largest are zero (structural directions)
STRUCTURAL_TOLERANCE = 1e-10


@dataclass(frozen=True)
class UndeterminedDirection:
    """One eigenvector of the scaled information the data did not determine.

    Attributes
    ----------
    relative_std
        Its standard deviation from the data alone in units of the nominal body (``inf``: structural).
    structural
        No record determines it (outside the span of the base parameters).
    loadings
        Standard-parameter name to ``v_i²``, largest first (those from :data:`LOADING_SHOWN`).
    """

    relative_std: float
    structural: bool
    loadings: tuple[tuple[str, float], ...]

    def to_dict(self) -> dict[str, Any]:
        return {"relative_std": None if not np.isfinite(self.relative_std) else self.relative_std,
                "structural": self.structural, "parameters": dict(self.loadings)}

    def describe(self) -> str:
        """``0.71 m2 + 0.25 mx2`` with its standard deviation."""
        names = " + ".join(f"{loading:.2f} {name}" for name, loading in self.loadings)
        size = "structural" if self.structural else f"std {self.relative_std:.3g} x nominal"
        return f"{names} ({size})"


@dataclass(frozen=True)
class Determination:
    """What the data determined of the bodies (module docstring).

    Attributes
    ----------
    directions
        The undetermined directions, structural ones last.
    links
        Link name to its undetermined parameters (only links with some).
    threshold
        :data:`RELATIVE_STD_THRESHOLD` as used.
    n_directions
        How many directions the bodies have (``10 n``).
    """

    directions: tuple[UndeterminedDirection, ...]
    links: dict[str, tuple[str, ...]]
    threshold: float
    n_directions: int

    @property
    def n_structural(self) -> int:
        return sum(direction.structural for direction in self.directions)

    def to_dict(self) -> dict[str, Any]:
        """The key ``consistent.undetermined`` of ``result.json``."""
        return {"threshold_relative_std": self.threshold, "n_directions": self.n_directions,
                "n_undetermined": len(self.directions), "n_structural": self.n_structural,
                "links": {name: list(parameters) for name, parameters in self.links.items()},
                "directions": [direction.to_dict() for direction in self.directions]}

    def lines(self, shown: int = 5) -> list[str]:
        """The summary printed by ``oed identify --consistent``."""
        weak = [direction for direction in self.directions if not direction.structural]
        lines = [f"not determined by the data: {len(self.directions)} of {self.n_directions} directions of the bodies "
                 f"({self.n_structural} structural, {len(weak)} with a standard deviation above "
                 f"{self.threshold:g} x the nominal body); there the prior sets the estimate"]
        lines += [f"  {name}: {', '.join(parameters)}" for name, parameters in self.links.items()]
        lines += [f"  direction {direction.describe()}" for direction in weak[:shown]]
        if len(weak) > shown:
            lines.append(f"  … {len(weak) - shown} more in result.json (consistent.undetermined)")
        return lines


def body_scales(model: IdentificationModel, prior: NDArray[np.float64]) -> NDArray[np.float64]:
    """``(10 n,)`` the nominal size of each standard parameter of the links: ``m₀``, ``m₀ ℓ``, ``m₀ ℓ²``
    (a massless nominal body takes a tenth of the mean nominal mass, 1 kg when all are massless)."""
    links = np.asarray(prior, dtype=float).reshape(-1, N_LINK_PARAMETERS)
    masses = links[:, 0]
    floor = 0.1 * float(masses.mean()) if np.any(masses > 0) else 1.0
    masses = np.maximum(masses, floor)
    reach = link_reach(model.robot)
    scales = np.empty_like(links)
    scales[:, 0] = masses
    scales[:, 1:4] = (masses * reach)[:, None]
    scales[:, 4:] = (masses * reach**2)[:, None]
    return scales.reshape(-1)


def link_information(model: IdentificationModel, cov: NDArray[np.float64]) -> NDArray[np.float64]:
    """``F_links`` (module docstring): the information on the links' standard parameters, the effects unknown."""
    K = np.asarray(model.base.K, dtype=float)
    cov = 0.5 * (cov + cov.T)
    values, vectors = np.linalg.eigh(cov)
    keep = values > STRUCTURAL_TOLERANCE * max(float(values.max()), 0.0)
    precision = (vectors[:, keep] / values[keep]) @ vectors[:, keep].T
    F = K.T @ precision @ K
    n = N_LINK_PARAMETERS * model.robot.n_joints
    links, effects = F[:n, :n], F[:n, n:]
    if effects.shape[1]:
        links = links - effects @ np.linalg.pinv(F[n:, n:], hermitian=True) @ effects.T
    return 0.5 * (links + links.T)


def determination(model: IdentificationModel, cov: NDArray[np.float64], prior: NDArray[np.float64], *,
                  threshold: float = RELATIVE_STD_THRESHOLD) -> Determination:
    """The directions of the bodies that ``cov`` (the unconstrained base parameters' covariance) leaves
    undetermined, in units of the ``prior`` bodies (``10 n`` standard parameters; module docstring)."""
    if not (np.isfinite(threshold) and threshold > 0):
        raise ValueError(f"threshold must be a positive number, got {threshold}")
    scales = body_scales(model, prior)
    scaled = scales[:, None] * link_information(model, np.asarray(cov, dtype=float)) * scales[None, :]
    values, vectors = np.linalg.eigh(scaled)
    largest = max(float(values.max()), 0.0)
    names = model.parameter_names[: scales.shape[0]]
    undetermined, directions = [], []
    for value, vector in sorted(zip(values, vectors.T), key=lambda pair: -pair[0]):
        structural = value <= STRUCTURAL_TOLERANCE * largest
        relative_std = np.inf if structural else float(1.0 / np.sqrt(value))
        if not structural and relative_std <= threshold:
            continue
        undetermined.append(vector)
        loadings = sorted(((names[i], float(vector[i] ** 2)) for i in range(vector.shape[0])
                           if vector[i] ** 2 >= LOADING_SHOWN), key=lambda pair: -pair[1])
        directions.append(UndeterminedDirection(relative_std, bool(structural), tuple(loadings)))
    share = np.sum(np.square(undetermined), axis=0) if undetermined else np.zeros(scales.shape[0])
    links: dict[str, tuple[str, ...]] = {}
    for k, link in enumerate(model.robot.joint_names):
        block = range(N_LINK_PARAMETERS * k, N_LINK_PARAMETERS * (k + 1))
        parameters = tuple(names[i] for i in block if share[i] > 0.5)
        if parameters:
            links[link] = parameters
    directions.sort(key=lambda direction: direction.structural)
    return Determination(tuple(directions), links, float(threshold), scales.shape[0])
