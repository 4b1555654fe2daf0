"""Output-error fit of the continuous servo-joint model (issue 17): physical ``b, k, σ`` that hold.

The ERLS route (:mod:`estimation.servo.protocol`) fits eq. 14 for one-step prediction and maps its coefficients back to
``b, k, σ``; both mappings are biased on a continuous plant sampled at 100 Hz (eq. 14 has one input
coefficient where the sampled plant has two, and the fit weighs one-step prediction). Here the continuous
model ``m q̈ + b q̇ + k q = σ u`` is simulated exactly on the sample grid (zero-order hold, optional input delay:
:mod:`estimation.servo.output_error_model`) and the **free-run** error on the estimation part is minimised::

    min over θ = (b/m, k/m, σ/m), x0 = (q0, q̇0), offset [, delay fraction f]:   ½ Σ_n (q(n) − q̂(n; θ, x0))²

with IPOPT and exact CasADi derivatives (gradient and Hessian through the ``mapaccum`` simulation; the NLP is
built once per sample count and cached). Like MATLAB's ``greyest``, it is the prediction-error method with the
output-error noise model, consistent whatever the colour of the measurement noise.

Starts: ERLS's coefficients mapped by the pole mapping (``zoh``); when that start fails or fits the estimation
part poorly (free-run R² below 0.9), ERLS's backward-Euler mapping, then two more with ERLS's natural frequency
and static gain and damping ratios 0.3 and 1.5. A start whose parameters are unstable (``b ≤ 0`` or ``k ≤ 0``) or
whose simulation is not finite is skipped; if every start is skipped or fails, :class:`OutputErrorDivergedError`.

Delay (``delay="estimate"``): a fraction ``f ∈ [0, 1]`` of a sample is an NLP variable; if it ends at 1, the
whole-sample delay ``l`` is raised by one and the fit repeated from there, up to ``max_delay`` samples.

Standard deviations: the sandwich (Gauss–Newton with the residual's autocovariance) covariance of
:mod:`estimation.servo.output_error_covariance`, from the exact sensitivity of the free run on the estimation part;
``b, k, σ`` scale ``b/m, k/m, σ/m`` by the measured mass, taken as exact. Parameters ending on a bound (the
delay fraction at 0) are held fixed in it.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass, field
from typing import Literal

import casadi
import numpy as np
from numpy.typing import ArrayLike

from estimation.estimators.metrics import cost_v, r2_adjusted, rmse
from estimation.servo.protocol import ServoJointFit, fit_servo_joint
from estimation.servo.model import Discretisation, discrete_to_gray_box
from estimation.servo.output_error_covariance import sandwich_covariance
from estimation.servo.output_error_model import (
    delayed_inputs,
    discrete_coefficients,
    fusion_gains,
    simulation_function,
    residual_function,
    zoh_function,
)

Delay = Literal["none", "estimate"]
DELAYS: tuple[str, ...] = ("none", "estimate")
#: parameters of the NLP, in this order (θ, delay fraction, initial state, offset)
PARAMETER_NAMES: tuple[str, ...] = ("b_over_m", "k_over_m", "sigma_over_m", "delay_fraction", "q0", "dq0", "offset")
#: a start whose estimation free-run R² is below this calls for the extra starts
POOR_START_R2 = 0.9
#: the parameters stay within this factor of their start (and the matrix exponential accurate)
_RANGE = 100.0


class OutputErrorInputError(ValueError):
    """The data cannot identify the model: an input that never changes, or a mass that is not positive."""


class OutputErrorDivergedError(ValueError):
    """Every start of the output-error fit was unstable, diverged, or failed in IPOPT."""


@dataclass(frozen=True)
class StartOutcome:
    """One start: its name, ``theta`` (b/m, k/m, σ/m) and what became of it (``status``, final ``cost``)."""

    name: str
    theta: tuple[float, float, float] | None
    status: str
    cost: float | None = None


@dataclass(frozen=True)
class ServoOutputErrorJointFit:
    """One joint's output-error fit: physical values with standard deviations, metrics, and the ERLS start.

    ``b, k, sigma`` (and their ``*_std``) are ``None`` without a mass; ``*_over_m`` are always given.
    ``a1, a2, K, K2, K3`` write the fitted continuous model as the exact difference equation
    ``q(n) = −a1 q(n−1) − a2 q(n−2) + K u(n−1−l) + K2 u(n−2−l) + K3 u(n−3−l)`` (``l = delay_samples``).
    ``rmse``/``r2_adj``: one-step-ahead prediction (that difference equation fed the measured angles) on the
    validation part; ``*_free_run``: the model alone from its fitted initial state, never reset.
    """

    joint: int
    method: str
    mass: float | None
    b: float | None
    k: float | None
    sigma: float | None
    b_std: float | None
    k_std: float | None
    sigma_std: float | None
    b_over_m: float
    k_over_m: float
    sigma_over_m: float
    b_over_m_std: float
    k_over_m_std: float
    sigma_over_m_std: float
    delay: float
    delay_std: float | None
    q0: float
    dq0: float
    offset: float
    a1: float
    a2: float
    K: float
    K2: float
    K3: float
    c: tuple[float, ...]
    V: float
    V_free_run: float
    rmse: float
    r2_adj: float
    rmse_free_run: float
    r2_adj_free_run: float
    n_parameters: int
    n_estimation: int
    n_validation: int
    std_lags: int
    std_inflation: float
    start: str
    starts: tuple[StartOutcome, ...]
    erls: ServoJointFit = field(repr=False)


@dataclass(frozen=True)
class KalmanFusionSettings:
    """The gyro/accelerometer fusion that produced the angle (eqs. 4–8, :func:`dynamics.kalman.kalman_fusion`):
    ``Q_d`` diagonal ``q``, ``R_d = r``, ``P(0) = p0 I``. Defaults: those of :mod:`dynamics.simulation.servo_simulator`
    (``oed servo-simulate``): ``q = (1e-5, 1e-8)``, ``r = 0.03²``."""

    q: tuple[float, float] = (1e-5, 1e-8)
    r: float = 0.03**2
    p0: float = 1.0


@functools.lru_cache(maxsize=16)
def _solver(n_samples: int, fused: bool) -> casadi.Function:
    """IPOPT on the free-run error of ``n_samples`` samples; data and scales are NLP parameters.

    Exact first derivatives from the forward sensitivities of :func:`residual_function` (gradient ``ρ Jᵀr``) and
    the Gauss–Newton Hessian ``λ_f ρ JᵀJ``: no reverse sweep or second-order sweep through the ``mapaccum``
    (those made one solve 20x slower for the same iterates). Built once per sample count.
    """
    w = casadi.MX.sym("w", 7)
    p = casadi.MX.sym("p", 7 + 5 * n_samples)
    residual, jacobian = residual_function(n_samples, fused)(w, p)
    weight = p[5]
    objective = 0.5 * weight * casadi.sumsqr(residual)
    # the NLP's own objective: the same free run without sensitivities, in the virtual machine (differentiable,
    # for the multipliers CasADi prepares; IPOPT's gradient and Hessian come from the options below)
    scale, dt = p[:6], p[6]
    u = casadi.reshape(p[7 + n_samples:7 + 3 * n_samples], 2, n_samples)
    gains = casadi.reshape(p[7 + 3 * n_samples:], 2, n_samples)
    simulated = simulation_function(n_samples, fused).expand()(
        scale[:3] * w[:3], w[3], casadi.vertcat(scale[3] * w[4], scale[4] * w[5]), scale[3] * w[6], u, dt, gains)
    plain_objective = 0.5 * weight * casadi.sumsqr(simulated.T - p[7:7 + n_samples])
    grad_f = casadi.Function(f"servo_output_error_grad_{n_samples}", [w, p],
                             [objective, weight * casadi.mtimes(jacobian.T, residual)], ["x", "p"], ["f", "grad_f_x"])
    lam_f = casadi.MX.sym("lam_f")
    lam_g = casadi.MX.sym("lam_g", 0, 1)
    hess_lag = casadi.Function(f"servo_output_error_gauss_newton_{n_samples}", [w, p, lam_f, lam_g],
                               [casadi.triu(lam_f * weight * casadi.mtimes(jacobian.T, jacobian))],
                               ["x", "p", "lam_f", "lam_g"], ["triu_hess_gamma_x_x"])
    options = {"print_time": False, "grad_f": grad_f, "hess_lag": hess_lag, "calc_lam_p": False, "calc_lam_x": False,
               "ipopt": {"print_level": 0, "sb": "yes", "tol": 1e-10, "acceptable_tol": 1e-8, "max_iter": 200}}
    return casadi.nlpsol(f"servo_output_error_{n_samples}_{'fused' if fused else 'angle'}", "ipopt", {"x": w, "p": p, "f": plain_objective}, options)


def _check_inputs(u: np.ndarray, mass: float | None, joint: int) -> None:
    if mass is not None and (isinstance(mass, bool) or not (isinstance(mass, (int, float, np.floating, np.integer))
                                                            and np.isfinite(mass) and mass > 0)):
        raise OutputErrorInputError(f"joint {joint}: the mass must be positive and finite, got {mass!r}")
    if np.ptp(u) == 0.0:
        raise OutputErrorInputError(f"joint {joint}: the input u never changes on the estimation part (constant "
                                    f"{u[0]:g}): nothing excites the joint, so b, k, σ cannot be identified")


def _starts(erls: ServoJointFit, dt: float) -> list[tuple[str, np.ndarray | None]]:
    """The two ERLS mappings (per unit mass); ``None`` where the mapping itself fails."""
    starts: list[tuple[str, np.ndarray | None]] = []
    for name in ("zoh", "backward-euler"):
        try:
            gray = discrete_to_gray_box(erls.a1, erls.a2, erls.K, mass=1.0, dt=dt, discretisation=name)
            starts.append((f"erls-{name}", np.array([gray.b, gray.k, gray.sigma])))
        except ValueError:
            starts.append((f"erls-{name}", None))
    return starts


def _seed(starts: list[tuple[str, np.ndarray | None]]) -> np.ndarray | None:
    """The first start with a positive stiffness (the extra starts keep its natural frequency and gain)."""
    return next((s for _, s in starts if s is not None and np.all(np.isfinite(s)) and s[1] > 0), None)


def _extra_starts(theta: np.ndarray | None) -> list[tuple[str, np.ndarray]]:
    """Natural frequency and static gain of ``theta``, damping ratios 0.3 and 1.5 (none without ``theta``)."""
    if theta is None:
        return []
    omega = np.sqrt(abs(theta[1]))
    gain = theta[2] / theta[1]
    return [(f"damping-{zeta:g}", np.array([2 * zeta * omega, omega**2, gain * omega**2])) for zeta in (0.3, 1.5)]


@dataclass(frozen=True)
class _Solution:
    name: str
    w: np.ndarray
    scale: np.ndarray
    whole: int
    cost: float
    gains: np.ndarray | None


def _solve(name: str, theta: np.ndarray, whole: int, fraction: float, delay: Delay, u: np.ndarray,
           q: np.ndarray, dt: float, gains: np.ndarray | None) -> tuple[_Solution | None, str]:
    """One IPOPT solve from ``theta`` (b/m, k/m, σ/m) with ``whole`` samples of delay; ``(None, why)`` if skipped."""
    if not (np.all(np.isfinite(theta)) and theta[0] > 0 and theta[1] > 0 and theta[2] != 0):
        return None, "skipped: unstable or degenerate start (b <= 0, k <= 0 or sigma = 0)"
    n = q.size
    rows = delayed_inputs(u, whole)
    q_scale = max(float(np.std(q)), 1e-12)
    scale = np.array([theta[0], theta[1], theta[2], q_scale, q_scale * np.sqrt(theta[1]),
                      1.0 / max(float(np.sum((q - q.mean()) ** 2)), 1e-300)])
    x0 = np.array([q[0] / q_scale, (q[min(1, n - 1)] - q[0]) / dt / scale[4]])
    w0 = np.array([1.0, 1.0, 1.0, fraction, x0[0], x0[1], 0.0])
    fused = gains is not None
    gain_rows = gains if fused else np.zeros((2, n))
    params = np.concatenate((scale, [dt], q, rows.T.reshape(-1), gain_rows.T.reshape(-1)))  # column-major (2 × N)
    with np.errstate(all="ignore"):
        first = np.asarray(simulation_function(n, fused)(theta, fraction, [q[0], 0.0], 0.0, rows, dt, gain_rows)).reshape(-1)
    if not np.all(np.isfinite(first)) or np.max(np.abs(first)) > 1e6 * max(np.max(np.abs(q)), 1.0):
        return None, "skipped: the simulation from this start diverges"
    f_bounds = (0.0, 1.0) if delay == "estimate" else (fraction, fraction)
    lower = [1.0 / _RANGE, 1.0 / _RANGE, -_RANGE, f_bounds[0], -np.inf, -np.inf, -np.inf]
    upper = [_RANGE, _RANGE, _RANGE, f_bounds[1], np.inf, np.inf, np.inf]
    solver = _solver(n, fused)
    try:
        result = solver(x0=w0, p=params, lbx=lower, ubx=upper)
    except RuntimeError as error:  # an evaluation error inside IPOPT (non-finite simulation)
        return None, f"failed: {error}"
    status = solver.stats()["return_status"]
    w = np.asarray(result["x"]).reshape(-1)
    cost = float(result["f"])
    if not np.all(np.isfinite(w)) or not np.isfinite(cost) or status not in (
            "Solve_Succeeded", "Solved_To_Acceptable_Level", "Search_Direction_Becomes_Too_Small"):
        return None, f"failed: IPOPT {status}"
    return _Solution(name=name, w=w, scale=scale, whole=whole, cost=cost, gains=gains), status


def _physical(solution: _Solution) -> tuple[np.ndarray, float, np.ndarray, float]:
    """``(theta, fraction, x0, offset)`` of a solution."""
    w, s = solution.w, solution.scale
    return s[:3] * w[:3], float(w[3]), np.array([s[3] * w[4], s[4] * w[5]]), float(s[3] * w[6])


def _fit_starts(starts, delay: Delay, max_delay: int, u: np.ndarray, q: np.ndarray, dt: float, gains: np.ndarray | None):
    outcomes: list[StartOutcome] = []
    best: _Solution | None = None
    for name, theta in starts:
        if theta is None:
            outcomes.append(StartOutcome(name, None, "skipped: the ERLS mapping has no continuous counterpart"))
            continue
        solution, status = _solve(name, theta, 0, 0.0, delay, u, q, dt, gains)
        while solution is not None and delay == "estimate" and solution.w[3] > 0.99 and solution.whole + 1 < max_delay:
            theta_next, *_ = _physical(solution)
            longer, _ = _solve(name, theta_next, solution.whole + 1, 0.0, delay, u, q, dt, gains)
            if longer is None or longer.cost >= solution.cost:
                break
            solution = longer
        outcomes.append(StartOutcome(name, tuple(float(v) for v in theta), status,
                                     None if solution is None else solution.cost))
        if solution is not None and (best is None or solution.cost < best.cost):
            best = solution
    return best, outcomes


def fit_servo_joint_output_error(
    u: ArrayLike, q: ArrayLike, *, dt: float, mass: float | None = None, joint: int = 1, estimation_fraction: float = 0.8,
    remove_mean: bool = True, delay: Delay = "none", max_delay: int = 3, nc: int = 1, forgetting: float = 1.0,
    discretisation: Discretisation = "backward-euler", fusion: KalmanFusionSettings | None = None,
) -> ServoOutputErrorJointFit:
    """Output-error fit of one joint (module docstring), started from its ERLS fit.

    Parameters
    ----------
    u, q
        Command and measured (fused) angle [rad], uniformly sampled at ``dt`` [s].
    mass
        Measured mass [kg]: scales ``b/m, k/m, σ/m`` to ``b, k, σ``.
    estimation_fraction, remove_mean, nc, forgetting
        As :func:`estimation.servo.protocol.fit_servo_joint` (the same split and means for both routes).
    delay
        ``"none"`` (zero-order hold only) or ``"estimate"`` (an input delay of up to ``max_delay`` samples).
    discretisation
        Mapping of the ERLS fit reported under ``erls`` (the starts use both).
    fusion
        When ``q`` is a Kalman fusion of a gyro and an accelerometer (the paper's, and ``oed servo-simulate``'s),
        its settings: the model's angle and rate then go through the same fusion, which is linear with gains
        independent of the data, so its signal distortion is modelled exactly (the paper's eq. 4 integrates the
        gyro with the rate at the end of the step, which advances the fused angle by about half a sample above
        the filter's bandwidth: ignored, it biases b, k, σ upwards by 17–47 % on Table 1's joints).

    Raises
    ------
    OutputErrorInputError
        A constant input on the estimation part, a mass that is not positive and finite.
    OutputErrorDivergedError
        No start converged (each unstable, diverging or failing).
    """
    u = np.asarray(u, dtype=float).reshape(-1)
    q = np.asarray(q, dtype=float).reshape(-1)
    if delay not in DELAYS:
        raise ValueError(f"delay must be one of {DELAYS}, got {delay!r}")
    if not (isinstance(max_delay, (int, np.integer)) and not isinstance(max_delay, bool) and 1 <= max_delay <= 50):
        raise ValueError(f"max_delay must be an integer number of samples in 1..50, got {max_delay!r}")
    n_est = int(round(estimation_fraction * u.size)) if 0.0 < estimation_fraction < 1.0 else u.size
    _check_inputs(u[:n_est], mass, joint)
    erls = fit_servo_joint(u, q, dt=dt, mass=mass, joint=joint, method="erls", estimation_fraction=estimation_fraction,
                           nc=nc, forgetting=forgetting, remove_mean=remove_mean, discretisation=discretisation)
    n_est, n_val = erls.n_estimation, erls.n_validation
    if remove_mean:
        u = u - u[:n_est].mean()
        q = q - q[:n_est].mean()
    u_est, q_est = u[:n_est], q[:n_est]
    starts = _starts(erls, dt)
    gains = None if fusion is None else fusion_gains(u.size, dt=dt, q=fusion.q, r=fusion.r, p0=fusion.p0)
    gains_est = None if gains is None else gains[:, :n_est]
    best, outcomes = _fit_starts(starts[:1], delay, max_delay, u_est, q_est, dt, gains_est)
    # further starts only when the first one failed or fits poorly: cost = ½ (1 − R²) on the estimation part
    for more in (lambda: starts[1:], lambda: _extra_starts(_seed(starts))):
        if best is not None and 1.0 - 2.0 * best.cost >= POOR_START_R2:
            break
        extra_best, extra = _fit_starts(more(), delay, max_delay, u_est, q_est, dt, gains_est)
        outcomes += extra
        if extra_best is not None and (best is None or extra_best.cost < best.cost):
            best = extra_best
    if best is None:
        raise OutputErrorDivergedError(
            f"joint {joint}: no start of the output-error fit converged: "
            + "; ".join(f"{o.name} (b/m, k/m, σ/m = {', '.join(f'{v:.4g}' for v in o.theta) if o.theta else '—'}): {o.status}"
                        for o in outcomes))
    return _report(best, tuple(outcomes), erls, u, q, dt, mass, joint, n_est, n_val, delay, gains)


def _report(best: _Solution, outcomes, erls: ServoJointFit, u: np.ndarray, q: np.ndarray, dt: float,
            mass: float | None, joint: int, n_est: int, n_val: int, delay: Delay,
            gains: np.ndarray | None) -> ServoOutputErrorJointFit:
    theta, fraction, x0, offset = _physical(best)
    n = u.size
    rows = delayed_inputs(u, best.whole)
    fused = gains is not None
    gain_rows = gains if fused else np.zeros((2, n))
    simulated = np.asarray(simulation_function(n, fused)(theta, fraction, x0, offset, rows, dt, gain_rows)).reshape(-1)
    params = np.concatenate((best.scale, [dt], q[:n_est], rows[:, :n_est].T.reshape(-1),
                             gain_rows[:, :n_est].T.reshape(-1)))
    residual, jacobian = (np.asarray(v) for v in residual_function(n_est, fused)(best.w, params))
    s = best.scale  # from the scaled NLP variables to θ, f, q0, dq0, offset
    jacobian = jacobian / np.array([s[0], s[1], s[2], 1.0, s[3], s[4], s[3]])
    free = [0, 1, 2, 4, 5, 6] + ([3] if delay == "estimate" and 1e-6 < fraction < 1 - 1e-6 else [])
    sandwich = sandwich_covariance(jacobian[:, free], residual.reshape(-1))
    std = dict.fromkeys(PARAMETER_NAMES)
    std.update({PARAMETER_NAMES[i]: float(np.sqrt(sandwich.covariance[j, j])) for j, i in enumerate(free)})
    phi, gamma = (np.asarray(v) for v in zoh_function()(theta, fraction, dt))
    a1, a2, (k1, k2, k3) = discrete_coefficients(phi, gamma)
    # one-step ahead: the difference equation fed the measured angles, i.e. the free run corrected by the
    # last two errors: q̂(n) = s(n) + a1 (s(n−1) − q(n−1)) + a2 (s(n−2) − q(n−2))
    one_step = simulated.copy()
    one_step[2:] += a1 * (simulated[1:-1] - q[1:-1]) + a2 * (simulated[:-2] - q[:-2])
    p = len(free) - 2  # as ERLS's count: model parameters, not the initial state (ERLS's are its first samples)
    q_val = q[n_est:]
    scale = 1.0 if mass is None else float(mass)
    physical = [None if mass is None else scale * v for v in theta]
    physical_std = [None if mass is None else scale * std[name] for name in PARAMETER_NAMES[:3]]
    return ServoOutputErrorJointFit(
        joint=joint, method="oe", mass=None if mass is None else float(mass),
        b=physical[0], k=physical[1], sigma=physical[2], b_std=physical_std[0], k_std=physical_std[1],
        sigma_std=physical_std[2], b_over_m=float(theta[0]), k_over_m=float(theta[1]), sigma_over_m=float(theta[2]),
        b_over_m_std=std["b_over_m"], k_over_m_std=std["k_over_m"], sigma_over_m_std=std["sigma_over_m"],
        delay=best.whole + fraction, delay_std=std["delay_fraction"], q0=float(x0[0]), dq0=float(x0[1]), offset=offset,
        a1=a1, a2=a2, K=k1, K2=k2, K3=k3, c=(),
        V=cost_v(q[2:n_est], one_step[2:n_est]), V_free_run=cost_v(q[:n_est], simulated[:n_est]),
        rmse=rmse(q_val, one_step[n_est:]), r2_adj=r2_adjusted(q_val, one_step[n_est:], p),
        rmse_free_run=rmse(q_val, simulated[n_est:]), r2_adj_free_run=r2_adjusted(q_val, simulated[n_est:], p),
        n_parameters=p, n_estimation=n_est, n_validation=n_val, std_lags=sandwich.lags,
        std_inflation=float(np.sqrt(np.max(sandwich.variance_inflation[:3]))), start=best.name, starts=outcomes, erls=erls,
    )
