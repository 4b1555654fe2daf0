"""``oed simulate``: simulated measurements of a robot tracking an excitation trajectory
(the work: :func:`oed.workflows.simulate.simulate`).

Writes the data format of :mod:`dynamics.measurements` (``t, q1..qn, [dq, ddq,] tau1..taun,
fx fy fz mx my mz``): quantised positions, noisy applied torques and base wrench. With
``--truth FILE`` it also writes a JSON record of the true parameters, effects, noise and seed.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from dynamics.simulation.effects import SIMULATED_EFFECTS
from oed.cli.shared.common import add_robot_arguments, print_warnings, seed, verb_keywords
from oed.cli.shared.verbs import verb_summary
from oed.workflows.simulate import CONTROLLERS, DATA_SUFFIXES, SimulateOptions, simulate


def register(subparsers: argparse._SubParsersAction) -> argparse.ArgumentParser:
    parser = subparsers.add_parser(
        "simulate",
        help=verb_summary("simulate"),
        description="Simulate the robot (Pinocchio forward dynamics, RK4 at the sampling rate with the torque "
        "held over each sample) under PD or computed-torque control tracking a Fourier trajectory; write "
        "quantised positions, noisy joint torques and base wrench in the measurement format.",
    )
    add_robot_arguments(parser)
    parser.add_argument("--trajectory", type=Path, required=True, help="Fourier trajectory JSON (oed design output)")
    parser.add_argument(
        "--effects", default="",
        help="extra effects, comma-separated: " + ", ".join(name for name in SIMULATED_EFFECTS if name != "viscous")
        + " (viscous friction is always simulated)",
    )
    parser.add_argument(
        "--effect-values", default=None,
        help='true values as JSON text or a JSON file, keyed by effect: {"viscous": [5.8, 9.5, 3.98], '
        '"coulomb": 2.0, "plate_moment": {"mz": 2.0}, "cable": {"stiffness": 3, "joint": 1}, ...}',
    )
    parser.add_argument("--controller", choices=CONTROLLERS, default="pd", help="tracking controller (default: pd)")
    parser.add_argument("--bandwidth", type=float, default=4.0, help="closed-loop bandwidth, Hz (default: 4)")
    parser.add_argument("--noise-tau", type=float, default=0.2, help="torque noise std, N·m (default: 0.2)")
    parser.add_argument(
        "--noise-wrench", type=float, nargs="+", default=[0.5, 0.5, 0.5, 0.1, 0.1, 0.1],
        help="wrench noise std: one value or six (fx fy fz in N, mx my mz in N·m; default: 0.5 N, 0.1 N·m)",
    )
    parser.add_argument(
        "--q-resolution", default="encoder",
        help="position quantum, rad: a number, 'encoder' (2π/(4·4096·|gear|), default) or 'none'",
    )
    parser.add_argument("--periods", type=int, default=1, help="periods recorded (default: 1)")
    parser.add_argument("--warmup-periods", type=int, default=0, help="periods simulated first and dropped (default: 0)")
    parser.add_argument("--rate", type=float, default=1000.0, help="sampling and control rate, Hz (default: 1000)")
    parser.add_argument("--seed", type=seed, default=None, help="seed of the sensor noise")
    parser.add_argument("--with-derivatives", action="store_true", help="also write the true dq, ddq columns")
    parser.add_argument("--truth", type=Path, default=None, help="write the true parameters and settings as JSON")
    parser.add_argument("--out", type=Path, required=True, help="output data file (.csv or .parquet)")
    return parser


def run(args: argparse.Namespace) -> int:
    if args.out.suffix.lower() not in DATA_SUFFIXES:
        raise ValueError(f"--out {args.out}: use a .csv or .parquet file")
    result = simulate(**verb_keywords(args, SimulateOptions))
    print_warnings("simulate", result.warnings)
    result.write(args.out, truth=args.truth)
    print(f"{result.summary()[0]}; wrote {args.out}")
    return 0
