"""``oed servo-fit`` as a library call: the servo arm's joints identified (eq. 14, gray-box b, k, σ), with a
free-run check of each; the metrics JSON is ``to_dict()``, written by :meth:`ServoFitRun.write`."""

from __future__ import annotations

import copy
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from dynamics.runtime.output_files import json_text
from oed.workflows.options import check_json_path

__all__ = ["ServoFitRun", "servo_fit"]


def masses_of(text: str | None, n_joints: int) -> tuple[float, ...] | None:
    """``--mass``: comma-separated joint masses [kg], or the paper's for 4 joints."""
    from dynamics.robots.servo_arm import SERVO_ARM_MASSES

    if text is None:
        return SERVO_ARM_MASSES if n_joints == len(SERVO_ARM_MASSES) else None
    try:
        masses = tuple(float(v) for v in text.split(","))
    except ValueError:
        raise ValueError(f"--mass must be comma-separated numbers, got {text!r}") from None
    if len(masses) != n_joints:
        raise ValueError(f"--mass gives {len(masses)} masses for {n_joints} joints")
    if any(not (m > 0 and m < float("inf")) for m in masses):
        raise ValueError(f"--mass values must be positive, got {text!r}")
    return masses


def positive(value: float, option: str) -> float:
    """``value`` when positive and finite, else a ``ValueError`` naming ``option``."""
    if not (value > 0 and value < float("inf")):
        raise ValueError(f"{option} must be positive and finite, got {value!r}")
    return value


def kalman_q_of(text: str) -> tuple[float, float]:
    """``--kalman-q``: two non-negative numbers (angle, bias)."""
    try:
        values = tuple(float(v) for v in text.split(","))
    except ValueError:
        raise ValueError(f"--kalman-q must be two comma-separated numbers, got {text!r}") from None
    if len(values) != 2 or not all(0 <= v < float("inf") for v in values):
        raise ValueError(f"--kalman-q must be two non-negative numbers (angle, bias), got {text!r}")
    return values  # type: ignore[return-value]


@dataclass(frozen=True)
class ServoFitRun:
    """The fit (``fit``), the metrics document with each joint's free-run check, and the warnings."""

    fit: Any = field(repr=False)
    document: dict[str, Any] = field(repr=False)
    warnings: tuple[str, ...]

    def to_dict(self) -> dict[str, Any]:
        """The metrics JSON ``oed servo-fit`` writes."""
        return copy.deepcopy(self.document)

    def summary(self) -> list[str]:
        """The table ``oed servo-fit`` prints."""
        return [self.fit.table()]

    def write(self, out: str | Path) -> None:
        """The metrics JSON at ``out``."""
        from estimation.servo.files import write_text_atomic

        check_json_path(out)
        write_text_atomic(out, json_text(self.document))


def servo_fit(*, data: str | Path, dt: float | None = None, mass: str | None = None, method: str = "erls",
              delay: str = "none", max_delay: int = 3, fusion: str = "kalman", kalman_q: str = "1e-5,1e-8",
              kalman_r: float = 0.03**2, nc: int = 1, forgetting: float = 1.0, estimation_fraction: float = 0.8,
              discretisation: str = "backward-euler") -> ServoFitRun:
    """``oed servo-fit``: second-order joint models fitted to the CSV ``data`` (t, u1..uJ, q1..qJ [s, rad]) by
    ``method`` (``erls``, ``rls``, ``ls`` or ``oe``), with the options of the verb by their names."""
    from estimation.data.loading import DEGREES_THRESHOLD, AngleUnitError
    from estimation.servo.files import read_csv
    from estimation.servo.free_run_check import check_free_run
    from estimation.servo.protocol import fit_servo_arm

    table = read_csv(data, required=("t", "u1", "q1"), dt=dt)
    u, q = table.stack("u"), table.stack("q")
    if u.shape != q.shape:
        raise ValueError(f"{data}: {u.shape[1]} input columns u* but {q.shape[1]} angle columns q*")
    peak = np.abs(q).max(axis=0)
    if np.any(peak > DEGREES_THRESHOLD):
        joint = int(np.argmax(peak > DEGREES_THRESHOLD))
        raise AngleUnitError(f"{data}: column q{joint + 1} reaches {peak[joint]:.4g}, beyond ±2π rad: the angles "
                             "look like degrees (the format is SI: convert with numpy.deg2rad)")
    if method == "oe":
        from estimation.servo.output_error import KalmanFusionSettings
        from estimation.servo.output_error_arm import fit_servo_arm_output_error

        settings = None if fusion == "none" else KalmanFusionSettings(q=kalman_q_of(kalman_q),
                                                                      r=positive(kalman_r, "--kalman-r"))
        fit = fit_servo_arm_output_error(
            table.t, u, q, masses=masses_of(mass, u.shape[1]), estimation_fraction=estimation_fraction,
            delay=delay, max_delay=max_delay, nc=nc, forgetting=forgetting, dt=table.dt,
            discretisation=discretisation, fusion=settings,
        )
    else:
        fit = fit_servo_arm(
            table.t, u, q, masses=masses_of(mass, u.shape[1]), method=method, estimation_fraction=estimation_fraction,
            nc=nc, forgetting=forgetting, dt=table.dt, discretisation=discretisation,
        )
    document = fit.to_dict()
    notes = []
    for key, entry in document["joints"].items():
        check = check_free_run(int(key), q[int(entry["n_estimation"]):, int(key) - 1], entry["rmse_free_run"],
                               entry["rmse"])
        entry["free_run_check"] = check.to_dict()
        if check.warning() is not None:
            notes.append(check.warning())
    document["warnings"] = notes
    return ServoFitRun(fit, document, tuple(notes))
