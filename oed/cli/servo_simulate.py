"""``oed servo-simulate``: drive the simulated servo arm with an APRBS CSV; write ``t, u1..uJ, q1..qJ``
(the work: :func:`oed.workflows.servo_simulate.servo_simulate`)."""

from __future__ import annotations

import argparse

from oed.cli.shared.common import seed
from oed.cli.shared.verbs import verb_summary
from oed.workflows.options import check_csv_path


def register(subparsers) -> argparse.ArgumentParser:
    parser = subparsers.add_parser("servo-simulate", help=verb_summary("servo-simulate"))
    parser.add_argument("--aprbs", required=True, help="input CSV with columns t, u1..u4 [rad]")
    parser.add_argument("--out", required=True, help="output CSV: t, u1..u4, q1..q4 (+ raw columns with --raw)")
    parser.add_argument("--raw", action="store_true", help="also write gyro1..4, acc_angle1..4 and q_true1..4")
    parser.add_argument("--no-gravity", action="store_true", help="leave out the gravity load of the links")
    parser.add_argument("--max-speed", type=float, default=5.2, help="rated servo speed [rad/s] (drive saturation); large = linear plant")
    parser.add_argument("--seed", type=seed, default=None, help="seed of the sensor noise")
    return parser


def run(args: argparse.Namespace) -> int:
    check_csv_path(args.out)
    from oed.workflows.servo_simulate import servo_simulate

    result = servo_simulate(aprbs=args.aprbs, raw=args.raw, no_gravity=args.no_gravity, max_speed=args.max_speed,
                            seed=args.seed)
    result.write(args.out)
    print(f"wrote {args.out}: {result.summary()[0]}")
    return 0
