"""Effects whose shape the data must give: linear coefficients plus shape parameters.

An effect of :mod:`dynamics.effects.linear` is linear in its parameters: ``tau += C(q, dq, ddq) θ``. The
effects here have, beside their linear coefficients ``θ``, *shape parameters* ``s`` that enter
nonlinearly, ``tau += C(q, dq, ddq; s) θ`` — a smoothing velocity, a Stribeck velocity, a
sigmoid's slope and shift, a ripple's period. They implement the :class:`ShapedEffect` protocol,
which extends :class:`dynamics.effects.linear.Effect` compatibly:

* ``columns(robot, q, dq, ddq)`` (the plain protocol) gives the columns at the *reference* shape
  (a generic value inside the bounds), so a shaped effect works wherever an effect does
  (``build_model`` reduces the base parameters with it, at that value);
* ``shape_parameters(robot)`` names each shape parameter with its bounds and starting values
  (:class:`ShapeParameter`);
* ``shaped_columns(robot, q, dq, ddq, shape)`` gives the columns for a CasADi vector ``shape``
  of those parameters, so that the estimator (:mod:`estimation.estimators.variable_projection`) has exact
  derivatives in ``s``.

A user's own effect implements the same three methods (see ``notebooks/puma_loop.ipynb``).

Built in (``--friction NAME[:VARIANT]``):

=================  =====================================================  ==========  ===========
spec               law on joint ``i``                                     linear      shape
=================  =====================================================  ==========  ===========
``coulomb:tanh``   ``fc_i tanh(dq_i / vc_i)``                             ``fc_i``    ``vc_i``
``stribeck:velocity`` ``(fc_i + fs_i exp(−(|dq_i|/vs_i)²)) sign(dq_i)``    ``fc_i, fs_i`` ``vs_i``
``sigmoid``        ``φ1 σ(φ2 (dq_i + φ3)) − φ1 σ(φ2 φ3)``, ``σ(x)=1/(1+e^−x)`` ``phi1_i``  ``phi2_i, phi3_i``
``ripple``         ``rs_i sin(n_i q_i) + rc_i cos(n_i q_i)``              ``rs_i, rc_i`` ``n_i``
=================  =====================================================  ==========  ===========

The sigmoid law is that of Gaz, Cognetti, Oliva, Robuffo Giordano, De Luca, "Dynamic
identification of the Franka Emika Panda robot with retrieval of feasible parameters using
penalty-based optimization", IEEE RA-L 4(4), 2019, eq. (5); the ripple is the position-periodic
torque of cogging or of a gear's tooth meshing, its phase carried by the sin/cos amplitudes.
"""

from __future__ import annotations

import itertools
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, ClassVar, Protocol, runtime_checkable

import casadi
import numpy as np

from dynamics.robot import RobotModel


class ShapeBoundsError(ValueError):
    """Shape-parameter bounds that are empty, reversed or not finite, or starts outside them."""


@dataclass(frozen=True)
class ShapeParameter:
    """One shape parameter: its name, bounds and starting values.

    Attributes
    ----------
    name
        Parameter name (``vc1``, ``phi2_3``…).
    lower, upper
        Bounds, ``lower < upper``, finite.
    starts
        Starting values of the search (inside the bounds).
    log_scale
        Search on ``log s`` (a positive scale such as a velocity): ``lower`` must then be positive.
    """

    name: str
    lower: float
    upper: float
    starts: tuple[float, ...]
    log_scale: bool = False

    def __post_init__(self) -> None:
        lower, upper = float(self.lower), float(self.upper)
        if not (np.isfinite(lower) and np.isfinite(upper)):
            raise ShapeBoundsError(f"shape parameter {self.name}: bounds must be finite, got [{lower}, {upper}]")
        if not lower < upper:
            raise ShapeBoundsError(f"shape parameter {self.name}: bounds [{lower}, {upper}] are empty or reversed "
                                   "(give lower < upper)")
        if self.log_scale and lower <= 0:
            raise ShapeBoundsError(f"shape parameter {self.name} is searched on a log scale: its lower bound must "
                                   f"be positive, got {lower}")
        starts = tuple(float(value) for value in np.atleast_1d(np.asarray(self.starts, dtype=float)))
        if not starts:
            raise ShapeBoundsError(f"shape parameter {self.name}: give at least one starting value")
        outside = [value for value in starts if not lower <= value <= upper]
        if outside:
            raise ShapeBoundsError(f"shape parameter {self.name}: starts {outside} outside the bounds [{lower}, {upper}]")
        object.__setattr__(self, "lower", lower)
        object.__setattr__(self, "upper", upper)
        object.__setattr__(self, "starts", starts)

    @property
    def reference(self) -> float:
        """A generic value inside the bounds (the middle start): where the base reduction is done."""
        return self.starts[len(self.starts) // 2]


@runtime_checkable
class ShapedEffect(Protocol):
    """An effect with shape parameters beside its linear coefficients (see the module docstring)."""

    name: str

    def parameter_names(self, robot: RobotModel) -> list[str]:
        ...

    def columns(self, robot: RobotModel, q: casadi.SX, dq: casadi.SX, ddq: casadi.SX):
        ...

    def shape_parameters(self, robot: RobotModel) -> tuple[ShapeParameter, ...]:
        ...

    def shaped_columns(self, robot: RobotModel, q: casadi.SX, dq: casadi.SX, ddq: casadi.SX, shape: casadi.SX):
        ...


def shape_parameters(effect: Any, robot: RobotModel) -> tuple[ShapeParameter, ...]:
    """The shape parameters of an effect, ``()`` for a plain (linear) effect."""
    method = getattr(effect, "shape_parameters", None)
    if method is None or not callable(getattr(effect, "shaped_columns", None)):
        return ()
    parameters = tuple(method(robot))
    for parameter in parameters:
        if not isinstance(parameter, ShapeParameter):
            raise TypeError(f"effect {effect.name!r}: shape_parameters must give ShapeParameter objects, "
                            f"got {type(parameter).__name__}")
    return parameters


def is_shaped(effect: Any, robot: RobotModel) -> bool:
    """Whether ``effect`` has shape parameters."""
    return bool(shape_parameters(effect, robot))


def start_grid(parameters: Sequence[ShapeParameter]) -> np.ndarray:
    """The starting points, ``(starts, n_shape)``: per parameter *kind* (name without its joint
    suffix) the product of the kinds' starts, the same value on every joint (a product over joints
    too would grow as ``starts^(kinds·joints)``)."""
    if not parameters:
        return np.zeros((1, 0))
    kinds: dict[str, list[int]] = {}
    for index, parameter in enumerate(parameters):
        kinds.setdefault(_kind(parameter.name), []).append(index)
    groups = list(kinds.values())
    points = []
    for combination in itertools.product(*(range(len(parameters[group[0]].starts)) for group in groups)):
        point = np.empty(len(parameters))
        for group, choice in zip(groups, combination):
            for index in group:
                starts = parameters[index].starts
                point[index] = starts[min(choice, len(starts) - 1)]
        points.append(point)
    return np.array(points)


def _kind(name: str) -> str:
    return name.rstrip("0123456789").rstrip("_")


def _joint_indices(robot: RobotModel, joints: tuple[int, ...] | None, effect: str) -> tuple[int, ...]:
    if joints is None:
        return tuple(range(robot.n_joints))
    for joint in joints:
        if not 0 <= joint < robot.n_joints:
            raise ValueError(f"effect {effect!r}: joint index {joint} outside 0..{robot.n_joints - 1}")
    return tuple(joints)


@dataclass(frozen=True)
class ShapeKind:
    """A kind of shape parameter of a per-joint law: symbol, default bounds and starts, scale."""

    symbol: str
    lower: float
    upper: float
    starts: tuple[float, ...]
    log_scale: bool = False


@dataclass(frozen=True)
class ShapedPerJointEffect:
    """A per-joint law with linear coefficients and shape parameters, one set per selected joint.

    Attributes
    ----------
    joints
        0-based joints (``None``: every joint).
    bounds
        ``((lower, upper), …)`` one pair per shape kind, replacing the defaults.
    starts
        ``((s, …), …)`` starting values per shape kind, replacing the defaults.
    """

    joints: tuple[int, ...] | None = None
    bounds: tuple[tuple[float, float], ...] | None = None
    starts: tuple[tuple[float, ...], ...] | None = None
    name: ClassVar[str] = ""
    variant: ClassVar[str] = ""
    linear: ClassVar[tuple[str, ...]] = ()
    kinds: ClassVar[tuple[ShapeKind, ...]] = ()

    def __post_init__(self) -> None:
        if self.joints is not None:
            object.__setattr__(self, "joints", tuple(int(joint) for joint in self.joints))
        for label, value in (("bounds", self.bounds), ("starts", self.starts)):
            if value is not None:
                value = tuple(tuple(float(x) for x in np.atleast_1d(item)) for item in value)
                if len(value) != len(self.kinds):
                    raise ShapeBoundsError(f"effect {self.spec!r}: give {label} for each of its {len(self.kinds)} "
                                           f"shape parameter kind(s) ({', '.join(k.symbol for k in self.kinds)}), "
                                           f"got {len(value)}")
                if label == "bounds" and any(len(pair) != 2 for pair in value):
                    raise ShapeBoundsError(f"effect {self.spec!r}: each bound is a (lower, upper) pair, got {value}")
                object.__setattr__(self, label, value)
        self._kind_parameters("")  # checks the bounds and starts now

    @property
    def spec(self) -> str:
        """``name:variant`` as ``--friction`` spells it."""
        return f"{self.name}:{self.variant}" if self.variant else self.name

    def _kind_parameters(self, suffix: str) -> list[ShapeParameter]:
        parameters = []
        for index, kind in enumerate(self.kinds):
            lower, upper = self.bounds[index] if self.bounds is not None else (kind.lower, kind.upper)
            starts = self.starts[index] if self.starts is not None else kind.starts
            if self.starts is None and self.bounds is not None:  # default starts clipped into the given bounds
                inside = tuple(value for value in kind.starts if lower <= value <= upper)
                starts = inside or ((np.sqrt(lower * upper) if kind.log_scale and lower > 0 else 0.5 * (lower + upper)),)
            parameters.append(ShapeParameter(f"{kind.symbol}{suffix}", lower, upper, starts, kind.log_scale))
        return parameters

    def parameter_names(self, robot: RobotModel) -> list[str]:
        return [f"{symbol}{index + 1}" for index in _joint_indices(robot, self.joints, self.spec) for symbol in self.linear]

    def shape_parameters(self, robot: RobotModel) -> tuple[ShapeParameter, ...]:
        return tuple(parameter for index in _joint_indices(robot, self.joints, self.spec)
                     for parameter in self._kind_parameters(str(index + 1)))

    def law(self, q: casadi.SX, dq: casadi.SX, ddq: casadi.SX, shape: list[casadi.SX]) -> list[casadi.SX]:
        """One term per linear coefficient, for one joint's ``q, dq, ddq`` and shape values."""
        raise NotImplementedError  # pragma: no cover - abstract

    def shaped_columns(self, robot, q, dq, ddq, shape):
        indices = _joint_indices(robot, self.joints, self.spec)
        width, kinds = len(self.linear), len(self.kinds)
        block = casadi.SX.zeros(robot.n_joints, width * len(indices))
        for position, index in enumerate(indices):
            values = [shape[position * kinds + k] for k in range(kinds)]
            for k, term in enumerate(self.law(q[index], dq[index], ddq[index], values)):
                block[index, position * width + k] = term
        return block, None

    def columns(self, robot, q, dq, ddq):
        reference = casadi.SX([parameter.reference for parameter in self.shape_parameters(robot)])
        return self.shaped_columns(robot, q, dq, ddq, reference)


@dataclass(frozen=True)
class TanhCoulombFriction(ShapedPerJointEffect):
    """``tau_i += fc_i tanh(dq_i / vc_i)``: Coulomb friction smoothed below the velocity ``vc_i``,
    which is estimated (``coulomb:tanh``; the plain ``coulomb`` is the limit ``sign``)."""

    name: ClassVar[str] = "coulomb"
    variant: ClassVar[str] = "tanh"
    linear: ClassVar[tuple[str, ...]] = ("fc",)
    kinds: ClassVar[tuple[ShapeKind, ...]] = (ShapeKind("vc", 1e-4, 2.0, (0.003, 0.02, 0.1, 0.5), log_scale=True),)

    def law(self, q, dq, ddq, shape):
        return [casadi.tanh(dq / shape[0])]


@dataclass(frozen=True)
class ShapedStribeckFriction(ShapedPerJointEffect):
    """``tau_i += (fc_i + fs_i exp(−(|dq_i|/vs_i)²)) sign(dq_i)``: Coulomb friction with the static
    bump of the Stribeck effect, the Stribeck velocity ``vs_i`` estimated (``stribeck:velocity``)."""

    name: ClassVar[str] = "stribeck"
    variant: ClassVar[str] = "velocity"
    linear: ClassVar[tuple[str, ...]] = ("fc", "fs")
    kinds: ClassVar[tuple[ShapeKind, ...]] = (ShapeKind("vs", 1e-3, 3.0, (0.02, 0.1, 0.4, 1.0), log_scale=True),)

    def law(self, q, dq, ddq, shape):
        sign = casadi.sign(dq)
        return [sign, casadi.exp(-((dq / shape[0]) ** 2)) * sign]


@dataclass(frozen=True)
class SigmoidFriction(ShapedPerJointEffect):
    """``tau_i += φ1 / (1 + exp(−φ2 (dq_i + φ3))) − φ1 / (1 + exp(−φ2 φ3))`` (Gaz et al., RA-L 2019,
    the Franka Panda's friction law): ``phi1_i`` linear, slope ``phi2_i`` and shift ``phi3_i`` shape."""

    name: ClassVar[str] = "sigmoid"
    variant: ClassVar[str] = ""
    linear: ClassVar[tuple[str, ...]] = ("phi1_",)
    kinds: ClassVar[tuple[ShapeKind, ...]] = (
        ShapeKind("phi2_", 1.0, 2000.0, (10.0, 50.0, 300.0), log_scale=True),
        ShapeKind("phi3_", -0.5, 0.5, (-0.05, 0.0, 0.05)),
    )

    def law(self, q, dq, ddq, shape):
        slope, shift = shape
        # σ(x) = (1 + tanh(x/2)) / 2: the same law, without exp overflowing at steep slopes
        return [0.5 * (casadi.tanh(0.5 * slope * (dq + shift)) - casadi.tanh(0.5 * slope * shift))]


@dataclass(frozen=True)
class PositionRipple(ShapedPerJointEffect):
    """``tau_i += rs_i sin(n_i q_i) + rc_i cos(n_i q_i)``: a torque periodic in the joint's position
    (cogging, tooth meshing), ``n_i`` periods a radian (in ``[1.5, 60]``, the starts every half from 2; ``n = 1`` is what gravity already has)."""

    name: ClassVar[str] = "ripple"
    variant: ClassVar[str] = ""
    linear: ClassVar[tuple[str, ...]] = ("rs", "rc")
    kinds: ClassVar[tuple[ShapeKind, ...]] = (ShapeKind("n", 1.5, 60.0, tuple(np.arange(2.0, 60.01, 0.5))),)

    def law(self, q, dq, ddq, shape):
        return [casadi.sin(shape[0] * q), casadi.cos(shape[0] * q)]


#: ``NAME[:VARIANT]`` of the built-in shaped effects
SHAPED_EFFECTS: dict[str, type] = {
    effect.name if not effect.variant else f"{effect.name}:{effect.variant}": effect
    for effect in (TanhCoulombFriction, ShapedStribeckFriction, SigmoidFriction, PositionRipple)
}
SHAPED_EFFECTS["stribeck:shape"] = ShapedStribeckFriction
SHAPED_EFFECTS["sigmoid:gaz"] = SigmoidFriction
#: effects that are a Coulomb-like friction law: at most one per joint
FRICTION_LAWS: frozenset[str] = frozenset({"coulomb", "stribeck", "sigmoid"})
