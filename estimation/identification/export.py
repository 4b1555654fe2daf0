"""A physically consistent identified model written out for other tools: a URDF and ``friction.json``.

The URDF (:mod:`dynamics.urdf_export`) carries the identified bodies; ``friction.json`` the rest of
the model, so that Pinocchio's RNEA on the URDF plus these terms is the model's prediction::

    {"joints": {"<joint name>": {"viscous": fv, "coulomb": fc, "offset": off, "armature": Ia,
                                 "coulomb_smoothing": V,                       # tanh(dq / V) instead of sign
                                 "stribeck": {"fs": …, "velocity": …}, "spring": {"k": …, "reference": …}}},
     "effects": [{"spec": "coulomb[q5+q6]", "parameters": {"fc56": …}}],       # effects not on one joint
     "laws": {"viscous": "fv * dq", …}, "delay": 0.007 | null, "gravity": [0, 0, -9.81], "channels": […]}

``τ_j = RNEA(q, q̇, q̈)_j + Σ laws of joint j`` (joint rows; the other effects and the delay as named).
Only a consistent estimate is exported (:func:`exported_model`: the chosen model when it is one, else the
file's consistent alternative, named): base parameters alone do not determine the bodies (a base
parameter is a sum of standard ones, and a body of unconstrained values need not be a real one).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from dynamics.effects.specs import effect_spec
from dynamics.urdf_export import robot_urdf, urdf_with_inertials
from estimation.identification.identified_model import IdentifiedModel
from estimation.identification.model_file import read_model_file
from estimation.identification.plausibility import link_findings

__all__ = ["LAWS", "ExportError", "exported_model", "exported_urdf", "friction_document", "implausible_links"]

#: the per-joint laws friction.json names, as formulas of the joint's motion
LAWS = {
    "viscous": "fv * dq",
    "coulomb": "fc * sign(dq), or fc * tanh(dq / coulomb_smoothing) when coulomb_smoothing is given",
    "offset": "off",
    "armature": "Ia * ddq",
    "stribeck": "fs * exp(-(dq / velocity)**2) * sign(dq)",
    "spring": "k * (q - reference)",
}


class ExportError(ValueError):
    """A model that cannot be exported as bodies (no consistent estimate)."""


def _check_consistent(model: IdentifiedModel) -> None:
    if model.file.consistent_links is None:
        raise ExportError("this model holds base parameters only (an unconstrained fit): they do not determine the "
                          "bodies' masses, centres of mass and inertias, and unconstrained values need not be a real "
                          "body; identify with `oed identify --consistent` and export that result")
    if model.estimate != "consistent":
        raise ExportError(f"the model {model.estimate!r} holds base parameters only (an unconstrained fit): only the "
                          "physically consistent one ('consistent') has bodies to export")


def exported_model(path: str | Path, *, alternative: str | None = None) -> tuple[IdentifiedModel, str | None]:
    """The model ``oed export`` writes from the result file ``path``, and a note when it is not the chosen one.

    The chosen model when it is physically consistent; else the file's consistent alternative, named in the
    note; ``alternative``: that model, which must be the consistent one. :class:`ExportError` when there is none.
    """
    model_file = read_model_file(path)
    if alternative is not None:
        model = IdentifiedModel(model_file, estimate=alternative)
        _check_consistent(model)
        return model, None
    chosen = model_file.chosen or "unconstrained"
    if chosen == "consistent":
        return IdentifiedModel(model_file), None
    if model_file.consistent_links is None:
        model = IdentifiedModel(model_file)
        _check_consistent(model)
    note = (f"the chosen model ({chosen}) holds base parameters only, which do not determine bodies: wrote its "
            "physically consistent alternative 'consistent' instead (oed predict --alternative consistent predicts "
            "with it)")
    return IdentifiedModel(model_file, estimate="consistent"), note


def implausible_links(model: IdentifiedModel) -> tuple[str, ...]:
    """One message per exported body that is degenerate or far from the description
    (:func:`estimation.identification.plausibility.link_findings`)."""
    _check_consistent(model)
    return link_findings(model.robot, model.file.consistent_links)


def exported_urdf(model: IdentifiedModel) -> str:
    """The URDF of the identified bodies: the model's own URDF with its inertials replaced, or one
    written from a built-in robot's description."""
    _check_consistent(model)
    links = model.file.consistent_links
    source = model.file.robot
    if source.urdf_text is not None:
        return urdf_with_inertials(source.urdf_text, model.robot, links)
    if source.urdf_path is not None:
        with open(source.urdf_path) as stream:  # the hash was checked when the model was loaded
            return urdf_with_inertials(stream.read(), model.robot, links)
    return robot_urdf(model.robot, links)


def _joint_entry(effect: Any, value: float) -> tuple[str, Any]:
    name = effect.name
    if name == "coulomb" and getattr(effect, "smoothing", None) is not None:
        return name, value
    if name == "stribeck":
        return name, {"fs": value, "velocity": float(effect.velocity)}
    if name == "spring":
        return name, {"k": value, "reference": float(effect.reference)}
    return name, value


def friction_document(model: IdentifiedModel) -> dict[str, Any]:
    """The ``friction.json`` document (module docstring) of the consistent estimate."""
    _check_consistent(model)
    values = dict(model.file.consistent_effects or {})
    robot = model.robot
    joints: dict[str, dict[str, Any]] = {name: {} for name in robot.joint_names}
    others = []
    for effect in model.model.effects:
        names = effect.parameter_names(robot)
        per_joint = getattr(effect, "symbol", "") and not getattr(effect, "motor", False) and effect.name in LAWS
        if not per_joint:
            others.append({"spec": effect_spec(effect), "parameters": {name: values.get(name) for name in names}})
            continue
        indices = effect.joints if effect.joints is not None else range(robot.n_joints)
        for index, name in zip(indices, names):
            key, entry = _joint_entry(effect, float(values[name]))
            joints[robot.joint_names[index]][key] = entry
            if key == "coulomb" and getattr(effect, "smoothing", None) is not None:
                joints[robot.joint_names[index]]["coulomb_smoothing"] = float(effect.smoothing)
    return {"joints": joints, "effects": others, "laws": dict(LAWS),
            "delay": model.delay, "gravity": np.asarray(robot.gravity, dtype=float).tolist(),
            "channels": list(model.channels)}
