"""``oed servo-fit``: identify the servo arm's joints (eq. 14, gray-box b, k, σ) and write the metrics as JSON
(the work: :func:`oed.workflows.servo_fit.servo_fit`)."""

from __future__ import annotations

import argparse

from oed.cli.shared.common import print_lines, print_warnings
from oed.cli.shared.verbs import verb_summary
from oed.workflows.options import check_json_path


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


def run(args: argparse.Namespace) -> int:
    check_json_path(args.out)
    from oed.workflows.servo_fit import servo_fit

    result = servo_fit(data=args.data, dt=args.dt, mass=args.mass, method=args.method, delay=args.delay,
                       max_delay=args.max_delay, fusion=args.fusion, kalman_q=args.kalman_q, kalman_r=args.kalman_r,
                       nc=args.nc, forgetting=args.forgetting, estimation_fraction=args.estimation_fraction,
                       discretisation=args.discretisation)
    result.write(args.out)
    print_warnings("servo-fit", result.warnings)
    print_lines(result.summary())
    return 0
