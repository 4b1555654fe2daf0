"""The true extra effects of a simulated robot, by name: friction, offsets, armature, springs, plate effects.

Each effect is a small frozen dataclass that names the channels it acts on and its true values,
so that an identification (or a later residual diagnosis) can be scored against them. Two families,
each in its own module (both re-exported here):

* **joint effects** (:mod:`dynamics.simulation.joint_effects`) act on the robot's motion and appear
  in the joint torques only: ``viscous``, ``coulomb``, ``offset``, ``armature``, ``spring``, with
  the PUMA 560's motor data as defaults;
* **plate effects** (:mod:`dynamics.simulation.plate_effects`) act on the force-plate reading only:
  ``plate_offset``, ``plate_moment``, ``cable``.

This module holds the catalogue: :data:`SIMULATED_EFFECTS`, :func:`effects_from_names` and
:func:`describe`.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import fields
from typing import Any

from dynamics.robot import RobotModel
from dynamics.simulation.joint_effects import (  # noqa: F401  (re-exported)
    GENERIC_DEFAULTS,
    JOINT_EFFECTS,
    PUMA560_GEAR_RATIOS,
    PUMA560_MOTOR_COULOMB,
    PUMA560_MOTOR_VISCOUS,
    PUMA560_ROTOR_INERTIA,
    SimulatedArmature,
    Coulomb,
    Offset,
    SimulatedSpring,
    Viscous,
    is_puma560,
    SimulatedPerJoint,
    default_joint_values,
    puma560_link_friction,
)
from dynamics.simulation.plate_effects import PLATE_EFFECTS, PlateCable, PlateOffset, PlateMoment  # noqa: F401

SIMULATED_EFFECTS: dict[str, type] = {
    "viscous": Viscous, "coulomb": Coulomb, "offset": Offset, "armature": SimulatedArmature, "spring": SimulatedSpring,
    "plate_offset": PlateOffset, "plate_moment": PlateMoment, "cable": PlateCable,
}


def is_plate_effect(effect: Any) -> bool:
    return isinstance(effect, PLATE_EFFECTS)


def describe(effect: Any, robot: RobotModel) -> dict[str, Any]:
    """A JSON-ready record: name, channels, true parameter values and settings."""
    settings = {field.name.rstrip("_"): getattr(effect, field.name) for field in fields(effect)}
    return {
        "name": effect.name,
        "channels": list(effect.channels(robot)),
        "parameters": effect.parameters(robot),
        "settings": {key: list(value) if isinstance(value, tuple) else value for key, value in settings.items()},
    }


def effects_from_names(
    names: str | Sequence[str], robot: RobotModel, values: Mapping[str, Any] | None = None, *, viscous: bool = True
) -> tuple[Any, ...]:
    """Simulated effects by name with default true values, overridden by ``values[name]``.

    Viscous friction is always included (the model's declared effect) unless ``viscous=False``.
    """
    if isinstance(names, str):
        names = [name.strip().lower() for name in names.split(",") if name.strip() and name.strip().lower() != "none"]
    names = list(names)
    if viscous and "viscous" not in names:
        names.insert(0, "viscous")
    values = dict(values or {})
    unknown = [name for name in list(names) + list(values) if name not in SIMULATED_EFFECTS]
    if unknown:
        raise ValueError(f"unknown effect {unknown[0]!r}; known effects are {', '.join(SIMULATED_EFFECTS)}")
    extra = [name for name in values if name not in names]
    if extra:
        raise ValueError(f"values given for effects not simulated: {extra} (add them to the effects list)")
    if len(set(names)) != len(names):
        raise ValueError(f"an effect is named twice in {names}")
    built = []
    for name in names:
        cls = SIMULATED_EFFECTS[name]
        try:
            effect = cls.from_json(robot, values[name]) if name in values else cls.default(robot)
        except (TypeError, ValueError) as error:
            if str(error).startswith(f"effect {name!r}"):
                raise
            raise ValueError(f"effect {name!r}: bad values {values.get(name)!r} ({error})") from None
        effect.parameters(robot)  # validate against the robot now, not mid-simulation
        built.append(effect)
    return tuple(built)


#: the per-joint laws of ``oed export``'s friction.json the simulator has, by its key
_FRICTION_LAWS = ("viscous", "coulomb", "offset", "armature", "spring")


def is_friction_document(document: Any) -> bool:
    """Whether ``document`` is the ``friction.json`` of ``oed export`` (keys ``joints`` and ``laws``)."""
    return isinstance(document, Mapping) and "joints" in document and "laws" in document


def effects_from_friction(document: Mapping[str, Any], robot: RobotModel,
                          names: str | Sequence[str] = "") -> tuple[tuple[Any, ...], tuple[str, ...]]:
    """The simulated effects of an exported model's ``friction.json``
    (:mod:`estimation.identification.export`), beside the effects ``names`` (with their default values).

    Each joint's ``viscous``, ``coulomb`` (with its ``coulomb_smoothing``; a sign law is simulated as
    ``tanh(dq / 0.05)``, the integrator needing a continuous law), ``offset``, ``armature`` and ``spring``
    become the simulator's effects, 0 on joints without them.

    Returns
    -------
    effects, notes
        The effects (:func:`effects_from_names`), and one note per term of the document the simulator
        does not have (a Stribeck law, an effect not on one joint, a delay) or approximates: the caller
        says them, nothing is dropped silently.

    Raises
    ------
    ValueError
        A joint the robot lacks, or values the simulator refuses (negative friction).
    """
    joints = document.get("joints")
    if not isinstance(joints, Mapping):
        raise ValueError("friction.json: 'joints' must be an object keyed by joint name")
    unknown = [name for name in joints if name not in robot.joint_names]
    if unknown:
        raise ValueError(f"friction.json names joint(s) {', '.join(unknown)} that {robot.name} lacks (joints: "
                         f"{', '.join(robot.joint_names)}): simulate the exported URDF (--urdf) with it")
    n = robot.n_joints
    values: dict[str, Any] = {}
    notes: list[str] = []
    smoothing: set[float] = set()
    springs: dict[int, tuple[float, float]] = {}
    for name, entry in joints.items():
        index = robot.joint_names.index(name)
        for key, value in dict(entry).items():
            if key in ("viscous", "coulomb", "offset", "armature"):
                values.setdefault(key, [0.0] * n)[index] = float(value)
            elif key == "coulomb_smoothing":
                smoothing.add(float(value))
            elif key == "spring":
                springs[index + 1] = (float(value["k"]), float(value["reference"]))
            else:
                notes.append(f"joint {name}: {key} {value} is not simulated (the simulator has "
                             f"{', '.join(_FRICTION_LAWS)})")
    if "coulomb" in values:
        if len(smoothing) > 1:
            raise ValueError(f"friction.json: Coulomb smoothing differs between joints ({sorted(smoothing)}); the "
                             "simulator takes one")
        if smoothing:
            values["coulomb"] = {"values": values["coulomb"], "smoothing": smoothing.pop()}
        else:
            notes.append("coulomb: a sign law, simulated as fc · tanh(dq / 0.05) (the integrator needs a continuous "
                         "law)")
    if springs:
        values["spring"] = {"joints": list(springs), "stiffness": [k for k, _ in springs.values()],
                            "q_ref": [reference for _, reference in springs.values()]}
    notes.extend(f"effect {effect.get('spec')} is not simulated" for effect in document.get("effects") or ())
    if document.get("delay"):
        notes.append(f"the delay of {document['delay']:g} s between torques and motion is not simulated")
    if isinstance(names, str):
        names = [name.strip().lower() for name in names.split(",") if name.strip() and name.strip().lower() != "none"]
    named = list(names) + [name for name in values if name not in names]
    return effects_from_names(named, robot, values), tuple(notes)


__all__ = [
    "is_friction_document", "effects_from_friction",
    "Viscous", "Coulomb", "Offset", "SimulatedArmature", "SimulatedSpring", "PlateOffset", "PlateCable",
    "SIMULATED_EFFECTS", "effects_from_names", "describe", "default_joint_values",
    "JOINT_EFFECTS", "PLATE_EFFECTS", "is_plate_effect", "puma560_link_friction",
]
