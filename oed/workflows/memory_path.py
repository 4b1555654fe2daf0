"""In memory or streamed: the path of ``oed identify`` and ``oed diagnose``, decided before the records are read.

``--chunk-size``, ``--workers`` or a scheduler ask for the streamed path. Otherwise the files' rows are counted
and what the in-memory path would need (rows × channels × base parameters) is compared with ``--memory-budget``
(default a fixed 1 GB, :data:`estimation.data.memory_budget.DEFAULT_BUDGET`: the record decides the path, not the
memory free at the moment). Past it, and when every option given is one the streamed
path has, the derivatives are chosen on the same window as in memory
(:func:`estimation.streaming.cutoff_choice.choose_streamed_preprocessing`) and the files are streamed; a Fourier
fit of averaged periods shrinks the training record to one period, which may bring it back within the budget.
The decision is said in one line (``say``; on stderr from the command line).
"""

from __future__ import annotations

import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace

from dynamics.models import IdentificationModel
from estimation.data.sampling_clock import RECEIVE_TIMES_RATIO
from estimation.identification.preprocessing_choice import SCORED_SAMPLES, PreprocessingChoice
from estimation.identification.time_base_choice import choose_time_base
from estimation.preprocessing.differentiation import whole_periods
from estimation.preprocessing.plan import Preprocessing
from estimation.data.input_findings import FindingsSaid, grouped_messages
from estimation.data.loading import HoldWarning
from estimation.data.memory_budget import (
    InMemoryNeed,
    count_rows,
    default_budget,
    estimate_in_memory,
    parse_memory_size,
)
from oed.workflows.options import RecordOptions, streaming_requested

__all__ = ["IN_MEMORY_ROUTE", "PathDecision", "decide_path", "on_time_base", "stamps_kept", "streamed_choice",
           "streamed_records", "streamed_time_base", "with_time_base"]

#: what an option the streamed path lacks leaves the user (:func:`decide_path` reads such a run in memory whatever
#: the records' size): said where ``--chunk-size``, ``--scheduler`` or ``--workers`` asked for the streamed path
IN_MEMORY_ROUTE = ("leave out --chunk-size, --scheduler and --workers to read the records in memory with it (a run "
                   "with this option is read in memory whatever --memory-budget says, and needs the memory for it)")


@dataclass(frozen=True)
class PathDecision:
    """The path a run takes.

    Attributes
    ----------
    stream
        Whether the files are streamed.
    plan
        The derivatives chosen before reading (``None``: the in-memory path chooses them as it reads).
    need
        The in-memory estimate against the budget (``None`` when streaming was asked for).
    findings
        What was said about the files while choosing the derivatives (``None`` when nothing was read): the
        streamed run goes on with it, so that its passes do not say those findings again.
    """

    stream: bool
    plan: Preprocessing | None = None
    need: InMemoryNeed | None = None
    findings: FindingsSaid | None = None


def budget_of(args: RecordOptions) -> int:
    """``--memory-budget`` in bytes, else the fixed default budget (the same on every machine)."""
    return default_budget() if args.memory_budget is None else parse_memory_size(args.memory_budget)


def streamed_choice(args: RecordOptions, model: IdentificationModel,
                    rows: Sequence[int] | None = None, *, validation_fits: tuple[str, ...] = (),
                    validation_model: IdentificationModel | None = None) -> PreprocessingChoice:
    """The derivatives of ``--data``, chosen as in memory (the same window, candidates and rule), with the
    derivative options given; ``validation_fits``: chosen again on a ``--validate`` record of another motion, as
    in memory (:mod:`estimation.identification.preprocessing_on_validation`), by fits of ``validation_model``
    (``None``: ``model``)."""
    from estimation.streaming.chunks import segment_sources
    from estimation.streaming.cutoff_choice import choose_streamed_preprocessing

    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", category=HoldWarning)  # said when the parts are read (streamed_records)
        data = segment_sources(args.data, model, holds_cut=holds_cut(args))  # a file split at its holes, as in memory
    validation = segment_sources(getattr(args, "validate", None) or (), model)
    rows = rows if len(data) == len(args.data) else None
    options = {"frequency_hz": args.frequency, "harmonics": args.harmonics, "cutoff_hz": args.cutoff,
               "average_periods": args.average_periods, "decimation": args.decimate,
               "held_torques": args.held_torques, "validation_fits": validation_fits,
               "validation_model": validation_model}
    choice = choose_streamed_preprocessing(data, model, rows=rows, held_out=validation, validation=validation,
                                           **options)
    chosen = choice.chosen
    if not (validation_fits and validation) or chosen.evidence is None or chosen.evidence.selection != "validation":
        return choice  # the time base is a candidate where the derivatives are chosen on another motion, as in memory
    return streamed_time_base(choice, data, validation, segment_sources(getattr(args, "test", None) or (), model),
                              model, options)


def streamed_time_base(choice: PreprocessingChoice, data: Sequence, validation: Sequence, test: Sequence,
                       model: IdentificationModel, options: dict) -> PreprocessingChoice:
    """``choice`` (made on the sources at their stamps, on a validation record of another motion) against the same
    choice on the sources' regular clock, as memory chooses the time base
    (:mod:`estimation.identification.time_base_choice`): only where the positions of a training or validation
    source are :data:`~estimation.data.sampling_clock.RECEIVE_TIMES_RATIO` times smoother on a regular clock (the
    ratio summed over every kept row, :func:`~estimation.streaming.chunks.receive_times_evidence_of`), every
    source has one, and no training source is a part between holds (those keep the stamps,
    :data:`~estimation.identification.time_base_choice.STREAMED_PARTS_TIME_BASE`); both clocks' validation
    candidates rescored together (:func:`~estimation.identification.time_base_choice.choose_time_base`). The plan
    chosen says its :attr:`~estimation.preprocessing.plan.Preprocessing.time_base`; :func:`on_time_base` then
    reads the sources on it."""
    from estimation.streaming.chunks import clock_source, receive_times_evidence_of, source_rows
    from estimation.streaming.cutoff_choice import choose_streamed_preprocessing
    from estimation.streaming.time_base import NoRegularClockError

    if stamps_kept(data):
        return choice
    ratios = [ratio for ratio in (receive_times_evidence_of(path, model) for path in (*data, *validation))
              if ratio is not None]
    if not ratios or max(ratios) < RECEIVE_TIMES_RATIO:
        return choice
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # said when the sources were read at their stamps
        try:
            for path in (*data, *validation, *test):
                source_rows(clock_source(path), model)  # a scan on the clock: none when a stamp lies off it
        except NoRegularClockError:
            return choice
        on_clock = choose_streamed_preprocessing(
            [clock_source(path) for path in data], model, held_out=[clock_source(path) for path in validation],
            validation=[clock_source(path) for path in validation], **options).chosen
    chooser = options["validation_model"] or model
    chosen = choose_time_base(choice.chosen, on_clock, chooser.channels, max(ratios))
    return PreprocessingChoice(chosen, chosen)


def stamps_kept(data: Sequence) -> bool:
    """Whether a training source is a part between holds, whose regular clock the streamed path does not score
    (:func:`streamed_time_base`; ``not_computed.time_base``)."""
    from estimation.streaming.chunks import source_file
    from estimation.streaming.time_base import Part

    return any(isinstance(source_file(path)[1], Part) for path in data)


def with_time_base(model_plan: dict, plan: Preprocessing) -> dict:
    """A streamed model file's preprocessing (``Preprocessing.to_dict`` keys) with ``plan``'s time base: ``oed
    predict`` reads a record on the regular clock when the fit read its sources on it (:func:`on_time_base`)."""
    if plan.velocity_from_positions:  # oed predict makes dq from the positions too (on_time_base)
        model_plan = {**model_plan, "velocity_from_positions": True}
    return {**model_plan, "time_base": "regular"} if plan.time_base == "regular" else model_plan


def on_time_base(args, plan: Preprocessing | None):
    """``args`` with the sources of ``--data`` and ``--validate`` read on the regular clock their stamps
    jitter around (:func:`estimation.streaming.chunks.clock_source`) when ``plan`` chose it
    (:func:`streamed_time_base`), else ``args``: every pass then reads the same samples as memory's records on that
    clock. Where ``plan`` makes ``dq`` from the positions though the files log it (``velocity_from_positions``,
    a candidate of memory's choice), the sources are read without their logged velocities
    (:func:`estimation.streaming.chunks.positions_source`): every pass derives ``dq`` as memory's filter does."""
    from estimation.streaming.chunks import clock_source, positions_source

    if plan is None or (plan.time_base != "regular" and not plan.velocity_from_positions):
        return args

    def placed(path):
        path = clock_source(path) if plan.time_base == "regular" else path
        return positions_source(path) if plan.velocity_from_positions else path
    changes = {name: [placed(path) for path in getattr(args, name)]
               for name in ("data", "validate") if getattr(args, name, None)}
    return replace(args, **changes)


def averaged_rows(plan: Preprocessing, args: RecordOptions, model: IdentificationModel,
                  rows: Sequence[int]) -> list[int] | None:
    """Samples each training file keeps when ``plan`` averages its periods (one period each), else ``None``."""
    if plan.method != "fourier" or plan.average_periods == "no":
        return None
    from estimation.streaming.cutoff_choice import first_rows

    head = first_rows(args.data[0], model, min(rows[0], SCORED_SAMPLES))
    found = whole_periods(head, plan.frequency_hz)
    if found is None:
        return None
    per_period = found[1]
    if any(count < 2 * per_period for count in rows):
        return None  # fewer than two periods: fitted sample by sample in memory
    return [per_period] * len(rows)


def streamed_records(args, model: IdentificationModel):
    """``args`` with the files of ``--data``, ``--validate`` and ``--test`` that hold holes longer than ``--max-gap``
    replaced by their segments (:func:`estimation.streaming.chunks.segment_sources`): the streamed path reads and
    preprocesses each on its own, as the in-memory path splits such a file; the training files with holds by their
    parts between them (:func:`holds_cut`), said in a :class:`~estimation.data.loading.HoldWarning`."""
    from estimation.streaming.chunks import segment_sources

    changes = {name: segment_sources(getattr(args, name), model, holds_cut=name == "data" and holds_cut(args))
               for name in ("data", "validate", "test") if getattr(args, name, None)}
    return replace(args, **changes) if changes else args


def holds_cut(args) -> bool:
    """The training files' holds are cut out of the fit, as in memory: rows at rest not handled by the user
    (no ``--min-speed``; :func:`estimation.identification.prepared.training_without_holds`)."""
    return getattr(args, "min_speed", None) is None


def decide_path(args: RecordOptions, model: IdentificationModel, *, task: str, bytes_per_value: float,
                in_memory_only: Callable[[], str | None], say: Callable[[str], None],
                validation_fits: tuple[str, ...] = (),
                validation_model: IdentificationModel | None = None) -> PathDecision:
    """The path of this run (module docstring); ``in_memory_only`` names an option given that the streamed path
    lacks (``None`` when there is none). Says the decision in one line (``say``) when it streams or when the
    budget is passed, and the warnings of choosing the derivatives before reading (``warning: ...``).
    ``validation_fits``, ``validation_model``: as :func:`streamed_choice`."""
    budget = budget_of(args)  # a bad --memory-budget is an error whichever the path
    if streaming_requested(args):
        return PathDecision(True)
    try:
        train = [count_rows(path) for path in args.data]
        held_out = [count_rows(path) for path in [*(args.validate or ()), *(getattr(args, "test", None) or ())]]
    except (OSError, ValueError, ImportError):  # a file missing, a folder, no pyarrow, a corrupt footer: the reader says so
        return PathDecision(False)
    need = estimate_in_memory(train + held_out, model, bytes_per_value=bytes_per_value, budget=budget)
    if not need.stream:
        return PathDecision(False, None, need)
    reason = in_memory_only()
    if reason is not None:
        say(f"{need.describe(task)}, but {reason}: in memory")
        return PathDecision(False, None, need)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        plan = streamed_choice(args, model, train, validation_fits=validation_fits,
                               validation_model=validation_model).chosen
    sources = [*args.data, *(args.validate or ()), *(getattr(args, "test", None) or ())]
    for message in grouped_messages(caught, sources):  # one line per finding across files
        say(f"warning: {message}")
    findings = FindingsSaid(sources)
    findings.mark(caught)
    kept = averaged_rows(plan, args, model, train)
    if kept is not None:
        need = estimate_in_memory(train + held_out, model, bytes_per_value=bytes_per_value, budget=budget,
                                  reduced_rows=kept + held_out)
        if not need.stream:
            say(f"{need.describe(task)} ({plan.describe_method()} of averaged periods)")
            return PathDecision(False, plan, need)
    say(need.describe(task) + " (--memory-budget to change it, --chunk-size to set the chunks)")
    return PathDecision(True, plan, need, findings)

