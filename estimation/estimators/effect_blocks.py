"""An effect's columns in an identification problem: which channels it reaches, its compiled columns
and their derivatives with respect to its shape parameters, over the samples.

:class:`Block` is what :mod:`estimation.estimators.variable_projection` and the diagnosis
(:mod:`estimation.diagnosis.candidates.trials`) fit: one named ``casadi.Function`` per effect and model kind
(columns, and columns stacked with their Jacobian in the shape parameters), built once, cached and
evaluated over the samples by the compiled sample loop (:class:`dynamics.codegen.compiled.SampleEvaluator`).
"""

from __future__ import annotations

import contextlib
import functools
import re
from collections.abc import Iterator
from dataclasses import dataclass

import casadi
import numpy as np
from numpy.typing import NDArray

from dynamics.codegen.compiled import SampleEvaluator
from dynamics.effects.linear import Effect
from dynamics.models import ModelKind
from dynamics.robot import RobotModel
from dynamics.effects.shaped import ShapeParameter, shape_parameters, start_grid


class ShapeSearchError(ValueError):
    """The search for an effect's shape parameters failed (non-finite or singular everywhere)."""


class NoRowsError(ValueError):
    """An effect has no rows in the model (friction in the external model, say)."""


#: random states at which an effect's rows are looked for: velocities from 1e-3 to 3 (a Stribeck
#: column underflows to zero at |dq| = 2.3 with a small Stribeck velocity, and tanh(dq/v) is ±1 far out)
ROW_CHECK_STATES = 16

#: the latest evaluations a block keeps along kept states (:meth:`Block.evaluate`): the searches of a diagnosis come
#: back to a shape a block left an evaluation or two before (a candidate refitted from its last optimum after another
#: start, its screen on the other record in between): ~390 evaluations of ~4 900 on the Panda with 2, ~440 with 4 (and
#: twice the memory: a shaped block's columns and derivatives, ~0.1-1 MB an evaluation of 13 840 samples)
KEPT_EVALUATIONS = 2


@functools.lru_cache(maxsize=512)
def effect_block_functions(kind: ModelKind, robot: RobotModel, effect: Effect) -> tuple[SampleEvaluator, SampleEvaluator]:
    """``(columns, columns_and_jacobian)`` over samples: per sample ``(q, dq, ddq[, shape]) -> vec(Cᵀ)``
    (``C`` is ``m x k``) and ``-> [vec(Cᵀ); vec(∂vec(Cᵀ)/∂shape)]``, from one named CasADi function each,
    built once per model kind and effect (compiled when a C compiler is present).

    A plain effect has no ``shape`` input.
    """
    n = robot.n_joints
    q, dq, ddq = (casadi.SX.sym(name, n) for name in ("q", "dq", "ddq"))
    parameters = shape_parameters(effect, robot)
    shape = casadi.SX.sym("shape", len(parameters))
    if parameters:
        joint, wrench = effect.shaped_columns(robot, q, dq, ddq, shape)
    else:
        joint, wrench = effect.columns(robot, q, dq, ddq)
    count = len(effect.parameter_names(robot))
    joint_block = joint if joint is not None and kind is not ModelKind.EXTERNAL else casadi.SX.zeros(n, count)
    wrench_block = wrench if wrench is not None and kind is not ModelKind.INTERNAL else casadi.SX.zeros(6, count)
    block = {
        ModelKind.INTERNAL: joint_block,
        ModelKind.EXTERNAL: wrench_block,
        ModelKind.COMBINED: casadi.vertcat(wrench_block, joint_block),
    }[kind]
    Ct = casadi.densify(casadi.vec(casadi.SX(block).T))
    label = "".join(character if character.isalnum() else "_" for character in getattr(effect, "spec", effect.name))
    joints = getattr(effect, "joints", None)
    label += "" if joints is None else "_j" + "_".join(str(joint) for joint in joints)
    label = re.sub(r"_+", "_", label).strip("_")  # coulomb[q5+q6]: a CasADi name has no '__'
    label = label if label[:1].isalpha() else f"effect_{label}"
    inputs, names_in = [q, dq, ddq], ["q", "dq", "ddq"]
    if parameters:
        inputs.append(shape)
        names_in.append("shape")
    columns = casadi.Function(f"{label}_{kind.value}_columns", inputs, [Ct], names_in, ["Ct"])
    jacobian = casadi.densify(casadi.jacobian(Ct, shape)) if parameters else casadi.SX(0, 1)
    both = casadi.Function(f"{label}_{kind.value}_columns_jacobian", inputs,
                           [casadi.vertcat(Ct, casadi.vec(jacobian))], names_in, ["Ct_dCt"])
    return SampleEvaluator(columns), SampleEvaluator(both)


@functools.lru_cache(maxsize=512)
def effect_row_functions(kind: ModelKind, robot: RobotModel, effect: Effect, rows: tuple[int, ...]
                         ) -> tuple[SampleEvaluator, SampleEvaluator]:
    """:func:`effect_block_functions` with the outputs of the channels ``rows`` only: per sample the columns
    ``(rows, k)`` row after row, and with them each shape's derivatives ``(n_s, rows, k)``. The same expressions
    (each output the full function's, selected), so the same values bit for bit; the other channels' outputs, zero
    by the rows' definition (:func:`effect_rows`), are neither computed nor written (a joint's law on a 7-joint arm:
    one output in seven; the Panda's search evaluates these ~5 000 times along 13 840 samples)."""
    selected = []
    for evaluator in effect_block_functions(kind, robot, effect):
        function = evaluator.function
        count = len(effect.parameter_names(robot))
        channels = {ModelKind.INTERNAL: robot.n_joints, ModelKind.EXTERNAL: 6,
                    ModelKind.COMBINED: 6 + robot.n_joints}[kind]
        parts = function.numel_out(0) // (channels * count)  # the columns, then one part a shape parameter
        index = [part * channels * count + row * count + column
                 for part in range(parts) for row in rows for column in range(count)]
        inputs = function.sx_in()
        output = function.call(inputs)[0]
        name = f"{function.name()}_rows_{'_'.join(str(row) for row in rows)}"
        selected.append(SampleEvaluator(casadi.Function(name, inputs, [output[index]], function.name_in(),
                                                        [function.name_out(0)])))
    return selected[0], selected[1]


def evaluate_at_shape(evaluator: SampleEvaluator, q, dq, ddq, shape: NDArray[np.float64] | None) -> NDArray[np.float64]:
    """An effect's function (its columns, or its columns and their shape derivatives) at the samples ``q, dq, ddq``
    ``(N, n)``, the ``shape`` the same on every sample (none for a plain effect): ``(N, outputs)``."""
    inputs = [q, dq, ddq]
    if shape is not None and np.size(shape):
        # the shape on every sample, C-contiguous: np.tile writes it whole (a broadcast view copied by
        # ascontiguousarray is copied a row at a time, 20x slower: 0.1 ms of a 0.3 ms evaluation)
        values = np.asarray(shape, dtype=float).reshape(-1)
        inputs.append(np.tile(values, q.shape[0]).reshape(q.shape[0], values.size))
    return evaluator(*inputs)


def rows_taken(values: NDArray[np.float64], rows: tuple[int, ...]) -> NDArray[np.float64]:
    """``values[..., rows, :]`` of ``values (N, …, m, k)``, laid out as numpy's advanced indexing lays it out (the
    indexed axis outermost in memory), copied a row at a time: the same array, strides included, several times
    faster than the indexing's general loop."""
    taken = np.empty((len(rows), *values.shape[:-2], values.shape[-1]))
    for position, row in enumerate(rows):
        taken[position] = values[..., row, :]
    # np.moveaxis(taken, 0, -2) as a transpose: the same view, without moveaxis's argument handling (~45 µs a call,
    # 5 500 calls a Panda diagnosis)
    return taken.transpose((*range(1, values.ndim - 1), 0, values.ndim - 1))


def effect_columns(kind: ModelKind, robot: RobotModel, effect: Effect, n_channels: int, states: States,
                   shape: NDArray[np.float64] | None = None) -> NDArray[np.float64]:
    """An effect's columns on every channel of a model, ``(N, m, k)``, at ``shape`` (default: the
    first start of each shape parameter; none for a plain effect)."""
    if shape is None:
        shape = np.array([parameter.starts[0] for parameter in shape_parameters(effect, robot)], dtype=float)
    columns, _ = effect_block_functions(kind, robot, effect)
    values = evaluate_at_shape(columns, states.q, states.dq, states.ddq, shape)
    return values.reshape(states.n_samples, n_channels, len(effect.parameter_names(robot)))


def effect_rows(kind: ModelKind, robot: RobotModel, effect: Effect, n_channels: int) -> tuple[int, ...]:
    """The channels an effect's columns reach: nonzero at any of :data:`ROW_CHECK_STATES` random
    states (velocities spread over three decades) and shape values (the declared starts)."""
    columns, _ = effect_block_functions(kind, robot, effect)
    generator = np.random.default_rng(0)
    n = robot.n_joints
    scales = np.geomspace(1e-3, 3.0, ROW_CHECK_STATES)
    q = generator.uniform(-np.pi, np.pi, (ROW_CHECK_STATES, n))
    dq = generator.choice([-1.0, 1.0], (ROW_CHECK_STATES, n)) * scales[:, None] * generator.uniform(0.5, 1.5, (ROW_CHECK_STATES, n))
    ddq = generator.normal(size=(ROW_CHECK_STATES, n))
    grid = start_grid(shape_parameters(effect, robot))
    reached = np.zeros(n_channels, dtype=bool)
    for point in grid[: max(1, min(len(grid), 4))]:
        inputs = [q.T, dq.T, ddq.T] + ([point] if point.size else [])
        values = np.asarray(columns.function.map(ROW_CHECK_STATES)(*inputs))  # the VM: no compilation for 16 states
        values = values.T.reshape(ROW_CHECK_STATES, n_channels, -1)
        reached |= np.any(np.nan_to_num(values) != 0, axis=(0, 2))
    return tuple(int(index) for index in np.flatnonzero(reached))


@dataclass(frozen=True)
class States:
    """Joint states of one record, ``(N, n)`` each (the inputs of the column functions); ``kept``: each block keeps its
    latest evaluation along these states (:meth:`Block.evaluate`: a search that asks for the same columns round after
    round, at the cost of one evaluation's memory a block)."""

    q: NDArray[np.float64]
    dq: NDArray[np.float64]
    ddq: NDArray[np.float64]
    kept: bool = False

    def __post_init__(self) -> None:
        # the column functions read C-contiguous float64 arrays: copied once here, not at each of the thousands
        # of evaluations a diagnosis makes (a record's columns arrive as strided views)
        for name in ("q", "dq", "ddq"):
            if getattr(self, name) is None:  # a record not yet derived: no silent array of NaN
                raise ValueError(f"the states need {name}: derive the record's velocities and accelerations first "
                                 "(estimation.preprocessing.differentiation.fill_derivatives)")
            object.__setattr__(self, name, np.ascontiguousarray(getattr(self, name), dtype=float))

    @property
    def n_samples(self) -> int:
        return self.q.shape[0]


class Block:
    """One effect's columns in a problem: its channels, linear names, shape parameters."""

    def __init__(self, kind: ModelKind, robot: RobotModel, effect: Effect, n_channels: int) -> None:
        self.effect = effect
        self.parameters: tuple[ShapeParameter, ...] = shape_parameters(effect, robot)
        self.names = tuple(effect.parameter_names(robot))
        self.rows = effect_rows(kind, robot, effect, n_channels)
        if not self.rows:
            raise NoRowsError(f"effect {getattr(effect, 'spec', effect.name)!r} has no rows in the {kind.value} model "
                              "(its columns are zero on every channel)")
        self.columns_function, self.jacobian_function = effect_block_functions(kind, robot, effect)
        # what :meth:`evaluate` runs: the same functions on the block's rows only
        self.row_columns_function, self.row_jacobian_function = effect_row_functions(kind, robot, effect, self.rows)
        self.n_channels = n_channels
        # the latest evaluation: (states, shape's bytes, columns, derivatives or None, products) (:meth:`evaluate`,
        # :meth:`products`)
        self._latest: tuple[States, bytes, NDArray[np.float64], NDArray[np.float64] | None, dict] | None = None
        # the :data:`KEPT_EVALUATIONS` latest along kept states, by (id(states), shape's bytes), the latest last:
        # (states, columns, derivatives or None, products) (:meth:`evaluate`)
        self._kept: dict[tuple[int, bytes], tuple[States, NDArray[np.float64], NDArray[np.float64] | None, dict]] = {}
        # the columns of every shape evaluated along one kept states object while :meth:`keeping_shapes` holds
        self._shapes: tuple[States, dict[bytes, NDArray[np.float64]]] | None = None

    def __getstate__(self) -> dict[str, object]:
        # the kept evaluations are caches: not sent with the block
        return {**self.__dict__, "_latest": None, "_shapes": None, "_kept": {}}

    @contextlib.contextmanager
    def keeping_shapes(self, states: States) -> Iterator[None]:
        """While held, the columns of every shape evaluated along ``states`` (kept states only) are kept, and asked
        again at the same shape (the same states object) are returned, not evaluated again: the columns of a shape
        grid's points, costed by the search and screened again by the linear solve
        (:func:`estimation.diagnosis.candidates.trials.better_physical_optimum`). The same arrays as an evaluation
        gives (read-only), so the same solves; released on exit."""
        if not states.kept or self._shapes is not None:
            yield
            return
        self._shapes = (states, {})
        try:
            yield
        finally:
            self._shapes = None

    @property
    def n_shape(self) -> int:
        return len(self.parameters)

    @property
    def n_linear(self) -> int:
        return len(self.names)

    def evaluate(self, states: States, shape: NDArray[np.float64], *, jacobian: bool = False):
        """Columns on the block's rows ``(N, rows, k)`` and, with ``jacobian``, ``(n_s, N, rows, k)``.

        Along states that are ``kept`` (:class:`States`) the latest evaluation is kept: asked again at the same states
        (the same object) and shape, the same arrays (read-only) are returned, not evaluated again (a plain candidate's columns,
        or a candidate screened at its last optimum, in every round of a diagnosis). Columns asked without the
        derivatives may come from an evaluation with them: the columns-and-Jacobian function's columns are the
        columns function's, bit for bit.
        """
        key = b"" if shape is None else np.asarray(shape, dtype=float).tobytes()
        latest = self._latest
        if latest is not None and latest[0] is states and latest[1] == key and (latest[3] is not None or not jacobian):
            return (latest[2], latest[3]) if jacobian else latest[2]
        shapes = self._shapes if self._shapes is not None and self._shapes[0] is states else None
        if shapes is not None and not jacobian and key in shapes[1]:
            columns = shapes[1][key]
            self._latest = (states, key, columns, None, {})  # as an evaluation leaves it (states are kept)
            return columns
        known = self._kept.pop((id(states), key), None) if states.kept else None
        if known is not None and known[0] is states and (known[2] is not None or not jacobian):
            # an evaluation kept: the same arrays (read-only) as that evaluation gave, with its products' store
            self._kept[(id(states), key)] = known
            self._latest = (states, key, known[1], known[2], known[3])
            return (known[1], known[2]) if jacobian else known[1]
        n_samples, k = states.n_samples, self.n_linear
        function = self.row_jacobian_function if jacobian else self.row_columns_function
        values = evaluate_at_shape(function, states.q, states.dq, states.ddq, shape)  # (N, r·k [+ r·k·n_s]), r = len(rows)
        r = len(self.rows)
        every = tuple(range(r))  # laid out as the rows taken from every channel's evaluation are (rows_taken)
        columns = rows_taken(values[:, : r * k].reshape(n_samples, r, k), every)
        derivative = None
        if jacobian:
            derivative = rows_taken(values[:, r * k:].reshape(n_samples, self.n_shape, r, k), every)
            derivative = derivative.transpose(1, 0, 2, 3)
        if states.kept:  # read-only: shared by every caller that asks for them again
            for array in (columns, derivative):
                if array is not None:
                    array.flags.writeable = False
            self._latest = (states, key, columns, derivative, {})
            self._kept[(id(states), key)] = (states, columns, derivative, self._latest[4])
            for old in list(self._kept)[:-KEPT_EVALUATIONS]:
                del self._kept[old]
            if shapes is not None and not jacobian:
                shapes[1][key] = columns
        return (columns, derivative) if jacobian else columns

    def products(self, columns: NDArray[np.float64]) -> dict | None:
        """A store that lives as long as the kept evaluation ``columns`` (:meth:`evaluate`), for what callers compute
        from these columns alone and other fixed arrays (:func:`estimation.estimators.separable_least_squares.solve_linear`
        keeps the products with each record's fixed columns there); ``None`` when ``columns`` are not the block's kept
        evaluation."""
        latest = self._latest
        return latest[4] if latest is not None and latest[2] is columns else None
