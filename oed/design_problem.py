"""The excitation design problem: Fourier trajectories (eq. 18) optimised with IPOPT (PUMA paper, IV.A).

The decision vector ``x`` holds ``[q0_i, a_i1..a_iN, b_i1..b_iN]`` per joint. The trajectory is
*linear* in ``x``: at any set of times ``q = B_q x``, ``dq = B_dq x``, ``ddq = B_ddq x`` with
constant matrices. Hence

- the motion bounds (eq. 19) at the constraint points are **linear** constraints ``A x`` with a
  constant, block-sparse Jacobian (each row touches one joint's 11 coefficients);
- the criterion is ``J(M(x))`` with ``M = (1/N) Σ_k Y_b(q_k, dq_k, ddq_k)ᵀ Y_b(·)`` over ``N``
  cost samples, built once as a CasADi graph (a compiled per-sample ``Y_bᵀY_b`` summed by a
  mapped reduction, :mod:`oed.design_solver`, then the criterion), differentiated exactly by
  reverse AD; IPOPT approximates the Hessian by L-BFGS and, after ``DesignSettings.sqp_after``
  iterations, hands the start to an SQP method (dense damped BFGS, one small QP an iteration).

After each solve the trajectory is checked on the full 1 kHz grid; the samples where a bound is
exceeded are added as constraint points and the problem is re-solved from the previous solution
(a few rounds), and as a last resort each joint's oscillation is shrunk onto the bounds.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import casadi
import numpy as np
import scipy.sparse
from numpy.typing import NDArray

from dynamics.codegen.jit_cache import cached_jit
from dynamics.effects.linear import parse_effects
from dynamics.runtime.memory import check_allocation
from dynamics.models import ModelKind, build_model
from dynamics.robot import RobotModel
from dynamics.runtime.threads import single_threaded
from oed.bounds import PUMA_BOUNDS, JointBounds
from oed.criteria import LogDet, criterion_from_name, information_matrix
from oed.design_settings import DesignSettings
from oed.design_solver import (
    SQP_OBJECTIVE_SCALE,
    call_solver,
    ipopt_solver,
    sampled_information,
    sqp_solver,
    violation_peaks,
)
from oed.fourier import FourierTrajectory, basis, unpack
from oed.rest_ramps import RestStart, hermite_weights
from oed.interrupt import interrupt_flag

_BOUND_GUARD = 1e-7
#: the constraints' smooth rows are asked to reach this much above zero (scaled units: about 1e-5 of an
#: effort limit, 3 nm of distance after the smooth minimum's log): IPOPT meets rows only to its tolerance
_NONLINEAR_GUARD = 1e-5
#: least refinement rounds of a problem with constraints (ExcitationDesign.refinement_rounds)
CONSTRAINED_REFINEMENTS = 10

SUCCESS_STATUSES = frozenset({"Solve_Succeeded", "Solved_To_Acceptable_Level"})


@dataclass(frozen=True)
class StartResult:
    """One start of the multi-start optimisation.

    ``cost`` is ``−log det(Y_bᵀY_b)`` over one period at ``rate_hz`` (unscaled); ``criterion_value``
    the chosen criterion there; ``objective`` the solver's (sample-normalised) objective; ``shrunk``:
    the refinement rounds left a bound exceeded at ``rate_hz`` and the oscillation was scaled down
    onto the bounds (a weaker trajectory than the optimiser's).
    """

    index: int
    status: str
    success: bool
    iterations: int
    time_s: float
    cost: float
    criterion_value: float
    objective: float
    feasible: bool
    refinements: int
    x: NDArray[np.float64] = field(repr=False)
    x0: NDArray[np.float64] = field(repr=False)
    shrunk: bool = False

    def to_dict(self) -> dict[str, Any]:
        return {key: getattr(self, key) for key in
                ("index", "status", "success", "iterations", "time_s", "cost", "criterion_value", "objective",
                 "feasible", "refinements", "shrunk")}


@dataclass(frozen=True, eq=False)
class ExcitationDesign:
    """The design problem of one robot, model, criterion, bounds and settings (reusable).

    Build it once (:meth:`build`, implicit on first solve) and call :meth:`solve` per start.
    """

    robot: RobotModel
    model: ModelKind | str = ModelKind.COMBINED
    bounds: JointBounds | None = None
    criterion: Any = "logdet"
    effects: Any = ("viscous",)
    settings: DesignSettings = field(default_factory=DesignSettings)
    constraints: tuple = ()
    rest: RestStart | None = None
    _cache: dict = field(default_factory=dict, repr=False)

    def __post_init__(self) -> None:
        if not isinstance(self.robot, RobotModel):
            raise TypeError(f"robot must be a RobotModel, got {type(self.robot).__name__}")
        if not isinstance(self.settings, DesignSettings):
            raise TypeError("settings must be a DesignSettings")
        try:
            object.__setattr__(self, "model", ModelKind(self.model))
        except ValueError:
            raise ValueError(f"unknown model {self.model!r}; expected one of {[k.value for k in ModelKind]}") from None
        object.__setattr__(self, "criterion", criterion_from_name(self.criterion))
        object.__setattr__(self, "effects", parse_effects(self.effects))
        bounds = self.bounds if self.bounds is not None else default_bounds(self.robot)
        bounds.check_joint_count(self.robot.n_joints)
        object.__setattr__(self, "bounds", bounds)
        constraints = tuple(self.constraints)
        for constraint in constraints:
            if not (callable(getattr(constraint, "function", None)) and callable(getattr(constraint, "margins", None))):
                raise TypeError(f"constraints must have function() and margins() (oed.design_constraints), got "
                                f"{type(constraint).__name__}")
        object.__setattr__(self, "constraints", constraints)
        if self.rest is not None:
            if not isinstance(self.rest, RestStart):
                raise TypeError(f"rest must be a RestStart, got {type(self.rest).__name__}")
            s = self.settings
            object.__setattr__(self, "rest", self.rest.with_ramp_for(s.frequency_hz, s.harmonics, s.rate_hz))
            self.rest.check(bounds, self.settings.rate_hz)
            from oed.design_constraints import check_rest_state

            check_rest_state(constraints, self.rest.q)

    # ---------------------------------------------------------------- building
    @property
    def n_joints(self) -> int:
        return self.robot.n_joints

    @property
    def n_variables(self) -> int:
        return self.n_joints * (2 * self.settings.harmonics + 1)

    @property
    def identification_model(self):
        return build_model(self.robot, self.model, self.effects)

    def sampled_states(self, x: casadi.MX) -> list[casadi.MX]:
        """``[q, dq, ddq]`` of the trajectory ``x`` at the ``cost_samples`` instants of one period, each ``(n, N)``,
        as expressions of the decision vector (the Fourier series of :mod:`oed.fourier`, eq. 30 of the PUMA paper)."""
        n, H, N = self.n_joints, self.settings.harmonics, self.settings.cost_samples
        t = np.arange(N) / N / self.settings.frequency_hz
        q0, a, b = unpack(x, n, H)
        block = casadi.horzcat(q0, a, b)  # (n, 2H+1)
        return [casadi.mtimes(block, casadi.DM(matrix)) for matrix in self._state_matrices(t)]

    def _state_matrices(self, t: NDArray[np.float64]) -> tuple[NDArray[np.float64], ...]:
        """``(3, 2N+1, T)`` rows of one joint's block: q, dq, ddq = block · B at times t (eq. 18)."""
        B = basis(self.settings.frequency_hz, self.settings.harmonics, t)
        ones, zeros = np.ones((1, t.size)), np.zeros((1, t.size))
        return (
            np.vstack([ones, B["sin_q"].T, -B["cos_q"].T]),
            np.vstack([zeros, B["cos"].T, B["sin"].T]),
            np.vstack([zeros, B["sin_dd"].T, B["cos_dd"].T]),
        )

    # ------------------------------------------------------- the experiment's grid
    @property
    def ramp_steps(self) -> int:
        """Samples of one ramp at ``rate_hz`` (0 without a rest start)."""
        return 0 if self.rest is None else self.rest.ramp_samples(self.settings.rate_hz)

    @property
    def fine_size(self) -> int:
        """Points of the fine grid: one period at ``rate_hz``, then the ramp in (``steps`` points) and the
        ramp out (``steps + 1``, its last at rest)."""
        steps = self.ramp_steps
        return self.settings.period_samples + (2 * steps + 1 if steps else 0)

    def point_matrices(self, indices: NDArray[np.int64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """``(3, 2N+1, T)`` rows and ``(3, T)`` weights of the rest position: at fine-grid point ``k``,
        ``state_j = block_j · rows[:, :, k] + Q_j · weights[:, k]`` for q, dq, ddq (period points: weight 0)."""
        s, steps = self.settings, self.ramp_steps
        indices = np.asarray(indices, dtype=int).reshape(-1)
        P, width = s.period_samples, 2 * s.harmonics + 1
        rows, weights = np.zeros((3, width, indices.size)), np.zeros((3, indices.size))
        periodic = indices < P
        if periodic.any():
            rows[:, :, periodic] = np.stack(self._state_matrices(indices[periodic] / s.rate_hz))
        if steps:
            at_zero = np.stack(self._state_matrices(np.zeros(1)))[:, :, 0]  # (3, width): q, dq, ddq at t = 0
            for ramp_in, mask, first in ((True, (indices >= P) & (indices < P + steps), P),
                                         (False, indices >= P + steps, P + steps)):
                if not mask.any():
                    continue
                w = hermite_weights((indices[mask] - first) / s.rate_hz, self.rest.ramp_s)  # (3, 6, T)
                # ends p0, v0, a0, a1, v1, p1: the periodic state's rows enter by its q, dq, ddq at t = 0
                order = (5, 4, 3) if ramp_in else (0, 1, 2)
                rows[:, :, mask] = sum(w[:, m, None, :] * at_zero[k][None, :, None] for k, m in enumerate(order))
                weights[:, mask] = w[:, 0 if ramp_in else 5, :]
        return rows, weights

    def _states(self, x: casadi.MX | NDArray, indices: NDArray[np.int64] | None = None) -> list:
        """``q, dq, ddq`` (``n x T``) of ``x`` at fine-grid points (symbolic for an MX ``x``); ``None``: the
        whole fine grid (its matrices cached)."""
        if indices is None:
            if "fine" not in self._cache:
                self._cache["fine"] = self.point_matrices(np.arange(self.fine_size))
            rows, weights = self._cache["fine"]
        else:
            rows, weights = self.point_matrices(indices)
        q_rest = np.zeros(self.n_joints) if self.rest is None else self.rest.q
        if isinstance(x, casadi.MX):
            q0, a, b = unpack(x, self.n_joints, self.settings.harmonics)
            block = casadi.horzcat(q0, a, b)
            return [casadi.mtimes(block, casadi.DM(rows[k])) + casadi.DM(np.outer(q_rest, weights[k]))
                    for k in range(3)]
        block = np.asarray(x, dtype=float).reshape(self.n_joints, -1)
        return [block @ rows[k] + np.outer(q_rest, weights[k]) for k in range(3)]

    def fine_states(self, x: NDArray[np.float64]) -> tuple[NDArray[np.float64], ...]:
        """``q, dq, ddq`` ``(T, n)`` of ``x`` on the fine grid (the period, then the ramps)."""
        return tuple(state.T for state in self._states(x))

    def base_points(self) -> NDArray[np.int64]:
        """The fine-grid indices of the constraint points: ``constraint_points`` equidistant over the
        period and, on each ramp, as many per second (at least 10; not the ends at rest)."""
        s, steps = self.settings, self.ramp_steps
        grid = np.arange(s.constraint_points) * s.period_samples // s.constraint_points
        if not steps:
            return grid
        count = max(10, int(np.ceil(s.constraint_points * self.rest.ramp_s * s.frequency_hz)))
        ramp = np.unique(np.round(np.linspace(0, steps, count + 1)).astype(int))
        P = s.period_samples
        # the ramps' ends at rest are fixed (checked before the design): no row there
        return np.concatenate([grid, P + ramp[(ramp > 0) & (ramp < steps)], P + steps + ramp[ramp < steps]])

    def nonlinear_function(self, indices: NDArray[np.int64]) -> casadi.Function | None:
        """``x -> g``: every constraint's rows at the points ``indices`` (``g ≥ 0`` met), constraint by
        constraint, point-major within each (``None`` without constraints).

        Its Jacobian is given by the chain rule, not left to AD over the coefficients: the states at a point
        are linear in ``x`` (``state_j = block_j · rows_k``), so ``∂g_k/∂x`` is the per-sample Jacobian
        ``∂g/∂(q, dq, ddq)`` (``3n`` columns, compiled with the constraint) times those rows; AD in the
        ``n (2N+1)`` coefficient directions costs several times more (``custom_jacobian``).
        """
        if not self.constraints:
            return None
        x = casadi.MX.sym("x", self.n_variables)
        states = self._states(x, indices)
        rows = [casadi.DM(matrix) for matrix in self.point_matrices(indices)[0]]
        count = len(indices)
        values = [casadi.vec(self._compiled(constraint).map(count)(*states)) for constraint in self.constraints]
        transposed = [self._compiled(constraint, jacobian=True).map(count)(*states, *rows)
                      for constraint in self.constraints]
        g = casadi.vertcat(*values)
        jacobian = casadi.Function("jac_design_constraints", [x, casadi.MX.sym("g", g.shape[0])],
                                   [casadi.horzcat(*transposed).T])
        return casadi.Function("design_constraints", [x], [g], ["x"], ["g"],
                               {"custom_jacobian": jacobian, "jac_penalty": 0, "never_inline": True})

    def _jacobian_rows(self, constraint: Any) -> casadi.Function:
        """``(q, dq, ddq, r_q, r_dq, r_ddq) -> (∂g/∂x)ᵀ`` of one point (``n (2N+1) x m``), ``r`` the point's
        rows of :meth:`point_matrices` (the same for every joint)."""
        n, width = self.n_joints, 2 * self.settings.harmonics + 1
        q, dq, ddq = (casadi.SX.sym(name, n) for name in ("q", "dq", "ddq"))
        r = [casadi.SX.sym(f"r_{name}", width) for name in ("q", "dq", "ddq")]
        per_state = casadi.jacobian(constraint.function()(q, dq, ddq), casadi.vertcat(q, dq, ddq))  # m x 3n
        blocks = [sum(casadi.mtimes(r[k], per_state[:, k * n + j].T) for k in range(3)) for j in range(n)]
        return casadi.Function(f"{constraint.name}_jacobian_rows", [q, dq, ddq, *r], [casadi.vertcat(*blocks)],
                               ["q", "dq", "ddq", "r_q", "r_dq", "r_ddq"], ["jacobian_t"])

    def _compiled(self, constraint: Any, jacobian: bool = False) -> casadi.Function:
        """The constraint's per-sample function (``jacobian``: :meth:`_jacobian_rows`), compiled into the
        on-disk cache when ``settings.jit`` (:func:`dynamics.codegen.jit_cache.cached_jit`; as it is if that
        fails)."""
        key = ("compiled", id(constraint), jacobian)
        if key not in self._cache:
            function = self._jacobian_rows(constraint) if jacobian else constraint.function()
            cached = cached_jit(function) if self.settings.jit else None
            self._cache[key] = function if cached is None else cached.function
        return self._cache[key]

    def constraint_margins(self, x: NDArray[np.float64]) -> list[NDArray[np.float64]]:
        """The smooth rows ``g`` ``(T, m)`` of each constraint on the fine grid (``< 0``: broken)."""
        q, dq, ddq = self._states(x)
        key = ("fine map", self.fine_size)
        if key not in self._cache:
            self._cache[key] = [self._compiled(constraint).map(self.fine_size) for constraint in self.constraints]
        return [np.asarray(function(q, dq, ddq)).T for function in self._cache[key]]

    def experiment_time(self, indices: NDArray[np.int64], periods: int = 1) -> NDArray[np.float64]:
        """Time (s) in the experiment of fine-grid points: the ramp in from 0, the first period after it,
        the ramp out after ``periods`` periods (without a rest start: the period's time)."""
        s, steps = self.settings, self.ramp_steps
        indices = np.asarray(indices, dtype=int)
        if not steps:
            return indices / s.rate_hz
        P = s.period_samples
        return np.where(indices < P, steps + indices,
                        np.where(indices < P + steps, indices - P, steps + periods * P + indices - P - steps)) / s.rate_hz

    def broken(self, x: NDArray[np.float64]) -> list[str]:
        """What ``x`` breaks on the fine grid: bounds and constraints named with their worst joint, link or pair."""
        messages = self.bounds.violations(*self.fine_states(x))
        for constraint, margins in zip(self.constraints, self.constraint_margins(x)):
            column = int(np.argmin(margins.min(axis=0)))
            if margins[:, column].min() < -1e-9:
                messages.append(f"{constraint.name} constraint at {constraint.labels[column % len(constraint.labels)]}")
        return messages

    def margin_report(self, x: NDArray[np.float64], periods: int = 1) -> list[dict[str, Any]]:
        """Each constraint, its rule and the worst margin on the fine grid (``rate_hz``, period and ramps)
        by the constraint's independent check (:meth:`margins`), with where and when it is reached, and
        the worst margin per sample over time (``t_s``, ``margin``, in experiment order)."""
        states = self.fine_states(x)
        indices = np.arange(self.fine_size)
        t = self.experiment_time(indices, periods)
        P, steps = self.settings.period_samples, self.ramp_steps
        # the experiment in order: ramp in, the period repeated, ramp out
        order = (np.concatenate([np.arange(P, P + steps), np.tile(np.arange(P), periods), np.arange(P + steps, self.fine_size)])
                 if steps else np.arange(P))
        report = []
        for constraint in self.constraints:
            margins = constraint.margins(*states)
            row, column = np.unravel_index(int(np.argmin(margins)), margins.shape)
            report.append({
                "name": constraint.name, "unit": constraint.unit, **constraint.describe(),
                "worst_margin": float(margins[row, column]), "worst_at": constraint.labels[column],
                "worst_t_s": float(t[row]), "grid_hz": self.settings.rate_hz, "met": bool(margins.min() >= 0),
                "t_s": np.arange(order.size) / self.settings.rate_hz, "margin": margins.min(axis=1)[order],
            })
        return report

    def cost_function(self) -> casadi.Function:
        """``design_objective(x) -> J``: criterion of ``M/N`` over ``cost_samples`` samples (cached)."""
        if "cost" not in self._cache:
            n, H, N = self.n_joints, self.settings.harmonics, self.settings.cost_samples
            model = self.identification_model
            # the sampled states (3 x (N, 2H+1) and (N, n)) and the mapped regressor's work and
            # derivative arrays (about four (N, channels, r) blocks): refuse before building them
            check_allocation(8.0 * N * (3 * (2 * H + 1) + 3 * n + 4 * model.n_channels * model.n_base),
                             f"cost_samples = {N}")
            x = casadi.MX.sym("x", self.n_variables)
            states = self.sampled_states(x)  # (n, N) each: q, dq, ddq
            information = sampled_information(self.identification_model.base_regressor, states,
                                              self.settings.jit) / N
            objective = self.criterion.expression(information)
            self._cache["cost"] = casadi.Function("design_objective", [x], [objective], ["x"], ["J"])
        return self._cache["cost"]

    @property
    def grid_factor(self) -> float:
        """Bounds at the constraint points are scaled by ``cos(π N / M)`` (``N`` harmonics, ``M`` points
        per period): between two points the highest harmonic overshoots its sampled values by at most
        about this factor, so the ``rate_hz`` check rarely fails."""
        s = self.settings
        return float(np.cos(np.pi * s.harmonics / s.constraint_points)) if s.constraint_points > 2 * s.harmonics else 1.0

    def constraint_matrix(self, t: NDArray[np.float64]) -> tuple[scipy.sparse.csr_matrix, NDArray, NDArray]:
        """Sparse ``A`` and bounds ``lb ≤ A x ≤ ub`` for q, dq, ddq of every joint at times ``t``."""
        rows = np.stack(self._state_matrices(np.asarray(t, dtype=float).reshape(-1)))
        return self._linear_rows(rows, np.zeros((3, rows.shape[2])))

    def _linear_rows(self, state_rows: NDArray[np.float64],
                     weights: NDArray[np.float64]) -> tuple[scipy.sparse.csr_matrix, NDArray, NDArray]:
        """:meth:`constraint_matrix` at points given by :meth:`point_matrices` (``rows, weights``): the rest
        position's share ``Q_j · weights`` moves each joint's bounds. Rows: joint, then q/dq/ddq, then point."""
        bounds, width, factor = self.bounds, 2 * self.settings.harmonics + 1, self.grid_factor
        blocks, lower, upper = [], [], []
        q_rest = np.zeros(self.n_joints) if self.rest is None else self.rest.q
        for joint in range(self.n_joints):
            centre, half = (bounds.q_max[joint] + bounds.q_min[joint]) / 2, (bounds.q_max[joint] - bounds.q_min[joint]) / 2
            limits = [(centre - factor * half, centre + factor * half),
                      (-factor * bounds.dq_max[joint], factor * bounds.dq_max[joint]),
                      (-factor * bounds.ddq_max[joint], factor * bounds.ddq_max[joint])]
            for rows, weight, (low, high) in zip(state_rows, weights, limits):
                block = scipy.sparse.lil_matrix((rows.shape[1], self.n_variables))
                block[:, joint * width:(joint + 1) * width] = rows.T
                blocks.append(block.tocsr())
                lower.append(np.full(rows.shape[1], low) - q_rest[joint] * weight)
                upper.append(np.full(rows.shape[1], high) - q_rest[joint] * weight)
        A = scipy.sparse.vstack(blocks).tocsr()
        A.eliminate_zeros()
        lower, upper = np.concatenate(lower), np.concatenate(upper)
        # IPOPT relaxes bounds by 1e-8 relative (bound_relax_factor): pull them in by more than that
        return A, lower + _BOUND_GUARD * np.maximum(1, np.abs(lower)), upper - _BOUND_GUARD * np.maximum(1, np.abs(upper))

    def points(self, extra: tuple[int, ...] = ()) -> NDArray[np.int64]:
        """The fine-grid indices of :meth:`base_points` plus ``extra`` (sorted)."""
        s = self.settings
        check_allocation(8.0 * 2 * (s.constraint_points + len(extra)) * 3 * self.n_joints * self.n_variables,
                         f"constraint_points = {s.constraint_points}")
        return np.union1d(self.base_points(), np.asarray(extra, dtype=int))

    def constraint_times(self, extra: tuple[int, ...] = ()) -> NDArray[np.float64]:
        """The equidistant constraint points plus the ``rate_hz`` samples ``extra`` (sorted, seconds)."""
        s = self.settings
        check_allocation(8.0 * 2 * (s.constraint_points + len(extra)) * 3 * self.n_joints * self.n_variables,
                         f"constraint_points = {s.constraint_points}")
        grid = np.arange(s.constraint_points) * s.period_samples // s.constraint_points  # on the rate_hz grid
        return np.union1d(grid, np.asarray(extra, dtype=int)) / s.rate_hz

    def _solver(self, extra: tuple[int, ...], handover: bool = False,
                warm: bool | None = None) -> tuple[casadi.Function, NDArray, NDArray]:
        """IPOPT on the constraint points plus ``extra``; ``handover``: stopped after
        ``settings.sqp_after`` iterations for the SQP method to finish; ``warm``: started from a given
        primal-dual point (default: for the refinement rounds, ``extra`` not empty)."""
        warm = bool(extra) if warm is None else warm
        key = ("solver", extra, handover, warm)
        if key not in self._cache:
            s = self.settings
            A, lower, upper = self._rows(extra)
            max_iter = min(s.max_iter, s.sqp_after) if handover and s.sqp_after is not None else s.max_iter
            solver = ipopt_solver(self.cost_function(), A, nonlinear=self._nonlinear(extra), tol=s.tol, acceptable_tol=s.acceptable_tol,
                                  acceptable_iter=s.acceptable_iter, max_iter=max_iter,
                                  lbfgs_memory=s.lbfgs_memory, verbose=s.verbose, warm=warm,
                                  ipopt_options=dict(s.ipopt_options))
            self._cache[key] = (solver, lower, upper)
        return self._cache[key]

    def _rows(self, extra: tuple[int, ...]) -> tuple[scipy.sparse.csr_matrix, NDArray, NDArray]:
        """The linear rows at the constraint points plus ``extra``, then the nonlinear constraints' bounds
        (``0 ≤ g``) appended to ``lower, upper`` (cached)."""
        key = ("rows", extra)
        if key not in self._cache:
            A, lower, upper = self._linear_rows(*self.point_matrices(self.points(extra)))
            function = self._nonlinear(extra)
            if function is not None:
                rows = function.size1_out(0)
                # IPOPT meets constraints to its tolerance: ask for a little more than g >= 0
                lower = np.concatenate([lower, np.full(rows, _NONLINEAR_GUARD)])
                upper = np.concatenate([upper, np.full(rows, np.inf)])
            self._cache[key] = (A, lower, upper)
        return self._cache[key]

    def _nonlinear(self, extra: tuple[int, ...]) -> casadi.Function | None:
        key = ("nonlinear", extra)
        if key not in self._cache:
            self._cache[key] = self.nonlinear_function(self.points(extra))
        return self._cache[key]

    def _sqp(self, extra: tuple[int, ...]) -> tuple[casadi.Function, NDArray, NDArray]:
        """A new SQP method on the constraint points plus ``extra`` (:func:`oed.design_solver.sqp_solver`),
        built for each start: CasADi's qpOASES hot-starts every QP from the previous one, so a solver
        kept across starts would make a start's result depend on the starts before it."""
        A, lower, upper = self._rows(extra)
        s = self.settings
        return sqp_solver(self.cost_function(), A, nonlinear=self._nonlinear(extra), tol=s.tol, max_iter=s.max_iter, verbose=s.verbose), lower, upper

    @property
    def hands_over(self) -> bool:
        """Whether IPOPT hands each start over to the SQP method: ``settings.sqp_after`` below
        ``max_iter`` and a smooth criterion (the kinks of ``cond`` and ``mineig`` defeat its BFGS model)."""
        s = self.settings
        return s.sqp_after is not None and s.sqp_after < s.max_iter and self.criterion.smooth

    def _extend_multipliers(self, lam_g: NDArray, old: tuple[int, ...], new: tuple[int, ...]) -> NDArray:
        """Constraint multipliers of the old constraint set placed on the rows of the new one (0 elsewhere)."""
        old_t, new_t = self.points(old), self.points(new)
        position = np.searchsorted(new_t, old_t)
        linear = 3 * self.n_joints * old_t.size
        blocks = lam_g[:linear].reshape(-1, old_t.size)  # rows: joint-major, then q, dq, ddq, then point
        extended = np.zeros((blocks.shape[0], new_t.size))
        extended[:, position] = blocks
        parts, offset = [extended.reshape(-1)], linear
        for constraint in self.constraints:  # point-major within each constraint
            rows = constraint.function().size1_out(0)
            block = lam_g[offset:offset + rows * old_t.size].reshape(old_t.size, rows)
            wider = np.zeros((new_t.size, rows))
            wider[position] = block
            parts.append(wider.reshape(-1))
            offset += rows * old_t.size
        return np.concatenate(parts)

    def build(self) -> float:
        """Build the objective and the first solver; returns the seconds it took (0 once built)."""
        start = time.perf_counter()
        self._solver((), handover=self.hands_over)
        return time.perf_counter() - start

    # ---------------------------------------------------------------- evaluation
    def trajectory(self, x: NDArray[np.float64], **metadata: Any) -> FourierTrajectory:
        s = self.settings
        return FourierTrajectory.from_vector(
            x, self.n_joints, s.harmonics, s.frequency_hz, joint_names=tuple(self.robot.joint_names), metadata=metadata
        )

    def sample(self, x: NDArray[np.float64]) -> tuple[NDArray[np.float64], ...]:
        """``t, q, dq, ddq`` over one period at ``rate_hz``."""
        return self.trajectory(x).sample(self.settings.rate_hz)

    def information(self, q, dq, ddq) -> NDArray[np.float64]:
        """Unscaled ``Y_bᵀY_b`` of the model at the given samples."""
        return information_matrix(self.identification_model.evaluate_base(q, dq, ddq))

    def evaluate(self, x: NDArray[np.float64], samples: tuple[NDArray[np.float64], ...] | None = None) -> dict[str, float]:
        """``cost`` (−log det), ``cond`` and the criterion over one period at ``rate_hz``; ``samples``:
        ``(q, dq, ddq)`` of ``x`` at ``rate_hz`` when already computed."""
        q, dq, ddq = self.sample(x)[1:] if samples is None else samples
        M = self.information(q, dq, ddq)
        eigenvalues = np.linalg.eigvalsh((M + M.T) / 2)
        cond = float(np.sqrt(eigenvalues[-1] / eigenvalues[0])) if eigenvalues[0] > 0 else float("inf")
        return {"cost": LogDet().value(M), "cond": cond, "criterion": self.criterion.value(M)}

    def random_start(self, generator: np.random.Generator) -> NDArray[np.float64]:
        """A random trajectory meeting the bounds on the ``rate_hz`` grid (scaled into 30–90 % of them)."""
        s, b = self.settings, self.bounds
        t = np.arange(s.period_samples) / s.rate_hz
        Bq, Bdq, Bddq = self._state_matrices(t)
        blocks = []
        for joint in range(self.n_joints):
            coefficients = np.concatenate([[0.0], generator.normal(size=2 * s.harmonics)])
            p, dq, ddq = coefficients @ Bq, coefficients @ Bdq, coefficients @ Bddq
            fill = generator.uniform(0.3, 0.9)
            scale = fill * min(b.dq_max[joint] / np.abs(dq).max(), b.ddq_max[joint] / np.abs(ddq).max(),
                               (b.q_max[joint] - b.q_min[joint]) / np.ptp(p))
            centre = (b.q_max[joint] + b.q_min[joint]) / 2 - scale * (p.max() + p.min()) / 2
            coefficients = scale * coefficients
            coefficients[0] = centre
            blocks.append(coefficients)
        return np.concatenate(blocks)

    def shrink_to_bounds(self, x: NDArray[np.float64]) -> NDArray[np.float64]:
        """Scale each joint's oscillation about ``q0`` so that the ``rate_hz`` grid meets the bounds."""
        s, b, width = self.settings, self.bounds, 2 * self.settings.harmonics + 1
        t = np.arange(s.period_samples) / s.rate_hz
        Bq, Bdq, Bddq = self._state_matrices(t)
        x = np.array(x, dtype=float)
        for joint in range(self.n_joints):
            block = x[joint * width:(joint + 1) * width]
            block[0] = np.clip(block[0], b.q_min[joint], b.q_max[joint])
            oscillation = block.copy()
            oscillation[0] = 0.0
            p = oscillation @ Bq
            ratios = [1.0, b.dq_max[joint] / np.abs(oscillation @ Bdq).max(initial=1e-300),
                      b.ddq_max[joint] / np.abs(oscillation @ Bddq).max(initial=1e-300)]
            if p.max() > 0:
                ratios.append((b.q_max[joint] - block[0]) / p.max())
            if p.min() < 0:
                ratios.append((block[0] - b.q_min[joint]) / -p.min())
            block[1:] *= min(ratios) * (1 - 1e-12)
            x[joint * width:(joint + 1) * width] = block
        return x

    # ---------------------------------------------------------------- solving
    def solve(self, x0: NDArray[np.float64], index: int = 0) -> StartResult:
        """One IPOPT start from ``x0``, then the ``rate_hz`` check and refinement rounds.

        Runs on one thread (:func:`dynamics.runtime.threads.single_threaded`): the matrices are too small for
        threaded BLAS to gain anything, and starts run side by side in process pools, where extra
        threads only compete for the cores.
        """
        x0 = np.asarray(x0, dtype=float).reshape(-1)
        if x0.shape[0] != self.n_variables:
            raise ValueError(f"start vector has {x0.shape[0]} values, the problem {self.n_variables}")
        with single_threaded(), interrupt_flag() as interrupted:
            result = self._solve(x0, index, interrupted)
        return result

    def _round(self, extra: tuple[int, ...], x: NDArray[np.float64], multipliers: dict[str, Any],
               interrupted: Callable[[], bool]) -> tuple[dict, dict]:
        """One solve on the constraint points plus ``extra`` from ``x``: the solution and the statistics
        (the iterations of every solver that ran). Without a hand-over: IPOPT. With one: IPOPT for
        ``settings.sqp_after`` iterations in the first round, then the SQP method from IPOPT's point
        (the refinement rounds: the SQP method alone); should it stop short of its tolerance, IPOPT,
        warm-started at its point and multipliers, finishes the round."""
        if not self.hands_over:
            return call_solver(self._solver(extra), x, multipliers, interrupted)
        used = 0
        if not extra:
            solution, stats = call_solver(self._solver((), handover=True), x, {}, interrupted)
            used = int(stats.get("iter_count", 0))
            if not (stats.get("return_status") == "Maximum_Iterations_Exceeded" and used == self.settings.sqp_after):
                return solution, stats  # IPOPT finished (or was stopped by an IPOPT option): nothing to hand over
            x = np.asarray(solution["x"]).reshape(-1)
        # the SQP method minimises SQP_OBJECTIVE_SCALE x the objective: its multipliers scale with it
        scaled = {name: SQP_OBJECTIVE_SCALE * np.asarray(value) for name, value in multipliers.items()}
        solution, stats = call_solver(self._sqp(extra), x, scaled, interrupted)
        solution = {name: solution[name] if name == "x" else solution[name] / SQP_OBJECTIVE_SCALE
                    for name in ("x", "f", "lam_x", "lam_g")}
        used += int(stats.get("iter_count", 0))
        if stats.get("return_status") not in SUCCESS_STATUSES:
            solution, stats = call_solver(self._solver(extra, warm=True), np.asarray(solution["x"]).reshape(-1),
                                   {"lam_x0": solution["lam_x"], "lam_g0": solution["lam_g"]}, interrupted)
            used += int(stats.get("iter_count", 0))
        return solution, {**stats, "iter_count": used}

    @property
    def refinement_rounds(self) -> int:
        """``settings.refinements``; with constraints at least :data:`CONSTRAINED_REFINEMENTS` (between two
        points a torque or a distance can dip further than a bound, and no shrinking repairs it)."""
        return max(self.settings.refinements, CONSTRAINED_REFINEMENTS) if self.constraints else self.settings.refinements

    def _solve(self, x0: NDArray[np.float64], index: int, interrupted: Callable[[], bool] = lambda: False) -> StartResult:
        s = self.settings
        started = time.perf_counter()
        extra: tuple[int, ...] = ()
        x, iterations, status, objective, rounds = x0, 0, "Not_Started", float("nan"), 0
        multipliers: dict[str, Any] = {}
        sampled: tuple[NDArray[np.float64], ...] | None = None  # q, dq, ddq of x on the fine grid
        for rounds in range(self.refinement_rounds + 1):
            solution, stats = self._round(extra, x, multipliers, interrupted)
            x = np.asarray(solution["x"]).reshape(-1)
            iterations += int(stats.get("iter_count", 0))
            status = str(stats.get("return_status", "unknown"))
            objective = float(solution["f"])
            if status not in SUCCESS_STATUSES:
                break
            sampled = self.fine_states(x)
            peaks = violation_peaks(self.bounds.excess(*sampled))
            for margins in self.constraint_margins(x):
                peaks |= violation_peaks({"g": -margins})
            if s.verbose:
                print(f"  round {rounds}: {stats.get('iter_count')} iterations, {len(peaks)} points over a bound "
                      f"or constraint at {s.rate_hz:g} Hz")
            if not peaks:
                break
            new_extra = tuple(sorted(set(extra) | peaks))
            multipliers = {"lam_x0": solution["lam_x"],
                           "lam_g0": self._extend_multipliers(np.asarray(solution["lam_g"]).reshape(-1), extra, new_extra)}
            extra = new_extra
            sampled = None  # the next round moves x
        if sampled is None:
            sampled = self.fine_states(x)
        shrunk = bool(self.bounds.violations(*sampled)) and self.rest is None
        if shrunk:
            x = self.shrink_to_bounds(x)
            sampled = self.fine_states(x)
        feasible = not self.bounds.violations(*sampled) and all(
            margins.min(initial=0.0) >= -1e-9 for margins in self.constraint_margins(x))
        values = self.evaluate(x, tuple(state[:s.period_samples] for state in sampled))
        return StartResult(
            index=index, status=status, success=status in SUCCESS_STATUSES and feasible, iterations=iterations,
            time_s=time.perf_counter() - started, cost=values["cost"], criterion_value=values["criterion"],
            objective=objective, feasible=feasible, refinements=rounds, x=x, x0=x0, shrunk=shrunk,
        )


def default_bounds(robot: RobotModel) -> JointBounds:
    """The paper's eq. 19 for the 3-joint PUMA; otherwise an error asking for bounds."""
    if robot.name.startswith("puma560") and robot.n_joints == 3:
        return PUMA_BOUNDS
    raise ValueError(
        f"no default bounds for {robot.name} ({robot.n_joints} joints): give JointBounds "
        "(e.g. JointBounds.from_robot(robot, ddq_max=...) or a bounds file)"
    )
