"""The second-order joint model of the servo-arm paper (Paiva et al., eqs. 10–14) and its gray-box mapping.

Continuous model (eq. 11), one joint, ``m`` the measured mass of the link chain [kg], ``q`` the joint
angle [rad], ``u`` the servo command [rad]::

    m q̈ + b q̇ + k q = σ u

Discretisation (eq. 12/13). With the difference quotients ``q̇(n) ≈ (q(n) − q(n−1))/T`` and
``q̈(n) ≈ (q(n) − 2q(n−1) + q(n−2))/T²`` (the paper calls this forward Euler; the quotients end at
sample ``n``, so strictly it is the *backward* difference, which is what eq. 13 is)::

    D q(n) = (2 + bT/m) q(n−1) − q(n−2) + (σT²/m) u(n),   D = 1 + bT/m + kT²/m        (eq. 13)

Eq. 14 writes the same structure as ``G(z⁻¹) = K z⁻¹ / (1 + a1 z⁻¹ + a2 z⁻²)``: it applies the input with
a one-sample delay, whereas eq. 13 uses ``u(n)``. **Decision:** this toolkit uses eq. 14's delay,
``q(n) = −a1 q(n−1) − a2 q(n−2) + K u(n−1)`` (a command written at sample ``n`` cannot move the angle read
at the same instant; it is also the regressor of eq. 25). Then, matching coefficients::

    a1 = −(2 + bT/m)/D,   a2 = 1/D,   K = σT²/(m D)

and the inverse, in closed form, given the measured mass ``m``::

    b = −m (a1 + 2 a2) / (a2 T)
    k =  m (1 + a1 + a2) / (a2 T²)
    σ =  m K / (a2 T²)

(so that ``σ/k = K/(1 + a1 + a2)``, the static gain, as it must). Only ``b/m``, ``k/m`` and ``σ/m``
are identifiable: the mass fixes the scale, nothing more.

Against the paper's eqs. 27–29 (with ``θ[1] = a1``, ``θ[2] = a2``, ``θ[3] = K`` as eq. 26 defines them):

* eq. 27: its numerator ``(1 − θ2)θ1 + (θ1 + 2)θ2 = θ1 + 2θ2`` matches ours, but its denominator
  ``(θ1 T − q(n)) θ2`` contains the measured angle ``q(n)`` and lacks the mass; ours is ``−a2 T / m``.
  It is not dimensionally consistent (b in N·m·s/rad would depend on the current angle).
* eq. 28: ``k = −m/(θ1 T²) (θ1 + 2 + b q(n))`` divides by ``θ1`` instead of ``θ2``, drops the ``θ2``
  term of ``1 + a1 + a2`` and adds ``b q(n)`` (again the angle, and not even in the same unit).
* eq. 29: ``σ = m θ3/T² ((1 + kT²)/m + bT/m)`` has a misplaced bracket: ``1/m`` instead of ``1``;
  with the bracket fixed it is ``σ = m K D / T²``, i.e. ours (as ``D = 1/a2``).
* eq. 26 also divides the noise coefficient ``c`` by ``D``, which has no counterpart in eq. 13.
* Table 1 reports V ≈ 10⁻² rad² on estimation data but Ω ≈ 10⁻⁵ rad on validation (Ω² ≈ 10⁻¹⁰):
  three orders of magnitude apart once squared, which no second-order fit explains.
``tests/test_servo_model.py`` checks these statements numerically.

Examples
--------
>>> from estimation.servo.model import gray_box_to_discrete, discrete_to_gray_box
>>> a1, a2, K = gray_box_to_discrete(b=19.1138, k=1778.9, sigma=1801.6, mass=0.294, dt=0.01)
>>> round(discrete_to_gray_box(a1, a2, K, mass=0.294, dt=0.01).k, 1)
1778.9
"""

from __future__ import annotations

import functools
from dataclasses import dataclass
from typing import Literal

import casadi
import numpy as np
from numpy.typing import ArrayLike


Discretisation = Literal["backward-euler", "zoh"]


@dataclass(frozen=True)
class GrayBoxParameters:
    """Physical parameters of one joint (eq. 11): damping ``b`` [N·m·s/rad], stiffness ``k`` [N·m/rad],
    input gain ``sigma`` [N·m/rad], mass ``mass`` [kg] (the paper's units)."""

    b: float
    k: float
    sigma: float
    mass: float


@functools.cache
def joint_step_function() -> casadi.Function:
    """Eq. 13 with eq. 14's input delay as a named ``casadi.Function`` ``servo_joint_step``.

    Inputs ``q1 = q(n−1)``, ``q2 = q(n−2)``, ``u1 = u(n−1)``, ``b``, ``k``, ``sigma``, ``mass``, ``dt``;
    output ``q = q(n)`` [rad].
    """
    q1, q2, u1, b, k, sigma, mass, dt = (casadi.SX.sym(name) for name in ("q1", "q2", "u1", "b", "k", "sigma", "mass", "dt"))
    d = 1 + b * dt / mass + k * dt**2 / mass
    q = ((b * dt / mass + 2) * q1 - q2 + sigma * dt**2 / mass * u1) / d
    return casadi.Function(
        "servo_joint_step", [q1, q2, u1, b, k, sigma, mass, dt], [q],
        ["q1", "q2", "u1", "b", "k", "sigma", "mass", "dt"], ["q"],
    )


@functools.cache
def gray_box_to_discrete_function() -> casadi.Function:
    """``servo_gray_box_to_discrete``: ``(b, k, sigma, mass, dt) -> (a1, a2, K)`` of eq. 14 (derived from eq. 13)."""
    b, k, sigma, mass, dt = (casadi.SX.sym(name) for name in ("b", "k", "sigma", "mass", "dt"))
    d = 1 + b * dt / mass + k * dt**2 / mass
    return casadi.Function(
        "servo_gray_box_to_discrete", [b, k, sigma, mass, dt],
        [-(2 + b * dt / mass) / d, 1 / d, sigma * dt**2 / (mass * d)],
        ["b", "k", "sigma", "mass", "dt"], ["a1", "a2", "K"],
    )


@functools.cache
def free_run_step_function() -> casadi.Function:
    """``servo_free_run_step``: state ``x = [q(n−1), q(n−2)]``, input ``u(n−1)``, coefficients ``c = [a1, a2, K]``.

    Outputs the next state and ``q(n)`` (eq. 14 as a recursion), ready for ``mapaccum``.
    """
    x = casadi.SX.sym("x", 2)
    u1 = casadi.SX.sym("u1")
    c = casadi.SX.sym("c", 3)
    q = -c[0] * x[0] - c[1] * x[1] + c[2] * u1
    return casadi.Function("servo_free_run_step", [x, u1, c], [casadi.vertcat(q, x[0]), q], ["x", "u1", "c"], ["x_next", "q"])


@functools.lru_cache(maxsize=64)
def _free_run_map(n_samples: int) -> casadi.Function:
    return free_run_step_function().mapaccum("servo_free_run", n_samples, ["x"], ["x_next"])


def gray_box_to_discrete(*, b: float, k: float, sigma: float, mass: float, dt: float) -> tuple[float, float, float]:
    """Coefficients ``(a1, a2, K)`` of eq. 14 from the physical parameters (coefficient matching with eq. 13)."""
    _check_mass_dt(mass, dt)
    out = gray_box_to_discrete_function()(b, k, sigma, mass, dt)
    return float(out[0]), float(out[1]), float(out[2])


def discrete_to_gray_box(
    a1: float, a2: float, K: float, *, mass: float, dt: float, discretisation: Discretisation = "backward-euler",
) -> GrayBoxParameters:
    """Gray-box recovery of ``b, k, σ`` from ``(a1, a2, K)`` and the measured mass (replaces eqs. 27–29).

    ``discretisation="backward-euler"`` inverts eq. 13 exactly: ``b = −m (a1 + 2a2)/(a2 T)``,
    ``k = m (1 + a1 + a2)/(a2 T²)``, ``σ = m K/(a2 T²)`` (module docstring: derivation, and what is wrong
    with the paper's eqs. 27–29). Eq. 13 is only a first-order-accurate discretisation: for a *continuous*
    plant with ``ω_n T`` not small (0.78 for the paper's joint 1 at 10 ms) it misreads ``b`` and ``k``: for
    Table 1's joints sampled (zero-order hold) at 10 ms it returns ``k`` 5–34 % too high and ``b`` anywhere from
    84 % too low to 5 % too high. ``discretisation="zoh"`` maps the discrete poles instead, ``s_i = ln(z_i)/T``, so that
    ``b/m = −(s1 + s2)``, ``k/m = s1 s2`` (exact for the poles of a sampled continuous plant), and keeps the
    static gain, ``σ = k K/(1 + a1 + a2)``.

    Raises
    ------
    ValueError
        If ``a2`` is zero (``D = 1/a2`` infinite), or, for ``"zoh"``, if a pole is on the non-positive real
        axis (no continuous counterpart).
    """
    _check_mass_dt(mass, dt)
    if a2 == 0.0 or not np.isfinite(a2):
        raise ValueError(f"gray-box mapping needs a2 != 0 (a2 = 1/D of eq. 13), got a2={a2!r}")
    if discretisation == "backward-euler":
        b = -mass * (a1 + 2 * a2) / (a2 * dt)
        k = mass * (1 + a1 + a2) / (a2 * dt**2)
        sigma = mass * K / (a2 * dt**2)
    elif discretisation == "zoh":
        poles = np.roots([1.0, a1, a2]).astype(complex)
        if np.any((np.abs(poles.imag) < 1e-12) & (poles.real <= 0)):
            raise ValueError(f"pole(s) {poles} on the non-positive real axis: no continuous second-order counterpart")
        s = np.log(poles) / dt
        b = mass * float(-(s[0] + s[1]).real)
        k = mass * float((s[0] * s[1]).real)
        if 1 + a1 + a2 == 0:
            raise ValueError("a pole at z = 1: the static gain (and sigma) is undefined")
        sigma = k * K / (1 + a1 + a2)
    else:
        raise ValueError(f"discretisation must be 'backward-euler' or 'zoh', got {discretisation!r}")
    return GrayBoxParameters(b=float(b), k=float(k), sigma=float(sigma), mass=float(mass))


def free_run(coefficients: ArrayLike, u: ArrayLike, q_initial: ArrayLike, *, u_initial: float = 0.0) -> np.ndarray:
    """Free-run simulation of eq. 14: ``q(n) = −a1 q(n−1) − a2 q(n−2) + K u(n−1)``, for ``n = 0 … N−1``.

    Parameters
    ----------
    coefficients
        ``(a1, a2, K)``.
    u
        Input samples ``u(0) … u(N−1)`` [rad], aligned with the output samples (``u(n)`` acts on ``q(n+1)``).
    q_initial
        ``(q(−1), q(−2))``: the two angles before the first simulated sample.
    u_initial
        ``u(−1)``, the input before the first sample (acts on ``q(0)``).

    Returns
    -------
    numpy.ndarray
        ``q(0) … q(N−1)``, shape ``(N,)`` — from the model alone, never reset to measurements.
    """
    u = np.asarray(u, dtype=float).reshape(-1)
    x0 = np.asarray(q_initial, dtype=float).reshape(2)
    c = np.asarray(coefficients, dtype=float).reshape(3)
    if u.size == 0:
        return np.zeros(0)
    delayed = np.concatenate(([float(u_initial)], u[:-1]))
    _, q = _free_run_map(int(u.size))(x0, delayed.reshape(1, -1), c)
    return np.asarray(q).reshape(-1)


def _check_mass_dt(mass: float, dt: float) -> None:
    if not (np.isfinite(mass) and mass > 0):
        raise ValueError(f"mass must be positive and finite, got {mass!r}")
    if not (np.isfinite(dt) and dt > 0):
        raise ValueError(f"dt must be positive and finite, got {dt!r}")
