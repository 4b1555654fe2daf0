"""The description's joint terms as the consistent fit's prior for the per-joint laws that are theirs.

A robot description may give, beside its bodies, each joint's rotor inertia and friction: an MJCF model's
``armature``, ``damping`` and ``frictionloss`` (:mod:`dynamics.mjcf`, held as :class:`dynamics.robot.Joint`'s
``armature``, ``damping`` and ``friction``). Where the identified model holds the law of one (``armature`` ``Ia_j``,
``viscous`` ``fv_j``, ``coulomb`` ``fc_j``, :mod:`dynamics.effects.linear`) and the description's value is not zero,
the consistent fit with a prior (``prior_weight = w > 0``, :mod:`estimation.consistent.least_squares`) pulls it
toward that value as it pulls the bodies toward the description's, by a Gaussian prior of the value's own size::

    w · ½ Σ_j ((θ_j − μ_j) / μ_j)²

(a relative deviation of ``1/√w`` costs ½ in ``½χ²``, as a body's log-det divergence does for a relative change of
its pseudo-inertia of about ``1/(2√w)``). A zero in the description is no statement (MJCF's default, a model that
leaves friction out): no prior. Without a prior weight (``w = 0``) nothing changes; a description without joint
terms (every URDF, DH table and built-in robot) gives none, and its fit is the one without this module.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from dynamics.effects.linear import Armature, CoulombFriction, ViscousFriction
from dynamics.models import IdentificationModel

__all__ = ["DESCRIBED_TERMS", "EffectPrior", "effect_prior"]

#: the per-joint laws whose values a description gives, and the :class:`dynamics.robot.Joint` field holding each
DESCRIBED_TERMS: dict[type, str] = {Armature: "armature", ViscousFriction: "damping", CoulombFriction: "friction"}


class EffectPrior:
    """The prior of the effect parameters ``θ[10 n:]``: ``mean`` and ``precision`` (``1/μ²``, 0 where none), and
    the named values (for reports)."""

    def __init__(self, mean: NDArray[np.float64], precision: NDArray[np.float64], values: dict[str, float]) -> None:
        self.mean, self.precision, self.values = mean, precision, values

    def cost(self, theta_effects: NDArray[np.float64]) -> float:
        """``½ Σ precision (θ − μ)²`` (without the weight)."""
        return float(0.5 * np.sum(self.precision * (np.asarray(theta_effects) - self.mean) ** 2))


def effect_prior(model: IdentificationModel) -> EffectPrior | None:
    """The description's prior for ``model``'s per-joint armature, viscous and Coulomb parameters (module
    docstring), or ``None`` when the description gives none of them a non-zero value."""
    robot = model.robot
    start = 10 * robot.n_joints
    names = list(model.parameter_names)[start:]
    mean, precision = np.zeros(len(names)), np.zeros(len(names))
    values: dict[str, float] = {}
    for effect in model.effects:
        field = next((term for kind, term in DESCRIBED_TERMS.items() if type(effect) is kind), None)
        if field is None:
            continue
        indices = effect.joints if effect.joints is not None else range(robot.n_joints)
        for index, name in zip(indices, effect.parameter_names(robot)):
            value = float(getattr(robot.joints[index], field))
            if value > 0 and name in names:
                position = names.index(name)
                mean[position], precision[position] = value, 1.0 / value**2
                values[name] = value
    return EffectPrior(mean, precision, values) if values else None
