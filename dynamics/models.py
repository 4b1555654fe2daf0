"""Identification models: the internal, external and combined regressors with their base parameters.

``build_model(robot, "combined", effects="viscous")`` returns an :class:`IdentificationModel`
holding named CasADi functions (built once per robot description, model and effects, and cached)::

    model.regressor        # internal_regressor(q, dq, ddq) -> Y        rows x p (standard params)
    model.base_regressor   # internal_base_regressor(q, dq, ddq) -> Y_base  rows x r
    model.evaluate(Q, DQ, DDQ)        # (N, rows, p) over N samples, one mapped call
    model.evaluate_base(Q, DQ, DDQ)   # (N, rows, r)

Rows (channels): internal ``tau1..taun``; external ``fx fy fz mx my mz``; combined the wrench
rows then the joint rows (PUMA paper, eq. 13 and 15). Columns: the ``10 n`` standard parameters
(:mod:`dynamics.robot`), then one block per effect, in the order given.
"""

from __future__ import annotations

import enum
import functools
from collections.abc import Iterable
from dataclasses import dataclass, field

import casadi
import numpy as np
from numpy.typing import ArrayLike, NDArray

from dynamics.base_parameters import BaseParameters, random_states, reduce_to_base
from dynamics.codegen.compiled import SampleEvaluator
from dynamics.channels import WRENCH_CHANNELS
from dynamics.effects.linear import Effect, parse_effects
from dynamics.errors import SampleShapeError
from dynamics.newton_euler import rigid_body_regressors
from dynamics.robot import ByDescription, JointType, RobotModel
from dynamics.runtime.threads import available_cores

STATE_NAMES: tuple[str, str, str] = ("q", "dq", "ddq")
# Threads for model.evaluate on large inputs (SampleEvaluator's default work threshold: about
# 2 600 samples for the 6-joint PUMA, 10 000 for 3 joints). On a 2-core machine, 6-joint PUMA,
# 5 000 samples: 0.20 against 0.34 µs a sample when the second core is free, 0.36 against 0.345
# when another process keeps it busy. Measured with two cores only, hence at most two.
EVALUATION_THREADS = min(2, available_cores())


class ModelKind(str, enum.Enum):
    """The three identification models of the PUMA paper (section III)."""

    INTERNAL = "internal"
    EXTERNAL = "external"
    COMBINED = "combined"


@dataclass(frozen=True, eq=False)
class IdentificationModel:
    """One model of one robot: regressor functions, names and base parameters.

    Use :func:`build_model` rather than the constructor.
    """

    robot: RobotModel
    kind: ModelKind
    effects: tuple[Effect, ...]
    channels: tuple[str, ...]
    parameter_names: tuple[str, ...]
    regressor: casadi.Function
    base: BaseParameters
    base_regressor: casadi.Function
    _evaluators: dict[str, SampleEvaluator] = field(repr=False)

    @property
    def n_parameters(self) -> int:
        return len(self.parameter_names)

    @property
    def n_base(self) -> int:
        return self.base.n_base

    @property
    def n_channels(self) -> int:
        return len(self.channels)

    @property
    def effect_slices(self) -> dict[str, slice]:
        """Column range of the rigid-body block and of each effect.

        Keys are the effect names; an effect whose name is shared (``coulomb`` on joint 1 and on
        joint 3, as :func:`estimation.diagnosis.search.diagnose` adds them) is keyed with its parameters,
        ``coulomb(fc1)``, ``coulomb(fc3)``.
        """
        slices = {"rigid_body": slice(0, 10 * self.robot.n_joints)}
        start = slices["rigid_body"].stop
        names = [effect.name for effect in self.effects]
        for effect in self.effects:
            parameters = effect.parameter_names(self.robot)
            stop = start + len(parameters)
            key = effect.name if names.count(effect.name) == 1 else f"{effect.name}({','.join(parameters)})"
            slices[key] = slice(start, stop)
            start = stop
        return slices

    def nominal_parameters(self, **effect_values: ArrayLike) -> NDArray[np.float64]:
        """The robot's standard parameters, then each effect's values (zero unless given by name).

        A value is one number or one per parameter of all the effects of that name together
        (in model order), e.g. ``coulomb=[fc1, fc3]`` for Coulomb friction on joints 1 and 3.
        """
        counts: dict[str, int] = {}
        for effect in self.effects:
            counts[effect.name] = counts.get(effect.name, 0) + len(effect.parameter_names(self.robot))
        unknown = sorted(set(effect_values) - set(counts))
        if unknown:
            raise ValueError(f"no such effects in this model: {unknown}; it has {sorted(counts)}")
        values: dict[str, list[float]] = {}
        for name, count in counts.items():
            given = np.asarray(effect_values.get(name, 0.0), dtype=float)
            if given.size not in (1, count):
                raise ValueError(f"{name}: give one value or {count} (one per parameter), got {given.size}")
            values[name] = list(np.broadcast_to(given.reshape(-1), (count,)))
        theta = [np.asarray(self.robot.standard_parameters, dtype=float)]
        for effect in self.effects:
            count = len(effect.parameter_names(self.robot))
            theta.append(np.array(values[effect.name][:count]))
            del values[effect.name][:count]
        return np.concatenate(theta)

    def evaluate(self, q: ArrayLike, dq: ArrayLike, ddq: ArrayLike, *,
                 out: NDArray[np.float64] | None = None) -> NDArray[np.float64]:
        """Regressor at ``N`` samples (arrays ``(N, n)``), as ``(N, channels, p)``.

        ``out``: a float64, C-contiguous ``(N, channels, p)`` array to write into and return (saves
        allocating, and the page faults of touching fresh memory, when called again and again).
        """
        return self._evaluate("full", q, dq, ddq, out)

    def evaluate_base(self, q: ArrayLike, dq: ArrayLike, ddq: ArrayLike, *,
                      out: NDArray[np.float64] | None = None) -> NDArray[np.float64]:
        """Base regressor at ``N`` samples, as ``(N, channels, r)`` (``out`` as in :meth:`evaluate`)."""
        return self._evaluate("base", q, dq, ddq, out)

    def predict(self, theta: ArrayLike, q: ArrayLike, dq: ArrayLike, ddq: ArrayLike) -> NDArray[np.float64]:
        """``Y θ`` at ``N`` samples, ``(N, channels)``; ``θ`` standard (``p``) or base (``r``) values."""
        theta = np.asarray(theta, dtype=float).reshape(-1)
        if theta.shape[0] == self.n_parameters:
            return self.evaluate(q, dq, ddq) @ theta
        if theta.shape[0] == self.n_base:
            return self.evaluate_base(q, dq, ddq) @ theta
        raise ValueError(
            f"theta has {theta.shape[0]} values; this model has {self.n_parameters} standard "
            f"and {self.n_base} base parameters"
        )

    def _evaluate(self, which: str, q: ArrayLike, dq: ArrayLike, ddq: ArrayLike,
                  out: NDArray[np.float64] | None) -> NDArray[np.float64]:
        states = check_states(self.robot.n_joints, q, dq, ddq)
        n_samples, width = states[0].shape[0], self.n_parameters if which == "full" else self.n_base
        if out is not None and np.shape(out) != (n_samples, self.n_channels, width):
            raise ValueError(f"out must have shape {(n_samples, self.n_channels, width)}, got {np.shape(out)}")
        # per sample the function returns Yᵀ (p x rows), whose column-major flattening is Y in
        # row-major order: the (N, rows·p) result reshapes to (N, rows, p) without a copy.
        return self._evaluators[which](*states, out=out).reshape(n_samples, self.n_channels, width)


def check_states(n_joints: int, *arrays: ArrayLike, names: Iterable[str] = STATE_NAMES) -> list[NDArray[np.float64]]:
    """Validate joint-state arrays: same ``(N, n)`` shape (a 1-D array is one sample), finite."""
    checked = []
    for name, array in zip(names, arrays):
        if np.iscomplexobj(array):
            raise TypeError(f"{name} must be real, got complex values")
        try:
            values = np.asarray(array, dtype=float)
        except (TypeError, ValueError):
            raise TypeError(f"{name} must be an array of numbers") from None
        if values.ndim == 1:
            values = values.reshape(1, -1)
        if values.ndim != 2 or values.shape[1] != n_joints:
            raise SampleShapeError(f"{name} must have shape (N, {n_joints}), got {np.shape(array)}")
        if not np.all(np.isfinite(values)):
            bad = np.argwhere(~np.isfinite(values))[0]
            raise SampleShapeError(f"{name} holds NaN or inf (sample {bad[0]}, joint {bad[1] + 1})")
        checked.append(values)
    if len({values.shape[0] for values in checked}) > 1:
        raise SampleShapeError(
            "q, dq and ddq must have the same number of samples, got "
            + ", ".join(f"{name}: {values.shape[0]}" for name, values in zip(names, checked))
        )
    return checked


def channel_names(robot: RobotModel, kind: ModelKind | str) -> tuple[str, ...]:
    """Row names of a model: ``tau1..taun`` and/or ``fx fy fz mx my mz``."""
    kind = ModelKind(kind)
    joints = tuple(f"tau{index}" for index in range(1, robot.n_joints + 1))
    if kind is ModelKind.INTERNAL:
        return joints
    if kind is ModelKind.EXTERNAL:
        return WRENCH_CHANNELS
    return WRENCH_CHANNELS + joints


def build_model(
    robot: RobotModel,
    kind: ModelKind | str = ModelKind.INTERNAL,
    effects: str | Iterable[str | Effect] | None = ("viscous",),
    *,
    reduction_samples: int | None = None,
    seed: int = 0,
) -> IdentificationModel:
    """Build (or fetch from the cache) an identification model.

    Parameters
    ----------
    robot
        The chain.
    kind
        ``internal`` (joint torques), ``external`` (base wrench) or ``combined`` (both).
    effects
        Extra columns (default: viscous friction, as in the PUMA paper); see
        :func:`dynamics.effects.linear.parse_effects`. Effects with no rows in the model (friction in
        the external model, plate offsets in the internal one) are left out.
    reduction_samples
        Random states stacked for the base-parameter reduction (default: enough for 4 rows per
        parameter).
    seed
        Seed of those random states.
    """
    if not isinstance(robot, RobotModel):
        raise TypeError(f"robot must be a RobotModel, got {type(robot).__name__}")
    try:
        kind = ModelKind(kind)
    except ValueError:
        raise ValueError(f"unknown model {kind!r}; expected one of {[k.value for k in ModelKind]}") from None
    return _build_model(ByDescription(robot), kind, parse_effects(effects), reduction_samples, seed)


@functools.lru_cache(maxsize=64)
def _build_model(
    described: ByDescription, kind: ModelKind, effects: tuple[Effect, ...], reduction_samples: int | None, seed: int
) -> IdentificationModel:
    robot = described.robot
    rigid = rigid_body_regressors(robot)
    q, dq, ddq = rigid.q, rigid.dq, rigid.ddq
    joint_blocks, wrench_blocks = [rigid.joint], [rigid.wrench]
    names = list(robot.standard_parameter_names)
    kept: list[Effect] = []
    for effect in effects:
        joint_columns, wrench_columns = effect.columns(robot, q, dq, ddq)
        acts_on_joints = joint_columns is not None and kind is not ModelKind.EXTERNAL
        acts_on_wrench = wrench_columns is not None and kind is not ModelKind.INTERNAL
        if not (acts_on_joints or acts_on_wrench):
            continue
        count = len(effect.parameter_names(robot))
        repeated = sorted(set(effect.parameter_names(robot)) & set(names))
        if repeated:
            raise ValueError(f"effect {effect.name!r}: parameter(s) {', '.join(repeated)} already in the model "
                             "(two effects cover the same joint or channel)")
        joint_blocks.append(joint_columns if joint_columns is not None else casadi.SX.zeros(robot.n_joints, count))
        wrench_blocks.append(wrench_columns if wrench_columns is not None else casadi.SX.zeros(6, count))
        names.extend(effect.parameter_names(robot))
        kept.append(effect)
    joint_rows, wrench_rows = casadi.horzcat(*joint_blocks), casadi.horzcat(*wrench_blocks)
    Y = {
        ModelKind.INTERNAL: joint_rows,
        ModelKind.EXTERNAL: wrench_rows,
        ModelKind.COMBINED: casadi.vertcat(wrench_rows, joint_rows),
    }[kind]
    label = kind.value
    Y = casadi.cse(Y)  # common subexpressions shared across columns: fewer operations per sample
    regressor = casadi.Function(f"{label}_regressor", [q, dq, ddq], [Y], list(STATE_NAMES), ["Y"])
    transposed_full = casadi.Function(f"{label}_regressor_t", [q, dq, ddq], [Y.T], list(STATE_NAMES), ["Yt"])

    samples = reduction_samples or max(40, int(np.ceil(4 * Y.shape[1] / Y.shape[0])))
    prismatic = [joint.joint_type is JointType.PRISMATIC for joint in robot.joints]
    states = random_states(robot.n_joints, samples, seed=seed, prismatic=prismatic)
    stacked = np.asarray(transposed_full.map(samples)(*(state.T for state in states))).T  # once, at build
    if not np.all(np.isfinite(stacked)):
        bad = names[int(np.argwhere(~np.isfinite(stacked))[0][1])]
        raise ValueError(f"column {bad} is NaN or inf at generic states (an effect's law, or its reference shape "
                         "value, is outside its domain)")
    base = reduce_to_base(stacked, names, geometry=robot.geometry)

    # a column slice of the shared expressions has no common subexpression left to find (casadi.cse of it gives
    # the same graph: the same generated code, tests/test_model_build_cost.py)
    Y_base = Y[:, list(base.independent)]
    base_regressor = casadi.Function(f"{label}_base_regressor", [q, dq, ddq], [Y_base], list(STATE_NAMES), ["Y_base"])
    transposed_base = casadi.Function(
        f"{label}_base_regressor_t", [q, dq, ddq], [Y_base.T], list(STATE_NAMES), ["Y_base_t"]
    )
    return IdentificationModel(
        robot=robot,
        kind=kind,
        effects=tuple(kept),
        channels=channel_names(robot, kind),
        parameter_names=tuple(names),
        regressor=regressor,
        base=base,
        base_regressor=base_regressor,
        _evaluators={
            "full": SampleEvaluator(transposed_full, threads=EVALUATION_THREADS),
            "base": SampleEvaluator(transposed_base, threads=EVALUATION_THREADS),
        },
    )
