"""``oed identify``: base parameters from measured data, with uncertainties and validation."""

from __future__ import annotations

import argparse
import contextlib
import sys
import warnings
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

from dynamics.runtime.memory import check_allocation
from dynamics.models import ModelKind, build_model
from estimation.streaming.cluster import SCHEDULER_VARIABLE, connect, scheduler_address
from estimation.identification.fit import identify
from estimation.data.log_cleaning import DEFAULT_MAX_GAP
from estimation.data.motor_side import read_record_with_transmission
from dynamics.measurements import Measurements
from estimation.estimators.normal_equations import DEFAULT_CHUNK_SIZE
from estimation.preprocessing.differentiation import ButterworthDifferentiation, Differentiation, FourierDifferentiation
from estimation.preprocessing.plan import Preprocessing, check_frequency, choose_preprocessing, prepare
from estimation.preprocessing.delay import split_delay
from estimation.streaming.identification import identify_files
from estimation.identification.validation import plot_comparison
from oed.cli.asbuilt import (add_asbuilt_arguments, finish_document, model_effects, resolve_transmission, rest_message,
                             rest_rows, trivial_predictors)
from oed.cli.common import OutputFiles, add_robot_arguments, check_figure_path, json_text, robot_from_arguments
from oed.cli.model_files import add_model_file
from oed.cli.options import check_hertz
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
        help="extra columns, comma-separated: viscous, coulomb, offset, armature, stribeck, spring, wrench_offset "
             "(default: viscous; 'none'); laws whose shape is estimated too (variable projection): coulomb:tanh "
             "(smoothing velocity), stribeck:velocity, sigmoid (Gaz et al. 2019), ripple (period in position); "
             "NAME[:VARIANT]@JOINTS for some joints (coulomb:tanh@1-4,offset@2+5); motor_viscous, motor_coulomb, "
             "motor_inertia on the transmission's motors; coulomb[q5+q6] on a joint combination; delay: a delay "
             "between torques and motion, one for the records, estimated within ±50 ms (delay:S: within ±S s)",
    )
    add_asbuilt_arguments(parser)
    add_data_arguments(parser, validate_required=False)
    parser.add_argument("--out", type=Path, required=True, help="result JSON file")
    parser.add_argument("--plot", type=Path, help="figure of measured vs predicted channels (.png, .pdf, .svg)")
    parser.add_argument("--method", choices=("wls", "ols"), default="wls",
                        help="channel-weighted (default) or ordinary least squares")
    add_derivative_arguments(parser)
    add_streaming_arguments(parser)
    add_consistent_arguments(parser)
    return parser


def add_data_arguments(parser: argparse.ArgumentParser, *, validate_required: bool) -> None:
    """``--data`` and ``--validate`` (each repeatable: the segments of one record) and ``--max-gap``."""
    parser.add_argument("--data", type=Path, required=True, action="append",
                        help="identification data (.csv or .parquet); repeat for several segments (files), each "
                             "preprocessed on its own and stacked")
    parser.add_argument("--validate", type=Path, required=validate_required, action="append",
                        help="validation data from another trajectory; repeatable like --data")
    parser.add_argument("--max-gap", type=float, default=DEFAULT_MAX_GAP, metavar="SECONDS",
                        help=f"longest logger stall bridged by interpolation (default {DEFAULT_MAX_GAP:g} s); a longer "
                             "hole splits a --data file into segments (and is an error in a --validate file)")


def add_streaming_arguments(parser: argparse.ArgumentParser) -> None:
    """``--chunk-size``, ``--scheduler``, ``--workers``: the bounded-memory, distributed path."""
    streaming = parser.add_argument_group(
        "bounded memory and clusters (estimation.streaming.identification)",
        "read and sum the files chunk by chunk (peak memory set by the chunk, not the record), in this process, "
        "a process pool or on a dask cluster; any of these options selects this path")
    streaming.add_argument("--chunk-size", type=int, help=f"samples a chunk (default {DEFAULT_CHUNK_SIZE} when "
                           "streaming)")
    streaming.add_argument("--scheduler", help=f"dask scheduler address (tcp://host:8786) to sum the files on a "
                           f"cluster (default: ${SCHEDULER_VARIABLE}); needs pip install 'robot-oed[cluster]'")
    streaming.add_argument("--workers", type=int, default=0, help="sum the files in a local process pool of this size")


def streaming_requested(args: argparse.Namespace) -> bool:
    return args.chunk_size is not None or args.workers > 0 or scheduler_address(args.scheduler) is not None


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
            result = identify_files(model, args.data, args.validate or [],
                                    method=args.method, chunk_size=chunk_size, cutoff_hz=args.cutoff,
                                    frequency_hz=args.frequency, harmonics=5 if args.harmonics is None else args.harmonics,
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
    if result.cov_method == "batch_means":
        print(f"standard deviations: batch means (batches of {result.batch_length} samples; a third pass over the files, "
              f"{result.seconds['covariance_pass']:.3g} s)")
    _print_estimate(estimate)
    document = result.to_dict()
    for label in ("train", "validation"):
        errors = document[label]
        if errors is not None:
            against, mse = ("vs recorded", errors["mse"]) if errors["mse"] is not None else \
                ("vs filtered: not against the recording", errors["mse_filtered"])
            print(f"{label} MSE ({against}): " + "  ".join(f"{channel} {value:.4g}" for channel, value in mse.items()))
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
    derivatives.add_argument("--frequency", type=float, help="periodic excitation: fundamental frequency, Hz, any "
                             "value (Fourier fit of the positions on their time stamps; checked against the period "
                             "the data show). Default: detected when the positions repeat, else a filter")
    derivatives.add_argument("--average-periods", choices=("auto", "yes", "no"), default="auto",
                             help="average whole periods before the Fourier fit: auto (default) when there are two or "
                                  "more and a period is a whole number of samples, else fit every sample")
    derivatives.add_argument("--harmonics", type=int, help="harmonics of the Fourier fit (default: 5, the paper's, with "
                             "--frequency; 15 for a detected frequency; records of a robot under feedback want about "
                             "three times the reference's)")
    derivatives.add_argument("--cutoff", type=float, help="otherwise: Butterworth cut-off, Hz (default: automatic)")
    derivatives.add_argument("--decimate", type=int, default=1, help="keep one sample in K after low-pass filtering")
    derivatives.add_argument("--held-torques", action="store_true",
                             help="joint torques were held over each sample (zero-order hold, as `oed simulate` "
                                  "and digital current commands): take the derived motion half a sample later")


def differentiation(args: argparse.Namespace) -> Differentiation:
    check_hertz(args, "frequency", "cutoff")
    if args.frequency is not None and args.cutoff is not None:
        raise ValueError("give --frequency (Fourier fit of periodic data) or --cutoff (Butterworth filter), not both")
    if args.frequency is not None:
        return FourierDifferentiation(args.frequency, 5 if args.harmonics is None else args.harmonics,
                                      args.average_periods)
    return ButterworthDifferentiation(args.cutoff)


def read_segments(paths: list[Path], model, args: argparse.Namespace, *, split: bool,
                  transmission=None) -> tuple[Measurements, ...]:
    """The segments of every file (a hole splits a file when ``split``, else it is an error); motor-side
    columns converted by ``transmission``."""
    seen: dict[Path, Path] = {}
    for path in paths:
        resolved = path.expanduser().resolve()
        if resolved in seen:
            raise ValueError(f"{path} given twice (as {seen[resolved]} too): each file is one segment of the record")
        seen[resolved] = path
    segments: list[Measurements] = []
    for path in paths:
        segments.extend(read_record_with_transmission(path, model=model, transmission=transmission,
                                                      max_gap=args.max_gap, split=split))
    return tuple(segments)


def prepare_data(model, args: argparse.Namespace,
                 transmission=None) -> tuple[Measurements, Measurements | None, Preprocessing]:
    """Training and validation records read, one preprocessing chosen on the training data, both prepared."""
    if not (args.max_gap > 0 and args.max_gap < float("inf")):
        raise ValueError(f"--max-gap must be a positive number of seconds, got {args.max_gap}")
    train = read_segments(args.data, model, args, split=True, transmission=transmission)
    validate = None if not args.validate else read_segments(args.validate, model, args, split=False,
                                                                transmission=transmission)
    preprocessing = choose_preprocessing(
        train, frequency_hz=args.frequency, harmonics=args.harmonics, cutoff_hz=args.cutoff,
        average_periods=args.average_periods, decimation=args.decimate, held_torques=args.held_torques)
    if preprocessing.method == "measured" and args.held_torques:
        warnings.warn("held torques: nothing to align, the data hold measured dq and ddq", stacklevel=2)
    prepared_train = prepare(train, preprocessing, role="training data")
    prepared_validate = None
    if validate is not None:
        if preprocessing.method == "fourier":
            check_frequency(validate, preprocessing.frequency_hz)
        prepared_validate = prepare(validate, preprocessing, role="validation data")
    return prepared_train, prepared_validate, preprocessing


def print_warnings(verb: str, caught) -> None:
    """Each warning once, in order, on stderr."""
    for message in dict.fromkeys(str(warning.message) for warning in caught):
        print(f"oed {verb}: warning: {message}", file=sys.stderr)


def check_shaped_effects_kept(effects, model) -> None:
    """A declared law with shape parameters that has no rows in this model is an error (a plain
    effect without rows is left out, as ``build_model`` does)."""
    from dynamics.effects.linear import parse_effects
    from dynamics.effects.shaped import is_shaped
    from estimation.estimators.variable_projection import NoRowsError

    for effect in parse_effects(effects):
        if is_shaped(effect, model.robot) and effect not in model.effects:
            raise NoRowsError(f"effect {getattr(effect, 'spec', effect.name)!r} has no rows in the {model.kind.value} model "
                              "(friction acts on the joint torques: use --model internal or combined)")


def result_has_shapes(model) -> bool:
    """Whether ``model`` holds a law with shape parameters (fitted by variable projection)."""
    from dynamics.effects.shaped import is_shaped

    return any(is_shaped(effect, model.robot) for effect in model.effects)


def run(args: argparse.Namespace) -> int:
    check_figure_path(args.plot)
    differentiation(args)  # contradicting derivative options are an error even when the data hold dq, ddq
    check_consistent_arguments(args)
    robot = robot_from_arguments(args)
    transmission = resolve_transmission(args, robot)
    args.friction, delay = split_delay(args.friction)  # the delay moves the motion: not a column effect
    effects = model_effects(args, robot, transmission)
    model = build_model(robot, args.model, effects)
    check_shaped_effects_kept(effects, model)
    if delay is not None and (args.consistent or streaming_requested(args)):
        raise ValueError("a delay between torques and motion is searched in memory by the weighted least squares: "
                         "not with --consistent or the streamed path (--chunk-size, --scheduler or --workers)")
    if args.consistent and result_has_shapes(model):
        raise ValueError("--consistent refits the linear effects: laws with shape parameters (coulomb:tanh, sigmoid…) "
                         "are not supported there yet; declare their plain forms (coulomb) for the consistent fit")
    if streaming_requested(args):
        if args.plot is not None:
            raise ValueError("--plot draws every sample: not with the streamed path (--chunk-size, --scheduler or "
                             "--workers)")
        if args.min_speed is not None:
            raise ValueError("--min-speed drops rows of the whole record: not with the streamed path (--chunk-size, "
                             "--scheduler or --workers)")
        if result_has_shapes(model):
            raise ValueError("laws with shape parameters (coulomb:tanh, sigmoid…) are fitted by variable projection "
                             "in memory: not with the streamed path (--chunk-size, --scheduler or --workers)")
        if args.consistent:
            raise ValueError("--consistent refits in memory: not with the streamed path (--chunk-size, --scheduler or "
                             "--workers)")
        unsupported = [option for option, given in (
            ("--transmission", args.transmission is not None), ("--average-periods", args.average_periods != "auto"),
            ("--max-gap", args.max_gap != DEFAULT_MAX_GAP)) if given]
        if unsupported:
            raise ValueError(f"{', '.join(unsupported)}: not with the streamed path (--chunk-size, --scheduler or "
                             "--workers), which reads whole files without holes, joint-side columns, and averages "
                             "periods whenever --frequency is given")
        return run_streaming(args, robot, model)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        train, validation, preprocessing = prepare_data(model, args, transmission)
        check_in_memory(model, train, validation)
        train, rest = rest_rows(train, model, args, "train")
        rest_validation = None
        if validation is not None:
            validation, rest_validation = rest_rows(validation, model, args, "validation")
        result = identify(model, train, validation, weighted=args.method == "wls", delay=delay)
        trivial, notes = trivial_predictors(result, validation)
        rest_record = {"train": rest, "validation": rest_validation}
        consistent = consistent_refit(args, result, train, validation)  # None without --consistent
    print_warnings("identify", caught)
    for note in notes:
        print(f"oed identify: warning: {note}", file=sys.stderr)
    document = finish_document(result.to_dict(), result, trivial=trivial, warnings=notes, rest=rest_record,
                               transmission=transmission)
    if consistent is not None:
        document.update(consistent.to_dict())
    add_model_file(document, result, args, preprocessing, transmission, verb="identify", consistent=consistent)
    with OutputFiles() as outputs:  # all files or none
        with outputs.open(args.out) as stream:
            stream.write(json_text(document))
        if args.plot is not None:
            comparisons = [result.train] + ([result.validation] if result.validation is not None else [])
            plot_comparison(comparisons, outputs.stage_figure(args.plot),
                            title=f"{robot.name}: {model.kind.value} model ({args.method})")

    estimate = result.estimate
    print(preprocessing.describe())
    print(f"{robot.name}: {model.kind.value} model, {model.n_base} base parameters, {train.n_samples} samples, "
          f"{estimate.method.upper()}, cond {estimate.cond:.4g}")
    _print_estimate(estimate)
    width = max(len(name) for name in estimate.names)
    for value in result.shapes:
        bound = "  (at its bound)" if value.at_bound else ""
        print(f"  {value.name:<{width}}  {value.value:+.5g} ± {value.std:.2g}  (shape of {value.effect}){bound}")
    for label, comparison in (("train", result.train), ("validation", result.validation)):
        if comparison is not None:
            print(f"{label} MSE (vs recorded): " + "  ".join(f"{channel} {value:.4g}" for channel, value in comparison.mse.items()))
            if comparison.mse_filtered is not None:
                print(f"{label} MSE (vs filtered): " + "  ".join(
                    f"{channel} {value:.4g}" for channel, value in comparison.mse_filtered.items()))
    if rest_message("identify", rest_record):
        print(rest_message("identify", rest_record))
    print_consistent(consistent)
    print(f"wrote {args.out}" + (f" and {args.plot}" if args.plot else ""))
    return 0
