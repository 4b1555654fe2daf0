"""``oed diagnose --chunk-size/--workers/--scheduler``: the diagnosis in bounded memory
(:mod:`estimation.streaming.diagnosis`), same report keys as the in-memory ``oed diagnose``, the model file
(``model_file``) that ``oed predict`` reads among them."""

from __future__ import annotations

import argparse
import warnings

from dynamics.models import IdentificationModel, build_model
from dynamics.robot import RobotModel
from estimation.data.log_cleaning import DEFAULT_MAX_GAP
from estimation.diagnosis.results import runner_up_line
from estimation.estimators.normal_equations import DEFAULT_CHUNK_SIZE
from estimation.preprocessing.plan import Preprocessing
from estimation.streaming.recorded_errors import streamed_plan
from estimation.streaming.diagnosis import DEFAULT_SUBSAMPLE, diagnose_files
from estimation.streaming.diagnosis_passes import FLOOR_WINDOW
from estimation.streaming.diagnosis_result import StreamedDiagnosis
from oed.cli.shared.asbuilt import model_effects
from oed.cli.shared.memory_path import streamed_choice
from oed.cli.shared.model_files import add_summed_model_file, add_summed_runner_up_model_file
from oed.cli.shared.common import (
    OutputFiles,
    check_shaped_effects_kept,
    executor_from_arguments,
    json_text,
    model_has_shapes,
    print_warnings,
    robot_from_arguments,
)

STREAMED = "the streamed path (--chunk-size, --scheduler or --workers)"


def add_streamed_diagnosis_arguments(parser: argparse.ArgumentParser) -> None:
    """``--subsample`` and ``--floor-window`` (``--chunk-size``, ``--workers``, ``--scheduler``: as identify's)."""
    group = parser.add_argument_group("streamed diagnosis (estimation.streaming.diagnosis)")
    group.add_argument("--subsample", type=int, default=DEFAULT_SUBSAMPLE, metavar="N",
                       help=f"training samples, spread evenly, on which shaped laws' shapes are searched and coupling "
                            f"pairs traced (default {DEFAULT_SUBSAMPLE}; up to twice that are kept)")
    group.add_argument("--floor-window", type=int, default=FLOOR_WINDOW, metavar="N",
                       help=f"rows of each validation file the noise floor is estimated on (default {FLOOR_WINDOW})")


def check_streamed_arguments(args: argparse.Namespace, model) -> None:
    """Options the streamed diagnosis does not have: an error naming them, before anything is read."""
    unsupported = [option for option, given in (
        ("--report", args.report is not None),
        ("--transmission", args.transmission is not None),
        ("--min-speed", args.min_speed is not None),
        ("--average-periods no", args.average_periods == "no"),
        ("--max-gap", args.max_gap != DEFAULT_MAX_GAP)) if given]
    if unsupported:
        raise ValueError(f"{', '.join(unsupported)}: not with {STREAMED}, which reads whole files without holes "
                         "on the filter path, the files' dq, ddq or a Fourier fit of averaged periods, and writes the "
                         "JSON report only")
    if model_has_shapes(model):
        raise ValueError(f"declared laws with shape parameters (coulomb:tanh, sigmoid…) are fitted in memory: not with "
                         f"{STREAMED}; declare their plain forms, or let the diagnosis find them")
    for option in ("subsample", "floor_window"):
        value = getattr(args, option)
        if isinstance(value, bool) or value < 1:
            raise ValueError(f"--{option.replace('_', '-')} must be a positive integer, got {value}")


def run_streaming(args: argparse.Namespace, plan: Preprocessing | None = None) -> int:
    """Diagnose the files read chunk by chunk (:func:`estimation.streaming.diagnosis.diagnose_files`), their
    derivatives chosen as in memory (``plan``: already chosen)."""
    robot = robot_from_arguments(args)
    effects = model_effects(args, robot, None)
    model = build_model(robot, args.model, effects)
    check_shaped_effects_kept(effects, model)
    check_streamed_arguments(args, model)
    chunk_size = DEFAULT_CHUNK_SIZE if args.chunk_size is None else args.chunk_size
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        if plan is None:
            plan = streamed_choice(args, model).chosen
        with executor_from_arguments(args) as executor:
            result = diagnose_files(model, args.data, args.validate, chunk_size=chunk_size, alpha=args.alpha,
                                    max_effects=args.max_effects, subsample=args.subsample,
                                    floor_window=args.floor_window, executor=executor, preprocessing=plan)
    print_warnings("diagnose", caught)
    document = result.to_dict()
    document["preprocessing"] = {"cutoff_hz": result.streaming["cutoff_hz"], **plan.to_dict()}
    document["max_effects"] = args.max_effects
    document["max_effects_reached"] = len(result.effects) >= args.max_effects
    # the model file: the final model's estimate from the sums; on the filter path (and with measured derivatives)
    # its validation error is against the channels as recorded, on the samples the in-memory preprocessing keeps,
    # which is what `oed predict` measures; a Fourier fit of averaged periods is not what `oed predict` repeats
    if plan.method == "fourier":
        model_plan, validation_mse = plan.to_dict(), None
    else:
        model_plan = streamed_plan(args.data[0], model, cutoff_hz=result.streaming["cutoff_hz"],
                                   decimation=plan.decimation, held_torques=plan.held_torques, chunk_size=chunk_size)
        validation_mse = result.validation_mse["after"]
    add_summed_model_file(document, result.final_model(), result.after, args, model_plan,
                          verb="diagnose", shape=result.final_shape(), recorded_mse=result.train_mse["after"],
                          validation_mse=validation_mse)
    runner_up = result.runner_up
    add_summed_runner_up_model_file(document, runner_up, args, model_plan, None if validation_mse is None or
                                    runner_up is None else runner_up.validation_mse)
    with OutputFiles() as outputs, outputs.open(args.out) as stream:
        stream.write(json_text(document))
    print(plan.describe())
    print_streamed_summary(args, robot, model, result, chunk_size)
    print(f"wrote {args.out}")
    return 0


def print_streamed_summary(args: argparse.Namespace, robot: RobotModel, model: IdentificationModel,
                           result: StreamedDiagnosis, chunk_size: int) -> None:
    """The records, the effects found, the validation MSE before and after and the noise floor."""
    streaming = result.streaming
    print(f"{robot.name}: {model.kind.value} model, streamed diagnosis of {result.n_train} training samples from "
          f"{len(streaming['files'])} file(s) in chunks of {chunk_size}, {result.n_validation} validation samples; "
          f"shapes searched on {streaming['subsample']['samples']} samples")
    if result.effects:
        for effect in result.effects:
            values = ", ".join(f"{n} = {v:.4g} ± {s:.2g}" for n, v, s in zip(effect.parameters, effect.values, effect.std))
            values += "".join(f", {n} = {v:.4g}" for n, v in effect.shape.items())
            print(f"found {effect.spec or effect.name} on {', '.join(effect.channels)}: {values} (p = {effect.p_value:.2g})")
    else:
        print("found nothing: the declared model explains the data")
    print(runner_up_line(result.runner_up, result.runner_up_reason))
    before, after = result.validation_mse["before"], result.validation_mse["after"]
    print("validation MSE vs recorded")
    print("                 " + "  ".join(f"{channel:>9s}" for channel in before))
    print("  before         " + "  ".join(f"{value:9.4g}" for value in before.values()))
    print("  after          " + "  ".join(f"{after[channel]:9.4g}" for channel in before))
    if result.floor is not None:
        floor = result.floor.mse()
        print("  noise floor    " + "  ".join(f"{floor[channel]:9.4g}" for channel in before)
              + f"   ({result.floor.method}; {result.floor_note})")
    else:
        print(result.floor_note)
    if len(result.effects) >= args.max_effects:
        print(f"stopped at --max-effects {args.max_effects}; raise --max-effects to test the rest")
