"""The result of a streamed diagnosis (:func:`estimation.streaming.diagnosis.diagnose_files`): its settings, the
passes and search it ran (:class:`StreamedRun`), and the result assembled from them (:func:`streamed_result`: the
in-memory path's :class:`~estimation.diagnosis.results.Diagnosis`, with ``path="streamed"``, a ``streaming`` entry
saying how the files were read, summed and estimated, and what the sums cannot give in ``not_computed``).
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from dynamics.effects.linear import Effect
from dynamics.models import IdentificationModel, build_model
from estimation.diagnosis.candidates.trials import candidate_label
from estimation.diagnosis.forward_selection import SearchOutcome
from estimation.diagnosis.rules.robust_test import estimate_test
from estimation.diagnosis.results import (
    STREAMED_NOT_COMPUTED,
    ChannelErrors,
    Diagnosis,
    FoundEffect,
    RejectedEffect,
    SummedFit,
    found_delay,
)
from estimation.diagnosis.sign_constraints import PinnedTerm
from estimation.diagnosis.statistics import FLOOR_ALPHA, ResidualReport
from estimation.estimators.summed_least_squares import SummedEstimate
from estimation.identification.fit import implausible_estimates
from estimation.identification.subtracted_load import SubtractedLoad
from estimation.identification.trivial_predictors import trivial_warnings
from estimation.uncertainty.noise_floor import NoiseFloor
from estimation.uncertainty.floor_comparison import compare_with_floor
from estimation.streaming.diagnosis_candidates import StreamedCandidates
from estimation.streaming.diagnosis_passes import SubsamplePass, SumsPass

__all__ = ["NOT_ON_THIS_PATH", "StreamedRun", "StreamedSettings", "file_record", "floor_report", "found_effects",
           "streamed_result", "streaming_record"]

NOT_ON_THIS_PATH = (
    "residual tracing, whiteness and residual statistics (need the residuals sample by sample)",
    "the declared model's HAC standard deviations (classical there; the augmented model's are batch means)",
    "the search over the whole record: the in-memory search (its shapes refined round by round, its HAC Wald tests, "
    "its final joint refit) runs on an evenly spread subsample of each record, the whole record's sums give the "
    "estimate at its shapes, the covariance and the errors",
    "shape standard deviations",
    "user stopping rules (the noise floor is the rule)",
    "model_parameters (the physical reading of the estimate)",
    "the delay's standard deviation over the whole record (the subsample's final refit gives it)",
    "limit laws in the final estimate (the subsample's final refit applies them to choose the findings; negative "
    "friction is held at zero on the whole record's sums, as in memory)",
)


@dataclass(frozen=True)
class StreamedSettings:
    """The settings of :func:`diagnose_files` (its keyword arguments but ``candidates`` and ``executor``)."""

    chunk_size: int
    cutoff_hz: float | None
    decimation: int
    held_torques: bool
    alpha: float
    min_improvement: float
    max_effects: int
    noise_floor: NoiseFloor | None
    subsample: int
    floor_window: int | None
    frequency_hz: float | None = None
    harmonics: int = 5
    order: int = 4
    #: memory's choice of averaging a periodic file's periods on the Fourier path (``--average-periods``:
    #: :func:`estimation.streaming.periods.read_periodic`'s ``average``)
    average: str = "auto"
    #: a load of the description the logged torques lack (:mod:`estimation.identification.subtracted_load`), added
    #: back to every prepared chunk of every pass (:func:`estimation.streaming.chunks.loaded_chunk`); ``None``: the
    #: torques as logged
    load: SubtractedLoad | None = None

    def reading(self) -> dict[str, Any]:
        """How each file is read and prepared (:func:`estimation.streaming.periods.plan_chunks`): the filter's
        filter covering the record's ends (nothing trimmed), as the in-memory preprocessing does; or the Fourier path;
        the load the torques lack added back (``load``, when there is one)."""
        options = {"chunk_size": self.chunk_size, "cutoff_hz": self.cutoff_hz, "decimation": self.decimation,
                   "held_torques": self.held_torques, "trim": False, "order": self.order}
        if self.frequency_hz is not None:
            options.update(frequency_hz=self.frequency_hz, harmonics=self.harmonics)
            if self.average != "auto":
                options["average"] = self.average
        if self.load is not None:
            options["load"] = self.load
        return options


@dataclass(frozen=True)
class StreamedRun:
    """One streamed diagnosis: its files and settings, passes, candidates and search, and the
    candidates its final estimate holds (``chosen``) with their columns in the sums."""

    paths: list[str]
    validate: list[str]
    settings: StreamedSettings
    first: SubsamplePass
    sums: SumsPass
    found: StreamedCandidates
    outcome: SearchOutcome
    chosen: list[int]
    columns: list[int]
    #: the declared effects the final estimate holds (a positive-by-physics term below zero held at zero: that
    #: joint removed, as in memory; ``None``: all of them), and the terms so held
    declared: tuple[Effect, ...] | None = None
    pinned: tuple[PinnedTerm, ...] = ()


def file_record(path: str, sums, record: dict) -> dict[str, Any]:
    return {"path": path, "rows": record["rows"], "samples": sums.n_samples,
            "trimmed_samples": record["metadata"].get("trimmed_samples", 0),
            "resampled_from": record["metadata"].get("resampled_from"),  # rows of a file resampled onto a grid
            # on the Fourier path: the periods its sums average (0: every sample fitted), else absent
            **({"periods_averaged": int(record["metadata"]["periods_averaged"])}
               if record["metadata"].get("periods_averaged") is not None else {})}


def found_effects(model: IdentificationModel, run: StreamedRun, after: SummedEstimate) -> tuple[FoundEffect, ...]:
    records = {r["name"]: r for r in after.records()}
    effects = []
    for index in run.chosen:
        block = run.found.blocks[index]
        test = estimate_test(after, block.names)  # the p-value of the reported (batch-means) covariance
        effects.append(FoundEffect(
            name=block.effect.name, channels=tuple(model.channels[r] for r in block.rows), parameters=block.names,
            values=tuple(records[name]["value"] for name in block.names),
            std=tuple(records[name]["std"] for name in block.names), p_value=test.p_value,
            f_statistic=test.f_statistic, spec=candidate_label(block.effect),
            shape={p.name: float(v) for p, v in zip(block.parameters, run.found.shapes[index])}, shape_std={}))
    return tuple(effects)


def streaming_record(run: StreamedRun, covariance: dict[str, Any], seconds: dict[str, float]) -> dict[str, Any]:
    """The report's ``streaming`` entry: how the files were read, summed and estimated."""
    settings, sums = run.settings, run.sums
    normal = sums.train.normal_system(run.columns, run.outcome.weights)[0]
    scale = np.sqrt(np.diag(normal))
    condition = float(np.linalg.cond(normal / np.outer(scale, scale)))
    return {
        "chunk_size": int(settings.chunk_size), "cutoff_hz": settings.cutoff_hz, "decimation": int(settings.decimation),
        "frequency_hz": settings.frequency_hz, "harmonics": settings.harmonics if settings.frequency_hz else None,
        **({"average_periods": settings.average} if settings.frequency_hz and settings.average != "auto" else {}),
        "files": [file_record(path, part, record) for path, (part, record) in zip(run.paths, sums.train_parts)],
        "validation_files": [file_record(path, part, record)
                             for path, (part, record) in zip(run.validate, sums.validate_parts)],
        "subsample": {"samples": run.first.sample.n_samples, "of": run.first.seen, "requested": int(settings.subsample),
                      "used_for": "shape search of shaped laws, coupling-pair tracing"},
        "floor_window": (None if settings.floor_window is None else int(settings.floor_window))
        if settings.noise_floor is None else None,
        "stopped_at_floor": run.outcome.stopped_at_floor,
        "covariance": covariance,
        "seconds": seconds,
        "errors_against": "the channels as recorded, along the derived motion",
        "accuracy": {"solve": "per-channel Gram sums, equilibrated, Cholesky (as the in-memory loop)",
                     "equilibrated_normal_cond": condition,
                     "relative_error_bound": condition * np.finfo(float).eps},
        "not_on_this_path": list(NOT_ON_THIS_PATH),
    }


def streamed_result(model: IdentificationModel, run: StreamedRun, before: SummedEstimate, after: SummedEstimate,
                    floor: NoiseFloor | None, floor_note: str, streaming: dict[str, Any]) -> Diagnosis:
    """The result (the :class:`~estimation.diagnosis.results.Diagnosis` of the in-memory path, its fields filled
    from the sums): errors before and after against the recording, the floor comparison, the trivial predictors,
    warnings; what the sums cannot give is ``None`` with its reason (``not_computed``)."""
    train, validation, base = run.sums.train, run.sums.validation, list(range(model.n_base))
    # the declared model along the motion as read (an adopted delay moved the passes' sums; in memory too, the
    # declared fit and the trivial predictors are along the records as read)
    as_read = {"train": train, "validation": validation} if run.sums.declared is None else \
        dict(zip(("train", "validation"), run.sums.declared))
    nominal = model.base.K @ model.nominal_parameters()
    trivial = {"zero_mse": dict(zip(model.channels, map(float, validation.power[:, 1] / validation.n_samples))),
               "nominal_mse": dict(zip(model.channels, map(float, as_read["validation"].channel_mse(base, nominal))))}
    mse = {(name, which): dict(zip(model.channels, map(float, (part if which == "after" else as_read[name])
                                                        .channel_mse(selection, theta))))
           for name, part in (("train", train), ("validation", validation))
           for which, selection, theta in (("before", base, before.values), ("after", run.columns, after.values))}
    rejected = dict(run.outcome.rejected)
    delay = run.found.delay
    if delay.reason is not None:  # the delay not adopted, with the rejected candidates, as in memory
        rejected[run.found.n_candidates] = RejectedEffect("delay", tuple(model.channels), delay.reason, "delay")
    for term in (term for term in run.pinned if term.found):  # a finding held at zero: dropped, as in memory
        index = next((index for index, block in run.found.blocks.items() if term.parameter in block.names
                      and candidate_label(block.effect) == term.effect), None)
        if index is not None:
            block = run.found.blocks[index]
            rejected[index] = RejectedEffect(
                block.effect.name, tuple(model.channels[row] for row in block.rows),
                f"added, but its estimate turned negative in the final fit ({term.parameter} = {term.value:.4g} ± "
                f"{term.std:.2g}): dropped", term.effect)
    found = tuple(run.found.blocks[index].effect for index in run.chosen)
    final = build_model(model.robot, model.kind, tuple(model.effects if run.declared is None else run.declared) + found)
    fits = {which: SummedFit(
        model=model if which == "before" else final, estimate=estimate,
        train=ChannelErrors(mse["train", which], train.n_samples),
        validation=ChannelErrors(mse["validation", which], validation.n_samples),
        warnings=implausible_estimates(model if which == "before" else final, estimate) + (
            trivial_warnings(mse["validation", "after"], trivial) if which == "after" else ()),
        cov_method="classical" if which == "before" else "batch_means")  # batch means: estimation.streaming.covariance
        for which, estimate in (("before", before), ("after", after))}
    if delay.value is not None:  # the adopted delay: the model's, as its shapes (the model file's ``delay``)
        fits["after"] = replace(fits["after"], shapes=(delay.value,), delay=delay.value)
    return Diagnosis(
        effects=found_effects(model, run, after) + found_delay(fits["after"], delay.value, model),
        rejected=tuple(rejected[i] for i in sorted(rejected)),
        before=fits["before"], after=fits["after"], residuals=None,
        statistics=floor_report(fits["before"], fits["after"], floor, floor_note),
        path="streamed", not_computed=dict(STREAMED_NOT_COMPUTED), trivial=trivial, streaming=streaming,
        pinned=run.pinned)


def floor_report(before: SummedFit, after: SummedFit, floor: NoiseFloor | None, floor_note: str) -> ResidualReport:
    """The validation errors against the noise floor (no tracing nor whiteness: no residuals held)."""
    comparison, statements = {}, {}
    if floor is not None:
        for which, fit in (("before", before), ("after", after)):
            comparison[which] = compare_with_floor(fit.validation.mse, floor, fit.validation.n_samples,
                                                   alpha=FLOOR_ALPHA)
        statements = {channel: c.statement() for channel, c in comparison["after"].items()}
    return ResidualReport(floor, floor_note, comparison, tracing=None, checks=None, statements=statements)
