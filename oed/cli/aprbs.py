"""``oed aprbs``: design an APRBS for the servo arm and write ``t, u1..uJ`` [rad] to CSV."""

from __future__ import annotations

import argparse

from dynamics.robots.servo_arm import SERVO_ARM_RANGES
from oed.cli.shared.common import check_csv_path, seed
from oed.cli.shared.verbs import verb_summary


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
    from estimation.servo.files import write_csv
    from oed.aprbs import APRBSDesign, design_aprbs
    from oed.cli.shared.common import OutputFiles, check_figure_path

    check_figure_path(args.figure)

    if not 1 <= args.joints <= len(SERVO_ARM_RANGES):
        raise ValueError(f"--joints must be between 1 and {len(SERVO_ARM_RANGES)}, got {args.joints}")
    design = APRBSDesign(
        ranges=SERVO_ARM_RANGES[: args.joints], duration=args.duration, dt=args.dt, hold_min=args.hold_min,
        hold_max=args.hold_max, n_levels=args.levels,
    )
    result = design_aprbs(design, candidates=args.candidates, seed=args.seed)
    with OutputFiles() as outputs:  # the CSV and the figure, or neither
        write_csv(outputs.stage(args.out), {"t": result.t, **{f"u{j + 1}": result.u[:, j] for j in range(args.joints)}})
        if args.figure:
            from oed.aprbs_figures import plot_aprbs

            plot_aprbs(result, outputs.stage_figure(args.figure))
    print(f"wrote {args.out}: {result.t.size} samples x {args.joints} joints, criterion {result.score:.4f} "
          f"(best of {len(result.candidate_scores)}, worst {min(result.candidate_scores):.4f})")
    return 0
