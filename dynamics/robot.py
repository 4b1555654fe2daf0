"""Serial-chain robot descriptions as plain data.

A robot is a chain of ``n`` one-degree-of-freedom joints. Link ``i`` carries a frame ``F_i`` in
which its standard inertial parameters are expressed; frames are chained as

.. math::  {}^{i-1}T_i(q_i) = A_i \\; J_i(q_i) \\; B_i ,

where ``A_i`` is the fixed placement of joint ``i`` in ``F_{i-1}`` (``F_0`` is the base frame),
``J_i`` the joint motion (rotation about, or translation along, the unit ``axis`` given in the
joint frame) and ``B_i`` a fixed transform from the joint frame to the link frame. A URDF has
``B_i = I`` (parameters in the child-link frame); a standard DH table has ``A_i = I``,
``J_i = R_z(q_i)`` and ``B_i = T_z(d_i) T_x(a_i) R_x(alpha_i)``, so that ``F_i`` is the DH frame
``i`` in which the DH literature gives inertial data.

Standard inertial parameters of one link, in this order, expressed in ``F_i``::

    m, mx, my, mz, Ixx, Ixy, Iyy, Ixz, Iyz, Izz

with ``(mx, my, mz) = m * c`` the first moments (``c``: centre of mass in ``F_i``) and ``I``
the rotational inertia **about the origin of** ``F_i`` (Pinocchio's ``toDynamicParameters``
order).
"""

from __future__ import annotations

import enum
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, fields, is_dataclass, replace

import numpy as np
from numpy.typing import ArrayLike, NDArray

from dynamics.errors import RobotDescriptionError

LINK_PARAMETER_NAMES: tuple[str, ...] = ("m", "mx", "my", "mz", "Ixx", "Ixy", "Iyy", "Ixz", "Iyz", "Izz")
N_LINK_PARAMETERS = len(LINK_PARAMETER_NAMES)
DEFAULT_GRAVITY: tuple[float, float, float] = (0.0, 0.0, -9.81)


class JointType(str, enum.Enum):
    """Kinds of one-degree-of-freedom joints a serial chain may hold."""

    REVOLUTE = "revolute"
    PRISMATIC = "prismatic"


def _as_transform(value: ArrayLike | None, what: str) -> NDArray[np.float64]:
    if value is None:
        return np.eye(4)
    transform = np.asarray(value, dtype=float)
    if transform.shape != (4, 4):
        raise RobotDescriptionError(f"{what} must be a 4x4 homogeneous transform, got shape {transform.shape}")
    if not np.all(np.isfinite(transform)):
        raise RobotDescriptionError(f"{what} holds NaN or inf")
    # exact zeros and ones (cos(pi/2) is 6e-17, not 0) let CasADi drop the products they cancel
    transform = np.where(np.abs(transform) < 1e-14, 0.0, transform)
    transform = np.where(np.abs(np.abs(transform) - 1.0) < 1e-14, np.sign(transform), transform)
    rotation = transform[:3, :3]
    if not np.allclose(rotation.T @ rotation, np.eye(3), atol=1e-9) or np.linalg.det(rotation) < 0:
        raise RobotDescriptionError(f"{what} does not hold a proper rotation matrix")
    return transform


@dataclass(frozen=True, eq=False)
class Joint:
    """One joint of the chain and the link it moves.

    Parameters
    ----------
    name
        Joint name (from the URDF, or ``joint1``… for a DH table).
    joint_type
        Revolute (``q`` in rad) or prismatic (``q`` in m).
    axis
        Unit vector of the joint axis in the joint frame.
    placement
        ``A_i``: 4x4 transform of the joint frame (at ``q = 0``) in the previous link frame.
    link_transform
        ``B_i``: 4x4 transform of the link frame ``F_i`` in the joint frame.
    inertial
        The ten standard parameters of the link, in ``F_i`` (see module docstring).
    lower, upper, velocity, effort
        Limits (``inf`` where unknown).
    armature, damping, friction
        The description's joint terms where it gives them (0: not given): the rotor's reflected inertia
        (kg·m², ``I_a q̈``), viscous (``f_v q̇``) and Coulomb (``f_c sign q̇``) friction; an MJCF model's ``armature``,
        ``damping`` and ``frictionloss`` (:mod:`dynamics.mjcf`), the consistent fit's prior for those laws.
    actuated
        ``False`` for a passive (unactuated) joint: no motor drives it, so its torque is zero by physics
        (``τ_j = 0 = Y_j θ``, its own friction in ``Y_j``): a measurement of zero, not a channel that was not logged
        (:meth:`RobotModel.with_passive`; the verbs' ``--passive``).
    """

    name: str
    joint_type: JointType
    axis: NDArray[np.float64]
    placement: NDArray[np.float64]
    link_transform: NDArray[np.float64]
    inertial: NDArray[np.float64]
    lower: float = -np.inf
    upper: float = np.inf
    velocity: float = np.inf
    effort: float = np.inf
    armature: float = 0.0
    damping: float = 0.0
    friction: float = 0.0
    actuated: bool = True

    def __post_init__(self) -> None:
        if not isinstance(self.actuated, (bool, np.bool_)):
            raise TypeError(f"joint {self.name!r}: actuated must be a bool, got {type(self.actuated).__name__}")
        object.__setattr__(self, "actuated", bool(self.actuated))
        for term in ("armature", "damping", "friction"):
            value = float(getattr(self, term))
            if not (np.isfinite(value) and value >= 0):
                raise RobotDescriptionError(f"joint {self.name!r}: {term} {value} is not a finite number of at least 0")
            object.__setattr__(self, term, value)
        if not isinstance(self.joint_type, JointType):
            try:
                object.__setattr__(self, "joint_type", JointType(self.joint_type))
            except ValueError:
                raise RobotDescriptionError(
                    f"joint {self.name!r}: unsupported joint type {self.joint_type!r}; "
                    f"expected one of {[kind.value for kind in JointType]}"
                ) from None
        axis = np.asarray(self.axis, dtype=float).reshape(-1)
        if axis.shape != (3,) or not np.all(np.isfinite(axis)) or np.linalg.norm(axis) < 1e-12:
            raise RobotDescriptionError(f"joint {self.name!r}: axis must be a finite non-zero 3-vector")
        object.__setattr__(self, "axis", axis / np.linalg.norm(axis))
        object.__setattr__(self, "placement", _as_transform(self.placement, f"joint {self.name!r} placement"))
        object.__setattr__(
            self, "link_transform", _as_transform(self.link_transform, f"joint {self.name!r} link transform")
        )
        inertial = np.asarray(self.inertial, dtype=float).reshape(-1)
        if inertial.shape != (N_LINK_PARAMETERS,):
            raise RobotDescriptionError(
                f"joint {self.name!r}: inertial parameters must have {N_LINK_PARAMETERS} entries "
                f"{LINK_PARAMETER_NAMES}, got {inertial.shape[0]}"
            )
        if not np.all(np.isfinite(inertial)):
            raise RobotDescriptionError(f"joint {self.name!r}: inertial parameters hold NaN or inf")
        if inertial[0] < 0:
            raise RobotDescriptionError(f"joint {self.name!r}: negative link mass {inertial[0]}")
        object.__setattr__(self, "inertial", inertial)
        if self.lower > self.upper:
            raise RobotDescriptionError(f"joint {self.name!r}: lower limit {self.lower} above upper {self.upper}")


@dataclass(frozen=True, eq=False)
class RobotModel:
    """A serial chain of one-degree-of-freedom joints, with gravity.

    Instances are immutable and compared by identity, so that models built from them can be
    cached per robot.

    Parameters
    ----------
    name
        A label for reports.
    joints
        The joints from base to tip.
    gravity
        Gravity vector in the base frame, m/s² (default ``(0, 0, -9.81)``: z up).
    geometry
        Named lengths of the description (``a2``, ``d3``…), used only to print base-parameter
        groupings as readable expressions.
    description_joints
        Where the chain was read out of a larger description (a URDF's tree, by joint names): every movable joint of
        that description in the order the file declares them, the numbering of a log of the whole description
        (``q1..qN``); empty where the chain is its description.
    apart_joints
        Those of ``description_joints`` neither on the chain's path from the base nor carried by it (another arm on
        a torso the chain shares no joint with): their motion moves nothing of the chain, nor loads its joints.
    """

    name: str
    joints: tuple[Joint, ...]
    gravity: NDArray[np.float64] = field(default_factory=lambda: np.array(DEFAULT_GRAVITY))
    geometry: Mapping[str, float] = field(default_factory=dict)
    description_joints: tuple[str, ...] = ()
    apart_joints: frozenset[str] = frozenset()

    def __post_init__(self) -> None:
        joints = tuple(self.joints)
        if not joints:
            raise RobotDescriptionError(f"robot {self.name!r} has no joints")
        if not all(isinstance(joint, Joint) for joint in joints):
            raise TypeError("joints must be dynamics.robot.Joint instances")
        names = [joint.name for joint in joints]
        if len(set(names)) != len(names):
            raise RobotDescriptionError(f"robot {self.name!r}: duplicate joint names {names}")
        object.__setattr__(self, "joints", joints)
        gravity = np.asarray(self.gravity, dtype=float).reshape(-1)
        if gravity.shape != (3,) or not np.all(np.isfinite(gravity)):
            raise RobotDescriptionError("gravity must be a finite 3-vector")
        object.__setattr__(self, "gravity", gravity)
        object.__setattr__(self, "geometry", dict(self.geometry))
        described = tuple(str(name) for name in self.description_joints)
        apart = frozenset(str(name) for name in self.apart_joints)
        if described and not set(names) <= set(described) or not apart <= set(described) or apart & set(names):
            raise RobotDescriptionError(f"robot {self.name!r}: description joints {list(described)} must hold the "
                                        f"chain's {names}, and the joints apart from it none of them")
        object.__setattr__(self, "description_joints", described)
        object.__setattr__(self, "apart_joints", apart)

    @property
    def n_joints(self) -> int:
        """Number of joints ``n``."""
        return len(self.joints)

    @property
    def joint_names(self) -> list[str]:
        return [joint.name for joint in self.joints]

    @property
    def standard_parameter_names(self) -> list[str]:
        """Names of the ``10 n`` standard inertial parameters, link by link (``m1, mx1, …, Izz_n``)."""
        return [f"{name}{index}" for index in range(1, self.n_joints + 1) for name in LINK_PARAMETER_NAMES]

    @property
    def standard_parameters(self) -> NDArray[np.float64]:
        """The ``10 n`` standard inertial parameters of the description, stacked link by link."""
        return np.concatenate([joint.inertial for joint in self.joints])

    @property
    def lower(self) -> NDArray[np.float64]:
        return np.array([joint.lower for joint in self.joints])

    @property
    def upper(self) -> NDArray[np.float64]:
        return np.array([joint.upper for joint in self.joints])

    @property
    def velocity_limit(self) -> NDArray[np.float64]:
        return np.array([joint.velocity for joint in self.joints])

    @property
    def passive_joints(self) -> tuple[str, ...]:
        """The names of the passive (unactuated) joints, base to tip (:attr:`Joint.actuated` false)."""
        return tuple(joint.name for joint in self.joints if not joint.actuated)

    def with_passive(self, joints: Sequence[str]) -> RobotModel:
        """Return a copy whose ``joints`` (names, or numbers from 1 base to tip) are passive (unactuated: their torque
        is zero by physics, :attr:`Joint.actuated`); the others as they are. A name or number of no joint of the chain
        is a :class:`~dynamics.errors.RobotDescriptionError` naming the chain's joints."""
        chosen = set(passive_joint_indices(self, joints))
        if not chosen:
            return self
        updated = tuple(replace(joint, actuated=False) if index in chosen else joint
                        for index, joint in enumerate(self.joints))
        return replace(self, joints=updated)

    def with_gravity(self, gravity: ArrayLike) -> RobotModel:
        """Return a copy with another gravity vector."""
        return replace(self, gravity=np.asarray(gravity, dtype=float))

    def with_parameters(self, theta: ArrayLike) -> RobotModel:
        """Return a copy whose links carry the standard parameters ``theta`` (``10 n`` values)."""
        theta = np.asarray(theta, dtype=float).reshape(-1)
        expected = N_LINK_PARAMETERS * self.n_joints
        if theta.shape != (expected,):
            raise ValueError(f"expected {expected} standard parameters, got {theta.shape[0]}")
        joints = tuple(
            Joint(
                joint.name, joint.joint_type, joint.axis, joint.placement, joint.link_transform,
                theta[N_LINK_PARAMETERS * index : N_LINK_PARAMETERS * (index + 1)],
                joint.lower, joint.upper, joint.velocity, joint.effort, joint.armature, joint.damping, joint.friction,
                joint.actuated,
            )
            for index, joint in enumerate(self.joints)
        )
        return replace(self, joints=joints)


def passive_joint_indices(robot: RobotModel, joints: Sequence[str]) -> tuple[int, ...]:
    """The 0-based indices of ``joints`` (each a joint's name, or its number from 1, base to tip), sorted and without
    repeats; a name or number of no joint of ``robot`` is a :class:`~dynamics.errors.RobotDescriptionError` naming the
    chain's joints."""
    names = [joint.name for joint in robot.joints]
    found = set()
    for given in joints:
        text = str(given).strip()
        if text in names:
            found.add(names.index(text))
        elif text.isdigit() and 1 <= int(text) <= len(names):
            found.add(int(text) - 1)
        else:
            raise RobotDescriptionError(
                f"passive joint {text!r}: no joint of {robot.name} has that name or number (its joints, 1 to "
                f"{len(names)} base to tip: {', '.join(names)})")
    return tuple(sorted(found))


def description_key(robot: RobotModel) -> tuple:
    """A hashable key that two robots share exactly when every field of their descriptions is equal, bit for bit.

    :class:`RobotModel` is compared by identity; a robot read again from the same description (a built-in robot
    loaded by each verb, a URDF read by each ``oed predict``) is another object with the same values. Caches of
    what is derived from a description alone (its regressors, the identification models built on it) are keyed on
    this, so that the derived functions are built once per description and not once per reading. Every field of
    the robot and of its joints enters the key (arrays by dtype, shape and bytes), whatever fields they gain.
    """
    return _value_key(robot)


@dataclass(frozen=True, eq=False)
class ByDescription:
    """A robot as a cache key: equal to (and hashed as) any robot of the same description (:func:`description_key`),
    so that what is derived from a robot read again (each verb loads its robot anew) is found in the cache of the
    first reading; ``robot`` is the robot the key was made from."""

    robot: RobotModel
    key: tuple = field(init=False, repr=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "key", description_key(self.robot))

    def __hash__(self) -> int:
        return hash(self.key)

    def __eq__(self, other: object) -> bool:
        return isinstance(other, ByDescription) and other.key == self.key


def _value_key(value: object) -> object:
    if isinstance(value, np.ndarray):
        return ("array", value.dtype.str, value.shape, value.tobytes())
    if is_dataclass(value) and not isinstance(value, type):
        return (type(value).__qualname__, *((item.name, _value_key(getattr(value, item.name))) for item in fields(value)))
    if isinstance(value, Mapping):
        return ("mapping", *sorted((str(key), _value_key(item)) for key, item in value.items()))
    if isinstance(value, (tuple, list)):
        return (type(value).__name__, *(_value_key(item) for item in value))
    if isinstance(value, float):
        return ("float", np.float64(value).tobytes())  # 0.0 and -0.0 apart, NaN equal to itself
    if isinstance(value, (str, int, bool, enum.Enum)) or value is None:
        return (type(value).__name__, value)
    return ("object", value)  # anything else by its own equality (identity unless it defines one)


def inertial_parameters(mass: float, com: ArrayLike, inertia_com: ArrayLike) -> NDArray[np.float64]:
    """Standard parameters from mass, centre of mass and inertia about the centre of mass.

    Uses the parallel-axis theorem ``I_O = I_C + m (|c|² 1 − c cᵀ)``.

    Parameters
    ----------
    mass
        Link mass, kg.
    com
        Centre of mass in the link frame, m.
    inertia_com
        3x3 inertia matrix about the centre of mass, or its 6 entries
        ``(Ixx, Iyy, Izz, Ixy, Iyz, Ixz)`` (the order of Corke's toolbox), kg·m².
    """
    com = np.asarray(com, dtype=float).reshape(3)
    inertia = np.asarray(inertia_com, dtype=float)
    if inertia.shape == (6,):
        ixx, iyy, izz, ixy, iyz, ixz = inertia
        inertia = np.array([[ixx, ixy, ixz], [ixy, iyy, iyz], [ixz, iyz, izz]])
    if inertia.shape != (3, 3):
        raise ValueError("inertia_com must be a 3x3 matrix or 6 values (Ixx, Iyy, Izz, Ixy, Iyz, Ixz)")
    inertia_origin = inertia + mass * (com @ com * np.eye(3) - np.outer(com, com))
    return np.array(
        [
            mass, *(mass * com),
            inertia_origin[0, 0], inertia_origin[0, 1], inertia_origin[1, 1],
            inertia_origin[0, 2], inertia_origin[1, 2], inertia_origin[2, 2],
        ]
    )


def translation(x: float, y: float, z: float) -> NDArray[np.float64]:
    transform = np.eye(4)
    transform[:3, 3] = (x, y, z)
    return transform


def rotation_x(angle: float) -> NDArray[np.float64]:
    cos, sin = np.cos(angle), np.sin(angle)
    transform = np.eye(4)
    transform[1:3, 1:3] = [[cos, -sin], [sin, cos]]
    return transform


def rotation_z(angle: float) -> NDArray[np.float64]:
    cos, sin = np.cos(angle), np.sin(angle)
    transform = np.eye(4)
    transform[0:2, 0:2] = [[cos, -sin], [sin, cos]]
    return transform


def check_joint_count(robot: RobotModel, values: Sequence[object], what: str) -> None:
    """Raise if ``values`` does not hold one entry per joint."""
    if len(values) != robot.n_joints:
        raise ValueError(f"{what}: expected {robot.n_joints} values (one per joint), got {len(values)}")
