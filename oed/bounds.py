"""Motion bounds of an excitation trajectory: position range, velocity and acceleration limits.

The PUMA paper (eq. 19) bounds each joint's position, velocity and acceleration symmetrically;
:class:`JointBounds` also allows an asymmetric position range (URDF ``lower``/``upper``).
"""

from __future__ import annotations

import json
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from dynamics.robot import RobotModel

STATE_LABELS: dict[str, str] = {"q": "position", "dq": "velocity", "ddq": "acceleration"}


class InfeasibleBoundsError(ValueError):
    """Bounds that no excitation trajectory can meet (or that leave nothing to excite)."""


#: the keys of a bounds document (JSON file or dict)
BOUND_KEYS: tuple[str, ...] = ("q_min", "q_max", "dq_max", "ddq_max", "joint_names")
#: a bound beyond this (rad, m, per s, per s²) is no bound: give the real limit
LARGEST_BOUND = 1e6


def _vector(values: ArrayLike, name: str, n: int | None = None) -> NDArray[np.float64]:
    if any(isinstance(value, (bool, np.bool_, str)) for value in np.ravel(np.asarray(values, dtype=object))):
        raise TypeError(f"bound {name} must be a sequence of numbers, got {values!r}")
    if np.ndim(values) > 1:
        raise ValueError(f"bound {name} must be a flat list, one value per joint, got shape {np.shape(values)}")
    try:
        array = np.asarray(values, dtype=float).reshape(-1)
    except (TypeError, ValueError):
        raise TypeError(f"bound {name} must be a sequence of numbers") from None
    if n is not None and array.shape[0] == 1:
        array = np.repeat(array, n)
    if n is not None and array.shape[0] != n:
        raise ValueError(f"bound {name} has {array.shape[0]} values for {n} joints")
    return array


def _iterable(values: Any) -> tuple:
    try:
        return tuple(values)
    except TypeError:
        raise TypeError(f"joint_names must be a list of names, got {values!r}") from None


@dataclass(frozen=True)
class JointBounds:
    """Per-joint bounds ``q_min ≤ q ≤ q_max``, ``|dq| ≤ dq_max``, ``|ddq| ≤ ddq_max`` (SI units).

    Parameters
    ----------
    q_min, q_max
        ``(n,)`` position range (rad or m); may be asymmetric.
    dq_max, ddq_max
        ``(n,)`` positive velocity and acceleration limits.
    joint_names
        Names used in messages (default ``joint1``…).
    """

    q_min: NDArray[np.float64]
    q_max: NDArray[np.float64]
    dq_max: NDArray[np.float64]
    ddq_max: NDArray[np.float64]
    joint_names: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        q_max = _vector(self.q_max, "q_max")
        n = q_max.shape[0]
        if n == 0:
            raise ValueError("bounds describe no joint")
        values = {"q_min": _vector(self.q_min, "q_min", n), "q_max": q_max}
        values["dq_max"] = _vector(self.dq_max, "dq_max", n)
        values["ddq_max"] = _vector(self.ddq_max, "ddq_max", n)
        if isinstance(self.joint_names, str) or not all(isinstance(name, str) for name in _iterable(self.joint_names)):
            raise TypeError(f"joint_names must be a list of names, got {self.joint_names!r}")
        names = tuple(self.joint_names) or tuple(f"joint{i}" for i in range(1, n + 1))
        if len(names) != n:
            raise ValueError(f"{len(names)} joint names for {n} joints in the bounds")
        object.__setattr__(self, "joint_names", names)
        for key in ("q_max", "q_min", "dq_max", "ddq_max"):  # q_min may be derived from q_max: name q_max first
            array = values[key]
            for index in np.flatnonzero(~np.isfinite(array)):
                raise ValueError(f"bound {key} of joint {names[index]!r} is not finite ({array[index]})")
            for index in np.flatnonzero(np.abs(array) > LARGEST_BOUND):
                raise ValueError(f"bound {key} of joint {names[index]!r} is {array[index]:.3g}: a bound this large is "
                                 "no bound; give the joint's real limit")
            object.__setattr__(self, key, array)
        for index in range(n):
            joint = names[index]
            if values["q_min"][index] >= values["q_max"][index]:
                raise InfeasibleBoundsError(
                    f"joint {joint!r}: position range [{values['q_min'][index]}, {values['q_max'][index]}] is empty "
                    "or a single point: no trajectory can move the joint"
                )
            for key in ("dq_max", "ddq_max"):
                if values[key][index] <= 0:
                    raise InfeasibleBoundsError(
                        f"joint {joint!r}: {key} = {values[key][index]} must be positive: no trajectory can move the joint"
                    )

    @property
    def n_joints(self) -> int:
        return self.q_max.shape[0]

    @classmethod
    def symmetric(cls, q_max: ArrayLike, dq_max: ArrayLike, ddq_max: ArrayLike, joint_names: Sequence[str] = ()) -> JointBounds:
        """``|q| ≤ q_max`` as in eq. 19."""
        q_max = _vector(q_max, "q_max")
        return cls(-q_max, q_max, dq_max, ddq_max, tuple(joint_names))

    @classmethod
    def from_robot(
        cls, robot: RobotModel, *, ddq_max: ArrayLike | None = None, dq_max: ArrayLike | None = None, scale: float = 1.0
    ) -> JointBounds:
        """Position and velocity limits of the robot description (URDF ``<limit>``), times ``scale``.

        URDF files carry no acceleration limits: ``ddq_max`` must be given (one value or one per joint).
        """
        if ddq_max is None:
            raise ValueError(f"{robot.name}: acceleration bounds (ddq_max) are not in the robot description; give them")
        n = robot.n_joints
        lower, upper = np.asarray(robot.lower, float), np.asarray(robot.upper, float)
        velocity = np.asarray(robot.velocity_limit, float) if dq_max is None else _vector(dq_max, "dq_max", n)
        for key, array in (("lower position", lower), ("upper position", upper), ("velocity", velocity)):
            for index in np.flatnonzero(~np.isfinite(array)):
                raise ValueError(f"joint {robot.joint_names[index]!r} has no {key} limit in {robot.name}; give a bounds file")
        centre, half = (upper + lower) / 2, (upper - lower) / 2 * scale
        return cls(centre - half, centre + half, velocity * scale, _vector(ddq_max, "ddq_max", n), tuple(robot.joint_names))

    @classmethod
    def from_dict(cls, document: Mapping[str, Any]) -> JointBounds:
        """Keys ``q_max`` (and optionally ``q_min``; default ``-q_max``), ``dq_max``, ``ddq_max``, ``joint_names``."""
        missing = [key for key in ("q_max", "dq_max", "ddq_max") if key not in document]
        if missing:
            raise ValueError(f"bounds lack {', '.join(missing)}")
        unknown = sorted(set(document) - set(BOUND_KEYS))
        if unknown:  # a typo such as "q_mn" would otherwise make the bounds silently symmetric
            raise ValueError(f"bounds have unknown key(s) {', '.join(unknown)}; expected some of {', '.join(BOUND_KEYS)}")
        q_max = _vector(document["q_max"], "q_max")
        q_min = _vector(document["q_min"], "q_min", q_max.shape[0]) if "q_min" in document else -q_max
        return cls(q_min, q_max, document["dq_max"], document["ddq_max"], document.get("joint_names", ()))

    @classmethod
    def load(cls, path: str | Path) -> JointBounds:
        """Read a JSON bounds file (see :meth:`from_dict`)."""
        path = Path(path)
        try:
            document = json.loads(path.read_text())
        except FileNotFoundError:
            raise FileNotFoundError(f"bounds file not found: {path}") from None
        except json.JSONDecodeError as error:
            raise ValueError(f"bounds file {path} is not valid JSON: {error}") from None
        if not isinstance(document, dict):
            raise ValueError(f"bounds file {path} must hold a JSON object")
        return cls.from_dict(document)

    def to_dict(self) -> dict[str, Any]:
        return {
            "joint_names": list(self.joint_names),
            "q_min": self.q_min.tolist(),
            "q_max": self.q_max.tolist(),
            "dq_max": self.dq_max.tolist(),
            "ddq_max": self.ddq_max.tolist(),
        }

    def check_joint_count(self, n_joints: int) -> None:
        if self.n_joints != n_joints:
            raise ValueError(f"bounds describe {self.n_joints} joints, the robot has {n_joints}")

    def excess(self, q: ArrayLike, dq: ArrayLike, ddq: ArrayLike) -> dict[str, NDArray[np.float64]]:
        """Amount by which each sample exceeds each bound, ``(T, n)`` per state (≤ 0 where met)."""
        q, dq, ddq = (np.atleast_2d(np.asarray(v, dtype=float)) for v in (q, dq, ddq))
        return {
            "q": np.maximum(q - self.q_max, self.q_min - q),
            "dq": np.abs(dq) - self.dq_max,
            "ddq": np.abs(ddq) - self.ddq_max,
        }

    def violations(self, q: ArrayLike, dq: ArrayLike, ddq: ArrayLike, *, tolerance: float = 1e-9) -> list[str]:
        """Human-readable list of the bounds exceeded (by more than ``tolerance``), worst sample per bound."""
        messages = []
        for state, excess in self.excess(q, dq, ddq).items():
            for joint in range(self.n_joints):
                worst = int(np.argmax(excess[:, joint]))
                if excess[worst, joint] > tolerance:
                    messages.append(
                        f"{STATE_LABELS[state]} bound of joint {self.joint_names[joint]!r} exceeded by "
                        f"{excess[worst, joint]:.3g} at sample {worst}"
                    )
        return messages


#: The PUMA paper's eq. 19 (first three joints).
PUMA_BOUNDS = JointBounds.symmetric(
    q_max=(2.5089, 1.6760, 2.1049),
    dq_max=(1.4312, 0.9425, 2.1293),
    ddq_max=(10.0, 5.0, 15.0),
    joint_names=("joint1", "joint2", "joint3"),
)
