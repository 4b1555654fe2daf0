"""All joints of the servo arm by the output-error route (issue 17): :func:`fit_servo_arm_output_error` and its
JSON/table report, the same shape as :class:`estimation.servo.protocol.ServoArmFit`'s with keys added, none renamed.

Which route for what: the ERLS route (``--method erls``, the paper's) gives the best **one-step-ahead
predictor** (its ``r2_adj``); the output-error route (``--method oe``) gives the **physical** ``b, k, σ`` with
standard deviations, and the better free run.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np
from numpy.typing import ArrayLike

from estimation.servo.model import Discretisation
from estimation.servo.output_error import Delay, KalmanFusionSettings, ServoOutputErrorJointFit, fit_servo_joint_output_error
from dynamics.signal_checks import check_uniform_time

LABELS = {
    "V": "one-step-ahead MSE on the estimation part [rad^2] (the fitted model as a difference equation)",
    "V_free_run": "free-run MSE on the estimation part [rad^2] (what the output-error fit minimises)",
    "rmse": "one-step-ahead prediction on the validation part [rad]",
    "r2_adj": "eq. 21, one-step-ahead prediction on the validation part",
    "rmse_free_run": "free-run simulation of the continuous model from its fitted initial state, validation part [rad]",
    "r2_adj_free_run": "eq. 21, free-run simulation on the validation part",
    "b_std": "standard deviation: sandwich (Gauss-Newton with the residual's autocovariance, Bartlett window "
             "std_lags) covariance of the free-run fit; the mass is taken as exact",
    "std_inflation": "largest ratio of a b/k/sigma standard deviation to the white-noise Gauss-Newton one",
    "a1": "the fitted model as q(n) = -a1 q(n-1) - a2 q(n-2) + K u(n-1-l) + K2 u(n-2-l) + K3 u(n-3-l), l = floor(delay)",
    "delay": "input delay beyond the zero-order hold [samples]",
    "erls": "the ERLS fit (method erls) the output-error fit started from, with its own mapping",
}


@dataclass(frozen=True)
class ServoArmOutputErrorFit:
    """All joints' output-error fits, the sample time and the protocol settings."""

    joints: tuple[ServoOutputErrorJointFit, ...]
    dt: float
    estimation_fraction: float
    delay: str
    fusion: dict | None = None
    method: str = "oe"

    def to_dict(self) -> dict:
        """JSON-ready: ``{"joints": {"1": {b, k, sigma, b_std, …, a1, a2, K, rmse, r2_adj, …, "erls": {…}}}, …}``."""
        joints = {}
        for j in self.joints:
            entry = asdict(j)
            entry["c"] = list(j.c)
            entry["starts"] = [asdict(s) for s in j.starts]
            entry["erls"] = {**asdict(j.erls), "c": list(j.erls.c)}
            joints[str(j.joint)] = entry
        return {"dt": self.dt, "method": self.method, "estimation_fraction": self.estimation_fraction,
                "delay": self.delay, "fusion": self.fusion, "labels": LABELS, "joints": joints}

    def table(self) -> str:
        """Plain-text table: output-error values ± standard deviation beside ERLS's, and the metrics."""
        header = f"{'parameter / criterion':32s}" + "".join(f"{'joint ' + str(j.joint):>22s}" for j in self.joints)
        lines = [header, "-" * len(header)]

        def row(label: str, cells: list[str]) -> None:
            lines.append(f"{label:32s}" + "".join(f"{c:>22s}" for c in cells))

        row("m (kg)", [f"{j.mass:.4g}" if j.mass is not None else "—" for j in self.joints])
        for label, key in (("b (Nm/(rad/s))", "b"), ("k (Nm/rad)", "k"), ("sigma (N/rad)", "sigma")):
            row(label + " OE", ["—" if getattr(j, key) is None else f"{getattr(j, key):.5g} ± {getattr(j, key + '_std'):.2g}"
                                for j in self.joints])
            row(label + " ERLS", ["—" if getattr(j.erls, key) is None else f"{getattr(j.erls, key):.5g}" for j in self.joints])
        for label, key in (("b/m OE", "b_over_m"), ("k/m OE", "k_over_m"), ("sigma/m OE", "sigma_over_m")):
            row(label, [f"{getattr(j, key):.5g} ± {getattr(j, key + '_std'):.2g}" for j in self.joints])
        row("delay (samples)", [f"{j.delay:.3g}" for j in self.joints])
        for label, key in (("RMSE (validation, 1-step)", "rmse"), ("R2adj (validation, 1-step)", "r2_adj"),
                           ("RMSE (validation, free run)", "rmse_free_run"), ("R2adj (validation, free run)", "r2_adj_free_run")):
            row(label + " OE", [f"{getattr(j, key):.6g}" for j in self.joints])
            row(label + " ERLS", [f"{getattr(j.erls, key):.6g}" for j in self.joints])
        return "\n".join(lines)


def fit_servo_arm_output_error(
    t: ArrayLike, u: ArrayLike, q: ArrayLike, *, masses: tuple[float, ...] | None = None, estimation_fraction: float = 0.8,
    remove_mean: bool = True, delay: Delay = "none", max_delay: int = 3, nc: int = 1, forgetting: float = 1.0,
    dt: float | None = None, discretisation: Discretisation = "backward-euler", fusion: KalmanFusionSettings | None = None,
) -> ServoArmOutputErrorFit:
    """Run :func:`estimation.servo.output_error.fit_servo_joint_output_error` on every column of ``u``/``q``
    (shape (N, joints)) sampled at the uniform times ``t``.

    Raises
    ------
    ValueError
        Non-uniform ``t``, mismatched shapes, wrong number of masses; the joint fit's named errors.
    """
    t = np.asarray(t, dtype=float).reshape(-1)
    u = np.atleast_2d(np.asarray(u, dtype=float))
    q = np.atleast_2d(np.asarray(q, dtype=float))
    dt = check_uniform_time(t, dt=dt)
    if u.shape != q.shape or u.shape[0] != t.size:
        raise ValueError(f"u {u.shape} and q {q.shape} must both have shape ({t.size}, joints)")
    if masses is not None and len(masses) != u.shape[1]:
        raise ValueError(f"{len(masses)} masses given for {u.shape[1]} joints")
    fits = tuple(
        fit_servo_joint_output_error(
            u[:, j], q[:, j], dt=dt, mass=None if masses is None else masses[j], joint=j + 1,
            estimation_fraction=estimation_fraction, remove_mean=remove_mean, delay=delay, max_delay=max_delay, nc=nc,
            forgetting=forgetting, discretisation=discretisation, fusion=fusion,
        )
        for j in range(u.shape[1])
    )
    return ServoArmOutputErrorFit(joints=fits, dt=dt, estimation_fraction=estimation_fraction, delay=delay,
                                  fusion=None if fusion is None else {"q": list(fusion.q), "r": fusion.r, "p0": fusion.p0})
