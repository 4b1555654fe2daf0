"""Effect specs as a user types them: ``NAME[:VARIANT][@JOINTS]``, and back.

Grammar (CLI ``--friction``, :func:`dynamics.effects.linear.parse_effects`): comma-separated items, each
``NAME[:VARIANT][@JOINTS]``; ``@JOINTS`` restricts a per-joint effect to 1-based joints, ranges
``a-b`` and lists joined by ``+`` (:mod:`dynamics.effects.joint_lists`): ``viscous,coulomb@1-4,offset@2+5``. ``@`` is split off first,
then ``:`` (the variant is the business of the effect's own parser). Besides the per-joint names
of :mod:`dynamics.effects.linear`, :func:`build_effects` reads

* ``motor_viscous``, ``motor_coulomb``, ``motor_inertia`` (``@MOTORS`` picks motors): friction and
  rotor inertia on the motors of a declared transmission (:mod:`dynamics.effects.motor`);
* ``viscous[q5+q6]``, ``coulomb[q5+q6]``, ``inertia[q4-q5]``: the same laws on a joint
  combination, as the diagnosis names them; ``coulomb:tanh[q5+q6]`` the Coulomb law on it with its
  own smoothing (:mod:`dynamics.effects.combination_shapes`).
"""

from __future__ import annotations

import re
from collections.abc import Iterable
from typing import Any

from dynamics.effects.combination_shapes import TanhCombinationCoulomb
from dynamics.effects.joint_lists import EffectSpecError, check_joints, split_joints
from dynamics.effects.linear import parse_effects
from dynamics.effects.motor import combination_from_label, motor_effects
from dynamics.robot import RobotModel

_COMBINATION = re.compile(r"(viscous|coulomb|inertia)(?::(tanh))?\[(.+)\]", re.IGNORECASE)
MOTOR_KINDS: dict[str, str] = {"motor_viscous": "viscous", "motor_coulomb": "coulomb", "motor_inertia": "inertia"}


def build_effects(spec: str | Iterable[Any] | None, robot: RobotModel, transmission: Any = None) -> tuple[Any, ...]:
    """Effects from a spec, with the motor-side and joint-combination names besides those of
    :func:`dynamics.effects.linear.parse_effects` (which reads the rest)."""
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
