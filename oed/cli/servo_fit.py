"""``oed servo-fit``: identify the servo arm's joints (eq. 14, gray-box b, k, σ) and write the metrics as JSON."""

from __future__ import annotations

import argparse


def register(subparsers) -> argparse.ArgumentParser:
    parser = subparsers.add_parser("servo-fit", help="fit second-order joint models to t,u1..uJ,q1..qJ data (JSON out)")
    parser.add_argument("--data", required=True, help="CSV with columns t, u1..uJ, q1..qJ [s, rad]")
    parser.add_argument("--dt", type=float, default=None, help="sample time [s]; the time column must match it")
    parser.add_argument("--mass", default=None, help="comma-separated joint masses [kg] (default: the paper's 0.294,0.239,0.144,0.072 for 4 joints)")
    parser.add_argument("--method", choices=("erls", "rls", "ls"), default="erls", help="ARMAX by ERLS, ARX by RLS, or ARX by batch LS")
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
    if any(not m > 0 for m in masses):
        raise ValueError(f"--mass values must be positive, got {text!r}")
    return masses


def run(args: argparse.Namespace) -> int:
    import numpy as np

    from estimation.loading import DEGREES_THRESHOLD, AngleUnitError
    from estimation.servo import fit_servo_arm
    from estimation.servo_data import read_csv, write_text_atomic
    from oed.cli.common import json_text

    table = read_csv(args.data, required=("t", "u1", "q1"), dt=args.dt)
    u, q = table.stack("u"), table.stack("q")
    if u.shape != q.shape:
        raise ValueError(f"{args.data}: {u.shape[1]} input columns u* but {q.shape[1]} angle columns q*")
    peak = np.abs(q).max(axis=0)
    if np.any(peak > DEGREES_THRESHOLD):
        joint = int(np.argmax(peak > DEGREES_THRESHOLD))
        raise AngleUnitError(f"{args.data}: column q{joint + 1} reaches {peak[joint]:.4g}, beyond ±2π rad: the angles "
                             "look like degrees (the format is SI: convert with numpy.deg2rad)")
    fit = fit_servo_arm(
        table.t, u, q, masses=_masses(args.mass, u.shape[1]), method=args.method, estimation_fraction=args.estimation_fraction,
        nc=args.nc, forgetting=args.forgetting, dt=table.dt, discretisation=args.discretisation,
    )
    write_text_atomic(args.out, json_text(fit.to_dict()))
    print(fit.table())
    return 0
