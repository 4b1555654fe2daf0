"""The diagnosis of long records in bounded memory (``oed diagnose --chunk-size``).

::

    result = diagnose_files(model, ["run1.parquet", "run2.parquet"], ["check.parquet"], chunk_size=10_000,
                            executor=client.get_executor())
    result.to_dict()   # the ``oed diagnose`` document (same keys), with ``diagnosis_path: "streamed"``

Passes over the data (each file one task on any ``concurrent.futures.Executor``, as
:func:`estimation.streaming.cluster.sum_files`; the chunks preprocessed on overlapping windows,
:func:`estimation.streaming.chunks.preprocessed_chunks`):

1. **Subsample** (training files): an evenly spread subsample of at most about ``2 x subsample``
   samples of the prepared training data (:class:`~estimation.streaming.diagnosis_sums.EvenSubsample`, split
   over the files). Shaped laws (``coulomb:tanh``, ``stribeck:velocity``, ``sigmoid``, ``ripple``)
   cannot be summed at an unknown shape: their shape parameters are searched on this subsample, by
   the in-memory diagnosis's own variable projection (:func:`estimation.diagnosis.candidate_trials.fit_or_reason`
   against the declared model, channel weights of the subsample's identification), then fixed. The
   coupling pairs are traced on it too (:func:`estimation.diagnosis.coupling_candidates.coupling_candidates`).
   A record no longer than the subsample is taken whole: the search is then the in-memory one.
2. **Sums** (training and validation files): per channel the Gram matrix of the base regressor and
   every candidate's columns (at the fixed shapes), their moments with the prepared channels and
   with the channels as recorded, and the powers (:mod:`estimation.streaming.diagnosis_sums`).

The forward selection, F tests, BIC, sign checks, spring-versus-offset, confirmation on validation
and the noise-floor stopping rule then run on the sums (:mod:`estimation.streaming.selection`), and
the declared and augmented models are estimated from them by
:class:`~estimation.estimators.summed_least_squares.SummedLeastSquares`. A third pass over the training files
gives the augmented estimate's batch-means covariance (:mod:`estimation.streaming.covariance`; residuals
correlated in time, as on the filter path, make the classical standard deviations far too small;
the declared model's stay classical). Every validation and training MSE is against the channels **as recorded** (the
recorded torques, along the derived motion), as the in-memory diagnosis measures them.

The noise floor: the model-free estimators of :mod:`estimation.uncertainty.noise_floor` are not sums (the
difference estimator takes a median); the floor is computed on a bounded window, the first
``floor_window`` rows of each validation file as recorded, pooled over the files
(:func:`estimation.uncertainty.noise_floor.pooled_floor`), and the report says so.

Not on this path (the report's ``streaming.not_on_this_path``): residual tracing, whiteness and
per-sample residual statistics (they need the residuals sample by sample), the per-round refinement and joint refit of shapes, shape standard deviations, the Fourier path.
"""

from __future__ import annotations

import functools
import pickle
import time
import warnings
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from dynamics.effects.linear import Effect
from dynamics.models import IdentificationModel
from estimation.diagnosis.candidate_trials import candidate_label, fit_or_reason
from estimation.streaming.cluster import file_stamp, model_payload
from estimation.diagnosis.coupling_candidates import coupling_candidates
from estimation.diagnosis.search import FoundEffect, RejectedEffect, default_candidates
from estimation.diagnosis.statistics import FLOOR_ALPHA
from estimation.streaming.diagnosis_sums import ColumnLayout, concatenate, normal_equations
from estimation.identification.fit import identify, implausible_estimates
from estimation.data.loading import MeasurementError
from estimation.uncertainty.noise_floor import NoiseFloor, compare_with_floor
from estimation.streaming.diagnosis_passes import (FLOOR_WINDOW, map_files, scores_task, subsample_task, sums_task,
                                                  window_floor)
from estimation.streaming.covariance import sandwich
from estimation.identification.trivial_predictors import trivial_warnings
from estimation.streaming.chunks import automatic_cutoff, read_chunks
from estimation.estimators.summed_least_squares import SummedEstimate, SummedLeastSquares
from estimation.streaming.selection import select_effects, simpler_laws
from estimation.estimators.effect_blocks import Block, NoRowsError, States
from estimation.estimators.separable_least_squares import FixedPart, solve_linear

__all__ = ["DEFAULT_SUBSAMPLE", "FLOOR_WINDOW", "StreamedDiagnosis", "diagnose_files", "window_floor"]

#: samples (about; at most twice) of the evenly spread training subsample the shapes are searched on.
#: The shape search costs what the in-memory diagnosis's first round costs on that many samples.
DEFAULT_SUBSAMPLE = 10_000

NOT_ON_THIS_PATH = (
    "residual tracing, whiteness and residual statistics (need the residuals sample by sample)",
    "the declared model's HAC standard deviations (classical there; the augmented model's are batch means)",
    "shapes refined round by round and refitted jointly at the end (fixed at the subsample's optimum)",
    "shape standard deviations",
    "a law paired with its offset searched jointly (the pair uses the law's own shape)",
    "user stopping rules (the noise floor is the rule)",
    "model_parameters (the physical reading of the estimate)",
    "a delay between torques and motion as a candidate (it moves the records)",
    "a pair's Coulomb and viscous laws tried as one candidate, limit laws, negative friction held at zero "
    "(pinned), the traced shape refinement",
)


# ---------------------------------------------------------------- the result

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
        }


# ---------------------------------------------------------------- the diagnosis

def _shape_search(model, blocks, rejected, subsample, weights, friction_joints) -> dict[int, np.ndarray]:
    """Each shaped law's shape on the subsample against the declared model (the in-memory first round)."""
    fixed = FixedPart.from_arrays(model.evaluate_base(subsample.q, subsample.dq, subsample.ddq),
                                  subsample.channels(model.channels))
    states = States(subsample.q, subsample.dq, subsample.ddq)
    rss = solve_linear(fixed, [], states, [], weights).rss
    shapes = {}
    for index, block in list(blocks.items()):
        if block.n_shape == 0:
            shapes[index] = np.zeros(0)
            continue
        joints = {int(model.channels[row][3:]) - 1 for row in block.rows if model.channels[row].startswith("tau")}
        if block.effect.name in friction_joints[0] and joints & friction_joints[1]:
            shapes[index] = np.array([p.starts[0] for p in block.parameters], dtype=float)  # rejected in the loop
            continue
        outcome = fit_or_reason((index,), [block], fixed, states, weights, rss, None, search=False)
        if isinstance(outcome, str):
            rejected[index] = RejectedEffect(block.effect.name, tuple(model.channels[r] for r in block.rows),
                                             outcome + " (on the subsample)", candidate_label(block.effect))
            del blocks[index]
        else:
            shapes[index] = outcome.fit.shape
    return shapes


def _file_record(path: str, sums, record: dict) -> dict[str, Any]:
    return {"path": path, "rows": record["rows"], "samples": sums.n_samples,
            "trimmed_samples": record["metadata"].get("trimmed_samples", 0)}


def diagnose_files(
    model: IdentificationModel,
    paths: Sequence[str | Path],
    validate: Sequence[str | Path],
    *,
    chunk_size: int,
    cutoff_hz: float | None = None,
    decimation: int = 1,
    held_torques: bool = False,
    candidates: Sequence[Effect] | None = None,
    alpha: float = 1e-3,
    min_improvement: float = 0.01,
    max_effects: int = 20,
    noise_floor: NoiseFloor | None = None,
    subsample: int = DEFAULT_SUBSAMPLE,
    floor_window: int = FLOOR_WINDOW,
    executor: Any = None,
) -> StreamedDiagnosis:
    """Diagnose ``model`` on the training ``paths``, confirmed on the ``validate`` files, in bounded memory.

    The settings are those of :func:`estimation.diagnosis.search.diagnose`; ``chunk_size``, ``cutoff_hz``,
    ``decimation``, ``held_torques`` and ``executor`` those of
    :func:`estimation.streaming.identification.identify_files`; ``subsample`` and ``floor_window``:
    module docstring. ``noise_floor``: the floor of the validation record as recorded (default: on
    the window).
    """
    from dynamics.effects.shaped import FRICTION_LAWS

    paths, validate = [str(path) for path in paths], [str(path) for path in validate]
    if not paths:
        raise ValueError("no training data files")
    if not validate:
        raise ValueError("diagnose confirms every effect on held-out data: give validation files")
    for name, group in (("training", paths), ("validation", validate)):
        if len(set(group)) != len(group):
            raise ValueError(f"a {name} file is given twice: {sorted({p for p in group if group.count(p) > 1})}")
    if set(paths) & set(validate):
        raise ValueError(f"a validation file is a training file ({sorted(set(paths) & set(validate))}): diagnose confirms "
                         "every effect on held-out data from another experiment")
    if not 0 < alpha < 1:
        raise ValueError(f"alpha must lie in (0, 1), got {alpha}")
    if not 0 <= min_improvement < 1:
        raise ValueError(f"min_improvement must lie in [0, 1), got {min_improvement}")
    if isinstance(subsample, bool) or int(subsample) != subsample or subsample < model.n_base + 1:
        raise ValueError(f"subsample must be an integer above the {model.n_base} base parameters, got {subsample!r}")
    if cutoff_hz is None:
        first = next(read_chunks(paths[0], model, chunk_size=chunk_size))
        if first.dq is None or first.ddq is None:
            cutoff_hz = automatic_cutoff(paths[0], model, chunk_size=chunk_size)
    # the filter's settling trimmed at each record's ends, as the CLI's in-memory preprocessing does
    options = dict(chunk_size=chunk_size, cutoff_hz=cutoff_hz, decimation=decimation, held_torques=held_torques,
                   trim=True)
    payload = model_payload(model)

    # ---- pass 1: the subsample (training files)
    clock = [time.perf_counter()]
    seconds: dict[str, float] = {}

    def lap(name: str) -> None:
        now = time.perf_counter()
        seconds[name] = round(now - clock[0], 3)
        clock[0] = now

    cap = -(-int(subsample) // len(paths))
    parts = map_files(executor, subsample_task, paths, lambda path: (payload, path, options, cap, file_stamp(path)))
    records = [record for _, _, record in parts]
    for path, record in zip(paths, records):
        if record["columns"] != records[0]["columns"]:
            raise MeasurementError(f"{path} holds the column groups {record['columns']}, {paths[0]} "
                                   f"{records[0]['columns']}: the files of one set must have the same columns")
    sample = concatenate([part for part, _, _ in parts])
    seen = sum(count for _, count, _ in parts)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the subsample's own fit: its warnings are not the record's
        reference = identify(model, sample).estimate
    weights_sample = reference.weights if reference.method == "wls" else 1.0 / reference.channel_variance
    candidates = tuple(default_candidates(model) + coupling_candidates(model, train=sample)
                       if candidates is None else candidates)
    rejected: dict[int, RejectedEffect] = {}
    blocks: dict[int, Block] = {}
    for index, candidate in enumerate(candidates):
        if not isinstance(candidate, Effect):
            raise TypeError(f"candidate {candidate!r} is not an effect")
        try:
            blocks[index] = Block(model.kind, model.robot, candidate, model.n_channels)
        except NoRowsError:
            rejected[index] = RejectedEffect(candidate.name, (), "has no rows in this model", candidate_label(candidate))
    declared_friction = {joint for effect in model.effects if effect.name in FRICTION_LAWS
                         for joint in (range(model.robot.n_joints) if getattr(effect, "joints", None) is None
                                       else effect.joints)}
    lap("subsample_pass")
    shapes = _shape_search(model, blocks, rejected, sample, weights_sample, (FRICTION_LAWS, declared_friction))
    lap("shape_search")

    # ---- pass 2: the sums (training and validation files)
    order = sorted(blocks)
    plan = pickle.dumps(([blocks[i].effect for i in order], [shapes[i] for i in order]))
    layout = ColumnLayout.build(model, [blocks[i] for i in order])
    train_parts = map_files(executor, sums_task, paths, lambda path: (payload, plan, path, options, file_stamp(path)))
    validate_parts = map_files(executor, sums_task, validate, lambda path: (payload, plan, path, options, file_stamp(path)))
    for path, (sums, record), count in zip(paths, train_parts, (count for _, count, _ in parts)):
        if sums.n_samples != count:
            raise MeasurementError(f"{path}: {sums.n_samples} samples summed, {count} read in the first pass (did the "
                                   "file change while it was read?)")
    for path, (_, record) in zip(validate, validate_parts):
        if record["columns"] != records[0]["columns"]:
            raise MeasurementError(f"{path} holds the column groups {record['columns']}, {paths[0]} "
                                   f"{records[0]['columns']}: the files of one set must have the same columns")
    train = functools.reduce(lambda a, b: a + b, [sums for sums, _ in train_parts])
    validation = functools.reduce(lambda a, b: a + b, [sums for sums, _ in validate_parts])
    position = {index: slot for slot, index in enumerate(order)}  # candidate index -> layout block
    local_blocks = {position[i]: blocks[i] for i in order}
    local_shapes = {position[i]: shapes[i] for i in order}

    lap("sums_pass")
    # ---- the noise floor, the declared model, the selection
    if noise_floor is None:
        floor, floor_note = window_floor(validate, model, window=floor_window)
    else:
        floor, floor_note = noise_floor, f"given ({noise_floor.method})"
    base = list(range(model.n_base))
    estimator = SummedLeastSquares(method="wls")
    before = estimator.fit(normal_equations(train, base, model.base.names, model.base.expressions)).estimate_
    weights = before.weights if before.method == "wls" else 1.0 / before.channel_variance
    selection = select_effects(model, local_blocks, local_shapes, {}, train, validation, weights, alpha=alpha,
                               min_improvement=min_improvement, max_effects=max_effects, floor=floor,
                               n_candidates=len(candidates))
    chosen = list(selection.chosen)

    def refit(indices):
        columns = base + [column for index in indices for column in layout.blocks[index]]
        names = list(model.base.names) + [name for index in indices for name in local_blocks[index].names]
        expressions = list(model.base.expressions) + names[model.n_base:]
        estimate = SummedLeastSquares(method="wls").fit(normal_equations(train, columns, names, expressions)).estimate_
        return columns, estimate

    columns, after = refit(chosen)
    weights = selection.weights  # the search's last weights (the declared model's unless it reweights)
    error = float(weights @ validation.channel_mse(columns, after.values))
    replacements = simpler_laws(chosen, local_blocks, {r["name"]: r for r in after.records()}, model)
    if replacements:
        simpler = [replacements.get(index, index) for index in chosen]
        columns_s, after_s = refit(simpler)
        if float(weights @ validation.channel_mse(columns_s, after_s.values)) <= (1.0 + min_improvement) * error:
            chosen, columns, after = simpler, columns_s, after_s

    # ---- pass 3: the batch-means covariance of the final estimate (residuals correlated in time)
    lap("selection_and_estimates")
    plan_final = pickle.dumps(([local_blocks[i].effect for i in chosen], [local_shapes[i] for i in chosen]))
    parts_scores = map_files(executor, scores_task, paths, lambda path: (payload, plan_final, path, options,
                                                                         after.values, after.weights, file_stamp(path)))
    cov, batch = sandwich(parts_scores, train.normal_system(columns, after.weights)[0], after.cov, after.weights)
    std = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    with np.errstate(divide="ignore", invalid="ignore"):
        relative_std = np.where(after.values != 0, 100.0 * std / np.abs(after.values), np.inf)
    classical_std = after.std
    after = replace(after, cov=cov, std=std, relative_std=relative_std)
    lap("covariance_pass")

    nominal = model.base.K @ model.nominal_parameters()
    trivial = {"zero_mse": dict(zip(model.channels, map(float, validation.power[:, 1] / validation.n_samples))),
               "nominal_mse": dict(zip(model.channels, map(float, validation.channel_mse(base, nominal))))}

    def mse(sums, columns, theta):
        return dict(zip(model.channels, map(float, sums.channel_mse(columns, theta))))

    found = []
    records = {r["name"]: r for r in after.records()}
    for index, p_value, statistic in zip(chosen, selection.p_values, selection.f_statistics):
        block = local_blocks[index]
        found.append(FoundEffect(
            name=block.effect.name, channels=tuple(model.channels[r] for r in block.rows), parameters=block.names,
            values=tuple(records[name]["value"] for name in block.names),
            std=tuple(records[name]["std"] for name in block.names), p_value=p_value, f_statistic=float(statistic),
            spec=candidate_label(block.effect),
            shape={p.name: float(v) for p, v in zip(block.parameters, local_shapes[index])}, shape_std={}))
    rejected_all = dict(rejected)
    rejected_all.update({order[slot]: value for slot, value in selection.rejected.items()})
    normal = train.normal_system(columns, weights)[0]
    scale = np.sqrt(np.diag(normal))
    condition = float(np.linalg.cond(normal / np.outer(scale, scale)))
    streaming = {
        "chunk_size": int(chunk_size), "cutoff_hz": cutoff_hz, "decimation": int(decimation),
        "files": [_file_record(path, sums, record) for path, (sums, record) in zip(paths, train_parts)],
        "validation_files": [_file_record(path, sums, record) for path, (sums, record) in zip(validate, validate_parts)],
        "subsample": {"samples": sample.n_samples, "of": seen, "requested": int(subsample),
                      "used_for": "shape search of shaped laws, coupling-pair tracing"},
        "floor_window": int(floor_window) if noise_floor is None else None,
        "stopped_at_floor": selection.stopped_at_floor,
        "covariance": {"method": "batch_means", "batch_length": batch,
                       "classical_std": dict(zip(after.names[model.n_base:], map(float, classical_std[model.n_base:])))},
        "seconds": seconds,
        "errors_against": "the channels as recorded, along the derived motion",
        "accuracy": {"solve": "per-channel Gram sums, equilibrated, Cholesky (as the in-memory loop)",
                     "equilibrated_normal_cond": condition,
                     "relative_error_bound": condition * np.finfo(float).eps},
        "not_on_this_path": list(NOT_ON_THIS_PATH),
    }
    return StreamedDiagnosis(
        model=model, effects=tuple(found), rejected=tuple(rejected_all[i] for i in sorted(rejected_all)),
        before=before, after=after,
        train_mse={"before": mse(train, base, before.values), "after": mse(train, columns, after.values)},
        validation_mse={"before": mse(validation, base, before.values), "after": mse(validation, columns, after.values)},
        n_train=train.n_samples, n_validation=validation.n_samples, floor=floor, floor_note=floor_note,
        streaming=streaming,
        warnings={"before": implausible_estimates(model, before),
                  "after": implausible_estimates(model, after) + trivial_warnings(
                      dict(zip(model.channels, map(float, validation.channel_mse(columns, after.values)))), trivial)},
        trivial=trivial,
    )
