"""Identification protocol of the servo paper (section 4.3 and 5): per-joint second-order fit, gray-box
mapping, and the Table-1 metrics on an estimation/validation split.

Per joint: means removed (eq. 16, computed on the estimation part only and applied to both parts), the
first ``estimation_fraction`` of the record estimates ``q(n) = −a1 q(n−1) − a2 q(n−2) + K u(n−1)`` (eq. 14,
plus ``C(z)`` noise terms for ERLS, eq. 22), the rest validates. Reported, labelled:

* ``V`` (eq. 18): one-step-ahead mean squared error on the estimation part;
* ``rmse``, ``r2_adj`` (eqs. 20–21): **one-step-ahead prediction** on the validation part;
* ``rmse_free_run``, ``r2_adj_free_run``: **free-run simulation** of eq. 14 over the validation part,
  started from the two measured angles before it and never reset — the honest figure (one-step R² flatters).

Examples
--------
>>> import numpy as np
>>> from estimation.servo.protocol import fit_servo_arm
>>> from estimation.servo.model import free_run, gray_box_to_discrete
>>> u = np.repeat(np.random.default_rng(0).uniform(-1, 1, 100), 30)
>>> q = free_run(gray_box_to_discrete(b=2.5, k=114.0, sigma=106.5, mass=0.239, dt=0.01), u, (0.0, 0.0))
>>> fit = fit_servo_arm(np.arange(u.size) * 0.01, u[:, None], q[:, None], masses=(0.239,), method="ls", remove_mean=False)
>>> round(fit.joints[0].k, 3)
114.0
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import asdict, dataclass
from typing import Literal, NoReturn

import numpy as np
from numpy.typing import ArrayLike

from estimation.estimators.arx import ARXEstimator, Polynomials
from estimation.estimators.metrics import cost_v, r2_adjusted, rmse
from estimation.estimators.recursive import Backend, ExtendedRecursiveLeastSquares, RecursiveLeastSquares
from estimation.servo.model import Discretisation, discrete_to_gray_box, free_run
from dynamics.signal_checks import check_uniform_time

Method = Literal["erls", "rls", "ls"]
METHODS: tuple[str, ...] = ("erls", "rls", "ls")


@dataclass(frozen=True)
class ServoJointFit:
    """One joint's identified model and metrics (Table 1 of the paper, plus free-run figures).

    ``b, k, sigma`` are ``None`` when no mass was given (only ``a1, a2, K`` are then identified).
    """

    joint: int
    method: str
    a1: float
    a2: float
    K: float
    c: tuple[float, ...]
    mass: float | None
    b: float | None
    k: float | None
    sigma: float | None
    V: float
    rmse: float
    r2_adj: float
    rmse_free_run: float
    r2_adj_free_run: float
    n_parameters: int
    n_estimation: int
    n_validation: int


@dataclass(frozen=True)
class ServoArmFit:
    """All joints' fits, the sample time and the protocol settings."""

    joints: tuple[ServoJointFit, ...]
    dt: float
    method: str
    estimation_fraction: float

    def to_dict(self) -> dict:
        """JSON-ready dictionary: ``{"joints": {"1": {b, k, sigma, a1, a2, K, rmse, r2_adj, r2_adj_free_run, ...}}, ...}``."""
        return {
            "dt": self.dt,
            "method": self.method,
            "estimation_fraction": self.estimation_fraction,
            "labels": {
                "V": "eq. 18, one-step-ahead MSE on the estimation part [rad^2]",
                "rmse": "eq. 20, one-step-ahead prediction on the validation part [rad]",
                "r2_adj": "eq. 21, one-step-ahead prediction on the validation part",
                "rmse_free_run": "free-run simulation of eq. 14 on the validation part [rad]",
                "r2_adj_free_run": "eq. 21, free-run simulation on the validation part",
            },
            "joints": {str(j.joint): {**asdict(j), "c": list(j.c)} for j in self.joints},
        }

    def table(self) -> str:
        """A plain-text table shaped like the paper's Table 1."""
        rows = [("m (kg)", "mass"), ("b (Nm/(rad/s))", "b"), ("k (Nm/rad)", "k"), ("sigma (N/rad)", "sigma"),
                ("a1", "a1"), ("a2", "a2"), ("K", "K"), ("V (estimation, 1-step)", "V"),
                ("RMSE (validation, 1-step)", "rmse"), ("R2adj (validation, 1-step)", "r2_adj"),
                ("RMSE (validation, free run)", "rmse_free_run"), ("R2adj (validation, free run)", "r2_adj_free_run")]
        header = f"{'parameter / criterion':32s}" + "".join(f"{'joint ' + str(j.joint):>14s}" for j in self.joints)
        lines = [header, "-" * len(header)]
        for label, key in rows:
            values = [getattr(j, key) for j in self.joints]
            lines.append(f"{label:32s}" + "".join(f"{'—':>14s}" if v is None else f"{v:14.5g}" for v in values))
        return "\n".join(lines)


def _estimator(method: str, *, nc: int, forgetting: float, backend: Backend):
    if method == "ls":
        return ARXEstimator(na=2, nb=1, nk=1)
    if method == "rls":
        return RecursiveLeastSquares(na=2, nb=1, nk=1, forgetting=forgetting, backend=backend)
    if method == "erls":
        return ExtendedRecursiveLeastSquares(na=2, nb=1, nc=nc, nk=1, forgetting=forgetting, backend=backend)
    raise ValueError(f"method must be one of {METHODS}, got {method!r}")


def fit_servo_joint(
    u: ArrayLike, q: ArrayLike, *, dt: float, mass: float | None = None, joint: int = 1, method: Method = "erls",
    estimation_fraction: float = 0.8, nc: int = 1, forgetting: float = 1.0, remove_mean: bool = True,
    backend: Backend = "compiled", discretisation: Discretisation = "backward-euler",
) -> ServoJointFit:
    """Identify one joint (eq. 14, ERLS/RLS/LS), map to ``b, k, σ`` with ``mass`` and compute the metrics.

    Parameters
    ----------
    u, q
        Command and measured (fused) angle of the joint [rad], uniformly sampled at ``dt`` [s].
    mass
        Measured mass [kg] for the gray-box mapping (:func:`estimation.servo.model.discrete_to_gray_box`).
    method
        ``"erls"`` (ARMAX by extended RLS, the paper's), ``"rls"`` (ARX, recursive) or ``"ls"`` (ARX, batch).
    estimation_fraction
        Leading fraction of the record used to estimate (the paper: 0.8); the rest validates.
    nc
        Order of ``C(z)`` for ERLS.
    forgetting
        Forgetting factor of RLS/ERLS.
    remove_mean
        Remove the estimation part's means of ``u`` and ``q`` (eq. 16).
    discretisation
        Gray-box mapping: ``"backward-euler"`` (exact inverse of eq. 13, default) or ``"zoh"`` (pole mapping,
        closer to a continuous plant's ``b, k`` when ``ω_n T`` is not small).
    """
    u = np.asarray(u, dtype=float).reshape(-1)
    q = np.asarray(q, dtype=float).reshape(-1)
    if u.size != q.size:
        raise ValueError(f"joint {joint}: u has {u.size} samples but q has {q.size}")
    if not 0.0 < estimation_fraction < 1.0:
        raise ValueError(f"estimation_fraction must be in (0, 1), got {estimation_fraction!r}")
    n_est = int(round(estimation_fraction * u.size))
    n_val = u.size - n_est
    if n_est < 20 or n_val < 10:
        raise ValueError(f"joint {joint}: {u.size} samples give {n_est} for estimation and {n_val} for validation: too few")
    if remove_mean:
        u = u - u[:n_est].mean()
        q = q - q[:n_est].mean()
    try:
        model = _estimator(method, nc=nc, forgetting=forgetting, backend=backend).fit(u[:n_est], q[:n_est])
    except ValueError as error:  # name the joint, keep the type (RecursionDivergedError…)
        try:
            renamed = type(error)(f"joint {joint}: {error}")
        except TypeError:
            renamed = ValueError(f"joint {joint}: {error}")
        raise renamed from error
    theta = np.asarray(model.theta_)
    a1, a2, K = (float(v) for v in theta[:3])
    c = tuple(float(v) for v in theta[3:])
    if c and np.max(np.abs(np.roots(np.r_[1.0, c]))) >= 1.0:  # the predictor filters by 1/C(z)
        _diverged(joint, "one-step predictor", "C(z)", c, method, forgetting)
    if np.max(np.abs(np.roots([1.0, a1, a2]))) >= 1.0:  # the simulation filters by K/A(z)
        _diverged(joint, "free-run simulation", "A(z)", (a1, a2), method, forgetting)
    polys = Polynomials.from_theta(theta, 2, 1, 1, len(c))
    p = theta.size
    q_val = q[n_est:]
    with np.errstate(over="ignore", invalid="ignore"):  # divergence is reported below, by name
        one_step = polys.one_step_prediction(u, q)
        simulated = free_run((a1, a2, K), u[n_est:], (q[n_est - 1], q[n_est - 2]), u_initial=u[n_est - 1])
        one_step_metrics = (rmse(q_val, one_step[n_est:]), r2_adjusted(q_val, one_step[n_est:], p)) \
            if np.all(np.isfinite(one_step)) else (np.inf,)
        free_run_metrics = (rmse(q_val, simulated), r2_adjusted(q_val, simulated, p)) \
            if np.all(np.isfinite(simulated)) else (np.inf,)
    for what, metrics, polynomial, coefficients in (("one-step predictor", one_step_metrics, "C(z)", c),
                                                    ("free-run simulation", free_run_metrics, "A(z)", (a1, a2))):
        if not np.all(np.isfinite(metrics)):  # overflowed: JSON would get Infinity and the table -inf
            _diverged(joint, what, polynomial, coefficients, method, forgetting)
    V = cost_v(q[2:n_est], one_step[2:n_est])
    gray = None if mass is None else discrete_to_gray_box(a1, a2, K, mass=mass, dt=dt, discretisation=discretisation)
    return ServoJointFit(
        joint=joint, method=method, a1=a1, a2=a2, K=K, c=c, mass=None if mass is None else float(mass),
        b=None if gray is None else gray.b, k=None if gray is None else gray.k, sigma=None if gray is None else gray.sigma,
        V=V, rmse=one_step_metrics[0], r2_adj=one_step_metrics[1],
        rmse_free_run=free_run_metrics[0], r2_adj_free_run=free_run_metrics[1],
        n_parameters=p, n_estimation=n_est, n_validation=n_val,
    )


def _diverged(joint: int, what: str, polynomial: str, coefficients: Sequence[float], method: str,
              forgetting: float) -> NoReturn:
    """Raise the error of an estimated model whose predictor or simulation blows up (a root of
    ``polynomial`` on or outside the unit circle, or metrics that overflowed), instead of NaN/inf metrics."""
    modulus = float(np.max(np.abs(np.roots(np.r_[1.0, coefficients])))) if len(coefficients) else float("nan")
    cause = (f"{polynomial} has a root of modulus {modulus:.4g} (not inside the unit circle)" if modulus >= 1.0
             else f"its metrics overflowed ({polynomial}'s largest root modulus {modulus:.4g})")
    raise ValueError(
        f"joint {joint}: the {what} of the estimated model diverges: {cause} with method {method!r}, forgetting "
        f"factor {forgetting:g}; the estimate is not usable (use a forgetting factor closer to 1, more data, or another method)"
    )


def fit_servo_arm(
    t: ArrayLike, u: ArrayLike, q: ArrayLike, *, masses: tuple[float, ...] | None = None, method: Method = "erls",
    estimation_fraction: float = 0.8, nc: int = 1, forgetting: float = 1.0, remove_mean: bool = True,
    backend: Backend = "compiled", dt: float | None = None, discretisation: Discretisation = "backward-euler",
) -> ServoArmFit:
    """Run :func:`fit_servo_joint` on every column of ``u``/``q`` (shape (N, joints)) sampled at times ``t``.

    ``dt`` is the expected sample time (default: the median step of ``t``); ``t`` must be uniform either way.

    Raises
    ------
    ValueError
        Non-uniform ``t`` (names the row), mismatched shapes, wrong number of masses, unknown method.
    """
    t = np.asarray(t, dtype=float).reshape(-1)
    u = np.atleast_2d(np.asarray(u, dtype=float))
    q = np.atleast_2d(np.asarray(q, dtype=float))
    dt = check_uniform_time(t, dt=dt)
    if u.shape != q.shape or u.shape[0] != t.size:
        raise ValueError(f"u {u.shape} and q {q.shape} must both have shape ({t.size}, joints)")
    if method not in METHODS:
        raise ValueError(f"method must be one of {METHODS}, got {method!r}")
    if masses is not None and len(masses) != u.shape[1]:
        raise ValueError(f"{len(masses)} masses given for {u.shape[1]} joints")
    fits = tuple(
        fit_servo_joint(
            u[:, j], q[:, j], dt=dt, mass=None if masses is None else masses[j], joint=j + 1, method=method,
            estimation_fraction=estimation_fraction, nc=nc, forgetting=forgetting, remove_mean=remove_mean, backend=backend,
            discretisation=discretisation,
        )
        for j in range(u.shape[1])
    )
    return ServoArmFit(joints=fits, dt=dt, method=method, estimation_fraction=estimation_fraction)
