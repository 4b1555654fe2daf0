"""Is an unconstrained fit physically plausible? Two checks a user should not have to make by hand.

* **Worse than the description.** The identified model predicts the validation data worse than the
  nominal model (the URDF's or DH table's inertial values, every effect 0): summed over the
  channels, each MSE relative to the channel's mean square, and per channel.
* **Negative inertia.** A base parameter that is, by its grouping ``θ_b = K θ``, a non-negative
  combination of masses, diagonal inertias about the link-frame origins and positive-by-physics
  effect terms (armature, friction) only, can never be below zero for real bodies; an estimate
  more than :data:`SIGMAS` standard deviations below zero is implausible.

Both are what a physically consistent fit (``oed identify --consistent``) rules out or exposes. Consistent
is not yet plausible: :func:`link_findings` names the bodies of a consistent fit that the data did not
determine (a degenerate pseudo-inertia: the bounds of consistency set it) or that lie far from the
description (a mass :data:`MASS_FACTOR` times the nominal one or more, or as much below it), or whose
centre of mass lies beyond :data:`COM_REACH_FACTOR` times the link's reach (:func:`link_reach`) from its
frame's origin.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from dynamics.effects.linear import POSITIVE_EFFECTS
from dynamics.models import IdentificationModel
from dynamics.physical_parameters import consistency_margin
from dynamics.robot import LINK_PARAMETER_NAMES, N_LINK_PARAMETERS, RobotModel

__all__ = ["COM_REACH_FACTOR", "DEGENERATE_MARGIN", "MASS_FACTOR", "SIGMAS", "Plausibility", "assess_plausibility",
           "link_findings", "link_reach", "positive_base_parameters"]

#: standard deviations below zero that make a positive-by-physics base parameter implausible
SIGMAS = 3.0
#: the link parameters that are never negative (mass, and the diagonal inertias about the frame origin)
NON_NEGATIVE_LINK_PARAMETERS = ("m", "Ixx", "Iyy", "Izz")
#: a body whose pseudo-inertia's smallest over largest eigenvalue is below this is degenerate (a point, a
#: rod or a plate): the data did not determine it, the bounds of consistency did
DEGENERATE_MARGIN = 1e-9
#: a consistent body this many times heavier or lighter than the description's is named
MASS_FACTOR = 10.0
#: a consistent body whose centre of mass lies farther than this many times its link's reach from the link
#: frame's origin is named
COM_REACH_FACTOR = 2.0
ADVICE = "a physically consistent fit (`oed identify --consistent`) keeps every link a real rigid body"


def positive_base_parameters(model: IdentificationModel) -> tuple[bool, ...]:
    """Per base parameter: whether its grouping is a non-negative combination of never-negative terms."""
    K = np.asarray(model.base.K, dtype=float)
    n_links = model.robot.n_joints
    allowed = np.zeros(K.shape[1], dtype=bool)
    for link in range(n_links):
        for name in NON_NEGATIVE_LINK_PARAMETERS:
            allowed[link * N_LINK_PARAMETERS + LINK_PARAMETER_NAMES.index(name)] = True
    start = n_links * N_LINK_PARAMETERS
    for effect in model.effects:
        count = len(effect.parameter_names(model.robot))
        if getattr(effect, "physical_kind", effect.name) in POSITIVE_EFFECTS:
            allowed[start:start + count] = True
        start += count
    tolerance = 1e-9 * max(float(np.max(np.abs(K))), 1.0)
    return tuple(bool(np.any(row > tolerance) and np.all(row >= -tolerance) and np.all(np.abs(row[~allowed]) <= tolerance))
                 for row in K)


@dataclass(frozen=True)
class Plausibility:
    """What the two checks found (module docstring)."""

    worse_than_nominal: bool
    channels_worse_than_nominal: tuple[str, ...]
    relative_mse: float | None
    nominal_relative_mse: float | None
    negative_terms: tuple[dict[str, float | str], ...]

    @property
    def plausible(self) -> bool:
        return not (self.worse_than_nominal or self.negative_terms)

    def messages(self) -> tuple[str, ...]:
        """One line per finding, each pointing to the consistent fit."""
        lines = []
        if self.worse_than_nominal:
            lines.append(f"the identified model predicts the validation data worse than the nominal description "
                         f"(relative MSE {self.relative_mse:.4g} against {self.nominal_relative_mse:.4g}; channels "
                         f"{', '.join(self.channels_worse_than_nominal) or 'none alone'}): not plausible; {ADVICE}")
        for term in self.negative_terms:
            lines.append(f"{term['name']} = {term['value']:.4g} ± {term['std']:.2g} ({term['expression']}) is "
                         f"{term['sigmas']:.1f} standard deviations below zero, which no real bodies give: not "
                         f"plausible; {ADVICE}")
        return tuple(lines)

    def to_dict(self) -> dict[str, Any]:
        return {"plausible": self.plausible, "worse_than_nominal": self.worse_than_nominal,
                "channels_worse_than_nominal": list(self.channels_worse_than_nominal),
                "relative_mse": self.relative_mse, "nominal_relative_mse": self.nominal_relative_mse,
                "negative_terms": [dict(term) for term in self.negative_terms], "sigmas": SIGMAS,
                "messages": list(self.messages())}


def assess_plausibility(model: IdentificationModel, records: list[dict[str, Any]], *,
                        validation_mse: Mapping[str, float] | None = None,
                        nominal_mse: Mapping[str, float] | None = None,
                        zero_mse: Mapping[str, float] | None = None, sigmas: float = SIGMAS) -> Plausibility:
    """The two checks on a fit of ``model``: ``records`` its base parameters (``name, expression, value,
    std``, in base order), the validation MSE per channel beside the nominal model's and the zero
    predictor's (the mean square that makes MSEs of channels in different units comparable)."""
    negative = []
    for positive, record in zip(positive_base_parameters(model), records):
        std, value = record.get("std"), record["value"]
        if positive and std is not None and np.isfinite(std) and std > 0 and value < -sigmas * std:
            negative.append({"name": record["name"], "expression": record["expression"], "value": float(value),
                             "std": float(std), "sigmas": float(-value / std)})
    relative = nominal = None
    worse_channels: tuple[str, ...] = ()
    if validation_mse and nominal_mse and zero_mse:
        channels = [channel for channel in validation_mse if zero_mse.get(channel, 0) > 0 and channel in nominal_mse]
        relative = float(sum(validation_mse[c] / zero_mse[c] for c in channels))
        nominal = float(sum(nominal_mse[c] / zero_mse[c] for c in channels))
        worse_channels = tuple(c for c in channels if validation_mse[c] > nominal_mse[c])
    worse = relative is not None and nominal is not None and relative > nominal
    return Plausibility(worse, worse_channels, relative, nominal, tuple(negative))


def link_reach(robot: RobotModel) -> np.ndarray:
    """``(n,)`` each link's reach, m: the farthest from its frame's origin of its own joint's origin, the next
    joint's origin and its nominal centre of mass, and at least a tenth of the chain's span (the summed
    distances from joint to joint; 1 m for a chain of coincident joints)."""
    own, span = [], 0.0
    for k, joint in enumerate(robot.joints):
        rotation, offset = joint.link_transform[:3, :3], joint.link_transform[:3, 3]
        start = -rotation.T @ offset  # the joint's origin in the link frame
        end = robot.joints[k + 1].placement[:3, 3] if k + 1 < robot.n_joints else start
        mass = joint.inertial[0]
        com = joint.inertial[1:4] / mass if mass > 0 else np.zeros(3)
        own.append(max(float(np.linalg.norm(start)), float(np.linalg.norm(end)), float(np.linalg.norm(com))))
        span += float(np.linalg.norm(end - start))
    floor = 0.1 * span if span > 0 else 1.0
    return np.maximum(np.array(own), floor)


def link_findings(robot: RobotModel, links: np.ndarray) -> tuple[str, ...]:
    """One message per body of a consistent fit (``links``: ``(n, 10)`` standard parameters) that is
    degenerate, whose mass is :data:`MASS_FACTOR` times the description's or more, or as much below, or
    whose centre of mass lies beyond :data:`COM_REACH_FACTOR` times the link's reach (:func:`link_reach`)."""
    messages = []
    reach = link_reach(robot)
    for joint, link, limit in zip(robot.joints, np.asarray(links, dtype=float).reshape(-1, N_LINK_PARAMETERS),
                                  COM_REACH_FACTOR * reach):
        margin = consistency_margin(link)
        nominal = float(joint.inertial[0])
        if margin < DEGENERATE_MARGIN:
            messages.append(f"link of {joint.name}: mass {link[0]:.4g} kg, consistency margin {margin:.2g}: a "
                            "degenerate body, set by the bounds of consistency rather than by the data (a richer "
                            "excitation, a larger prior weight or link bounds (--consistent --prior-weight W, --link-bounds FILE) determine it)")
            continue
        if nominal > 0 and not nominal / MASS_FACTOR <= link[0] <= MASS_FACTOR * nominal:
            messages.append(f"link of {joint.name}: mass {link[0]:.4g} kg against {nominal:.4g} kg in the description: "
                            "the data hardly determine it (a larger prior weight or link bounds (--consistent --prior-weight W, --link-bounds FILE) "
                            "keep it near the description)")
        distance = float(np.linalg.norm(link[1:4] / link[0])) if link[0] > 0 else 0.0
        if distance > limit:
            messages.append(f"link of {joint.name}: centre of mass {distance:.3g} m from the link frame's origin, "
                            f"beyond {COM_REACH_FACTOR:g} x the link's reach ({limit / COM_REACH_FACTOR:.3g} m): the "
                            "data hardly determine it (a larger prior weight or link bounds (--consistent --prior-weight W, --link-bounds FILE) keep it "
                            "on the link)")
    return tuple(messages)
