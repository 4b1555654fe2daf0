"""The true extra effects of a simulated robot: friction, offsets, armature, springs, plate effects.

Each effect is a small frozen dataclass that names the channels it acts on and its true values,
so that an identification (or a later residual diagnosis) can be scored against them.

Two families:

* **joint effects** act on the robot's motion and appear in the joint torques only (they are
  internal to the robot: the force plate does not see them):
  ``tau_applied = M(q) ddq + h(q, dq) + Σ joint_torque(q, dq)`` (+ armature on ``M``'s diagonal);
* **plate effects** act on the force-plate reading only (a moment from tightened screws, a cable
  pulling on the plate): ``wrench_measured = wrench_rigid_body(q, dq, ddq) + Σ plate_wrench(q)``.

Defaults for the PUMA 560 come from the motor data of Corke's Robotics Toolbox
(``mdl_puma560``), reflected to the link side through the gear ratios ``G``: viscous
``fv = B G²``, Coulomb ``fc = (Tc⁺ − Tc⁻)/2 · |G|``, offset ``off = (Tc⁺ + Tc⁻)/2 · G`` (Corke's
asymmetric Coulomb friction is exactly ``fc sign(dq) + off``), armature ``Ia = Jm G²``.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, fields
from typing import Any, ClassVar

import numpy as np
from numpy.typing import ArrayLike, NDArray

from dynamics import effects as model_effects
from dynamics.effects import WRENCH_CHANNELS
from dynamics.robot import RobotModel

# Corke, Robotics Toolbox mdl_puma560: motor viscous friction B, Coulomb (Tc+, Tc-), rotor inertia
# Jm and gear ratio G of joints 1..6.
PUMA560_MOTOR_VISCOUS: tuple[float, ...] = (1.48e-3, 0.817e-3, 1.38e-3, 71.2e-6, 82.6e-6, 36.7e-6)
PUMA560_MOTOR_COULOMB: tuple[tuple[float, float], ...] = (
    (0.395, -0.435), (0.126, -0.071), (0.132, -0.105), (11.2e-3, -16.9e-3), (9.26e-3, -14.5e-3), (3.96e-3, -10.5e-3),
)
PUMA560_ROTOR_INERTIA: tuple[float, ...] = (200e-6, 200e-6, 200e-6, 33e-6, 33e-6, 33e-6)
PUMA560_GEAR_RATIOS: tuple[float, ...] = (-62.6111, 107.815, -53.7063, 76.0364, 71.923, 76.686)

# Illustrative link-side values for robots without motor data (per joint, SI).
GENERIC_DEFAULTS: dict[str, float] = {"viscous": 0.05, "coulomb": 0.05, "offset": 0.02, "armature": 1e-3}


def _is_puma(robot: RobotModel) -> bool:
    return robot.name.split("[")[0] == "puma560"


def puma560_link_friction(n_joints: int) -> dict[str, NDArray[np.float64]]:
    """Link-side viscous, Coulomb, offset and armature values of the first ``n_joints`` PUMA joints."""
    gear = np.array(PUMA560_GEAR_RATIOS[:n_joints])
    tc = np.array(PUMA560_MOTOR_COULOMB[:n_joints])
    return {
        "viscous": np.array(PUMA560_MOTOR_VISCOUS[:n_joints]) * gear**2,
        "coulomb": (tc[:, 0] - tc[:, 1]) / 2 * np.abs(gear),
        "offset": (tc[:, 0] + tc[:, 1]) / 2 * gear,
        "armature": np.array(PUMA560_ROTOR_INERTIA[:n_joints]) * gear**2,
    }


def default_joint_values(name: str, robot: RobotModel) -> NDArray[np.float64]:
    """Default true values of a per-joint effect (``viscous``, ``coulomb``, ``offset``, ``armature``)."""
    if _is_puma(robot) and robot.n_joints <= 6:
        return puma560_link_friction(robot.n_joints)[name]
    return np.full(robot.n_joints, GENERIC_DEFAULTS[name])


def _floats(values: ArrayLike, what: str) -> tuple[float, ...]:
    array = np.atleast_1d(np.asarray(values, dtype=float)).reshape(-1)
    if not np.all(np.isfinite(array)):
        raise ValueError(f"{what} holds NaN or inf")
    return tuple(float(value) for value in array)


@dataclass(frozen=True)
class _PerJoint:
    """One value per joint (all joints of the robot, in order)."""

    values: tuple[float, ...]
    name: ClassVar[str] = ""
    symbol: ClassVar[str] = ""

    def __post_init__(self) -> None:
        object.__setattr__(self, "values", _floats(self.values, f"{self.name} values"))

    def _check(self, robot: RobotModel) -> NDArray[np.float64]:
        if len(self.values) != robot.n_joints:
            raise ValueError(f"effect {self.name!r} has {len(self.values)} values for a robot of {robot.n_joints} joints")
        return np.array(self.values)

    def channels(self, robot: RobotModel) -> tuple[str, ...]:
        return tuple(f"tau{index}" for index in range(1, robot.n_joints + 1))

    def parameters(self, robot: RobotModel) -> dict[str, float]:
        """True values named as in the identification model (``fv1``, ``fc2``…)."""
        return {f"{self.symbol}{index}": value for index, value in enumerate(self._check(robot), start=1)}

    def armature(self, robot: RobotModel) -> NDArray[np.float64]:
        return np.zeros(robot.n_joints)

    def joint_torque(self, robot: RobotModel, q: NDArray, dq: NDArray) -> NDArray[np.float64]:
        return np.zeros(robot.n_joints)

    def model_effect(self) -> Any:
        """The :mod:`dynamics.effects` object whose columns model this effect (``None`` when none does)."""
        return model_effects.EFFECTS[self.name]()

    @classmethod
    def default(cls, robot: RobotModel):
        return cls(default_joint_values(cls.name, robot))

    @classmethod
    def from_json(cls, robot: RobotModel, value: Any):
        if isinstance(value, Mapping):
            return cls(**value)
        values = np.atleast_1d(np.asarray(value, dtype=float))
        if values.shape not in ((1,), (robot.n_joints,)):
            raise ValueError(
                f"effect {cls.name!r}: give one value or {robot.n_joints} (one per joint), got {values.tolist()}"
            )
        return cls(np.broadcast_to(values, (robot.n_joints,)))


@dataclass(frozen=True)
class Viscous(_PerJoint):
    """Viscous friction ``fv_i · dq_i`` (N·m·s/rad), joint rows (PUMA paper, eq. 14)."""

    name: ClassVar[str] = "viscous"
    symbol: ClassVar[str] = "fv"

    def joint_torque(self, robot, q, dq):
        return self._check(robot) * dq


@dataclass(frozen=True)
class Coulomb(_PerJoint):
    """Coulomb friction ``fc_i · tanh(dq_i / smoothing)`` (N·m), joint rows.

    The integrator needs a continuous law: ``smoothing`` (rad/s) is the velocity below which the
    friction fades; the identification model :class:`dynamics.effects.CoulombFriction` with
    the same smoothing reproduces it exactly, with ``smoothing=None`` (``sign``) up to the band.
    """

    smoothing: float = 0.05
    name: ClassVar[str] = "coulomb"
    symbol: ClassVar[str] = "fc"

    def __post_init__(self) -> None:
        super().__post_init__()
        if not self.smoothing > 0:
            raise ValueError(f"coulomb smoothing must be a positive velocity, got {self.smoothing}")

    def joint_torque(self, robot, q, dq):
        return self._check(robot) * np.tanh(dq / self.smoothing)

    def model_effect(self):
        return model_effects.CoulombFriction(smoothing=self.smoothing)


@dataclass(frozen=True)
class Offset(_PerJoint):
    """A constant joint torque ``off_i`` (N·m) the drive must supply (bias, asymmetric friction)."""

    name: ClassVar[str] = "offset"
    symbol: ClassVar[str] = "off"

    def joint_torque(self, robot, q, dq):
        return self._check(robot)


@dataclass(frozen=True)
class Armature(_PerJoint):
    """Reflected rotor inertia ``Ia_i · ddq_i`` (kg·m²), added to the mass matrix diagonal.

    Joint rows only: the rotor's reaction on the stator (``1/G`` of it) is neglected, as in the
    identification model :class:`dynamics.effects.Armature`.
    """

    name: ClassVar[str] = "armature"
    symbol: ClassVar[str] = "Ia"

    def armature(self, robot):
        return self._check(robot)


@dataclass(frozen=True)
class Spring:
    """A configuration-dependent joint moment ``k_j (q_j − q_ref_j)`` (a cable harness on joint ``j``).

    ``joints`` are 1-based joint numbers; ``stiffness`` (N·m/rad) and ``q_ref`` (rad) one value
    each. Joint rows only. No identification-model effect exists for it yet.
    """

    joints: tuple[int, ...] = (1,)
    stiffness: tuple[float, ...] = (5.0,)
    q_ref: tuple[float, ...] = (0.0,)
    name: ClassVar[str] = "spring"

    def __post_init__(self) -> None:
        joints = tuple(int(joint) for joint in np.atleast_1d(self.joints))
        object.__setattr__(self, "joints", joints)
        for label in ("stiffness", "q_ref"):
            values = np.broadcast_to(np.asarray(getattr(self, label), dtype=float), (len(joints),))
            object.__setattr__(self, label, _floats(values, f"spring {label}"))

    def _indices(self, robot: RobotModel) -> list[int]:
        for joint in self.joints:
            if not 1 <= joint <= robot.n_joints:
                raise ValueError(f"effect 'spring': joint {joint} outside 1..{robot.n_joints}")
        return [joint - 1 for joint in self.joints]

    def channels(self, robot):
        return tuple(f"tau{index + 1}" for index in self._indices(robot))

    def parameters(self, robot):
        self._indices(robot)
        named = {f"k_spring{j}": k for j, k in zip(self.joints, self.stiffness)}
        named.update({f"q_ref_spring{j}": value for j, value in zip(self.joints, self.q_ref)})
        return named

    def armature(self, robot):
        return np.zeros(robot.n_joints)

    def joint_torque(self, robot, q, dq):
        torque = np.zeros(robot.n_joints)
        for index, k, ref in zip(self._indices(robot), self.stiffness, self.q_ref):
            torque[index] += k * (q[index] - ref)
        return torque

    def model_effect(self):
        return None

    @classmethod
    def default(cls, robot):
        return cls()

    @classmethod
    def from_json(cls, robot, value):
        return cls(**value) if isinstance(value, Mapping) else cls(stiffness=value)


@dataclass(frozen=True)
class PlateOffset:
    """Constant offsets of force-plate channels (N, N·m): tightened screws, sensor bias.

    Wrench rows only; modelled by :class:`dynamics.effects.WrenchOffset` on the same channels.
    The default of ``plate_moment`` is a moment of 2 N·m about z (the screws of the PUMA paper).
    """

    channels_: tuple[str, ...] = ("mz",)
    values: tuple[float, ...] = (2.0,)
    name: ClassVar[str] = "plate_offset"

    def __post_init__(self) -> None:
        channels = tuple(self.channels_)
        unknown = [channel for channel in channels if channel not in WRENCH_CHANNELS]
        if unknown or len(set(channels)) != len(channels):
            raise ValueError(f"plate offset: channels must be distinct names among {WRENCH_CHANNELS}, got {channels}")
        object.__setattr__(self, "channels_", channels)
        values = _floats(self.values, "plate offset values")
        if len(values) != len(channels):
            raise ValueError(f"plate offset: {len(values)} values for channels {channels}")
        object.__setattr__(self, "values", values)

    def channels(self, robot):
        return self.channels_

    def parameters(self, robot):
        return {f"{channel}_off": value for channel, value in zip(self.channels_, self.values)}

    def plate_wrench(self, robot: RobotModel, q: NDArray) -> NDArray[np.float64]:
        """``(N, 6)`` added to the wrench at positions ``q`` ``(N, n)``."""
        offset = np.zeros(6)
        for channel, value in zip(self.channels_, self.values):
            offset[WRENCH_CHANNELS.index(channel)] = value
        return np.broadcast_to(offset, (q.shape[0], 6)).copy()

    def model_effect(self):
        return model_effects.WrenchOffset(channels=self.channels_)

    @classmethod
    def default(cls, robot):
        return cls(WRENCH_CHANNELS, (1.5, -1.0, 3.0, 0.5, -0.3, 2.0))

    @classmethod
    def from_json(cls, robot, value):
        if not isinstance(value, Mapping):
            raise ValueError('plate offsets are given by channel, e.g. {"fz": 3.0, "mz": 2.0}')
        return cls(tuple(value), tuple(value.values()))


@dataclass(frozen=True)
class PlateCable:
    """A cable pulling on the plate: ``channel += k (q_joint − q_ref)`` (N·m/rad), wrench rows only.

    The PUMA paper blames such a moment about x for its poor combined-model estimates.
    """

    joint: int = 1
    stiffness: float = 3.0
    q_ref: float = 0.0
    channel: str = "mx"
    name: ClassVar[str] = "cable"

    def __post_init__(self) -> None:
        if self.channel not in WRENCH_CHANNELS:
            raise ValueError(f"cable: channel {self.channel!r} is not one of {WRENCH_CHANNELS}")
        for label in ("stiffness", "q_ref"):
            if not np.isfinite(getattr(self, label)):
                raise ValueError(f"cable {label} must be finite")

    def channels(self, robot):
        return (self.channel,)

    def parameters(self, robot):
        return {f"k_cable_{self.channel}": self.stiffness, f"q_ref_cable_{self.channel}": self.q_ref}

    def plate_wrench(self, robot, q):
        if not 1 <= self.joint <= robot.n_joints:
            raise ValueError(f"effect 'cable': joint {self.joint} outside 1..{robot.n_joints}")
        wrench = np.zeros((q.shape[0], 6))
        wrench[:, WRENCH_CHANNELS.index(self.channel)] = self.stiffness * (q[:, self.joint - 1] - self.q_ref)
        return wrench

    def model_effect(self):
        return None

    @classmethod
    def default(cls, robot):
        return cls()

    @classmethod
    def from_json(cls, robot, value):
        return cls(**value) if isinstance(value, Mapping) else cls(stiffness=float(value))


@dataclass(frozen=True)
class _PlateMoment(PlateOffset):
    """``plate_moment``: a constant moment offset only (default 2 N·m about z)."""

    name: ClassVar[str] = "plate_moment"

    @classmethod
    def default(cls, robot):
        return cls(("mz",), (2.0,))


JOINT_EFFECTS = (Viscous, Coulomb, Offset, Armature, Spring)
PLATE_EFFECTS = (PlateOffset, PlateCable)
SIMULATED_EFFECTS: dict[str, type] = {
    "viscous": Viscous, "coulomb": Coulomb, "offset": Offset, "armature": Armature, "spring": Spring,
    "plate_offset": PlateOffset, "plate_moment": _PlateMoment, "cable": PlateCable,
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
]
