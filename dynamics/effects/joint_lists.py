"""The ``@JOINTS`` part of an effect spec: 1-based joint lists and ranges, split off an item.

``coulomb@1-4`` restricts a per-joint effect to joints 1 to 4, ``offset@2+5`` to joints 2 and 5; ranges ``a-b``
and lists joined by ``+`` combine (``@1-3+6``). :func:`split_joints` splits ``@`` off first; what is left
(``NAME[:VARIANT]``) is read by :func:`dynamics.effects.linear.parse_effects` and
:func:`dynamics.effects.specs.build_effects`. Every reading error is an :class:`EffectSpecError`.
"""

from __future__ import annotations

import dataclasses
import re
from collections.abc import Iterable
from typing import Any

from dynamics.robot import RobotModel

_RANGE = re.compile(r"(\d+)(?:-(\d+))?")


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
    """Raise :class:`EffectSpecError` naming ``item`` for a joint (0-based; a motor when ``what="motor"``)
    outside the robot's."""
    for joint in joints:
        if not 0 <= joint < robot.n_joints:
            raise EffectSpecError(f"effect {item!r}: {what} {joint + 1} outside 1..{robot.n_joints} ({robot.name})")
