"""The result of a streamed diagnosis (:func:`estimation.streaming.diagnosis.diagnose_files`): its settings, the
passes and search it ran (:class:`StreamedRun`), and the report assembled from them (:class:`StreamedDiagnosis`, the
keys of the in-memory diagnosis's document, with ``diagnosis_path: "streamed"`` and a ``streaming`` entry saying how
the files were read, summed and estimated).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from dynamics.effects.linear import Effect
from dynamics.models import IdentificationModel, build_model
from estimation.diagnosis.candidates.trials import candidate_label
from estimation.diagnosis.forward_selection import SearchOutcome
from estimation.diagnosis.rules.robust_test import estimate_test
from estimation.diagnosis.search import FoundEffect, RejectedEffect
from estimation.diagnosis.statistics import FLOOR_ALPHA
from estimation.estimators.summed_least_squares import SummedEstimate
from estimation.identification.fit import implausible_estimates
from estimation.identification.trivial_predictors import trivial_warnings
from estimation.uncertainty.noise_floor import NoiseFloor
from estimation.uncertainty.floor_comparison import compare_with_floor
from estimation.streaming.diagnosis_candidates import StreamedCandidates
from estimation.streaming.diagnosis_passes import SubsamplePass, SumsPass

__all__ = ["NOT_ON_THIS_PATH", "StreamedDiagnosis", "StreamedRun", "StreamedSettings", "file_record", "found_effects",
           "streamed_result", "streaming_record"]

NOT_ON_THIS_PATH = (
    "residual tracing, whiteness and residual statistics (need the residuals sample by sample)",
    "the declared model's HAC standard deviations (classical there; the augmented model's are batch means)",
    "shapes refined round by round and refitted jointly at the end (fixed at the subsample's optimum)",
    "shape standard deviations",
    "a law paired with its offset searched jointly (the pair uses the law's own shape)",
    "user stopping rules (the noise floor is the rule)",
    "model_parameters (the physical reading of the estimate)",
    "a delay between torques and motion as a candidate (it moves the records)",
    "the search's Wald tests from a HAC covariance (classical on the sums; the reported p-values are the final "
    "estimate's batch-means ones, and a finding within its noise there is not dropped)",
    "a pair's Coulomb and viscous laws tried as one candidate, limit laws, negative friction held at zero "
    "(pinned), the traced shape refinement",
)


@dataclass(frozen=True)
class StreamedDiagnosis:
    """Result of :func:`diagnose_files` (the keys of :class:`estimation.diagnosis.search.Diagnosis`'s document)."""

    model: IdentificationModel
    effects: tuple[FoundEffect, ...]
    rejected: tuple[RejectedEffect, ...]
    before: SummedEstimate
    after: SummedEstimate
    train_mse: dict[str, dict[str, float]]  # before/after, against the recording
    validation_mse: dict[str, dict[str, float]]
    n_train: int
    n_validation: int
    floor: NoiseFloor | None
    floor_note: str
    streaming: dict[str, Any] = field(repr=False)
    warnings: dict[str, tuple[str, ...]] = field(default_factory=dict)
    trivial: dict[str, dict[str, float]] = field(default_factory=dict)  # zero_mse, nominal_mse (validation)
    #: the effect objects of ``effects``, in the order of ``after``'s columns (shaped laws at ``effects[i].shape``)
    found_effects: tuple[Effect, ...] = ()
    runner_up: Any = field(default=None, repr=False)  # estimation.diagnosis.runner_up, from the sums
    runner_up_reason: str | None = None

    def final_model(self) -> IdentificationModel:
        """The declared model with the effects found: ``after`` holds its base parameters (in the order of its columns)."""
        return build_model(self.model.robot, self.model.kind, tuple(self.model.effects) + tuple(self.found_effects))

    def final_shape(self) -> dict[str, float]:
        """The fixed shapes of the shaped laws found, by parameter name."""
        return {name: float(value) for effect in self.effects for name, value in effect.shape.items()}

    def to_dict(self) -> dict[str, Any]:
        comparison, statements, ratios = {}, {}, {"before": None, "after": None}
        if self.floor is not None:
            for which in ("before", "after"):
                comparison[which] = compare_with_floor(self.validation_mse[which], self.floor, self.n_validation,
                                                       alpha=FLOOR_ALPHA)
                ratios[which] = {channel: c.ratio for channel, c in comparison[which].items()}
            statements = {channel: c.statement() for channel, c in comparison["after"].items()}
        floor = ({"mse": None, "note": self.floor_note} if self.floor is None
                 else {**self.floor.to_dict(), "note": self.floor_note})
        return {
            "robot": self.model.robot.name,
            "model": self.model.kind.value,
            "declared_effects": [effect.name for effect in self.model.effects],
            "effects": [effect.to_dict() for effect in self.effects],
            "rejected": [{"name": r.name, "spec": r.spec or r.name, "channels": list(r.channels), "reason": r.reason}
                         for r in self.rejected],
            "residuals": None,  # per-sample statistics: not on the streamed path
            "warnings": {which: list(self.warnings.get(which, ())) for which in ("before", "after")},
            "train": {which: {"mse": self.train_mse[which]} for which in ("before", "after")},
            "validation": {**{which: {"mse": self.validation_mse[which], "mse_over_floor": ratios[which]}
                              for which in ("before", "after")}, **{key: dict(value) for key, value in self.trivial.items()}},
            "cov_method": "batch_means",  # the sandwich of estimation.streaming.covariance (a third pass)
            "noise_floor": floor,
            "floor_comparison": {which: {channel: c.to_dict() for channel, c in values.items()}
                                 for which, values in comparison.items()},
            "floor_statements": statements,
            "tracing": None,
            "whiteness": None,
            "rest": None,
            "transmission": None,
            "diagnosis_path": "streamed",
            "streaming": dict(self.streaming),
            "runner_up": None if self.runner_up is None else self.runner_up.to_dict(),
            "runner_up_reason": self.runner_up_reason,
        }


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
    floor_window: int
    frequency_hz: float | None = None
    harmonics: int = 5
    order: int = 4

    def reading(self) -> dict[str, Any]:
        """How each file is read and prepared (:func:`estimation.streaming.periods.plan_chunks`): the filter's
        filter covering the record's ends (nothing trimmed), as the in-memory preprocessing does; or the Fourier path."""
        options = {"chunk_size": self.chunk_size, "cutoff_hz": self.cutoff_hz, "decimation": self.decimation,
                   "held_torques": self.held_torques, "trim": False, "order": self.order}
        if self.frequency_hz is not None:
            options.update(frequency_hz=self.frequency_hz, harmonics=self.harmonics)
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


def file_record(path: str, sums, record: dict) -> dict[str, Any]:
    return {"path": path, "rows": record["rows"], "samples": sums.n_samples,
            "trimmed_samples": record["metadata"].get("trimmed_samples", 0),
            "resampled_from": record["metadata"].get("resampled_from")}  # rows of a file resampled onto a grid


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
        "files": [file_record(path, part, record) for path, (part, record) in zip(run.paths, sums.train_parts)],
        "validation_files": [file_record(path, part, record)
                             for path, (part, record) in zip(run.validate, sums.validate_parts)],
        "subsample": {"samples": run.first.sample.n_samples, "of": run.first.seen, "requested": int(settings.subsample),
                      "used_for": "shape search of shaped laws, coupling-pair tracing"},
        "floor_window": int(settings.floor_window) if settings.noise_floor is None else None,
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
            floor: NoiseFloor | None, floor_note: str, streaming: dict[str, Any]) -> StreamedDiagnosis:
    """The result: errors before and after against the recording, the trivial predictors, warnings."""
    train, validation, base = run.sums.train, run.sums.validation, list(range(model.n_base))
    nominal = model.base.K @ model.nominal_parameters()
    trivial = {"zero_mse": dict(zip(model.channels, map(float, validation.power[:, 1] / validation.n_samples))),
               "nominal_mse": dict(zip(model.channels, map(float, validation.channel_mse(base, nominal))))}
    mse = {(name, which): dict(zip(model.channels, map(float, part.channel_mse(selection, theta))))
           for name, part in (("train", train), ("validation", validation))
           for which, selection, theta in (("before", base, before.values), ("after", run.columns, after.values))}
    rejected = run.outcome.rejected
    return StreamedDiagnosis(
        model=model, effects=found_effects(model, run, after), rejected=tuple(rejected[i] for i in sorted(rejected)),
        before=before, after=after,
        train_mse={which: mse["train", which] for which in ("before", "after")},
        validation_mse={which: mse["validation", which] for which in ("before", "after")},
        n_train=train.n_samples, n_validation=validation.n_samples, floor=floor, floor_note=floor_note,
        streaming=streaming,
        warnings={"before": implausible_estimates(model, before),
                  "after": implausible_estimates(model, after) + trivial_warnings(mse["validation", "after"], trivial)},
        trivial=trivial, found_effects=tuple(run.found.blocks[index].effect for index in run.chosen),
    )
