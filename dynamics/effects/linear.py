"""Extra regressor columns beyond rigid-body dynamics: friction, offsets, armature, plate offsets.

Each effect is a small frozen object that adds columns to the joint rows and/or to the base
wrench rows of a model, built on the same CasADi symbols ``q, dq, ddq``. New effects (a user's
own, or those of the residual diagnosis) implement the same two methods; nothing else changes.

The PUMA paper's model (eq. 14–15) uses viscous friction only, on the joint rows only: friction
is internal to the robot, so the force plate does not see it.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from typing import ClassVar, Protocol, runtime_checkable

import casadi

from dynamics.channels import WRENCH_CHANNELS
from dynamics.effects.joint_lists import restricted, split_joints
from dynamics.effects.shaped import SHAPED_EFFECTS
from dynamics.robot import RobotModel

#: effects whose parameters are positive by physics (dissipation, inertia): an estimate of the
#: other sign is not that effect
POSITIVE_EFFECTS: frozenset[str] = frozenset({"viscous", "coulomb", "stribeck", "armature", "sigmoid"})


@runtime_checkable
class Effect(Protocol):
    """What an extra set of regressor columns provides."""

    name: str

    def parameter_names(self, robot: RobotModel) -> list[str]:
        """Names of the new parameters, one per column."""
        ...

    def columns(
        self, robot: RobotModel, q: casadi.SX, dq: casadi.SX, ddq: casadi.SX
    ) -> tuple[casadi.SX | None, casadi.SX | None]:
        """``(joint_columns n x k, wrench_columns 6 x k)``; ``None`` where the effect has no rows."""
        ...


def _joint_indices(robot: RobotModel, joints: tuple[int, ...] | None, effect: str) -> tuple[int, ...]:
    if joints is None:
        return tuple(range(robot.n_joints))
    for joint in joints:
        if not 0 <= joint < robot.n_joints:
            raise ValueError(f"effect {effect!r}: joint {joint + 1} outside 1..{robot.n_joints} (joints count from 1)")
    return tuple(joints)


@dataclass(frozen=True)
class _PerJointEffect:
    """An effect with one parameter per selected joint, acting on that joint's row only."""

    joints: tuple[int, ...] | None = None
    name: ClassVar[str] = ""
    symbol: ClassVar[str] = ""

    def parameter_names(self, robot: RobotModel) -> list[str]:
        return [f"{self.symbol}{index + 1}" for index in _joint_indices(robot, self.joints, self.name)]

    def term(self, q: casadi.SX, dq: casadi.SX, ddq: casadi.SX) -> casadi.SX:  # pragma: no cover - abstract
        raise NotImplementedError

    def columns(self, robot, q, dq, ddq):
        indices = _joint_indices(robot, self.joints, self.name)
        block = casadi.SX.zeros(robot.n_joints, len(indices))
        for column, index in enumerate(indices):
            block[index, column] = self.term(q[index], dq[index], ddq[index])
        return block, None


@dataclass(frozen=True)
class ViscousFriction(_PerJointEffect):
    """``tau_i += fv_i · dq_i`` (PUMA paper, eq. 14)."""

    name: ClassVar[str] = "viscous"
    symbol: ClassVar[str] = "fv"

    def term(self, q, dq, ddq):
        return dq


@dataclass(frozen=True)
class DirectionalViscousFriction(_PerJointEffect):
    """``tau_i += fvd_i · |dq_i|``: viscous friction whose slope differs by direction, beside ``fv_i · dq_i``.

    Separate slopes for positive and negative speed, ``fv⁺ dq`` for ``dq > 0`` and ``fv⁻ dq`` for ``dq < 0``, are
    ``(fv⁺ + fv⁻)/2 · dq + (fv⁺ − fv⁻)/2 · |dq|``: the viscous law's column and this one, linear in both
    coefficients (``fv = (fv⁺ + fv⁻)/2``, ``fvd = (fv⁺ − fv⁻)/2``). ``fvd`` takes either sign (the stronger
    direction); each direction's slope ``fv ± fvd`` is positive on a physical joint. Coulomb levels that differ by
    direction need no law of their own: ``fc⁺`` and ``fc⁻`` are ``(fc⁺ + fc⁻)/2 · sign(dq)`` plus the constant
    ``(fc⁺ − fc⁻)/2`` while moving, which is the offset on every sample whose speed is not exactly zero (a
    differentiated speed never is).
    """

    name: ClassVar[str] = "viscous:direction"
    symbol: ClassVar[str] = "fvd"

    def term(self, q, dq, ddq):
        return casadi.fabs(dq)


@dataclass(frozen=True)
class CoulombFriction(_PerJointEffect):
    """``tau_i += fc_i · sign(dq_i)``, or ``fc_i · tanh(dq_i / smoothing)`` when ``smoothing`` is set."""

    smoothing: float | None = None
    name: ClassVar[str] = "coulomb"
    symbol: ClassVar[str] = "fc"

    def __post_init__(self) -> None:
        if self.smoothing is not None and not self.smoothing > 0:
            raise ValueError(f"coulomb smoothing must be a positive velocity, got {self.smoothing}")

    def term(self, q, dq, ddq):
        return casadi.sign(dq) if self.smoothing is None else casadi.tanh(dq / self.smoothing)


@dataclass(frozen=True)
class JointOffset(_PerJointEffect):
    """``tau_i += off_i``: a constant torque (force) offset of joint ``i`` (drive or sensor bias)."""

    name: ClassVar[str] = "offset"
    symbol: ClassVar[str] = "off"

    def term(self, q, dq, ddq):
        return casadi.SX(1)


@dataclass(frozen=True)
class Armature(_PerJointEffect):
    """``tau_i += Ia_i · ddq_i``: rotor inertia reflected through the gear (joint rows only)."""

    name: ClassVar[str] = "armature"
    symbol: ClassVar[str] = "Ia"

    def term(self, q, dq, ddq):
        return ddq


@dataclass(frozen=True)
class StribeckFriction(_PerJointEffect):
    """``tau_i += fs_i · exp(−(dq_i / velocity)²) · sign(dq_i)``: the static-friction bump at low speed.

    The Stribeck velocity is fixed (default 0.05 rad/s or m/s), which keeps the model linear in
    ``fs_i``; a user who knows it better passes another value.
    """

    velocity: float = 0.05
    name: ClassVar[str] = "stribeck"
    symbol: ClassVar[str] = "fs"

    def __post_init__(self) -> None:
        if not self.velocity > 0:
            raise ValueError(f"stribeck velocity must be positive, got {self.velocity}")

    def term(self, q, dq, ddq):
        return casadi.exp(-((dq / self.velocity) ** 2)) * casadi.sign(dq)


@dataclass(frozen=True)
class Spring(_PerJointEffect):
    """``tau_i += k_i · (q_i − q_ref)``: a cable harness or a gravity compensator acting on joint ``i``."""

    reference: float = 0.0
    name: ClassVar[str] = "spring"
    symbol: ClassVar[str] = "k"

    def term(self, q, dq, ddq):
        return q - self.reference


@dataclass(frozen=True)
class WrenchOffset:
    """Constant offsets of the force-plate channels (external rows only)."""

    channels: tuple[str, ...] = WRENCH_CHANNELS
    name: ClassVar[str] = "wrench_offset"

    def __post_init__(self) -> None:
        unknown = [channel for channel in self.channels if channel not in WRENCH_CHANNELS]
        if unknown:
            raise ValueError(f"wrench_offset: unknown channels {unknown}; expected some of {WRENCH_CHANNELS}")

    def parameter_names(self, robot: RobotModel) -> list[str]:
        return [f"{channel}_off" for channel in self.channels]

    def columns(self, robot, q, dq, ddq):
        block = casadi.SX.zeros(6, len(self.channels))
        for column, channel in enumerate(self.channels):
            block[WRENCH_CHANNELS.index(channel), column] = 1
        return None, block


EFFECTS: dict[str, type] = {
    effect.name: effect
    for effect in (ViscousFriction, DirectionalViscousFriction, CoulombFriction, JointOffset, Armature, StribeckFriction,
                   Spring, WrenchOffset)
}


def _effect_type(item: str) -> type:
    """The effect class named ``NAME[:VARIANT]`` (shaped variants: :data:`dynamics.effects.shaped.SHAPED_EFFECTS`)."""
    key = "wrench_offset" if item.lower() in ("plate_offset", "plate_offsets") else item.lower().replace(" ", "")
    if key.endswith(":sign") and key[: -len(":sign")] == "coulomb":
        key = "coulomb"
    if key in SHAPED_EFFECTS:
        return SHAPED_EFFECTS[key]
    if key not in EFFECTS:
        known = ", ".join(list(EFFECTS) + list(SHAPED_EFFECTS))
        raise ValueError(f"unknown effect {item!r}; known effects are {known}")
    return EFFECTS[key]


def parse_effects(spec: str | Iterable[str | Effect] | None) -> tuple[Effect, ...]:
    """Effects from a comma-separated list of names (``"viscous,coulomb"``) or a sequence.

    Names: ``viscous``, ``viscous:direction`` (a slope differing by direction), ``coulomb``, ``offset``,
    ``armature``, ``stribeck``, ``spring``,
    ``wrench_offset`` (alias ``plate_offset``); ``none`` or an empty string for rigid-body only.
    ``NAME@JOINTS`` restricts a per-joint effect to 1-based joints (``coulomb@1-4``, ``offset@2+5``;
    :mod:`dynamics.effects.joint_lists`).
    ``NAME:VARIANT`` selects a variant with shape parameters (:mod:`dynamics.effects.shaped`):
    ``coulomb:tanh``, ``stribeck:velocity``, ``sigmoid``, ``ripple`` (``coulomb:sign`` is ``coulomb``).
    """
    if spec is None:
        return ()
    items: Sequence[str | Effect]
    if isinstance(spec, str):
        items = [item.strip() for item in spec.split(",") if item.strip() and item.strip().lower() != "none"]
    else:
        items = list(spec)
    effects: list[Effect] = []
    for item in items:
        if isinstance(item, str):
            text, joints = split_joints(item)  # NAME[:VARIANT][@JOINTS]: @ first (dynamics.effects.joint_lists)
            item = restricted(_effect_type(text), joints, item)
        if not isinstance(item, Effect):
            raise TypeError(f"{item!r} is not an effect (needs name, parameter_names and columns)")
        if any(existing == item for existing in effects):
            raise ValueError(f"effect {item.name!r} given twice")
        effects.append(item)
    return tuple(effects)
