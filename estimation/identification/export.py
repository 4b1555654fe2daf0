"""A physically consistent identified model written out for other tools: a URDF and ``friction.json``, or MuJoCo's MJCF.

The URDF (:mod:`dynamics.urdf_export`) carries the identified bodies (and, in the ``<dynamics damping friction>``
the description holds on a joint, its identified viscous and Coulomb friction); ``friction.json`` the rest of
the model, so that Pinocchio's RNEA on the URDF plus these terms is the model's prediction::

    {"joints": {"<joint name>": {"viscous": fv, "viscous_direction": fvd, "coulomb": fc, "offset": off, "armature": Ia,
                                 "coulomb_smoothing": V,                       # tanh(dq / V) instead of sign
                                 "stribeck": {"fs": …, "velocity": …}, "spring": {"k": …, "reference": …},
                                 "sigmoid": {"phi1": …, "phi2": …, "phi3": …}, "ripple": {"rs": …, "rc": …, "n": …}}},
     "effects": [{"spec": "coulomb:tanh[q5+q6]", "parameters": {"fc[q5+q6]": …},  # effects not on one joint
                  "shape": {"vc[q5+q6]": …}}],
     "laws": {"viscous": "fv * dq", …}, "delay": 0.007 | null, "gravity": [0, 0, -9.81], "channels": […]}

``τ_j = RNEA(q, q̇, q̈)_j + Σ laws of joint j`` (joint rows; the other effects and the delay as named).
The MJCF (:func:`exported_mjcf`, :mod:`dynamics.mjcf_export`) of a robot read from an MJCF model is the user's file
with the identified bodies, joint terms and gravity in place of its own, everything else kept
(:func:`dynamics.mjcf_export.mjcf_with_inertials`; the chain's MJCF, with the reason, when a link cannot be written
into the file's bodies); of any other robot, the chain's. It carries the bodies and the joint terms
MuJoCo has: ``armature`` (rotor inertia), ``damping`` (viscous), ``frictionloss`` (Coulomb), ``stiffness``
and ``springref`` (a spring), gravity; what it cannot express (an offset, a viscous slope differing by
direction, a Stribeck law, a smoothed or
shaped Coulomb law, an effect not on one joint, a motor-side effect, a delay) is listed in a comment and
in :attr:`MjcfExport.notes`.

The shaped laws (:mod:`dynamics.effects.shaped`) are written at their fitted shapes: ``coulomb:tanh`` as
``coulomb`` with its ``coulomb_smoothing``, ``stribeck:velocity`` as ``coulomb`` and ``stribeck`` with its
velocity, ``sigmoid`` and ``ripple`` with their shape parameters.
A payload the model file carries (``oed payload``) is added to its link's body (the sum of two rigid bodies in
one frame is the sum of their standard parameters), in the URDF and the MJCF.
The gravity the model was fitted with (the model file's ``gravity``: the description's, or a mount the verbs found
and chose on the validation record) is the MJCF's ``<option gravity>`` and ``friction.json``'s ``gravity``; a URDF
holds no gravity, so when it is not the description's :func:`gravity_note` says the mount to write.
Only a consistent estimate is exported (:func:`exported_model`: the chosen model when it is one, else the
file's consistent alternative, named): base parameters alone do not determine the bodies (a base
parameter is a sum of standard ones, and a body of unconstrained values need not be a real one).
"""

from __future__ import annotations

import tempfile
import xml.etree.ElementTree as ElementTree
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from dynamics.effects.shaped import shape_parameters
from dynamics.effects.specs import effect_spec
from dynamics.mjcf import is_mjcf, is_mjcf_text
from dynamics.mjcf_export import MjcfBodyError, mjcf_with_inertials, robot_mjcf
from dynamics.urdf_export import robot_urdf, urdf_with_inertials, with_joint_friction
from estimation.identification.identified_model import IdentifiedModel
from estimation.identification.model_file import read_model_file
from estimation.identification.mount import mount_rpy
from estimation.identification.plausibility import link_findings

__all__ = ["LAWS", "LAW_KEYS", "SHAPED_ENTRIES", "ExportError", "MjcfExport", "exported_mjcf", "exported_model", "exported_urdf",
           "friction_document", "gravity_note", "implausible_links", "urdf_dynamics_joints", "urdf_friction"]

#: the per-joint laws friction.json names, as formulas of the joint's motion
LAWS = {
    "viscous": "fv * dq",
    "viscous_direction": "fvd * abs(dq): with the viscous law, the slope fv + fvd for dq > 0 and fv - fvd for dq < 0",
    "coulomb": "fc * sign(dq), or fc * tanh(dq / coulomb_smoothing) when coulomb_smoothing is given",
    "offset": "off",
    "armature": "Ia * ddq",
    "stribeck": "fs * exp(-(dq / velocity)**2) * sign(dq)",
    "spring": "k * (q - reference)",
    "sigmoid": "phi1 / (1 + exp(-phi2 * (dq + phi3))) - phi1 / (1 + exp(-phi2 * phi3))",
    "ripple": "rs * sin(n * q) + rc * cos(n * q)",
}
#: a per-joint law whose friction.json key is not its name (a name with a variant)
LAW_KEYS: dict[str, str] = {"viscous:direction": "viscous_direction"}
#: a shaped per-joint law (its spec) as friction.json's entries: the key of each linear coefficient (a
#: ``(law, field)`` pair, field ``None`` for a plain number) and of each shape parameter, by symbol
SHAPED_ENTRIES: dict[str, dict[str, tuple[str, str | None]]] = {
    "coulomb:tanh": {"fc": ("coulomb", None), "vc": ("coulomb_smoothing", None)},
    "stribeck:velocity": {"fc": ("coulomb", None), "fs": ("stribeck", "fs"), "vs": ("stribeck", "velocity")},
    "sigmoid": {"phi1_": ("sigmoid", "phi1"), "phi2_": ("sigmoid", "phi2"), "phi3_": ("sigmoid", "phi3")},
    "ripple": {"rs": ("ripple", "rs"), "rc": ("ripple", "rc"), "n": ("ripple", "n")},
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


def implausible_links(model: IdentifiedModel, *, scale: float | None = None) -> tuple[str, ...]:
    """One message per exported body that is degenerate or far from the description
    (:func:`estimation.identification.plausibility.link_findings`); ``scale``: the description's bodies judged at
    that scale (the recorded torques' over the description's, when the estimate's prior was taken there: a
    description in grams, ``oed.workflows.identify.prior_at_scale``)."""
    _check_consistent(model)
    robot = model.robot if scale is None else model.robot.with_parameters(scale * model.robot.standard_parameters)
    return link_findings(robot, model.file.consistent_links)


def exported_links(model: IdentifiedModel) -> np.ndarray:
    """The bodies exported: the consistent estimate's, with the payload the model file carries (``oed payload``)
    added to its link's."""
    links = np.array(model.file.consistent_links, dtype=float)
    if model.payload_link is not None:
        links[model.payload_link - 1] += model.payload_theta
    return links


def exported_urdf(model: IdentifiedModel) -> str:
    """The URDF of the identified bodies: the model's own URDF with its inertials replaced, or one
    written from the chain (a built-in robot's description, or a robot read from an MJCF model)."""
    _check_consistent(model)
    links = exported_links(model)
    source = model.file.robot
    merged = source.joint_names is not None  # the locked joints' bodies are in the named joints' ones
    text = source.urdf_text
    if text is None and source.urdf_path is not None:
        with open(source.urdf_path) as stream:  # the hash was checked when the model was loaded
            text = stream.read()
    if text is not None and not is_mjcf_text(text):
        return with_joint_friction(urdf_with_inertials(text, model.robot, links, merge_locked=merged),
                                   urdf_friction(model))[0]
    return robot_urdf(model.robot, links)


def urdf_friction(model: IdentifiedModel) -> dict[str, tuple[float, float]]:
    """Each chain joint's ``(viscous, Coulomb)`` friction of the consistent estimate (:func:`friction_document`;
    0 for a law the model does not hold on that joint), the values a URDF's ``<dynamics damping friction>`` holds
    (:func:`dynamics.urdf_export.with_joint_friction`)."""
    def number(value: Any) -> float:
        return float(value) if isinstance(value, (int, float)) else 0.0

    return {name: (number(entry.get("viscous", 0.0)), number(entry.get("coulomb", 0.0)))
            for name, entry in friction_document(model)["joints"].items()}


def urdf_dynamics_joints(text: str) -> tuple[str, ...]:
    """The joints of the URDF ``text`` that hold a ``<dynamics>`` element (those :func:`exported_urdf` writes the
    identified friction into)."""
    return tuple(str(joint.get("name")) for joint in ElementTree.fromstring(text).findall("joint")
                 if joint.find("dynamics") is not None)


def _joint_entry(effect: Any, value: float) -> tuple[str, Any]:
    name = LAW_KEYS.get(effect.name, effect.name)
    if name == "coulomb" and getattr(effect, "smoothing", None) is not None:
        return name, value
    if name == "stribeck":
        return name, {"fs": value, "velocity": float(effect.velocity)}
    if name == "spring":
        return name, {"k": value, "reference": float(effect.reference)}
    return name, value


def _shaped_entries(effect: Any, robot: Any, values: dict[str, float], shape: dict[str, float],
                    joints: dict[str, dict[str, Any]]) -> bool:
    """Write a built-in shaped per-joint law into ``joints`` (:data:`SHAPED_ENTRIES`); ``False`` for another effect."""
    entries = SHAPED_ENTRIES.get(getattr(effect, "spec", ""))
    if entries is None or not hasattr(effect, "kinds"):
        return False
    indices = effect.joints if effect.joints is not None else range(robot.n_joints)
    for index in indices:
        terms = joints[robot.joint_names[index]]
        symbols = [(symbol, values) for symbol in effect.linear] + [(kind.symbol, shape) for kind in effect.kinds]
        for symbol, source in symbols:
            key, field = entries[symbol]
            value = source.get(f"{symbol}{index + 1}")
            value = None if value is None else float(value)
            if field is None:
                terms[key] = value
            else:
                terms.setdefault(key, {})[field] = value
    return True


def friction_document(model: IdentifiedModel) -> dict[str, Any]:
    """The ``friction.json`` document (module docstring) of the consistent estimate."""
    _check_consistent(model)
    values = dict(model.file.consistent_effects or {})
    shape = {name: float(value) for name, value in model.file.shape.items()}
    robot = model.robot
    joints: dict[str, dict[str, Any]] = {name: {} for name in robot.joint_names}
    others = []
    for effect in model.model.effects:
        names = effect.parameter_names(robot)
        if _shaped_entries(effect, robot, values, shape, joints):
            continue
        per_joint = getattr(effect, "symbol", "") and not getattr(effect, "motor", False) and (
            LAW_KEYS.get(effect.name, effect.name) in LAWS)
        if not per_joint:
            shape_names = [parameter.name for parameter in shape_parameters(effect, robot)]
            others.append({"spec": effect_spec(effect), "parameters": {name: values.get(name) for name in names},
                           **({"shape": {name: shape.get(name) for name in shape_names}} if shape_names else {})})
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


def gravity_note(model: IdentifiedModel) -> str | None:
    """The sentence that the model was fitted with another gravity than its description's (the model file's
    ``gravity``, a mount found and chosen on the validation record), with the ``<origin rpy>`` of the fixed ``world ->
    base`` joint that gives it (:func:`estimation.identification.mount.mount_rpy`): a URDF holds no gravity, and the
    one written keeps the description's mount. ``None`` when the gravity is the description's."""
    fitted, described = np.asarray(model.robot.gravity, dtype=float), model.description_gravity
    if np.allclose(fitted, described, rtol=0.0, atol=1e-9):
        return None
    shown = ", ".join(f"{value:.4g}" for value in fitted)
    described_shown = ", ".join(f"{value:.4g}" for value in described)
    if not np.any(fitted):
        return (f"the model was fitted without gravity (the torques hold no gravity load), not with the description's "
                f"({described_shown}) m/s²: a URDF holds no gravity, so a simulator of the URDF written adds a gravity "
                "load this model does not have (the MJCF and friction.json say gravity 0)")
    roll, pitch, yaw = mount_rpy(fitted)
    return (f"the model was fitted with gravity ({shown}) m/s² in the base frame, not the description's "
            f"({described_shown}): a URDF holds no gravity and the one written keeps the description's mount; give "
            "it the mount found: a link \"world\" and a fixed joint from it to the base link, <origin xyz=\"0 0 0\" "
            f"rpy=\"{roll:.4f} {pitch:.4f} {yaw:.4f}\"/> (the MJCF and friction.json hold the fitted gravity)")


#: friction.json's per-joint laws as MuJoCo joint attributes (a spring as two)
_MUJOCO_TERMS = {"viscous": "damping", "coulomb": "frictionloss", "armature": "armature"}


@dataclass(frozen=True)
class MjcfExport:
    """The MJCF text of a consistent model and what MuJoCo cannot express of it (one note each); ``source``: the
    user's MJCF file it was written into (``None``: the chain written from the bodies and joints), ``changes``: what
    of that file, besides the bodies and joint terms, the export changed (a term of the file set to 0, the asset
    folders made absolute)."""

    text: str
    notes: tuple[str, ...]
    source: str | None = None
    changes: tuple[str, ...] = ()


def exported_mjcf(model: IdentifiedModel) -> MjcfExport:
    """MuJoCo's MJCF of the consistent estimate (module docstring): MuJoCo's inverse dynamics of it, with
    friction loss disabled, is ``oed predict --consistent`` less the Coulomb term and the terms in ``notes``."""
    document = friction_document(model)
    terms: dict[str, dict[str, float]] = {}
    notes: list[str] = []
    for joint, laws in document["joints"].items():
        entry = terms.setdefault(joint, {})
        for law, value in laws.items():
            if law in _MUJOCO_TERMS:
                entry[_MUJOCO_TERMS[law]] = float(value)
            elif law == "spring":
                entry.update(stiffness=float(value["k"]), springref=float(value["reference"]))
            elif law == "coulomb_smoothing":
                notes.append(f"joint {joint}: the Coulomb law is smoothed (tanh(dq / {value:g})); MuJoCo's "
                             "frictionloss is its own dry-friction constraint")
            else:
                notes.append(f"joint {joint}: {law} {value} ({LAWS.get(law, law)})")
    notes.extend(f"effect {effect['spec']}: {effect['parameters']}" for effect in document["effects"])
    if document.get("delay"):
        notes.append(f"a delay of {document['delay']:g} s between torques and motion")
    header = (f"robot-oed: the physically consistent estimate of {model.robot.name} ({model.file.effects or 'no'} "
              "effects); numbers at full precision")
    source = model.file.robot
    if source.urdf_sha256 is not None and (
            is_mjcf_text(source.urdf_text) if source.urdf_text is not None else is_mjcf(source.urdf_path or "")):
        try:
            if source.joints is not None:
                raise MjcfBodyError(f"the model holds the file's first {source.joints} joints (--joints)")
            return _users_mjcf(model, terms, notes, header)
        except MjcfBodyError as error:
            notes.append(f"not written into the user's MJCF ({error}): the chain's bodies and joints are written "
                         "instead, without its geoms and actuators")
    text = robot_mjcf(model.robot, exported_links(model), terms, notes=notes, header=header)
    return MjcfExport(text, tuple(notes))


def _users_mjcf(model: IdentifiedModel, terms: dict[str, dict[str, float]], notes: list[str],
                header: str) -> MjcfExport:
    """The user's MJCF (the model file's, its ``<include>`` files in place) with the identified bodies and terms
    (:func:`dynamics.mjcf_export.mjcf_with_inertials`)."""
    source = model.file.robot
    folder = None if source.urdf_path is None else Path(source.urdf_path).parent
    with tempfile.TemporaryDirectory() as temporary:
        path = Path(source.urdf_path or "")
        if source.urdf_text is not None:
            path = Path(temporary) / "robot.xml"
            path.write_text(source.urdf_text)
        text, changes = mjcf_with_inertials(path, model.robot, exported_links(model), terms,
                                            joint_names=source.joint_names, locked_at=source.locked_at,
                                            assets=folder, notes=notes, header=header)
    return MjcfExport(text, tuple(notes), source.urdf_path or "the model file's MJCF", changes)
