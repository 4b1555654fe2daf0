"""``oed servo-simulate``: drive the simulated servo arm with an APRBS CSV; write ``t, u1..uJ, q1..qJ``."""

from __future__ import annotations

import argparse

from oed.cli.shared.common import check_csv_path, seed
from oed.cli.shared.verbs import verb_summary


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
    from dynamics.simulation.servo_simulator import PAPER_JOINTS, simulate_servo_arm
    from estimation.servo.files import read_csv, write_csv

    table = read_csv(args.aprbs, required=("t", "u1"))
    u = table.stack("u")
    if u.shape[1] != len(PAPER_JOINTS):
        raise ValueError(f"{args.aprbs}: the servo arm has {len(PAPER_JOINTS)} joints, found columns u1..u{u.shape[1]}")
    record = simulate_servo_arm(table.t, u, gravity=not args.no_gravity, max_speed=args.max_speed, seed=args.seed)
    n = u.shape[1]
    columns = {"t": record.t, **{f"u{j + 1}": record.u[:, j] for j in range(n)}, **{f"q{j + 1}": record.q[:, j] for j in range(n)}}
    if args.raw:
        for name, values in (("gyro", record.gyro), ("acc_angle", record.acc_angle), ("q_true", record.q_true)):
            columns.update({f"{name}{j + 1}": values[:, j] for j in range(n)})
    write_csv(args.out, columns)
    print(f"wrote {args.out}: {record.t.size} samples, columns {', '.join(columns)}")
    return 0
