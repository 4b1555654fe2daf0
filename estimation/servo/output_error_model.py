"""The continuous servo-joint model ``m q̈ + b q̇ + k q = σ u`` (eq. 11 of the servo paper) sampled exactly,
as CasADi graphs for the output-error fit (issue 17).

Per unit mass, ``θ = (b/m, k/m, σ/m)`` and the state ``x = (q, q̇)``::

    ẋ = A x + B u(t − τ),   A = [[0, 1], [−k/m, −b/m]],   B = [0, σ/m]ᵀ

with the command held between samples (zero-order hold, as a servo receives it) and an input delay
``τ = (l + f) T`` (``l`` whole samples, ``f ∈ [0, 1]`` a fraction of one). Over one sample the held,
delayed input is ``u(n − l − 1)`` for the first ``f T`` and ``u(n − l)`` for the rest, so the exact
discretisation is (Åström & Wittenmark, *Computer-Controlled Systems*, sec. 2.3, "systems with time delay")::

    x(n+1) = Φ x(n) + Γ0 u(n − l) + Γ1 u(n − l − 1),
    Φ = e^{AT},  Γ0 = ∫₀^{(1−f)T} e^{As} ds B,  Γ1 = e^{A(1−f)T} ∫₀^{fT} e^{As} ds B

and the angle read at sample ``n`` is ``q(n) = x1(n) + offset``. No approximation is made: ``f = 0`` is
the plain zero-order-hold model, which already delays the command by one sample as eq. 14 does.

**Matrix exponential.** ``[[e^{At}, ∫₀ᵗ e^{As}ds B], [0, 1]] = exp([[A, B], [0, 0]] t)``, computed in SX
(differentiable to any order) by scaling and squaring: the state is first balanced to ``(q, q̇/ω)`` with
``ω = √(k/m)`` (so the matrix norm is about ``ω_n T`` or ``bT/m``, not ``kT/m``), scaled by ``2⁻¹²``, expanded
to 12 Taylor terms and squared back 12 times on ``E − I`` (no loss of digits to the identity). For
``‖M t‖ ≤ 100`` the truncation error is below 1e-20; the fit keeps the parameters within 100× their start.
The result is checked against ``scipy.linalg.expm`` in ``tests/test_servo_output_error.py``.
"""

from __future__ import annotations

import functools

import casadi
import numpy as np

from dynamics.codegen.compiled import compile_function

_SQUARINGS = 12
_TAYLOR_TERMS = 12
#: samples per compiled block of the sensitivity recursion
CHUNK = 200


def _expm_minus_identity(m: casadi.SX) -> casadi.SX:
    """``exp(M) − I`` by Taylor expansion of ``M 2⁻ˢ`` and ``s`` squarings of ``I + X`` kept as ``X``."""
    scaled = m / 2.0**_SQUARINGS
    term = scaled
    x = scaled
    for order in range(2, _TAYLOR_TERMS + 1):
        term = casadi.mtimes(term, scaled) / order
        x = x + term
    for _ in range(_SQUARINGS):
        x = 2 * x + casadi.mtimes(x, x)
    return x


def _held_input_exponential(theta: casadi.SX, t: casadi.SX) -> tuple[casadi.SX, casadi.SX]:
    """``(e^{At}, ∫₀ᵗ e^{As} ds B)`` of the per-unit-mass model for a (symbolic) duration ``t``."""
    b, k, sigma = theta[0], theta[1], theta[2]
    omega = casadi.sqrt(k)
    # balanced coordinates z = D⁻¹ x, D = diag(1, ω): A_z = [[0, ω], [−ω, −b]], B_z = [0, σ/ω]
    augmented = casadi.SX.zeros(3, 3)
    augmented[0, 1] = omega
    augmented[1, 0] = -omega
    augmented[1, 1] = -b
    augmented[1, 2] = sigma / omega
    e = _expm_minus_identity(augmented * t) + casadi.SX.eye(3)
    scale = casadi.diag(casadi.vertcat(1, omega))
    inverse_scale = casadi.diag(casadi.vertcat(1, 1 / omega))
    phi = casadi.mtimes([scale, e[:2, :2], inverse_scale])
    gamma = casadi.mtimes(scale, e[:2, 2])
    return phi, gamma


@functools.cache
def zoh_function() -> casadi.Function:
    """``servo_zoh``: ``(theta = [b/m, k/m, σ/m], fraction f, dt) -> (phi 2×2, gamma 2×2 = [Γ0, Γ1])``.

    The exact sampled model of the module docstring (``k/m > 0``).
    """
    theta = casadi.SX.sym("theta", 3)
    fraction = casadi.SX.sym("fraction")
    dt = casadi.SX.sym("dt")
    phi_late, gamma_late = _held_input_exponential(theta, (1 - fraction) * dt)
    phi_early, gamma_early = _held_input_exponential(theta, fraction * dt)
    phi = casadi.mtimes(phi_late, phi_early)
    gamma = casadi.horzcat(gamma_late, casadi.mtimes(phi_late, gamma_early))
    return casadi.Function("servo_zoh", [theta, fraction, dt], [phi, gamma], ["theta", "fraction", "dt"], ["phi", "gamma"])


@functools.cache
def sampled_step_function() -> casadi.Function:
    """``servo_sampled_step``: ``x(n+1) = Φ x(n) + Γ [u(n − l), u(n − l − 1)]ᵀ``, output ``x(n)``."""
    x = casadi.SX.sym("x", 2)
    inputs = casadi.SX.sym("u", 2)
    phi = casadi.SX.sym("phi", 2, 2)
    gamma = casadi.SX.sym("gamma", 2, 2)
    x_next = casadi.mtimes(phi, x) + casadi.mtimes(gamma, inputs)
    return casadi.Function("servo_sampled_step", [x, inputs, phi, gamma], [x_next, x],
                           ["x", "u", "phi", "gamma"], ["x_next", "state"])


@functools.lru_cache(maxsize=32)
def simulation_function(n_samples: int, fused: bool = False) -> casadi.Function:
    """``servo_oe_simulation_<N>``: free run of the sampled model over ``N`` samples (``mapaccum``).

    Inputs ``theta`` (3), ``fraction``, ``x0 = (q0, dq0)`` (state at sample 0, without the offset),
    ``offset`` [rad], ``u`` (2 × N: row 0 ``u(n − l)``, row 1 ``u(n − l − 1)``), ``dt``, ``gains`` (2 × N,
    :func:`fusion_gains`, used when ``fused``); output ``q`` (1 × N): the angle, or with ``fused`` its Kalman
    fusion (:func:`fusion_filter_function`). Cached per sample count.
    """
    theta = casadi.MX.sym("theta", 3)
    fraction = casadi.MX.sym("fraction")
    x0 = casadi.MX.sym("x0", 2)
    offset = casadi.MX.sym("offset")
    u = casadi.MX.sym("u", 2, n_samples)
    dt = casadi.MX.sym("dt")
    gains = casadi.MX.sym("gains", 2, n_samples)
    phi, gamma = zoh_function()(theta, fraction, dt)
    run = sampled_step_function().mapaccum(f"servo_oe_run_{n_samples}", n_samples, ["x"], ["x_next"])
    _, x = run(x0, u, phi, gamma)
    q = fusion_filter_function(n_samples, 1)(x[0, :], x[1, :], gains, dt) if fused else x[0, :]
    return casadi.Function(f"servo_oe_simulation_{n_samples}", [theta, fraction, x0, offset, u, dt, gains], [q + offset],
                           ["theta", "fraction", "x0", "offset", "u", "dt", "gains"], ["q"])


def fusion_gains(n_samples: int, *, dt: float, q: tuple[float, float], r: float, p0: float = 1.0) -> np.ndarray:
    """Kalman gains ``K(n)`` (2 × N) of the gyro/accelerometer fusion (eqs. 4–8, :mod:`dynamics.kalman`).

    They depend on ``Q_d, R_d, P(0)`` and ``T`` only, never on the data: the fusion is a linear time-varying
    filter, so the fused angle of the model is the filter applied to the model's angle and rate. Computed once
    per setting (cached; read-only array); once the gain has settled to 1e-15 it is held.
    """
    return _fusion_gains(int(n_samples), float(dt), (float(q[0]), float(q[1])), float(r), float(p0))


@functools.lru_cache(maxsize=16)
def _fusion_gains(n_samples: int, dt: float, q: tuple[float, float], r: float, p0: float) -> np.ndarray:
    a = np.array([[1.0, -dt], [0.0, 1.0]])
    qd = np.diag(q)
    p = p0 * np.eye(2)
    gains = np.empty((2, n_samples))
    previous = np.full(2, np.inf)
    for n in range(n_samples):
        predicted = a @ p @ a.T + qd
        gain = predicted[:, 0] / (predicted[0, 0] + r)
        p = predicted - np.outer(gain, predicted[0, :])
        gains[:, n] = gain
        if np.all(np.abs(gain - previous) <= 1e-15 * np.maximum(np.abs(gain), 1e-300)):
            gains[:, n:] = gain[:, None]
            break
        previous = gain
    gains.setflags(write=False)
    return gains


@functools.lru_cache(maxsize=64)
def fusion_filter_function(n_samples: int, n_columns: int) -> casadi.Function:
    """``servo_fusion_<N>_<m>``: the Kalman fusion of :mod:`dynamics.kalman` (eqs. 4–7) with given gains,
    applied to ``m`` columns at once: inputs ``angle`` (m × N, the accelerometer's role), ``rate`` (m × N, the
    gyro's), ``gains`` (2 × N), ``dt``; output the fused angles (m × N). Started, like
    :func:`dynamics.kalman.kalman_fusion`, from ``(angle(0), 0)``. Linear in ``angle`` and ``rate``, so it
    carries sensitivities as well as values.
    """
    state = casadi.SX.sym("e", 2, n_columns)
    angle = casadi.SX.sym("angle", 1, n_columns)
    rate = casadi.SX.sym("rate", 1, n_columns)
    gain = casadi.SX.sym("gain", 2)
    dt = casadi.SX.sym("dt")
    predicted = casadi.vertcat(state[0, :] + dt * (rate - state[1, :]), state[1, :])
    updated = predicted + casadi.mtimes(gain, angle - predicted[0, :])
    step = casadi.Function("servo_fusion_step", [state, angle, rate, gain, dt], [updated, updated[0, :]],
                           ["e", "angle", "rate", "gain", "dt"], ["e_next", "fused"])
    run = step.mapaccum(f"servo_fusion_run_{n_samples}_{n_columns}", n_samples, ["e"], ["e_next"])
    angles = casadi.MX.sym("angle", n_columns, n_samples)
    rates = casadi.MX.sym("rate", n_columns, n_samples)
    gains = casadi.MX.sym("gains", 2, n_samples)
    step_dt = casadi.MX.sym("dt")
    start = casadi.vertcat(angles[:, 0].T, casadi.MX.zeros(1, n_columns))
    _, fused = run(start, _rows(angles), _rows(rates), gains, step_dt)
    return casadi.Function(f"servo_fusion_{n_samples}_{n_columns}", [angles, rates, gains, step_dt],
                           [casadi.reshape(fused, n_columns, n_samples)], ["angle", "rate", "gains", "dt"], ["fused"])


def _rows(matrix: casadi.MX) -> casadi.MX:
    """(m × N) -> (1 × m N), sample after sample (the layout ``mapaccum`` reads a (1 × m) input from)."""
    return casadi.reshape(matrix, 1, -1)


@functools.cache
def sensitivity_step_function() -> casadi.Function:
    """``servo_sensitivity_step``: one sample of the free run with its forward sensitivities, through the fusion.

    State ``s = [x (2), S (2×4, column-major), T (2×2), E (2×7, row-major)]``: ``S = ∂x/∂(w0..w3)`` (the four
    variables that enter ``Φ, Γ``), ``T = ∂x/∂x0 = Φⁿ``; ``x⁺ = Φx + Γv``, ``S⁺_j = Φ S_j + (∂Φ/∂w_j) x +
    (∂Γ/∂w_j) v``, ``T⁺ = ΦT``. The angle row ``a = [q, ∂q/∂w0..w3, ∂q/∂w4, ∂q/∂w5]`` and the rate row likewise
    drive the fusion filter ``E`` (eqs. 4–7 with the given gain ``K(n)``; ``K = (1, 0)`` passes the angle through
    unchanged), whose angle row is the output (7) of the current sample. Input ``v = [u(n−l), u(n−l−1), K(n)]``.
    """
    state = casadi.SX.sym("s", 28)
    v = casadi.SX.sym("v", 4)
    phi = casadi.SX.sym("phi", 2, 2)
    gamma = casadi.SX.sym("gamma", 2, 2)
    d_phi = casadi.SX.sym("d_phi", 2, 8)
    d_gamma = casadi.SX.sym("d_gamma", 2, 8)
    x_scale = casadi.SX.sym("x_scale", 2)
    dt = casadi.SX.sym("dt")
    x = state[:2]
    s = casadi.reshape(state[2:10], 2, 4)
    t = casadi.reshape(state[10:14], 2, 2)
    e_angle, e_bias = state[14:21], state[21:28]
    inputs, gain = v[:2], v[2:]
    angle = casadi.vertcat(x[0], s[0, :].T, x_scale[0] * t[0, 0], x_scale[1] * t[0, 1])
    rate = casadi.vertcat(x[1], s[1, :].T, x_scale[0] * t[1, 0], x_scale[1] * t[1, 1])
    predicted = e_angle + dt * (rate - e_bias)
    innovation = angle - predicted
    fused = predicted + gain[0] * innovation
    columns = [casadi.mtimes(phi, s[:, j]) + casadi.mtimes(d_phi[:, 2 * j:2 * j + 2], x)
               + casadi.mtimes(d_gamma[:, 2 * j:2 * j + 2], inputs) for j in range(4)]
    state_next = casadi.vertcat(casadi.mtimes(phi, x) + casadi.mtimes(gamma, inputs), *columns,
                                casadi.vec(casadi.mtimes(phi, t)), fused, e_bias + gain[1] * innovation)
    return casadi.Function("servo_sensitivity_step", [state, v, phi, gamma, d_phi, d_gamma, x_scale, dt],
                           [state_next, fused], ["s", "v", "phi", "gamma", "d_phi", "d_gamma", "x_scale", "dt"],
                           ["s_next", "out"])


@functools.cache
def sensitivity_chunk_function() -> casadi.Function:
    """``servo_sensitivity_chunk``: :func:`sensitivity_step_function` over ``CHUNK`` samples (``mapaccum``),
    returning the last state and every output; compiled to C once (``dynamics.codegen.compiled``, disk cache), so a
    record of any length runs as ``mapaccum`` over chunks without a per-sample virtual-machine call."""
    step = sensitivity_step_function()
    inner = step.mapaccum("servo_sensitivity_chunk_steps", CHUNK, ["s"], ["s_next"])
    state = casadi.MX.sym("s", 28)
    v = casadi.MX.sym("v", 4, CHUNK)
    phi, gamma = casadi.MX.sym("phi", 2, 2), casadi.MX.sym("gamma", 2, 2)
    d_phi, d_gamma = casadi.MX.sym("d_phi", 2, 8), casadi.MX.sym("d_gamma", 2, 8)
    x_scale, dt = casadi.MX.sym("x_scale", 2), casadi.MX.sym("dt")
    states, out = inner(state, v, phi, gamma, d_phi, d_gamma, x_scale, dt)
    chunk = casadi.Function("servo_sensitivity_chunk", [state, v, phi, gamma, d_phi, d_gamma, x_scale, dt],
                            [states[:, CHUNK - 1], out], ["s", "v", "phi", "gamma", "d_phi", "d_gamma", "x_scale", "dt"],
                            ["s_next", "out"])
    return compile_function(chunk.expand())


@functools.cache
def zoh_sensitivity_function() -> casadi.Function:
    """``servo_zoh_sensitivity``: ``(w4 = [θ/scale (3), f], scale (3), dt) -> (phi, gamma, d_phi, d_gamma)``,
    ``d_phi = [∂Φ/∂w_0, …, ∂Φ/∂w_3]`` (2 × 8), likewise ``d_gamma``."""
    w = casadi.SX.sym("w", 4)
    scale = casadi.SX.sym("scale", 3)
    dt = casadi.SX.sym("dt")
    phi, gamma = zoh_function()(scale * w[:3], w[3], dt)
    d_phi = casadi.horzcat(*[casadi.reshape(casadi.jacobian(casadi.vec(phi), w[j]), 2, 2) for j in range(4)])
    d_gamma = casadi.horzcat(*[casadi.reshape(casadi.jacobian(casadi.vec(gamma), w[j]), 2, 2) for j in range(4)])
    return casadi.Function("servo_zoh_sensitivity", [w, scale, dt], [phi, gamma, d_phi, d_gamma],
                           ["w", "scale", "dt"], ["phi", "gamma", "d_phi", "d_gamma"])


@functools.lru_cache(maxsize=32)
def residual_function(n_samples: int, fused: bool = False) -> casadi.Function:
    """``servo_oe_residual_<N>``: ``(w (7), p) -> (r (N), J (N × 7))``, the free-run residual ``q̂ − q`` and its
    exact Jacobian (forward sensitivities, :func:`sensitivity_step_function` under ``mapaccum``; with ``fused``,
    values and sensitivities both through the linear fusion filter).

    ``w = [b/m, k/m, σ/m, f, q0, dq0, offset]`` divided by ``p[0:6] = scale``; ``p = [scale (6), dt, q (N),
    u (2N, column-major 2 × N), gains (2N, column-major 2 × N)]`` (``scale[5]``, the objective's weight, unused
    here). Cached per sample count.
    """
    w = casadi.MX.sym("w", 7)
    p = casadi.MX.sym("p", 7 + 5 * n_samples)
    scale, dt = p[:6], p[6]
    q = p[7:7 + n_samples]
    u = casadi.reshape(p[7 + n_samples:7 + 3 * n_samples], 2, n_samples)
    gains = casadi.reshape(p[7 + 3 * n_samples:], 2, n_samples)
    phi, gamma, d_phi, d_gamma = zoh_sensitivity_function()(w[:4], scale[:3], dt)
    if not fused:
        gains = casadi.repmat(casadi.DM([1.0, 0.0]), 1, n_samples)
    q0 = scale[3] * w[4]
    state0 = casadi.vertcat(q0, scale[4] * w[5], casadi.MX.zeros(8), 1, 0, 0, 1,
                            q0, casadi.MX.zeros(4), scale[3], 0, casadi.MX.zeros(7))
    n_chunks = -(-n_samples // CHUNK)
    v = casadi.vertcat(u, gains)
    padded = casadi.horzcat(v, casadi.MX.zeros(4, n_chunks * CHUNK - n_samples))  # causal: the tail is dropped
    run = sensitivity_chunk_function().mapaccum(f"servo_sensitivity_run_{n_samples}", n_chunks, ["s"], ["s_next"])
    _, out = run(state0, padded, phi, gamma, d_phi, d_gamma, scale[3:5], dt)
    out = out[:, :n_samples].T
    residual = out[:, 0] + scale[3] * w[6] - q
    jacobian = casadi.horzcat(out[:, 1:7], scale[3] * casadi.MX.ones(n_samples, 1))
    return casadi.Function(f"servo_oe_residual_{n_samples}", [w, p], [residual, jacobian], ["w", "p"], ["r", "J"])


def delayed_inputs(u: np.ndarray, whole_samples: int) -> np.ndarray:
    """The (2, N) input rows ``[u(n − l), u(n − l − 1)]`` of the sampled model, the record's first value
    standing for the samples before it (the plant is taken at rest on it, as :func:`simulation_function`'s
    free initial state allows)."""
    u = np.asarray(u, dtype=float).reshape(-1)
    padded = np.concatenate((np.full(whole_samples + 1, u[0]), u))
    n = u.size
    return np.vstack((padded[1:n + 1], padded[:n]))


def discrete_coefficients(phi: np.ndarray, gamma: np.ndarray) -> tuple[float, float, tuple[float, float, float]]:
    """``(a1, a2, (K, K2, K3))`` of the sampled model as a difference equation (delay ``l`` aside)::

        q(n) = −a1 q(n−1) − a2 q(n−2) + K u(n−1−l) + K2 u(n−2−l) + K3 u(n−3−l)

    (``a1 = −tr Φ``, ``a2 = det Φ``; ``C adj(zI − Φ) Γ`` gives the input coefficients). Eq. 14 has ``K`` only;
    a sampled second-order plant has ``K2`` too, and a fractional delay ``K3``.
    """
    phi = np.asarray(phi, dtype=float)
    gamma = np.asarray(gamma, dtype=float)
    a1 = -float(np.trace(phi))
    a2 = float(np.linalg.det(phi))
    g0, g1 = gamma[:, 0], gamma[:, 1]
    k1 = float(g0[0])
    k2 = float(phi[0, 1] * g0[1] - phi[1, 1] * g0[0] + g1[0])
    k3 = float(phi[0, 1] * g1[1] - phi[1, 1] * g1[0])
    return a1, a2, (k1, k2, k3)
