"""Effect specs as a user types them: ``NAME[:VARIANT][@JOINTS]``, and back.

Grammar (CLI ``--friction``, :func:`dynamics.effects.linear.parse_effects`): comma-separated items, each
``NAME[:VARIANT][@JOINTS]``; ``@JOINTS`` restricts a per-joint effect to 1-based joints, ranges
``a-b`` and lists joined by ``+``: ``viscous,coulomb@1-4,offset@2+5``. ``@`` is split off first,
then ``:`` (the variant is the business of the effect's own parser). Besides the per-joint names
of :mod:`dynamics.effects.linear`, :func:`build_effects` reads

* ``motor_viscous``, ``motor_coulomb``, ``motor_inertia`` (``@MOTORS`` picks motors): friction and
  rotor inertia on the motors of a declared transmission (:mod:`dynamics.effects.motor`);
* ``viscous[q5+q6]``, ``coulomb[q5+q6]``, ``inertia[q4-q5]``: the same laws on a joint
  combination, as the diagnosis names them; ``coulomb:tanh[q5+q6]`` the Coulomb law on it with its
  own smoothing (:mod:`dynamics.effects.combination_shapes`).
"""

from __future__ import annotations

import dataclasses
import re
from collections.abc import Iterable
from typing import Any

from dynamics.robot import RobotModel

_RANGE = re.compile(r"(\d+)(?:-(\d+))?")
_COMBINATION = re.compile(r"(viscous|coulomb|inertia)(?::(tanh))?\[(.+)\]", re.IGNORECASE)
MOTOR_KINDS: dict[str, str] = {"motor_viscous": "viscous", "motor_coulomb": "coulomb", "motor_inertia": "inertia"}


class EffectSpecError(ValueError):
    """An effect spec that cannot be read (bad ``@JOINTS``, unknown name, a joint the robot lacks)."""


def parse_joint_list(text: str) -> tuple[int, ...]:
    """``"1-4"``, ``"2+5"``, ``"1-3+6"`` → 0-based joint indices, sorted, each once."""
    joints: set[int] = set()
    for part in text.split("+"):
        match = _RANGE.fullmatch(part.strip())
        if match is None:
            raise EffectSpecError(f"cannot read joints {text!r}: use 1-based numbers, ranges a-b and '+' "
                                  "(e.g. @1-4, @2+5, @1-3+6)")
        first = int(match.group(1))
        last = int(match.group(2)) if match.group(2) else first
        if first < 1 or last < first:
            raise EffectSpecError(f"joints {part!r} in {text!r}: joints count from 1 and a range a-b needs a <= b")
        joints.update(range(first - 1, last))
    return tuple(sorted(joints))


def split_joints(item: str) -> tuple[str, tuple[int, ...] | None]:
    """``"coulomb:tanh@1-4"`` → ``("coulomb:tanh", (0, 1, 2, 3))``; no ``@``: ``(item, None)``."""
    if "@" not in item:
        return item.strip(), None
    name, _, joints = item.partition("@")
    if not name.strip() or not joints.strip():
        raise EffectSpecError(f"effect {item!r}: write NAME@JOINTS, e.g. coulomb@1-4")
    if "@" in joints:
        raise EffectSpecError(f"effect {item!r}: one @ per item")
    return name.strip(), parse_joint_list(joints)


def restricted(effect_type: type, joints: tuple[int, ...] | None, item: str) -> Any:
    """An instance of ``effect_type`` on ``joints`` (0-based), or a named error if it has no joints."""
    if joints is None:
        return effect_type()
    if "joints" not in {field.name for field in dataclasses.fields(effect_type)}:
        raise EffectSpecError(f"effect {item!r}: {effect_type.name} acts on no joints, so it takes no @JOINTS")
    return effect_type(joints=joints)


def check_joints(joints: Iterable[int], robot: RobotModel, item: str, what: str = "joint") -> None:
    for joint in joints:
        if not 0 <= joint < robot.n_joints:
            raise EffectSpecError(f"effect {item!r}: {what} {joint + 1} outside 1..{robot.n_joints} ({robot.name})")


def build_effects(spec: str | Iterable[Any] | None, robot: RobotModel, transmission: Any = None) -> tuple[Any, ...]:
    """Effects from a spec, with the motor-side and joint-combination names besides those of
    :func:`dynamics.effects.linear.parse_effects` (which reads the rest)."""
    from dynamics.effects.linear import parse_effects
    from dynamics.effects.motor import combination_from_label, motor_effects

    if spec is None:
        return ()
    items = [item.strip() for item in spec.split(",")] if isinstance(spec, str) else list(spec)
    effects: list[Any] = []
    for item in items:
        if not isinstance(item, str):
            effects.append(item)
            continue
        if not item or item.lower() == "none":
            continue
        name, joints = split_joints(item)
        check_joints(joints or (), robot, item)
        key = name.lower()
        combination = _COMBINATION.fullmatch(name)
        if key in MOTOR_KINDS:
            if transmission is None:
                raise EffectSpecError(f"effect {item!r} acts on motors: declare the transmission (--transmission "
                                      "FILE, a URDF with <transmission> elements, or a built-in robot that has one)")
            effects.extend(motor_effects(transmission, MOTOR_KINDS[key], joints))
        elif combination is not None:
            if joints is not None:
                raise EffectSpecError(f"effect {item!r}: a joint combination names its joints itself; no @JOINTS")
            kind, variant, label = combination.group(1).lower(), combination.group(2), combination.group(3)
            effect = combination_from_label(kind, label, robot.n_joints)
            if variant is not None:
                if kind != "coulomb":
                    raise EffectSpecError(f"effect {item!r}: only coulomb has the :tanh variant on a joint combination")
                from dynamics.effects.combination_shapes import TanhCombinationCoulomb

                effect = TanhCombinationCoulomb.from_combination(effect)
            effects.append(effect)
        else:
            effects.extend(parse_effects([item]))
    return parse_effects(effects)


def effect_spec(effect: Any) -> str:
    """The spec item that rebuilds ``effect`` (``coulomb@2+5``, ``motor_coulomb@6``, ``coulomb[q5+q6]``)."""
    joints = getattr(effect, "joints", None)
    if getattr(effect, "motor", False):
        return f"motor_{effect.kind}@" + "+".join(label.removeprefix("m") for label in effect.labels)
    name = getattr(effect, "spec", effect.name)  # a law with shape parameters: coulomb:tanh, sigmoid…
    if joints is None:
        return name
    return f"{name}@" + "+".join(str(joint + 1) for joint in joints)
