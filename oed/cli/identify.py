"""``oed identify``: base parameters from measured data, with uncertainties and validation."""

from __future__ import annotations

import argparse
import sys
import warnings
from pathlib import Path

from dynamics.models import ModelKind, build_model
from estimation.identification import identify
from estimation.loading import read_measurements
from estimation.measurements import Measurements
from estimation.preprocessing import ButterworthDifferentiation, Differentiation, FourierDifferentiation, fill_derivatives
from estimation.validation import plot_comparison
from oed.cli.common import OutputFiles, add_robot_arguments, check_figure_path, json_text, robot_from_arguments
from oed.cli.identify_consistent import (
    add_consistent_arguments, check_consistent_arguments, consistent_refit, print_consistent,
)


def register(subparsers: argparse._SubParsersAction) -> argparse.ArgumentParser:
    parser = subparsers.add_parser(
        "identify",
        help="estimate base parameters from measured motion and torques/wrench",
        description="Least-squares identification of the base parameters of the internal, external or combined "
        "model (PUMA paper, section IV) from a CSV/Parquet file (columns t, q1..qn [, dq.., ddq..], tau1..taun, "
        "fx fy fz mx my mz), with validation on another experiment.",
    )
    add_robot_arguments(parser)
    parser.add_argument("--model", choices=[kind.value for kind in ModelKind], default="internal", help="which model (default: internal)")
    parser.add_argument(
        "--friction", default="viscous",
        help="extra columns, comma-separated: viscous, coulomb, offset, armature, wrench_offset (default: viscous; 'none')",
    )
    parser.add_argument("--data", type=Path, required=True, help="identification data (.csv or .parquet)")
    parser.add_argument("--validate", type=Path, help="validation data from another trajectory")
    parser.add_argument("--out", type=Path, required=True, help="result JSON file")
    parser.add_argument("--plot", type=Path, help="figure of measured vs predicted channels (.png, .pdf, .svg)")
    parser.add_argument("--method", choices=("wls", "ols"), default="wls",
                        help="channel-weighted (default) or ordinary least squares")
    add_derivative_arguments(parser)
    add_consistent_arguments(parser)
    return parser


def add_derivative_arguments(parser: argparse.ArgumentParser) -> None:
    """``--frequency/--harmonics`` (Fourier fit) or ``--cutoff`` (Butterworth), and ``--decimate``."""
    derivatives = parser.add_argument_group("derivatives (only when dq/ddq columns are absent)")
    derivatives.add_argument("--frequency", type=float, help="periodic excitation: fundamental frequency, Hz "
                             "(average the periods, Fourier-fit the positions)")
    derivatives.add_argument("--harmonics", type=int, default=5, help="harmonics of the Fourier fit (default: 5, the paper's; "
                             "records of a robot under feedback want about three times the reference's)")
    derivatives.add_argument("--cutoff", type=float, help="otherwise: Butterworth cut-off, Hz (default: automatic)")
    derivatives.add_argument("--decimate", type=int, default=1, help="keep one sample in K after low-pass filtering")
    derivatives.add_argument("--held-torques", action="store_true",
                             help="joint torques were held over each sample (zero-order hold, as `oed simulate` "
                                  "and digital current commands): take the derived motion half a sample later")


def differentiation(args: argparse.Namespace) -> Differentiation:
    if args.frequency is not None and args.cutoff is not None:
        raise ValueError("give --frequency (Fourier fit of periodic data) or --cutoff (Butterworth filter), not both")
    if args.frequency is not None:
        return FourierDifferentiation(args.frequency, args.harmonics)
    return ButterworthDifferentiation(args.cutoff)


def prepare(path: Path, model, args: argparse.Namespace) -> Measurements:
    measurements = read_measurements(path, model=model)
    method = None if measurements.dq is not None and measurements.ddq is not None else differentiation(args)
    return fill_derivatives(measurements, method, decimation=args.decimate, held_torques=args.held_torques)


def run(args: argparse.Namespace) -> int:
    check_figure_path(args.plot)
    differentiation(args)  # contradicting derivative options are an error even when the data hold dq, ddq
    check_consistent_arguments(args)
    robot = robot_from_arguments(args)
    model = build_model(robot, args.model, args.friction)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        train = prepare(args.data, model, args)
        validation = None if args.validate is None else prepare(args.validate, model, args)
        result = identify(model, train, validation, weighted=args.method == "wls")
    consistent = consistent_refit(args, result, train, validation)  # None without --consistent
    for warning in caught:
        print(f"oed identify: warning: {warning.message}", file=sys.stderr)
    with OutputFiles() as outputs:  # all files or none
        with outputs.open(args.out) as stream:
            stream.write(json_text({**result.to_dict(), **({} if consistent is None else consistent.to_dict())}))
        if args.plot is not None:
            comparisons = [result.train] + ([result.validation] if result.validation is not None else [])
            plot_comparison(comparisons, outputs.stage_figure(args.plot),
                            title=f"{robot.name}: {model.kind.value} model ({args.method})")

    estimate = result.estimate
    print(f"{robot.name}: {model.kind.value} model, {model.n_base} base parameters, {train.n_samples} samples, "
          f"{estimate.method.upper()}, cond {estimate.cond:.4g}")
    width = max(len(name) for name in estimate.names)
    for record in estimate.records():
        relative = record["relative_std"]
        print(f"  {record['name']:<{width}}  {record['value']:+.5g} ± {record['std']:.2g}  ({relative:.3g} %)")
    for label, comparison in (("train", result.train), ("validation", result.validation)):
        if comparison is not None:
            print(f"{label} MSE: " + "  ".join(f"{channel} {value:.4g}" for channel, value in comparison.mse.items()))
    print_consistent(consistent)
    print(f"wrote {args.out}" + (f" and {args.plot}" if args.plot else ""))
    return 0
