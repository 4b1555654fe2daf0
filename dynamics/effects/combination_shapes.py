"""Coulomb friction on a joint combination with its own smoothing: ``coulomb:tanh[q5+q6]``.

A motor turning with ``v = r q̇`` (``r`` a row of the transmission, :mod:`dynamics.effects.motor`)
whose Coulomb law is smooth near ``v = 0`` adds ``τ = rᵀ fc tanh(r q̇ / vc)``; ``fc`` is linear,
the smoothing ``vc`` (in the unit of ``v``: joint rad/s for ``r = e5 + e6``) a shape parameter the
data give (the :class:`dynamics.effects.shaped.ShapedEffect` protocol, as ``coulomb:tanh`` is for
one joint). It matters for a coupled wrist: the motor that turns with ``q5 + q6`` stands nearly
still whenever ``q5`` and ``q6`` turn against each other while both joints move, so rows that a
per-joint rest threshold keeps sit where the sign law and a motor's smooth law differ. On the
simulated PUMA 560 whose last motor turns with ``q5 + q6`` (motor smoothing 1 rad/s, 0.013 rad/s on
the joints; 5 % of the kept rows below it), the sign law's ``fc[q5+q6]`` came out 0.494 ± 0.013
against 0.554 true (4.6 standard deviations low), the smoothed law's 0.552 ± 0.009
(``tests/test_asbuilt_puma.py``).

The diagnosis proposes it beside the sign law for each traced pair
(:func:`estimation.diagnosis.candidates.coupling.coupling_candidates`); at most one Coulomb law per
combination is added (:func:`estimation.diagnosis.candidates.coupling.combination_taken`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import casadi
import numpy as np

from dynamics.effects.motor import CombinationEffect
from dynamics.robot import RobotModel
from dynamics.effects.shaped import ShapeParameter, TanhCoulombFriction

#: bounds and starts of the smoothing, as for the per-joint ``coulomb:tanh`` (rad/s)
SMOOTHING = TanhCoulombFriction.kinds[0]


@dataclass(frozen=True)
class TanhCombinationCoulomb:
    """``τ += rᵀ fc tanh(r q̇ / vc)`` for one joint combination ``r`` (``fc[q5+q6]``, ``vc[q5+q6]``).

    Parameters
    ----------
    weights
        The row ``r`` (one value per joint), as a one-row tuple like :class:`CombinationEffect`'s.
    labels
        Its text (``q5+q6``), one.
    """

    weights: tuple[tuple[float, ...], ...]
    labels: tuple[str, ...]
    kind: ClassVar[str] = "coulomb"
    variant: ClassVar[str] = "tanh"
    motor: ClassVar[bool] = False
    physical_kind: ClassVar[str] = "coulomb"

    def __post_init__(self) -> None:
        plain = CombinationEffect("coulomb", self.weights, self.labels)  # the same checks of the rows
        if len(plain.weights) != 1:
            raise ValueError("coulomb:tanh on a joint combination takes one row (one motor)")
        object.__setattr__(self, "weights", plain.weights)
        object.__setattr__(self, "labels", plain.labels)

    @classmethod
    def from_combination(cls, effect: CombinationEffect) -> TanhCombinationCoulomb:
        """The smoothed law on the combination of a plain ``coulomb[...]`` effect."""
        return cls(effect.weights, effect.labels)

    @property
    def name(self) -> str:
        """``coulomb[q5+q6]``: the same name as the sign law (one Coulomb law per combination)."""
        return f"coulomb[{self.labels[0]}]"

    @property
    def spec(self) -> str:
        """``coulomb:tanh[q5+q6]`` as ``--friction`` spells it."""
        return f"coulomb:tanh[{self.labels[0]}]"

    def _check(self, robot: RobotModel) -> None:
        if len(self.weights[0]) != robot.n_joints:
            raise ValueError(f"effect {self.spec}: {len(self.weights[0])} weights for a robot of {robot.n_joints} joints")

    def parameter_names(self, robot: RobotModel) -> list[str]:
        self._check(robot)
        return [f"fc[{self.labels[0]}]"]

    def shape_parameters(self, robot: RobotModel) -> tuple[ShapeParameter, ...]:
        self._check(robot)
        return (ShapeParameter(f"vc[{self.labels[0]}]", SMOOTHING.lower, SMOOTHING.upper, SMOOTHING.starts,
                               SMOOTHING.log_scale),)

    def shaped_columns(self, robot: RobotModel, q: casadi.SX, dq: casadi.SX, ddq: casadi.SX, shape: casadi.SX):
        self._check(robot)
        r = casadi.DM(self.weights[0])
        block = casadi.SX.zeros(robot.n_joints, 1)
        block[:, 0] = r * casadi.tanh(casadi.dot(r, dq) / shape[0])
        return block, None

    def columns(self, robot: RobotModel, q: casadi.SX, dq: casadi.SX, ddq: casadi.SX):
        reference = casadi.SX([parameter.reference for parameter in self.shape_parameters(robot)])
        return self.shaped_columns(robot, q, dq, ddq, reference)


def combination_row(effect: object, kind: str = "coulomb") -> tuple[float, ...] | None:
    """The row ``r`` of a ``kind`` law on one joint combination (Coulomb: sign or smoothed), scaled to
    a largest ``|r|`` of 1, else ``None`` (to keep one Coulomb law per combination, and to group a
    combination's Coulomb and viscous laws)."""
    if getattr(effect, "kind", None) != kind or getattr(effect, "motor", False):
        return None
    weights = getattr(effect, "weights", ())
    if len(weights) != 1:
        return None
    row = np.asarray(weights[0], dtype=float)
    return tuple(np.round(row / row[np.argmax(np.abs(row))], 12).tolist())
