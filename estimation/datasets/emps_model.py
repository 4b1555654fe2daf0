"""A second-order model of the EMPS axis, force → position: ``M q̈ + Fv q̇ + Fc sign(q̇) + offset = F``.

This is the servo paper's eq. 10 (``m q̈ + b q̇ + k q = f``) for a prismatic axis without stiffness
(``k = 0``), augmented with the Coulomb friction and offset the EMPS description recommends. Parameters are
identified by the inverse-model least squares of the benchmark (IDIM-LS): ``q̇`` and ``q̈`` come from the
measured position through a zero-phase Butterworth low-pass (``filtfilt``) and central differences, and
the force equation is solved by least squares. Validation on the other file: (i) force reconstructed from
the measured motion, (ii) position simulated in free run from the measured force (open loop: the axis is
an integrator, so the free run drifts — reported, not hidden).

Examples
--------
>>> from estimation.datasets.shared import load_emps                                           # doctest: +SKIP
>>> from estimation.datasets.emps_model import fit_emps_second_order                                   # doctest: +SKIP
>>> fit = fit_emps_second_order(load_emps("../shared/data/emps", "estimation"))          # doctest: +SKIP
>>> round(fit.M), round(fit.Fv)                                                         # doctest: +SKIP
(95, 204)
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.integrate
import scipy.signal

from estimation.datasets.shared import EMPSData
from estimation.estimators.metrics import r2_adjusted, rmse


@dataclass(frozen=True)
class EMPSFit:
    """IDIM-LS estimate: mass ``M`` [kg], viscous ``Fv`` [N·s/m], Coulomb ``Fc`` [N], ``offset`` [N], their standard
    deviations, and the force fit on the estimation data."""

    M: float
    Fv: float
    Fc: float
    offset: float
    std: tuple[float, float, float, float]
    force_rmse: float
    force_r2_adj: float
    cutoff_hz: float


@dataclass(frozen=True)
class EMPSValidation:
    """Validation on another record: force reconstruction and free-run position simulation (RMSE, adjusted R²)."""

    force_rmse: float
    force_r2_adj: float
    position_rmse_free_run: float
    position_r2_adj_free_run: float
    position_free_run: np.ndarray


def motion_from_position(q: np.ndarray, dt: float, *, cutoff_hz: float = 50.0, order: int = 4) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Zero-phase low-passed position and its first two central-difference derivatives."""
    nyquist = 0.5 / dt
    if not 0 < cutoff_hz < nyquist:
        raise ValueError(f"cutoff_hz must be in (0, {nyquist}) Hz, got {cutoff_hz}")
    b, a = scipy.signal.butter(order, cutoff_hz / nyquist)
    qf = scipy.signal.filtfilt(b, a, q)
    dq = np.gradient(qf, dt)
    ddq = np.gradient(dq, dt)
    return qf, dq, ddq


def _regressor(dq: np.ndarray, ddq: np.ndarray) -> np.ndarray:
    return np.column_stack((ddq, dq, np.sign(dq), np.ones_like(dq)))


def fit_emps_second_order(data: EMPSData, *, cutoff_hz: float = 50.0, trim: int = 500) -> EMPSFit:
    """IDIM-LS of ``[M, Fv, Fc, offset]`` from ``data`` (``trim`` samples dropped at each end: filter edges)."""
    _, dq, ddq = motion_from_position(data.qm, data.dt, cutoff_hz=cutoff_hz)
    keep = slice(trim, data.qm.size - trim)
    phi, force = _regressor(dq[keep], ddq[keep]), data.force[keep]
    theta, *_ = np.linalg.lstsq(phi, force, rcond=None)
    residual = force - phi @ theta
    sigma2 = float(residual @ residual) / (force.size - theta.size)
    std = np.sqrt(np.diag(sigma2 * np.linalg.inv(phi.T @ phi)))
    return EMPSFit(
        M=float(theta[0]), Fv=float(theta[1]), Fc=float(theta[2]), offset=float(theta[3]), std=tuple(float(s) for s in std),
        force_rmse=rmse(force, phi @ theta), force_r2_adj=r2_adjusted(force, phi @ theta, 4), cutoff_hz=cutoff_hz,
    )


def simulate_emps(fit: EMPSFit, force: np.ndarray, t: np.ndarray, *, q0: float, v0: float, smooth_velocity: float = 1e-3) -> np.ndarray:
    """Free-run position from the force (zero-order hold) through ``M q̈ = F − Fv q̇ − Fc tanh(q̇/ε) − offset``.

    ``sign`` is smoothed to ``tanh(q̇/ε)`` with ``ε = smooth_velocity`` [m/s] so the ODE solver can step.
    """
    def rhs(time, state):
        i = min(int((time - t[0]) / (t[1] - t[0])), force.size - 1)
        v = state[1]
        return [v, (force[i] - fit.Fv * v - fit.Fc * np.tanh(v / smooth_velocity) - fit.offset) / fit.M]

    solution = scipy.integrate.solve_ivp(rhs, (t[0], t[-1]), [q0, v0], t_eval=t, max_step=t[1] - t[0], rtol=1e-6, atol=1e-9)
    if not solution.success:
        raise ValueError(f"EMPS free-run simulation failed: {solution.message}")
    return solution.y[0]


def validate_emps(fit: EMPSFit, data: EMPSData, *, trim: int = 500) -> EMPSValidation:
    """Force reconstruction (inverse model) and free-run position (forward model) on another record."""
    _, dq, ddq = motion_from_position(data.qm, data.dt, cutoff_hz=fit.cutoff_hz)
    keep = slice(trim, data.qm.size - trim)
    predicted = _regressor(dq[keep], ddq[keep]) @ np.array([fit.M, fit.Fv, fit.Fc, fit.offset])
    force = data.force[keep]
    position = simulate_emps(fit, data.force, data.t, q0=float(data.qm[0]), v0=0.0)
    return EMPSValidation(
        force_rmse=rmse(force, predicted), force_r2_adj=r2_adjusted(force, predicted, 4),
        position_rmse_free_run=rmse(data.qm, position), position_r2_adj_free_run=r2_adjusted(data.qm, position, 4),
        position_free_run=position,
    )
