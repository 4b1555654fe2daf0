"""The true joint effects of a simulated robot: friction, torque offsets, armature, springs.

They act on the robot's motion and appear in the joint torques only (they are internal to the
robot: the force plate does not see them)::

    tau_applied = M(q) ddq + h(q, dq) + Σ joint_torque(q, dq)   (+ armature on M's diagonal)

Each effect is a small frozen dataclass that names the channels it acts on and its true values,
so that an identification (or a later residual diagnosis) can be scored against them.

Defaults for the PUMA 560 come from the motor data of Corke's Robotics Toolbox
(``mdl_puma560``), reflected to the link side through the gear ratios ``G``: viscous
``fv = B G²``, Coulomb ``fc = (Tc⁺ − Tc⁻)/2 · |G|``, offset ``off = (Tc⁺ + Tc⁻)/2 · G`` (Corke's
asymmetric Coulomb friction is exactly ``fc sign(dq) + off``), armature ``Ia = Jm G²``; other
robots get the illustrative :data:`GENERIC_DEFAULTS`.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np
from numpy.typing import ArrayLike, NDArray

from dynamics.effects import linear as model_effects
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


def is_puma560(robot: RobotModel) -> bool:
    """Whether ``robot`` is the built-in PUMA 560 (any number of its joints)."""
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
    if is_puma560(robot) and robot.n_joints <= 6:
        return puma560_link_friction(robot.n_joints)[name]
    return np.full(robot.n_joints, GENERIC_DEFAULTS[name])


def finite_floats(values: ArrayLike, what: str) -> tuple[float, ...]:
    """``values`` (a number or a sequence) as a tuple of floats; ``ValueError`` naming ``what`` on NaN/inf."""
    array = np.atleast_1d(np.asarray(values, dtype=float)).reshape(-1)
    if not np.all(np.isfinite(array)):
        raise ValueError(f"{what} holds NaN or inf")
    return tuple(float(value) for value in array)


@dataclass(frozen=True)
class SimulatedPerJoint:
    """One value per joint (all joints of the robot, in order)."""

    values: tuple[float, ...]
    name: ClassVar[str] = ""
    symbol: ClassVar[str] = ""
    #: friction dissipates and inertia is positive: a negative value would be another effect
    non_negative: ClassVar[bool] = False

    def __post_init__(self) -> None:
        object.__setattr__(self, "values", finite_floats(self.values, f"{self.name} values"))
        if self.non_negative and any(value < 0 for value in self.values):
            raise ValueError(f"{self.name} values must be non-negative, got {list(self.values)}: a negative "
                             f"{self.name} term would push the joint, which no {self.name} does")
        # the values as a read-only array, made once: the plant asks for them at every RK4 stage
        array = np.array(self.values)
        array.flags.writeable = False
        object.__setattr__(self, "_array", array)

    def _check(self, robot: RobotModel) -> NDArray[np.float64]:
        if len(self.values) != robot.n_joints:
            raise ValueError(f"effect {self.name!r} has {len(self.values)} values for a robot of {robot.n_joints} joints")
        return self._array

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
        """The :mod:`dynamics.effects.linear` object whose columns model this effect (``None`` when none does)."""
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
class Viscous(SimulatedPerJoint):
    """Viscous friction ``fv_i · dq_i`` (N·m·s/rad), joint rows (PUMA paper, eq. 14)."""

    name: ClassVar[str] = "viscous"
    symbol: ClassVar[str] = "fv"
    non_negative: ClassVar[bool] = True

    def joint_torque(self, robot, q, dq):
        return self._check(robot) * dq


@dataclass(frozen=True)
class Coulomb(SimulatedPerJoint):
    """Coulomb friction ``fc_i · tanh(dq_i / smoothing)`` (N·m), joint rows.

    The integrator needs a continuous law: ``smoothing`` (rad/s) is the velocity below which the
    friction fades; the identification model :class:`dynamics.effects.linear.CoulombFriction` with
    the same smoothing reproduces it exactly, with ``smoothing=None`` (``sign``) up to the band.
    """

    smoothing: float = 0.05
    name: ClassVar[str] = "coulomb"
    symbol: ClassVar[str] = "fc"
    non_negative: ClassVar[bool] = True

    def __post_init__(self) -> None:
        super().__post_init__()
        if not self.smoothing > 0:
            raise ValueError(f"coulomb smoothing must be a positive velocity, got {self.smoothing}")

    def joint_torque(self, robot, q, dq):
        return self._check(robot) * np.tanh(dq / self.smoothing)

    def model_effect(self):
        return model_effects.CoulombFriction(smoothing=self.smoothing)


@dataclass(frozen=True)
class Offset(SimulatedPerJoint):
    """A constant joint torque ``off_i`` (N·m) the drive must supply (bias, asymmetric friction)."""

    name: ClassVar[str] = "offset"
    symbol: ClassVar[str] = "off"

    def joint_torque(self, robot, q, dq):
        return self._check(robot)


@dataclass(frozen=True)
class SimulatedArmature(SimulatedPerJoint):
    """Reflected rotor inertia ``Ia_i · ddq_i`` (kg·m²), added to the mass matrix diagonal.

    Joint rows only: the rotor's reaction on the stator (``1/G`` of it) is neglected, as in the
    identification model :class:`dynamics.effects.linear.SimulatedArmature`.
    """

    name: ClassVar[str] = "armature"
    symbol: ClassVar[str] = "Ia"
    non_negative: ClassVar[bool] = True

    def armature(self, robot):
        return self._check(robot)


@dataclass(frozen=True)
class SimulatedSpring:
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
            object.__setattr__(self, label, finite_floats(values, f"spring {label}"))

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


JOINT_EFFECTS = (Viscous, Coulomb, Offset, SimulatedArmature, SimulatedSpring)
