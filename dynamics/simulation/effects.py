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
    Armature,
    Coulomb,
    Offset,
    Spring,
    Viscous,
    is_puma560,
    SimulatedPerJoint,
    default_joint_values,
    puma560_link_friction,
)
from dynamics.simulation.plate_effects import PLATE_EFFECTS, PlateCable, PlateOffset, PlateMoment  # noqa: F401

SIMULATED_EFFECTS: dict[str, type] = {
    "viscous": Viscous, "coulomb": Coulomb, "offset": Offset, "armature": Armature, "spring": Spring,
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


__all__ = [
    "Viscous", "Coulomb", "Offset", "Armature", "Spring", "PlateOffset", "PlateCable",
    "SIMULATED_EFFECTS", "effects_from_names", "describe", "default_joint_values",
    "JOINT_EFFECTS", "PLATE_EFFECTS", "is_plate_effect", "puma560_link_friction",
]
