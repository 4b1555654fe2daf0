"""Numerical building blocks of the excitation design: the sampled information matrix and IPOPT.

- :func:`sampled_information` sums ``Y_b(q_k, dq_k, ddq_k)ᵀ Y_b(·)`` over the cost samples inside one
  compiled, mapped per-sample function that returns only the upper triangle (the symmetric half).
  The sum is a ``map`` reduction, so neither the stacked ``(rows·N) x r`` regressor nor a large
  matrix product ever appears in the MX graph; its derivatives are compiled as well (once, into an
  on-disk cache that later processes reuse: :mod:`dynamics.codegen.jit_cache`).
  :func:`stacked_information` is the same sum for wide Jacobians (more than :data:`STACKED_ABOVE` columns: the
  sequential and the payload designs) as one product of the stacked per-sample transposes.
- :func:`violation_peaks` picks the samples to add as constraint points after a ``rate_hz`` check.
- :func:`ipopt_solver` wraps ``casadi.nlpsol("ipopt")`` for an objective with *linear* constraints
  ``lb ≤ A x ≤ ub`` (constant Jacobian), L-BFGS Hessian and the convergence settings of
  :class:`oed.design_problem.DesignSettings`.
- :func:`sqp_solver` wraps ``casadi.nlpsol("sqpmethod")`` for the same problem: a dense damped BFGS
  Hessian and one small dense QP an iteration (qpOASES), which finishes a start that IPOPT has
  brought near an optimum in a fraction of IPOPT's time (``DesignSettings.sqp_after``).
"""

from __future__ import annotations

import contextlib
import ctypes
import io
import os
import sys
import tempfile
from collections.abc import Callable, Iterator, Mapping
from pathlib import Path
from typing import Any

import casadi
import numpy as np
import scipy.sparse
from numpy.typing import NDArray

from dynamics.codegen.compiled import find_compiler
from dynamics.codegen.jit_cache import cached_jit

#: re-solves after adding constraint points start from the previous primal-dual point
WARM_START = {"warm_start_init_point": "yes", "warm_start_bound_push": 1e-9, "warm_start_mult_bound_push": 1e-9,
              "warm_start_slack_bound_push": 1e-9, "mu_init": 1e-7}


#: the SQP method minimises this multiple of the design objective. Its BFGS matrix starts as the
#: identity, so its first steps are the (projected) gradient; unscaled they left the optimum IPOPT was
#: heading for about one start in ten on the PUMA internal model (-196.9 against -200.7 once); at a
#: tenth the single starts match IPOPT alone on average (benchmarks/README.md). Its stationarity
#: tolerance is scaled with it.
SQP_OBJECTIVE_SCALE = 0.1


def jit_options() -> dict[str, Any]:
    """CasADi options compiling a function and its forward/reverse derivatives with the C compiler
    of :func:`dynamics.codegen.compiled.find_compiler` (``$CC``, ``cc``, ``gcc`` or ``clang``)."""
    compiler = find_compiler()
    if compiler is None:
        raise RuntimeError("jit=True needs a C compiler ($CC, cc, gcc or clang) on the PATH; use jit=False")
    # CasADi writes its JIT sources and objects to the working directory unless told otherwise
    directory = Path(tempfile.gettempdir()) / "robot-oed-jit"
    directory.mkdir(parents=True, exist_ok=True)
    options = {
        "jit": True, "compiler": "shell",
        "jit_options": {"compiler": compiler, "flags": ["-O1"], "verbose": False, "directory": str(directory)},
    }
    return {**options, "reverse_options": options, "forward_options": options}


def sampled_information(base_regressor: casadi.Function, states: list[casadi.MX], jit: bool) -> casadi.MX:
    """``Σ_k Y_b(q_k, dq_k, ddq_k)ᵀ Y_b(q_k, dq_k, ddq_k)`` (symmetric ``r x r``, unscaled).

    Parameters
    ----------
    base_regressor
        ``(q, dq, ddq) -> Y_b`` (``rows x r``) of one sample.
    states
        ``q, dq, ddq`` as ``n x N`` MX matrices (one column per cost sample).
    jit
        Compile the per-sample function and its forward/reverse derivatives with the system C
        compiler, once into the on-disk cache of :func:`dynamics.codegen.jit_cache.cached_jit` (later
        builds, in any process, load the library); if that fails, with CasADi's JIT.
    """
    n, samples = states[0].shape
    q, dq, ddq = (casadi.SX.sym(name, n) for name in ("q", "dq", "ddq"))
    Y = base_regressor(q, dq, ddq)
    upper = casadi.triu(casadi.mtimes(Y.T, Y))  # only the symmetric half is computed
    per_sample = casadi.Function("sample_information", [q, dq, ddq], [upper], ["q", "dq", "ddq"], ["M_upper"])
    if jit:
        cached = cached_jit(per_sample)
        per_sample = cached.function if cached is not None else casadi.Function(
            "sample_information", [q, dq, ddq], [upper], ["q", "dq", "ddq"], ["M_upper"], jit_options())
    summed = per_sample.map("information_sum", "serial", samples, [], [0])(*states)
    return summed + casadi.triu(summed, False).T


#: more columns than this: the information sum as one product of the stacked per-sample Jacobians
#: (:func:`stacked_information`). Measured: for the 7-joint KUKA (50 columns) the stacked form compiles in 6 s
#: against 64 s at about the same gradient time; for the PUMA (21) the per-sample form's gradient takes 0.6 ms
#: against 5.8 ms (benchmarks/README.md)
STACKED_ABOVE = 30


def stacked_information(function: casadi.Function, states: list[casadi.MX], jit: bool) -> casadi.MX:
    """``Σ_k J_kᵀ J_k`` over the cost samples of ``function(q, dq, ddq) -> J`` (``rows x p``).

    Up to :data:`STACKED_ABOVE` columns the compiled per-sample ``JᵀJ`` of :func:`sampled_information`; above, the
    per-sample function is ``Jᵀ`` alone, mapped over the samples into one ``p x (rows N)`` matrix ``S``, and the sum
    is ``S Sᵀ``, one product (far shorter to compile for many columns).
    """
    if function.size2_out(0) <= STACKED_ABOVE:
        return sampled_information(function, states, jit)
    n, samples = states[0].shape
    q, dq, ddq = (casadi.SX.sym(name, n) for name in ("q", "dq", "ddq"))
    transposed = casadi.Function(f"{function.name()}_t", [q, dq, ddq], [function(q, dq, ddq).T],
                                 ["q", "dq", "ddq"], ["Jt"], jit_options() if jit else {})
    stacked = transposed.map(samples, "serial")(*states)  # (p, rows N)
    return casadi.mtimes(stacked, stacked.T)


def ipopt_solver(objective: casadi.Function, A: scipy.sparse.spmatrix, *, nonlinear: casadi.Function | None = None,
                 tol: float, acceptable_tol: float,
                 acceptable_iter: int, max_iter: int, lbfgs_memory: int, verbose: bool,
                 warm: bool, ipopt_options: Mapping[str, Any] | None = None,
                 nlpsol_options: Mapping[str, Any] | None = None) -> casadi.Function:
    """IPOPT for ``min objective(x)`` s.t. ``lbg ≤ A x ≤ ubg`` (bounds given per call).

    Parameters
    ----------
    objective
        ``x -> J`` (scalar, exact derivatives by AD).
    A
        Constant constraint matrix (sparse).
    nonlinear
        ``x -> g``: further constraints (torque, distances; :mod:`oed.design_constraints`) appended below
        ``A x``, with exact Jacobians by AD (then the constraint Jacobian is not constant).
    tol, acceptable_tol, acceptable_iter, max_iter, lbfgs_memory, verbose
        IPOPT's ``tol``, ``acceptable_tol``, ``acceptable_iter``, ``max_iter``,
        ``limited_memory_max_history`` and iteration log on/off.
    warm
        Start from a given primal-dual point (``x0, lam_x0, lam_g0``) instead of IPOPT's default.
    ipopt_options, nlpsol_options
        Further IPOPT options and CasADi ``nlpsol`` options (e.g. ``hess_lag``), over the above
        (``benchmarks/design_curvature.py`` uses them to examine the Hessian approximation).
    """
    options = {
        "ipopt": {
            "hessian_approximation": "limited-memory",
            "limited_memory_max_history": lbfgs_memory,
            "jac_c_constant": "yes" if nonlinear is None else "no",
            "jac_d_constant": "yes" if nonlinear is None else "no",
            "tol": tol,
            "acceptable_tol": acceptable_tol,
            "acceptable_iter": acceptable_iter,
            "max_iter": max_iter,
            "print_level": 5 if verbose else 0,
            "sb": "yes",
            **(WARM_START if warm else {}),
            **(ipopt_options or {}),
        },
        "print_time": bool(verbose),
        **(nlpsol_options or {}),
    }
    return casadi.nlpsol("excitation_design", "ipopt", linear_problem(objective, A, nonlinear), options)


def linear_problem(objective: casadi.Function, A: scipy.sparse.spmatrix,
                   nonlinear: casadi.Function | None = None) -> dict[str, casadi.MX]:
    """``{x, f, g}`` of ``min objective(x)`` s.t. ``lbg ≤ A x ≤ ubg`` with ``A`` a sparse CasADi constant
    (and ``nonlinear(x)`` appended to ``g`` when given).

    The objective's graph is inlined, not called as a function: the solvers' gradient functions (which
    return the objective with its gradient) then reuse the forward pass (the sampled information
    matrix) for the reverse sweep instead of evaluating it a second time inside the objective's reverse
    derivative (PUMA combined model: objective and gradient 0.49 ms against 0.67 ms, the same values).
    """
    csc = scipy.sparse.csc_matrix(A)
    csc.sort_indices()
    pattern = casadi.Sparsity(csc.shape[0], csc.shape[1], csc.indptr.tolist(), csc.indices.tolist())
    A_dm = casadi.DM(pattern, np.asarray(csc.data, dtype=float))  # CasADi stores column-compressed, like CSC
    x = casadi.MX.sym("x", csc.shape[1])
    (f,) = objective.call([x], True, False)  # always inline
    g = casadi.mtimes(A_dm, x)
    if nonlinear is not None:
        g = casadi.vertcat(g, nonlinear(x))
    return {"x": x, "f": f, "g": casadi.densify(g)}


def sqp_solver(objective: casadi.Function, A: scipy.sparse.spmatrix, *, nonlinear: casadi.Function | None = None,
               tol: float, max_iter: int, verbose: bool) -> casadi.Function:
    """SQP (CasADi ``sqpmethod``) for ``min objective(x)`` s.t. ``lbg ≤ A x ≤ ubg``.

    Each iteration solves one dense QP in the ``n`` coefficients with the rows of ``A`` (qpOASES, an
    active-set method, or CasADi's ``qrqp`` where qpOASES is missing) under a BFGS Hessian with
    Powell's damping (Nocedal & Wright, Procedure 18.2), so it keeps curvature information where
    IPOPT's L-BFGS skips the updates of negative curvature. Its iterations are much cheaper than
    IPOPT's (no sparse factorisation of the ``n + rows`` KKT system), but from a random start it
    stops at the first optimum it reaches on the bounds, often a worse one: the design hands it
    IPOPT's point after ``DesignSettings.sqp_after`` iterations.

    Parameters
    ----------
    objective, A, nonlinear
        As for :func:`ipopt_solver`.
    tol
        Stationarity tolerance on the gradient of the objective (``tol_du``, scaled with
        :data:`SQP_OBJECTIVE_SCALE`; the constraints are met to ``1e-9``, ``tol_pr``).
    max_iter, verbose
        Iteration limit and iteration log on/off.
    """
    qpsol = "qpoases" if casadi.has_conic("qpoases") else "qrqp"
    # dense qpOASES told that the damped BFGS matrix is positive definite, without its ramping
    # strategy: the cold first QP of a start is about a third faster, with the same steps
    quiet_qp = ({"printLevel": "none", "sparse": False, "hessian_type": "posdef", "enableRamping": False,
                 "error_on_fail": False} if qpsol == "qpoases" else
                {"print_iter": False, "print_header": False, "print_info": False, "error_on_fail": False})
    options = {
        "qpsol": qpsol,
        "qpsol_options": quiet_qp,
        "hessian_approximation": "limited-memory",  # sqpmethod's name for its dense damped BFGS
        "tol_du": tol * SQP_OBJECTIVE_SCALE,
        "tol_pr": 1e-9,
        "max_iter": max_iter,
        "print_header": bool(verbose),
        "print_iteration": bool(verbose),
        "print_status": bool(verbose),
        "print_time": bool(verbose),
        "error_on_fail": False,
    }
    with stdout_silenced():  # qpOASES prints its licence banner whatever its printLevel
        problem = linear_problem(objective, A, nonlinear)
        problem["f"] = SQP_OBJECTIVE_SCALE * problem["f"]
        return casadi.nlpsol("excitation_design_sqp", "sqpmethod", problem, options)


@contextlib.contextmanager
def stdout_silenced() -> Iterator[None]:
    """Standard output discarded for the ``with`` block: ``sys.stdout`` (where CasADi's Python module
    sends what its plugins print) and file descriptor 1 (where C code prints directly). Python's and
    C's buffers are flushed at both ends, so that nothing printed before is lost and nothing printed
    inside comes out later."""
    sys.stdout.flush()
    _flush_c_streams()
    saved = os.dup(1)
    try:
        with open(os.devnull, "w") as null, contextlib.redirect_stdout(io.StringIO()):
            os.dup2(null.fileno(), 1)
            try:
                yield
            finally:
                _flush_c_streams()
    finally:
        os.dup2(saved, 1)
        os.close(saved)


def _flush_c_streams() -> None:
    """``fflush(NULL)``: the C library's output buffers written out (nothing where it cannot be reached)."""
    try:
        ctypes.CDLL(None).fflush(None)
    except (OSError, TypeError, AttributeError):  # no C library handle by that name (Windows)
        pass


def call_solver(entry: tuple[casadi.Function, NDArray, NDArray], x0: NDArray[np.float64], multipliers: dict[str, Any],
                interrupted: Callable[[], bool]) -> tuple[dict, dict]:
    """One call of a solver with its constraint bounds ``(solver, lbg, ubg)`` from ``x0`` (and the
    multipliers ``lam_x0``, ``lam_g0`` given): the solution and the solver's statistics.

    Raises
    ------
    KeyboardInterrupt
        When ``interrupted()`` says Ctrl-C came during the call (CasADi turns it into a solver status;
        it ends the design, not one start).
    """
    solver, lower, upper = entry
    solution = solver(x0=x0, lbg=lower, ubg=upper, **multipliers)
    if interrupted():
        raise KeyboardInterrupt("interrupted during an IPOPT solve")
    return solution, solver.stats()


def violation_peaks(excess: dict[str, NDArray[np.float64]], tolerance: float = 1e-9) -> set[int]:
    """Sample indices of the worst point of every run of consecutive violations, per state and joint."""
    peaks: set[int] = set()
    for values in excess.values():
        for column in values.T:
            violated = column > tolerance
            if not violated.any():
                continue
            # runs of violated samples (periodic: a run may wrap around the end)
            edges = np.flatnonzero(np.diff(np.concatenate([[False], violated, [False]]).astype(int)))
            for begin, end in zip(edges[::2], edges[1::2]):
                peaks.add(int(begin + np.argmax(column[begin:end])))
    return peaks
