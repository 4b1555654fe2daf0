"""Kalman fusion of a gyroscope and an accelerometer-derived angle, per joint (servo paper eqs. 1–8).

State ``x = [θ, ḃ]`` (angle [rad], gyro bias [rad/s]); input the gyro rate ``ω`` [rad/s]; measurement the
accelerometer angle [rad] (the paper uses °/s; this toolkit uses SI units throughout)::

    x(n) = A x(n−1) + B ω(n) + w(n),   A = [[1, −T], [0, 1]],  B = [T, 0]ᵀ        (eq. 1)
    y(n) = C x(n) + v(n),              C = [1, 0]                                  (eq. 2)
    x̂⁻ = A x̂ + B ω;  P⁻ = A P Aᵀ + Q;  K = P⁻Cᵀ (C P⁻ Cᵀ + R)⁻¹                  (eqs. 4–6)
    x̂ = x̂⁻ + K (y − C x̂⁻);  P = (I − K C) P⁻                                      (eqs. 7–8)

The step is a named ``casadi.Function`` evaluated over the record with ``mapaccum``.

Examples
--------
>>> import numpy as np
>>> from dynamics.kalman import kalman_fusion
>>> t = np.arange(0, 10, 0.01); angle = np.sin(t)
>>> fused = kalman_fusion(np.cos(t) + 0.05, angle + 0.02 * np.random.default_rng(0).standard_normal(t.size), dt=0.01)
>>> bool(abs(fused.bias[-1] - 0.05) < 0.02)
True
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import casadi
import numpy as np
from numpy.typing import ArrayLike

from dynamics.signal_checks import single_channel


@dataclass(frozen=True)
class FusionResult:
    """Kalman fusion of one joint: fused ``angle`` [rad], estimated gyro ``bias`` [rad/s], final covariance ``P``."""

    angle: np.ndarray
    bias: np.ndarray
    P: np.ndarray
    q: tuple[float, float]
    r: float


@functools.cache
def kalman_step_function() -> casadi.Function:
    """Eqs. 4–8 as ``casadi.Function`` ``kalman_gyro_acc_step``: ``(x, P, omega, y, dt, q, r) -> (x_next, P_next)``.

    ``P`` is passed column-major as a 4-vector, ``q`` holds the diagonal of ``Q_d``.
    """
    x = casadi.SX.sym("x", 2)
    p = casadi.SX.sym("P", 4)
    omega, y, dt, r = casadi.SX.sym("omega"), casadi.SX.sym("y"), casadi.SX.sym("dt"), casadi.SX.sym("r")
    q = casadi.SX.sym("q", 2)
    A = casadi.vertcat(casadi.horzcat(1, -dt), casadi.horzcat(0, 1))
    B = casadi.vertcat(dt, 0)
    C = casadi.horzcat(1, 0)
    P = casadi.reshape(p, 2, 2)
    x_pred = casadi.mtimes(A, x) + B * omega                                   # eq. 4
    P_pred = casadi.mtimes([A, P, A.T]) + casadi.diag(q)                       # eq. 5
    K = casadi.mtimes(P_pred, C.T) / (casadi.mtimes([C, P_pred, C.T]) + r)     # eq. 6
    x_next = x_pred + K * (y - casadi.mtimes(C, x_pred))                       # eq. 7
    P_next = casadi.mtimes(casadi.DM.eye(2) - casadi.mtimes(K, C), P_pred)     # eq. 8
    return casadi.Function(
        "kalman_gyro_acc_step", [casadi.vertcat(x, p), omega, y, dt, q, r], [casadi.vertcat(x_next, casadi.vec(P_next))],
        ["xP", "omega", "y", "dt", "q", "r"], ["xP_next"],
    )


@functools.lru_cache(maxsize=32)
def _kalman_run(n_samples: int) -> casadi.Function:
    return kalman_step_function().mapaccum("kalman_gyro_acc", n_samples, ["xP"], ["xP_next"])


def kalman_fusion(
    gyro: ArrayLike, acc_angle: ArrayLike, *, dt: float, q: tuple[float, float] = (1e-5, 1e-8), r: float = 1e-3,
    x0: tuple[float, float] | None = None, p0: float = 1.0,
) -> FusionResult:
    """Fuse a gyro rate and an accelerometer angle of one joint (eqs. 1–8).

    Parameters
    ----------
    gyro
        Gyro rate ``ω(n)`` [rad/s] (bias included).
    acc_angle
        Accelerometer-derived angle ``y(n)`` [rad].
    dt
        Sample time ``T`` [s].
    q
        Diagonal of the process covariance ``Q_d``: angle [rad²] and bias [(rad/s)²] per sample.
    r
        Measurement covariance ``R_d`` [rad²].
    x0
        Initial ``(angle, bias)``; default ``(acc_angle[0], 0)``.
    p0
        Initial covariance ``P(0) = p0 I``.
    """
    gyro, acc = single_channel(gyro, "gyro"), single_channel(acc_angle, "acc_angle")
    if gyro.size != acc.size:
        raise ValueError(f"gyro has {gyro.size} samples but acc_angle has {acc.size}")
    if gyro.size == 0:
        raise ValueError("kalman_fusion needs at least one sample")
    if not (np.all(np.isfinite(gyro)) and np.all(np.isfinite(acc))):
        raise ValueError("gyro or acc_angle holds NaN/inf")
    if not (np.isfinite(dt) and dt > 0):
        raise ValueError(f"dt must be positive, got {dt}")
    q = tuple(float(v) for v in q)
    if len(q) != 2 or not (np.all(np.isfinite(q)) and min(q) >= 0 and np.isfinite(r) and r > 0):
        raise ValueError(f"Q diagonal must be two non-negative numbers and R positive, got q={q}, r={r}")
    if not (np.isfinite(p0) and p0 > 0):
        raise ValueError(f"p0 (initial covariance scale) must be positive, got {p0}")
    start = np.array([acc[0], 0.0] if x0 is None else x0, dtype=float).reshape(-1)
    if start.shape != (2,) or not np.all(np.isfinite(start)):
        raise ValueError(f"x0 must be two finite numbers (angle, bias), got {start.tolist()}")
    xp0 = np.concatenate((start, (p0 * np.eye(2)).reshape(-1)))
    out = np.asarray(_kalman_run(gyro.size)(xp0, gyro.reshape(1, -1), acc.reshape(1, -1), dt, q, r))
    return FusionResult(angle=out[0].copy(), bias=out[1].copy(), P=out[2:, -1].reshape(2, 2, order="F"), q=q, r=float(r))


def integrated_gyro(gyro: ArrayLike, *, dt: float, angle0: float) -> np.ndarray:
    """Angle from integrating the gyro rate alone (drifts with the bias): ``θ(n) = θ0 + T Σ ω``."""
    gyro = np.asarray(gyro, dtype=float).reshape(-1)
    return angle0 + dt * np.cumsum(gyro)


@dataclass(frozen=True)
class FusionComparison:
    """RMSE [rad] against the true angle of the Kalman fusion, the accelerometer alone and the integrated gyro."""

    rmse_fused: float
    rmse_accelerometer: float
    rmse_integrated_gyro: float


def compare_fusion(
    gyro: ArrayLike, acc_angle: ArrayLike, true_angle: ArrayLike, *, dt: float, q: tuple[float, float] = (1e-5, 1e-8), r: float = 1e-3,
) -> FusionComparison:
    """Score the fusion (eqs. 1–8) against accelerometer-only angles and the integrated gyro (simulation only:
    needs the true angle)."""
    truth = np.asarray(true_angle, dtype=float).reshape(-1)
    acc = np.asarray(acc_angle, dtype=float).reshape(-1)
    if truth.size != acc.size:
        raise ValueError(f"true_angle has {truth.size} samples but acc_angle has {acc.size}")
    fused = kalman_fusion(gyro, acc, dt=dt, q=q, r=r).angle
    gyro_only = integrated_gyro(gyro, dt=dt, angle0=float(acc[0]))
    rms = lambda estimate: float(np.sqrt(np.mean((estimate - truth) ** 2)))  # noqa: E731
    return FusionComparison(rmse_fused=rms(fused), rmse_accelerometer=rms(acc), rmse_integrated_gyro=rms(gyro_only))
