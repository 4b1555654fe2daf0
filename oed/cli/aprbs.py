"""``oed aprbs``: design an APRBS for the servo arm and write ``t, u1..uJ`` [rad] to CSV
(the work: :func:`oed.workflows.aprbs.aprbs`)."""

from __future__ import annotations

import argparse

from dynamics.runtime.output_files import check_figure_path
from oed.cli.shared.common import seed
from oed.cli.shared.verbs import verb_summary
from oed.workflows.options import check_csv_path


def register(subparsers) -> argparse.ArgumentParser:
    parser = subparsers.add_parser("aprbs", help=verb_summary("aprbs"))
    parser.add_argument("--joints", type=int, default=4, help="number of joints (1-4, the paper's ranges)")
    parser.add_argument("--duration", type=float, default=60.0, help="signal length [s]")
    parser.add_argument("--dt", type=float, default=0.01, help="sample time [s]")
    parser.add_argument("--hold-min", type=float, default=0.2, help="minimum hold time [s] (about the dominant time constant)")
    parser.add_argument("--hold-max", type=float, default=None, help="maximum hold time [s] (default 5 x hold-min)")
    parser.add_argument("--levels", type=int, default=12, help="amplitude strata per joint")
    parser.add_argument("--candidates", type=int, default=64, help="random candidates; the best by the criterion is kept")
    parser.add_argument("--seed", type=seed, default=None, help="random seed")
    parser.add_argument("--figure", default=None, help="also save signal/histogram/spectrum figure (PNG/PDF)")
    parser.add_argument("--out", required=True, help="output CSV")
    return parser


def run(args: argparse.Namespace) -> int:
    check_csv_path(args.out)
    check_figure_path(args.figure)
    from oed.workflows.aprbs import aprbs

    result = aprbs(joints=args.joints, duration=args.duration, dt=args.dt, hold_min=args.hold_min,
                   hold_max=args.hold_max, levels=args.levels, candidates=args.candidates, seed=args.seed)
    result.write(args.out, figure=args.figure)
    print(f"wrote {args.out}: {result.summary()[0]}")
    return 0
