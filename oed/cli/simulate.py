"""``oed simulate``: simulated measurements of a robot tracking an excitation trajectory.

Writes the data format of :mod:`dynamics.measurements` (``t, q1..qn, [dq, ddq,] tau1..taun,
fx fy fz mx my mz``): quantised positions, noisy applied torques and base wrench. With
``--truth FILE`` it also writes a JSON record of the true parameters, effects, noise and seed.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

import numpy as np

from dynamics.simulation.controllers import ComputedTorqueController, computed_torque_gains
from dynamics.models import build_model
from dynamics.simulation.effects import SIMULATED_EFFECTS, Viscous, effects_from_names
from dynamics.simulation.simulator import NoiseModel, Simulator
from oed.cli.shared.common import OutputFiles, add_robot_arguments, json_text, robot_from_arguments, seed
from oed.fourier import FourierTrajectory
from oed.rest_ramps import playable
from oed.cli.shared.verbs import verb_summary

CONTROLLERS = ("pd", "computed-torque")
DATA_SUFFIXES = (".csv", ".parquet")


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


def _effect_values(text: str | None) -> dict[str, Any]:
    if text is None:
        return {}
    path = Path(text)
    if not text.lstrip().startswith("{"):
        if text.lstrip().startswith(("[", '"')) or text.strip() in ("null", "true", "false"):
            raise ValueError(f"--effect-values must be a JSON object {{effect: value(s)}}, got {text}")
        if not path.exists():
            raise FileNotFoundError(f"--effect-values: {text!r} is neither JSON text nor an existing file")
        text = path.read_text()
    try:
        values = json.loads(text)
    except json.JSONDecodeError as error:
        raise ValueError(f"--effect-values is not valid JSON: {error}") from None
    if not isinstance(values, dict):
        raise ValueError("--effect-values must be a JSON object keyed by effect name")
    return values


def _resolution(text: str) -> Any:
    if text.strip().lower() in ("encoder", "none"):
        return None if text.strip().lower() == "none" else "encoder"
    try:
        return float(text)
    except ValueError:
        raise ValueError(f"--q-resolution must be a number, 'encoder' or 'none', got {text!r}") from None


def _controller(name: str, simulator: Simulator, bandwidth: float):
    robot = simulator.robot
    if name == "pd":
        return simulator.default_controller(bandwidth)
    # computed torque with the nominal model: the description's inertias and the true viscous friction
    model = build_model(robot, "internal", ("viscous",))
    viscous = [effect.values for effect in simulator.effects if isinstance(effect, Viscous)]  # type: ignore[union-attr]
    theta = model.nominal_parameters(viscous=viscous[0] if viscous else 0.0)
    kp, kd = computed_torque_gains(bandwidth_hz=bandwidth, n_joints=robot.n_joints)
    return ComputedTorqueController.from_model(model, theta, kp=kp, kd=kd, label="computed torque, nominal model")


def run(args: argparse.Namespace) -> int:
    if args.out.suffix.lower() not in DATA_SUFFIXES:
        raise ValueError(f"--out {args.out}: use a .csv or .parquet file")
    if len(args.noise_wrench) not in (1, 6):
        raise ValueError("--noise-wrench takes one value or six")
    robot = robot_from_arguments(args)
    trajectory = FourierTrajectory.load(args.trajectory)
    if trajectory.n_joints != robot.n_joints:
        raise ValueError(
            f"trajectory {args.trajectory} has {trajectory.n_joints} joints, the robot {robot.name} has {robot.n_joints}"
        )
    designed_for = trajectory.metadata.get("robot")
    if designed_for and designed_for != robot.name:
        print(f"oed simulate: warning: {args.trajectory} was designed for {designed_for}, and is played on "
              f"{robot.name}: its bounds were not checked for this robot", file=sys.stderr)
    effects = effects_from_names(args.effects, robot, _effect_values(args.effect_values))
    noise = NoiseModel(args.noise_tau, tuple(args.noise_wrench), _resolution(args.q_resolution))
    simulator = Simulator(robot, effects, noise=noise, rate_hz=args.rate)
    controller = _controller(args.controller, simulator, args.bandwidth)
    reference, duration = playable(trajectory, args.rate, args.periods, args.warmup_periods)
    result = simulator.run(
        reference, controller, periods=args.periods, duration=duration, warmup_periods=args.warmup_periods,
        with_derivatives=args.with_derivatives, seed=args.seed,
    )
    metadata = dict(result.metadata, trajectory=str(args.trajectory), data=str(args.out))
    with OutputFiles() as outputs:  # the data and the truth file, or neither
        result.measurements.write(outputs.stage(args.out), staged=False)
        if args.truth is not None:
            with outputs.open(args.truth) as stream:
                stream.write(json_text(metadata))
    error = np.abs(result.tracking_error).max(axis=0)
    print(
        f"{robot.name}: {result.t.shape[0]} samples over {result.t[-1] + 1 / args.rate:.3f} s at {args.rate:g} Hz "
        f"({result.t.shape[0] / result.elapsed_s:.0f} steps/s); effects: "
        f"{', '.join(effect.name for effect in simulator.effects)}; "  # type: ignore[union-attr]
        f"max tracking error {np.array2string(error, precision=4)}; wrote {args.out}"
    )
    return 0
