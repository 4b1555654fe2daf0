"""Effects on a combination of joint velocities: motor-side friction and rotor inertia, coupled joints.

A motor that turns with ``θ̇_m = r q̇`` (``r`` a row of the transmission's ``R``,
:mod:`dynamics.transmission`) and dissipates ``τ_m = f(θ̇_m)`` adds ``τ = rᵀ f(r q̇)`` to the joint
torques (``τ = Rᵀ τ_m``). For a coupled wrist ``r`` has two or more non-zero entries, so one motor
parameter acts on two joint rows at once, which no per-joint effect can describe. Laws (linear in
their parameter, so that identification stays least squares)::

    viscous   f = fv · v                    v = r q̇      (N·m·s/rad on the motor side)
    coulomb   f = fc · sign(v)              or fc · tanh(v / smoothing)
    inertia   f = J · a                     a = r q̈      (rotor inertia, kg·m²)

:class:`CombinationEffect` implements :class:`dynamics.effects.linear.Effect` for any ``r``;
:func:`motor_effects` builds one per motor of a transmission (parameters ``fvm6``, ``fcm6``,
``Jm6``: motor-side values), :func:`pair_combinations` the joint pairs the diagnosis tries
(``coulomb[q5+q6]``, parameter ``fc[q5+q6]``).
"""

from __future__ import annotations

import re
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from typing import Literal

import casadi
import numpy as np

from dynamics.robot import RobotModel
from dynamics.transmission import Transmission

CombinationKind = Literal["viscous", "coulomb", "inertia"]
KINDS: tuple[str, ...] = ("viscous", "coulomb", "inertia")
#: parameter symbol per kind, for a joint combination (``fc[q5+q6]``) and for a motor (``fcm6``)
SYMBOLS: dict[str, str] = {"viscous": "fv", "coulomb": "fc", "inertia": "Ia"}
MOTOR_SYMBOLS: dict[str, str] = {"viscous": "fvm", "coulomb": "fcm", "inertia": "Jm"}
#: the effect kind used by the physical-sign checks (``dynamics.effects.linear.POSITIVE_EFFECTS``)
PHYSICAL_KINDS: dict[str, str] = {"viscous": "viscous", "coulomb": "coulomb", "inertia": "armature"}


@dataclass(frozen=True)
class CombinationEffect:
    """``τ += Σ_k r_kᵀ f(r_k q̇)``: one parameter per row ``r_k`` of ``weights``.

    Parameters
    ----------
    kind
        ``viscous``, ``coulomb`` or ``inertia`` (the law ``f`` above).
    weights
        Rows ``r_k`` (each one value per joint of the robot).
    labels
        One text per row, naming the combination (``q5+q6``) or the motor (``m6``).
    motor
        Whether the rows are motors of a transmission (names ``motor_coulomb[m6]``, parameters
        ``fcm6``) rather than joint combinations (``coulomb[q5+q6]``, ``fc[q5+q6]``).
    smoothing
        Coulomb only: ``tanh(v / smoothing)`` instead of ``sign(v)`` (same unit as ``v``). The
        shape parameters of other Coulomb variants go through :meth:`coulomb_law` later.
    """

    kind: CombinationKind
    weights: tuple[tuple[float, ...], ...]
    labels: tuple[str, ...]
    motor: bool = False
    smoothing: float | None = None

    def __post_init__(self) -> None:
        if self.kind not in KINDS:
            raise ValueError(f"unknown combination kind {self.kind!r}; expected one of {KINDS}")
        weights = tuple(tuple(float(value) for value in row) for row in self.weights)
        if not weights or len({len(row) for row in weights}) != 1 or len(self.labels) != len(weights):
            raise ValueError("weights must be equal-length rows, one label per row")
        if not all(np.all(np.isfinite(row)) and np.any(row) for row in weights):
            raise ValueError("each weight row must be finite and not all zero")
        object.__setattr__(self, "weights", weights)
        object.__setattr__(self, "labels", tuple(self.labels))
        if self.smoothing is not None and (self.kind != "coulomb" or not self.smoothing > 0):
            raise ValueError("smoothing is a positive velocity, for the coulomb kind only")

    @property
    def name(self) -> str:
        """``coulomb[q5+q6]`` or ``motor_coulomb[m6]`` (several rows: labels joined by ``,``)."""
        prefix = f"motor_{self.kind}" if self.motor else self.kind
        return f"{prefix}[{','.join(self.labels)}]"

    @property
    def physical_kind(self) -> str:
        """The per-joint effect of the same physics (sign checks: friction and inertia are positive)."""
        return PHYSICAL_KINDS[self.kind]

    def parameter_names(self, robot: RobotModel) -> list[str]:
        self._check(robot)
        if self.motor:
            return [f"{MOTOR_SYMBOLS[self.kind]}{label.removeprefix('m')}" for label in self.labels]
        return [f"{SYMBOLS[self.kind]}[{label}]" for label in self.labels]

    def _check(self, robot: RobotModel) -> None:
        if len(self.weights[0]) != robot.n_joints:
            raise ValueError(f"effect {self.name}: {len(self.weights[0])} weights per row for a robot of "
                             f"{robot.n_joints} joints")

    def coulomb_law(self, velocity: casadi.SX) -> casadi.SX:
        """The Coulomb shape: ``sign(v)``, or ``tanh(v / smoothing)``."""
        return casadi.sign(velocity) if self.smoothing is None else casadi.tanh(velocity / self.smoothing)

    def columns(self, robot, q, dq, ddq):
        self._check(robot)
        block = casadi.SX.zeros(robot.n_joints, len(self.weights))
        for column, row in enumerate(self.weights):
            r = casadi.DM(row)
            if self.kind == "inertia":
                term = casadi.dot(r, ddq)
            elif self.kind == "viscous":
                term = casadi.dot(r, dq)
            else:
                term = self.coulomb_law(casadi.dot(r, dq))
            block[:, column] = r * term
        return block, None


def motor_effects(transmission: Transmission, kind: CombinationKind, motors: Iterable[int] | None = None, *,
                  smoothing: float | None = None) -> tuple[CombinationEffect, ...]:
    """One motor-side effect per motor (0-based ``motors``, default all): ``motor_coulomb[m6]``…

    Each is its own effect (one parameter), so that the diagnosis and the spec ``@JOINTS`` can
    pick motors one by one.
    """
    indices = range(transmission.n_motors) if motors is None else motors
    effects = []
    for index in indices:
        if not 0 <= index < transmission.n_motors:
            raise ValueError(f"motor {index + 1} outside 1..{transmission.n_motors}")
        effects.append(CombinationEffect(kind, (tuple(transmission.matrix[index]),), (f"m{index + 1}",), motor=True,
                                         smoothing=smoothing))
    return tuple(effects)


def pair_combinations(n_joints: int, kind: CombinationKind, *, signs: Sequence[int] = (1, -1)) -> tuple[CombinationEffect, ...]:
    """``kind[qj+qj+1]`` and ``kind[qj-qj+1]`` for each adjacent pair of joints (a belt, a differential)."""
    effects = []
    for joint in range(n_joints - 1):
        for sign in signs:
            row = np.zeros(n_joints)
            row[joint], row[joint + 1] = 1.0, float(sign)
            label = f"q{joint + 1}{'+' if sign > 0 else '-'}q{joint + 2}"
            effects.append(CombinationEffect(kind, (tuple(row),), (label,)))
    return tuple(effects)


def combination_from_label(kind: CombinationKind, label: str, n_joints: int, *,
                           smoothing: float | None = None) -> CombinationEffect:
    """The effect named ``kind[label]``, e.g. ``coulomb[q5+q6]`` or ``viscous[q4-0.5*q5]`` (the
    names the diagnosis reports, so that a user can declare what it found)."""
    row = np.zeros(n_joints)
    text = label.replace(" ", "")
    terms = re.findall(r"([+-]?)(?:(\d+(?:\.\d*)?(?:[eE][+-]?\d+)?)\*)?q(\d+)", text)
    rebuilt = "".join(f"{sign}{factor + '*' if factor else ''}q{joint}" for sign, factor, joint in terms)
    if not terms or rebuilt.lstrip("+") != text.lstrip("+"):
        raise ValueError(f"cannot read the joint combination {label!r}: write it like q5+q6 or q4-0.5*q5")
    for sign, factor, joint in terms:
        index = int(joint) - 1
        if not 0 <= index < n_joints:
            raise ValueError(f"{kind}[{label}]: joint {joint} outside 1..{n_joints}")
        row[index] += (-1.0 if sign == "-" else 1.0) * (float(factor) if factor else 1.0)
    return CombinationEffect(kind, (tuple(row),), (label,), smoothing=smoothing)
