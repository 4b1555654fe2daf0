"""``oed identify``: base parameters from measured data, with uncertainties and validation."""

from __future__ import annotations

import argparse
import contextlib
import sys
import warnings
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

from dynamics.memory import check_allocation
from dynamics.models import ModelKind, build_model
from estimation.cluster import SCHEDULER_VARIABLE, connect, scheduler_address
from estimation.identification import identify
from estimation.loading import read_measurements
from estimation.measurements import Measurements
from estimation.normal_equations import DEFAULT_CHUNK_SIZE
from estimation.preprocessing import ButterworthDifferentiation, Differentiation, FourierDifferentiation, fill_derivatives
from estimation.streamed_identification import identify_files
from estimation.validation import plot_comparison
from oed.cli.common import OutputFiles, add_robot_arguments, check_figure_path, json_text, robot_from_arguments


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
    parser.add_argument("--data", type=Path, required=True, action="append",
                        help="identification data (.csv or .parquet); repeat for several files (one estimate from "
                             "all, by accumulated sums)")
    parser.add_argument("--validate", type=Path, help="validation data from another trajectory")
    parser.add_argument("--out", type=Path, required=True, help="result JSON file")
    parser.add_argument("--plot", type=Path, help="figure of measured vs predicted channels (.png, .pdf, .svg)")
    parser.add_argument("--method", choices=("wls", "ols"), default="wls",
                        help="channel-weighted (default) or ordinary least squares")
    add_derivative_arguments(parser)
    add_streaming_arguments(parser)
    return parser


def add_streaming_arguments(parser: argparse.ArgumentParser) -> None:
    """``--chunk-size``, ``--scheduler``, ``--workers``: the bounded-memory, distributed path."""
    streaming = parser.add_argument_group(
        "bounded memory and clusters (estimation.streamed_identification)",
        "read and sum the files chunk by chunk (peak memory set by the chunk, not the record); several "
        "--data files always take this path")
    streaming.add_argument("--chunk-size", type=int, help=f"samples a chunk (default {DEFAULT_CHUNK_SIZE} when "
                           "streaming)")
    streaming.add_argument("--scheduler", help=f"dask scheduler address (tcp://host:8786) to sum the files on a "
                           f"cluster (default: ${SCHEDULER_VARIABLE}); needs pip install 'robot-oed[cluster]'")
    streaming.add_argument("--workers", type=int, default=0, help="sum the files in a local process pool of this size")


def streaming_requested(args: argparse.Namespace) -> bool:
    return (len(args.data) > 1 or args.chunk_size is not None or args.workers > 0
            or scheduler_address(args.scheduler) is not None)


@contextlib.contextmanager
def executor_from_arguments(args: argparse.Namespace):
    """A dask executor (``--scheduler`` or ``$ROBOT_OED_SCHEDULER``), a process pool (``--workers``) or ``None``."""
    if args.workers < 0:
        raise ValueError(f"--workers must be 0 (in this process) or a pool size, got {args.workers}")
    address = scheduler_address(args.scheduler)
    if address is not None and args.workers:
        raise ValueError("give --scheduler (a dask cluster) or --workers (a local pool), not both")
    if address is not None:
        with connect(address) as executor:
            yield executor
    elif args.workers:
        with ProcessPoolExecutor(args.workers) as executor:
            yield executor
    else:
        yield None


def run_streaming(args: argparse.Namespace, robot, model) -> int:
    chunk_size = DEFAULT_CHUNK_SIZE if args.chunk_size is None else args.chunk_size
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        with executor_from_arguments(args) as executor:
            result = identify_files(model, args.data, [] if args.validate is None else [args.validate],
                                    method=args.method, chunk_size=chunk_size, cutoff_hz=args.cutoff,
                                    frequency_hz=args.frequency, harmonics=args.harmonics,
                                    decimation=args.decimate, held_torques=args.held_torques, executor=executor)
    for message in dict.fromkeys(str(warning.message) for warning in caught):  # once each, in order
        print(f"oed identify: warning: {message}", file=sys.stderr)
    with OutputFiles() as outputs:
        with outputs.open(args.out) as stream:
            stream.write(json_text(result.to_dict()))
    estimate = result.estimate
    print(f"{robot.name}: {model.kind.value} model, {model.n_base} base parameters, {result.train.n_samples} samples "
          f"from {len(result.files)} file(s) in chunks of {chunk_size}, {estimate.method.upper()}, cond {estimate.cond:.4g}")
    if result.cutoff_hz is not None:
        print(f"Butterworth cut-off {result.cutoff_hz:.4g} Hz" + ("" if args.cutoff is not None else
              f" (automatic, from the first chunk of {args.data[0]})"))
    _print_estimate(estimate)
    print("train MSE: " + "  ".join(f"{channel} {value:.4g}" for channel, value in result.train_mse.items()))
    if result.validation_mse is not None:
        print("validation MSE: " + "  ".join(f"{channel} {value:.4g}" for channel, value in result.validation_mse.items()))
    print(f"wrote {args.out}")
    return 0


#: bytes a sample, channel and base parameter the in-memory identification holds at its peak (the
#: stacked regressor and the prediction's; measured 3.5 KB a sample for the 7-joint KUKA, m r = 350)
IN_MEMORY_BYTES = 2 * 8


def check_in_memory(model, *records: Measurements | None) -> None:
    """Refuse an in-memory identification larger than the machine (the streamed path is not)."""
    samples = sum(record.n_samples for record in records if record is not None)
    check_allocation(IN_MEMORY_BYTES * samples * model.n_channels * model.n_base,
                     f"identifying {samples} samples in memory (use --chunk-size to stream them in bounded memory)")


def _print_estimate(estimate) -> None:
    width = max(len(name) for name in estimate.names)
    for record in estimate.records():
        relative = record["relative_std"]
        print(f"  {record['name']:<{width}}  {record['value']:+.5g} ± {record['std']:.2g}  ({relative:.3g} %)")


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
    robot = robot_from_arguments(args)
    model = build_model(robot, args.model, args.friction)
    if streaming_requested(args):
        if args.plot is not None:
            raise ValueError("--plot draws every sample: not with the streamed path (several --data files, "
                             "--chunk-size, --scheduler or --workers)")
        return run_streaming(args, robot, model)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        train = prepare(args.data[0], model, args)
        validation = None if args.validate is None else prepare(args.validate, model, args)
        check_in_memory(model, train, validation)
        result = identify(model, train, validation, weighted=args.method == "wls")
    for warning in caught:
        print(f"oed identify: warning: {warning.message}", file=sys.stderr)
    with OutputFiles() as outputs:  # all files or none
        with outputs.open(args.out) as stream:
            stream.write(json_text(result.to_dict()))
        if args.plot is not None:
            comparisons = [result.train] + ([result.validation] if result.validation is not None else [])
            plot_comparison(comparisons, outputs.stage_figure(args.plot),
                            title=f"{robot.name}: {model.kind.value} model ({args.method})")

    estimate = result.estimate
    print(f"{robot.name}: {model.kind.value} model, {model.n_base} base parameters, {train.n_samples} samples, "
          f"{estimate.method.upper()}, cond {estimate.cond:.4g}")
    _print_estimate(estimate)
    for label, comparison in (("train", result.train), ("validation", result.validation)):
        if comparison is not None:
            print(f"{label} MSE: " + "  ".join(f"{channel} {value:.4g}" for channel, value in comparison.mse.items()))
    print(f"wrote {args.out}" + (f" and {args.plot}" if args.plot else ""))
    return 0
