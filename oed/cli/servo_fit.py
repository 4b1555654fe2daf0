"""``oed servo-fit``: identify the servo arm's joints (eq. 14, gray-box b, k, σ) and write the metrics as JSON."""

from __future__ import annotations

import argparse
import sys
from oed.cli.shared.verbs import verb_summary


def register(subparsers) -> argparse.ArgumentParser:
    parser = subparsers.add_parser("servo-fit", help=verb_summary("servo-fit"))
    parser.add_argument("--data", required=True, help="CSV with columns t, u1..uJ, q1..qJ [s, rad]")
    parser.add_argument("--dt", type=float, default=None, help="sample time [s]; the time column must match it")
    parser.add_argument("--mass", default=None, help="comma-separated joint masses [kg] (default: the paper's 0.294,0.239,0.144,0.072 for 4 joints)")
    parser.add_argument("--method", choices=("erls", "rls", "ls", "oe"), default="erls",
                        help="ARMAX by ERLS (the paper's; best one-step-ahead predictor), ARX by RLS, ARX by batch LS, or "
                             "oe: output error on the continuous model, started from ERLS (physical b, k, sigma with "
                             "standard deviations; use it for the parameters)")
    parser.add_argument("--delay", choices=("none", "estimate"), default="none",
                        help="--method oe: input delay beyond the zero-order hold, none or estimated (a fraction of a "
                             "sample, then whole samples up to --max-delay)")
    parser.add_argument("--max-delay", type=int, default=3, help="--method oe --delay estimate: largest delay [samples]")
    parser.add_argument("--fusion", choices=("kalman", "none"), default="kalman",
                        help="--method oe: the angles q are a Kalman fusion of gyro and accelerometer (eqs. 1-8, as "
                             "servo-simulate writes them; the model goes through the same filter) or measured directly")
    parser.add_argument("--kalman-q", default="1e-5,1e-8", help="--fusion kalman: Q_d diagonal (angle, bias) of the fusion")
    parser.add_argument("--kalman-r", type=float, default=0.03**2, help="--fusion kalman: R_d of the fusion [rad^2]")
    parser.add_argument("--nc", type=int, default=1, help="order of C(z) for ERLS")
    parser.add_argument("--forgetting", type=float, default=1.0, help="forgetting factor of RLS/ERLS")
    parser.add_argument("--estimation-fraction", type=float, default=0.8, help="leading fraction used to estimate")
    parser.add_argument("--discretisation", choices=("backward-euler", "zoh"), default="backward-euler",
                        help="gray-box mapping: exact inverse of eq. 13 (default) or pole mapping (zero-order hold)")
    parser.add_argument("--out", required=True, help="output JSON")
    return parser


def _masses(text: str | None, n_joints: int) -> tuple[float, ...] | None:
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


def _positive(value: float, option: str) -> float:
    if not (value > 0 and value < float("inf")):
        raise ValueError(f"{option} must be positive and finite, got {value!r}")
    return value


def _kalman_q(text: str) -> tuple[float, float]:
    try:
        values = tuple(float(v) for v in text.split(","))
    except ValueError:
        raise ValueError(f"--kalman-q must be two comma-separated numbers, got {text!r}") from None
    if len(values) != 2 or not all(0 <= v < float("inf") for v in values):
        raise ValueError(f"--kalman-q must be two non-negative numbers (angle, bias), got {text!r}")
    return values  # type: ignore[return-value]


def run(args: argparse.Namespace) -> int:
    import numpy as np

    from estimation.data.loading import DEGREES_THRESHOLD, AngleUnitError
    from estimation.servo.protocol import fit_servo_arm
    from estimation.servo.files import read_csv, write_text_atomic
    from estimation.servo.free_run_check import check_free_run
    from oed.cli.shared.common import json_text

    table = read_csv(args.data, required=("t", "u1", "q1"), dt=args.dt)
    u, q = table.stack("u"), table.stack("q")
    if u.shape != q.shape:
        raise ValueError(f"{args.data}: {u.shape[1]} input columns u* but {q.shape[1]} angle columns q*")
    peak = np.abs(q).max(axis=0)
    if np.any(peak > DEGREES_THRESHOLD):
        joint = int(np.argmax(peak > DEGREES_THRESHOLD))
        raise AngleUnitError(f"{args.data}: column q{joint + 1} reaches {peak[joint]:.4g}, beyond ±2π rad: the angles "
                             "look like degrees (the format is SI: convert with numpy.deg2rad)")
    if args.method == "oe":
        from estimation.servo.output_error_arm import fit_servo_arm_output_error
        from estimation.servo.output_error import KalmanFusionSettings

        fusion = None if args.fusion == "none" else KalmanFusionSettings(q=_kalman_q(args.kalman_q), r=_positive(args.kalman_r, "--kalman-r"))
        fit = fit_servo_arm_output_error(
            table.t, u, q, masses=_masses(args.mass, u.shape[1]), estimation_fraction=args.estimation_fraction,
            delay=args.delay, max_delay=args.max_delay, nc=args.nc, forgetting=args.forgetting, dt=table.dt,
            discretisation=args.discretisation, fusion=fusion,
        )
    else:
        fit = fit_servo_arm(
            table.t, u, q, masses=_masses(args.mass, u.shape[1]), method=args.method, estimation_fraction=args.estimation_fraction,
            nc=args.nc, forgetting=args.forgetting, dt=table.dt, discretisation=args.discretisation,
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
    write_text_atomic(args.out, json_text(document))
    for note in notes:
        print(f"oed servo-fit: warning: {note}", file=sys.stderr)
    print(fit.table())
    return 0
