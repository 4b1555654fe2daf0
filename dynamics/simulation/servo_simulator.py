"""Simulator of the 4-DOF hobby-servo arm of the servo paper (Paiva et al.), with MPU6050-like sensors.

Each joint ``i`` is a position servo with a second-order plant (eq. 11 of the paper), the gravity load of
the links beyond it and a saturated drive::

    m_i q̈_i + b_i q̇_i + g_i(q) = sat(σ_i u_i − k_i q_i, ±τ_max,i)

``g(q)`` is the generalized gravity of :func:`dynamics.robots.servo_arm.servo_arm` computed by Pinocchio
(the paper's units are kept: ``m`` in kg stands for the chain's equivalent inertia). Defaults
(:data:`PAPER_JOINTS`) are the paper's Table 1. The drive saturates at ``τ_max = b · v_max``, so that a large
step slews at the servo's rated speed ``v_max`` (5.2 rad/s, a 0.2 s/60° hobby servo). Integration is RK4 with
``substeps`` steps per sample, the command held over the sample (zero-order hold).

Sensors at the sample time (10 ms): gyro rate ``ω = q̇ + bias + noise`` with a random-walk bias, and an
accelerometer-derived angle ``q + noise`` (white; the base yaw ``ρ`` stands for the odometry the paper
uses there). The reported angle ``q`` is the Kalman fusion of both (eqs. 1–8, :mod:`dynamics.kalman`).

Examples
--------
>>> import numpy as np
>>> from dynamics.simulation.servo_simulator import simulate_servo_arm
>>> t = np.arange(200) * 0.01
>>> u = np.tile([0.0, 1.2, 2.0, 2.5], (200, 1))
>>> record = simulate_servo_arm(t, u, seed=0)
>>> record.q.shape, record.gyro.shape
((200, 4), (200, 4))
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike

from dynamics.robots.servo_arm import SERVO_ARM_MASSES, SERVO_ARM_RANGES
from dynamics.kalman import kalman_fusion
from dynamics.signal_checks import check_in_ranges, check_uniform_time


@dataclass(frozen=True)
class ServoJoint:
    """One joint's plant: mass ``mass`` [kg], damping ``b``, stiffness ``k``, input gain ``sigma`` (paper units)."""

    mass: float
    b: float
    k: float
    sigma: float


PAPER_JOINTS: tuple[ServoJoint, ...] = tuple(
    ServoJoint(mass=m, b=b, k=k, sigma=s)
    for m, b, k, s in zip(SERVO_ARM_MASSES, (19.1138, 2.4919, 6.5824, 2.3477), (1778.9, 114.0636, 113.2759, 41.9973), (1801.6, 106.5490, 118.6264, 33.7255))
)


@dataclass(frozen=True)
class SensorModel:
    """MPU6050-like noise levels: gyro white noise [rad/s], initial bias spread [rad/s], bias random walk per
    sample [rad/s], accelerometer-angle white noise [rad]."""

    gyro_noise: float = 0.01
    gyro_bias_initial: float = 0.03
    gyro_bias_walk: float = 2e-4
    acc_noise: float = 0.03


@dataclass(frozen=True)
class ServoArmRecord:
    """A simulated experiment: ``t`` (N,), ``u``, fused ``q``, true ``q_true``/``dq_true``, raw ``gyro``, ``acc_angle``,
    true ``gyro_bias`` — every array (N, joints), angles in rad, rates in rad/s."""

    t: np.ndarray
    u: np.ndarray
    q: np.ndarray
    q_true: np.ndarray
    dq_true: np.ndarray
    gyro: np.ndarray
    acc_angle: np.ndarray
    gyro_bias: np.ndarray = field(repr=False)


class _Gravity:
    def __init__(self) -> None:
        import pinocchio

        from dynamics.pinocchio_bridge import to_pinocchio
        from dynamics.robots.servo_arm import servo_arm

        self._pin = pinocchio
        self._model = to_pinocchio(servo_arm())
        self._data = self._model.createData()

    def __call__(self, q: np.ndarray) -> np.ndarray:
        return np.asarray(self._pin.computeGeneralizedGravity(self._model, self._data, q))


def simulate_servo_arm(
    t: ArrayLike, u: ArrayLike, *, joints: tuple[ServoJoint, ...] = PAPER_JOINTS, sensors: SensorModel = SensorModel(),
    max_speed: float = 5.2, gravity: bool = True, substeps: int = 5, kalman_q: tuple[float, float] = (1e-5, 1e-8),
    kalman_r: float | None = None, ranges: tuple[tuple[float, float], ...] = SERVO_ARM_RANGES, seed: int | None = None,
) -> ServoArmRecord:
    """Simulate the servo arm driven by ``u`` (N, 4) [rad] sampled at the uniform times ``t`` (N,) [s].

    Parameters
    ----------
    joints
        Plant parameters per joint (default: the paper's Table 1).
    sensors
        Noise levels of the simulated MPU6050s.
    max_speed
        Rated servo speed [rad/s]; the drive saturates at ``τ_max = b · max_speed``.
    gravity
        Include the gravity load ``g(q)`` of the links beyond each joint (Pinocchio).
    substeps
        RK4 steps per sample.
    kalman_q, kalman_r
        ``Q_d`` diagonal and ``R_d`` of the fusion (``R_d`` defaults to ``acc_noise²``).
    ranges
        Joint ranges the command must respect (the paper's, section 4.2).
    seed
        Seed of the sensor noise.

    Raises
    ------
    ValueError
        Non-uniform ``t``, wrong shape, or a command outside its joint range (names column, row and bound).
    """
    t = np.asarray(t, dtype=float).reshape(-1)
    u = np.asarray(u, dtype=float)
    dt = check_uniform_time(t)
    if dt >= 1.0:
        raise ValueError(f"the time column advances by {dt:g} a sample: t must be in seconds (milliseconds given?)")
    if u.ndim != 2 or u.shape[0] != t.size:
        raise ValueError(f"u must have shape ({t.size}, {len(joints)}), got {u.shape}")
    check_in_ranges(u, ranges)
    if len(joints) != u.shape[1]:
        raise ValueError(f"{len(joints)} joint plants for {u.shape[1]} input columns")
    if not max_speed > 0:
        raise ValueError(f"max_speed must be positive, got {max_speed}")
    if not (isinstance(substeps, int) and substeps >= 1):
        raise ValueError(f"substeps must be a positive integer, got {substeps!r}")
    mass = np.array([j.mass for j in joints])
    b = np.array([j.b for j in joints])
    k = np.array([j.k for j in joints])
    sigma = np.array([j.sigma for j in joints])
    tau_max = b * max_speed
    load = _Gravity() if gravity else (lambda q: np.zeros_like(q))

    def acceleration(q: np.ndarray, dq: np.ndarray, command: np.ndarray) -> np.ndarray:
        drive = np.minimum(np.maximum(sigma * command - k * q, -tau_max), tau_max)  # np.clip's values, at half its cost
        return (drive - b * dq - load(q)) / mass

    n, n_joints = u.shape
    q_true, dq_true = np.zeros((n, n_joints)), np.zeros((n, n_joints))
    q, dq = sigma * u[0] / k, np.zeros(n_joints)
    h = dt / substeps
    for i in range(n):
        q_true[i], dq_true[i] = q, dq
        command = u[i]
        for _ in range(substeps):
            k1q, k1v = dq, acceleration(q, dq, command)
            k2q, k2v = dq + 0.5 * h * k1v, acceleration(q + 0.5 * h * k1q, dq + 0.5 * h * k1v, command)
            k3q, k3v = dq + 0.5 * h * k2v, acceleration(q + 0.5 * h * k2q, dq + 0.5 * h * k2v, command)
            k4q, k4v = dq + h * k3v, acceleration(q + h * k3q, dq + h * k3v, command)
            q = q + h / 6 * (k1q + 2 * k2q + 2 * k3q + k4q)
            dq = dq + h / 6 * (k1v + 2 * k2v + 2 * k3v + k4v)
        if not np.all(np.isfinite(q)):
            raise ValueError(f"simulation diverged at row {i} (check the plant parameters and substeps)")
    rng = np.random.default_rng(seed)
    bias = sensors.gyro_bias_initial * rng.standard_normal(n_joints) + np.cumsum(sensors.gyro_bias_walk * rng.standard_normal((n, n_joints)), axis=0)
    gyro = dq_true + bias + sensors.gyro_noise * rng.standard_normal((n, n_joints))
    acc_angle = q_true + sensors.acc_noise * rng.standard_normal((n, n_joints))
    r = sensors.acc_noise**2 if kalman_r is None else kalman_r
    fused = np.column_stack([kalman_fusion(gyro[:, j], acc_angle[:, j], dt=dt, q=kalman_q, r=r).angle for j in range(n_joints)])
    return ServoArmRecord(t=t, u=u, q=fused, q_true=q_true, dq_true=dq_true, gyro=gyro, acc_angle=acc_angle, gyro_bias=bias)
