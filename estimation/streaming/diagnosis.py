"""The diagnosis of long records in bounded memory (``oed diagnose --chunk-size``).

::

    result = diagnose_files(model, ["run1.parquet", "run2.parquet"], ["check.parquet"], chunk_size=10_000,
                            executor=client.get_executor())
    result.to_dict()   # the ``oed diagnose`` document (the in-memory Diagnosis, same keys), ``diagnosis_path: "streamed"``

Passes over the data (each file one task on any ``concurrent.futures.Executor``, as
:func:`estimation.streaming.cluster.sum_files`; the chunks preprocessed on overlapping windows,
:func:`estimation.streaming.chunks.preprocessed_chunks`):

1. **Subsamples** (training files, then validation files): an evenly spread subsample of at most about
   ``2 x subsample`` samples of the prepared data of each set
   (:class:`~estimation.streaming.diagnosis_sums.EvenSubsample`, split over the files). The search is the in-memory
   diagnosis's own, run on them (:func:`estimation.streaming.diagnosis_candidates.subsample_search`:
   :class:`~estimation.diagnosis.forward_selection.DiagnosisSearch` on
   :class:`~estimation.diagnosis.record_fits.RecordFits`, then its final joint refit): F tests, BIC, sign checks,
   spring-versus-offset, confirmation on the validation subsample against its channels as recorded, the Wald tests
   from the HAC covariance with the shape directions, and the shaped laws' shapes (``coulomb:tanh``,
   ``stribeck:velocity``, ``sigmoid``, ``ripple``) refined round by round against the model of the moment as in
   memory (a shape enters its columns nonlinearly: sums at one shape hold nothing of another's columns). The coupling
   pairs are traced on the training subsample too (:func:`estimation.diagnosis.candidates.coupling.coupling_candidates`).
   Records no longer than the subsample are taken whole: the search and its findings are then the in-memory ones.
2. **Sums** (training and validation files): per channel the Gram matrix of the base regressor and
   every candidate's columns (at the shapes the search left), their moments with the prepared channels and
   with the channels as recorded, and the powers (:mod:`estimation.streaming.diagnosis_sums`).

The declared and augmented models are estimated from the whole records' sums by
:class:`~estimation.estimators.summed_least_squares.SummedLeastSquares`. A third pass over the training files
gives the augmented estimate's batch-means covariance (:mod:`estimation.streaming.covariance`; residuals
correlated in time, as on the filter path, make the classical standard deviations far too small;
the declared model's stay classical); a finding within its noise there (Wald p not below the search's threshold) is
dropped and the rest refitted, the weakest first, as the in-memory final refit drops it (not when both subsamples
hold their whole records: the subsample's final refit then made memory's own test on the same samples, and a second
test with another covariance estimator, its batch length on a grid of powers of two, dropped at the margin a law
memory keeps: the Panda's joint-2 offset, Wald p = 9.6e-6 in memory, 2.4e-5 from the sums, threshold 1.05e-5). Every validation and
training MSE is against the channels **as recorded** (the recorded torques, along the derived motion), as the
in-memory diagnosis measures them. :func:`robust_covariance` and :class:`~estimation.streaming.selection.SummedFits`
are the search from sums alone (every sample of the record in each test, the shapes fixed where the subsample's
first round left them): on the KUKA LWR4+ it named 15 effects against the in-memory 14 (benchmarks/README.md).

The noise floor: memory's, of every row of each validation file (segment) as recorded, pooled over them
(:func:`estimation.streaming.record_floor.segment_floors`: the difference estimator's medians found exactly by
selection over passes, a long periodic segment's estimate from sums); ``floor_window`` rows: the first rows of each
file alone (the report's ``streaming.floor_window`` says which).

Not on this path (the report's ``streaming.not_on_this_path``): residual tracing, whiteness and
per-sample residual statistics (they need the residuals sample by sample), the search over every sample (it runs on the
subsamples), shape standard deviations, a Fourier fit of every sample (periods are averaged:
:func:`estimation.streaming.periods.plan_chunks`).
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from dynamics.effects.linear import Effect
from dynamics.runtime.progress import step
from dynamics.models import IdentificationModel
from dynamics.transmission import Transmission
from estimation.data.passive import passive_channels
from estimation.data.input_findings import FindingsSaid
from dynamics.models import build_model
from estimation.diagnosis.forward_selection import SearchOutcome, SearchSettings
from estimation.diagnosis.sign_constraints import PASSES, PinnedTerm, negative_estimates, pinned_terms
from estimation.estimators.summed_least_squares import SummedEstimate, SummedLeastSquares, summed_estimator
from estimation.preprocessing.delay import DelayBounds
from estimation.preprocessing.plan import Preprocessing
from dynamics.measurements import Measurements
from estimation.preprocessing.plan import at_recorded_stamps
from estimation.identification.subtracted_load import SubtractedLoad
from estimation.streaming.chunks import automatic_cutoff, logged_chunks, read_chunks
from estimation.streaming.cluster import model_payload
from estimation.streaming.covariance import BatchScores, sandwich
from estimation.streaming.diagnosis_passes import (LagSums, SumsPass, scores_pass, subsample_pass,
                                                  sums_pass, window_floor)
from estimation.streaming.diagnosis_candidates import StreamedCandidates, streamed_candidates
from estimation.diagnosis.results import Diagnosis, RejectedEffect
from estimation.diagnosis.candidates.trials import candidate_label
from estimation.diagnosis.rules.robust_test import estimate_test
from estimation.streaming.diagnosis_result import StreamedRun, StreamedSettings, streamed_result, streaming_record
from estimation.streaming.diagnosis_sums import ChannelSums, concatenate, normal_equations
from estimation.streaming.periods import plan_options
from estimation.streaming.selection import STILL_HELD_OUT, simpler_laws, summed_runner_up
from estimation.streaming.settings import DEFAULT_SUBSAMPLE
from estimation.uncertainty.noise_floor import NoiseFloor

__all__ = ["DEFAULT_SUBSAMPLE", "diagnose_files", "diagnose_files_run"]



# ---------------------------------------------------------------- the diagnosis

class Stopwatch:
    """Seconds spent in each stage of a diagnosis (the report's ``streaming.seconds``)."""

    def __init__(self) -> None:
        self.seconds: dict[str, float] = {}
        self.last = time.perf_counter()

    def lap(self, name: str) -> None:
        now = time.perf_counter()
        self.seconds[name] = round(now - self.last, 3)
        self.last = now


def _checked_settings(model: IdentificationModel, paths: list[str], validate: list[str],
                      settings: StreamedSettings) -> StreamedSettings:
    """The settings checked, the Butterworth cut-off chosen when the files hold positions alone."""
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
    if not 0 < settings.alpha < 1:
        raise ValueError(f"alpha must lie in (0, 1), got {settings.alpha}")
    if not 0 <= settings.min_improvement < 1:
        raise ValueError(f"min_improvement must lie in [0, 1), got {settings.min_improvement}")
    subsample = settings.subsample
    if isinstance(subsample, bool) or int(subsample) != subsample or subsample < model.n_base + 1:
        raise ValueError(f"subsample must be an integer above the {model.n_base} base parameters, got {subsample!r}")
    if settings.cutoff_hz is None and settings.frequency_hz is None:
        first = next(read_chunks(paths[0], model, chunk_size=settings.chunk_size))
        if first.dq is None or first.ddq is None:
            return replace(settings, cutoff_hz=automatic_cutoff(paths[0], model, chunk_size=settings.chunk_size))
    return settings


def _refit(model: IdentificationModel, train: ChannelSums, found: StreamedCandidates, indices: Sequence[int],
           declared: IdentificationModel | None = None) -> tuple[list[int], SummedEstimate]:
    """The declared model with the candidates ``indices``, estimated from the training sums (``declared``: the
    declared model with terms held at zero, :func:`_held_signs`, its base columns among ``model``'s)."""
    declared = model if declared is None else declared
    names = list(model.base.names)
    columns = [names.index(name) for name in declared.base.names] + [
        column for index in indices for column in found.columns[index]]
    names = list(declared.base.names) + [name for index in indices for name in found.blocks[index].names]
    expressions = list(declared.base.expressions) + names[declared.n_base:]
    n_shape = sum(found.blocks[index].n_shape for index in indices)  # weighted as in memory (summed_estimator)
    return columns, summed_estimator("wls", n_shape, passive_channels(model)).fit(normal_equations(train, columns, names, expressions)).estimate_


def _held_signs(model: IdentificationModel, train: ChannelSums, found: StreamedCandidates, chosen: list[int],
                columns: list[int], after: SummedEstimate
                ) -> tuple[IdentificationModel, list[int], list[int], SummedEstimate, tuple[PinnedTerm, ...]]:
    """The in-memory sign step (:func:`estimation.diagnosis.sign_constraints.pin_wrong_signs`) on the sums: while a
    positive-by-physics term (viscous, Coulomb, rotor inertia) is estimated below zero, it is held at zero (a
    declared effect loses that joint, a finding holding it is dropped) and the model refitted from the training
    sums, at most :data:`~estimation.diagnosis.sign_constraints.PASSES` times, from the declared model without the
    terms the subsample's final refit held at zero (``found.pinned``: on a record taken whole, memory's). ``(declared
    model kept, chosen, columns, after, pinned)``; a declared model whose base is not among the sums' columns is not
    reduced."""
    declared, pinned = model, list(found.pinned)
    if pinned:  # the declared terms the subsample's final refit held at zero, as memory's mixed model inherits them
        effects, _, _ = pinned_terms(list(model.effects), [], {term.parameter: (term.value, term.std)
                                                              for term in pinned}, model)
        reduced = build_model(model.robot, model.kind, tuple(effects))
        if set(reduced.base.names) <= set(model.base.names):
            declared = reduced
            columns, after = _refit(model, train, found, chosen, declared)
        else:
            pinned = []
    for _ in range(PASSES):
        final = build_model(model.robot, model.kind, tuple(declared.effects) + tuple(
            found.blocks[index].effect for index in chosen))
        negative = negative_estimates(final, after)
        if not negative:
            break
        by_effect = {id(found.blocks[index].effect): index for index in chosen}
        effects, kept, held = pinned_terms(list(declared.effects), [found.blocks[index].effect for index in chosen],
                                           negative, model)
        reduced = build_model(model.robot, model.kind, tuple(effects))
        if not set(reduced.base.names) <= set(model.base.names):
            break
        declared, chosen, pinned = reduced, [by_effect[id(effect)] for effect in kept], pinned + held
        columns, after = _refit(model, train, found, chosen, declared)
    return declared, chosen, columns, after, tuple(pinned)


def _final_estimate(model: IdentificationModel, sums: SumsPass, found: StreamedCandidates, outcome: SearchOutcome,
                    min_improvement: float
                    ) -> tuple[list[int], list[int], SummedEstimate, IdentificationModel, tuple[PinnedTerm, ...]]:
    """``(chosen, columns, after, declared, pinned)``: the augmented model refitted on all samples at the shapes as
    selected; a found Stribeck law the fit does not support becomes Coulomb friction when the
    weighted validation error does not grow by more than ``min_improvement`` (:func:`simpler_laws`); then a
    positive-by-physics term below zero held at zero as in memory (:func:`_held_signs`: ``declared`` the declared
    model without the joints so held, ``pinned`` the terms)."""
    chosen = [item.index for item in outcome.adopted]
    columns, after = _refit(model, sums.train, found, chosen)
    weights = outcome.weights  # the search's last weights (the declared model's unless it reweights)
    error = float(weights @ sums.validation.channel_mse(columns, after.values))
    replacements = simpler_laws(chosen, found.blocks, {r["name"]: r for r in after.records()}, model)
    if replacements:
        simpler = [replacements.get(index, index) for index in chosen]
        columns_s, after_s = _refit(model, sums.train, found, simpler)
        if float(weights @ sums.validation.channel_mse(columns_s, after_s.values)) <= (1.0 + min_improvement) * error:
            chosen, columns, after = simpler, columns_s, after_s
    declared, chosen, columns, after, pinned = _held_signs(model, sums.train, found, chosen, columns, after)
    return chosen, columns, after, declared, pinned


def _full_columns(model: IdentificationModel, chosen: Sequence[int], found: StreamedCandidates) -> list[int]:
    """The columns the covariance pass evaluates: the declared model's and the candidates ``chosen``."""
    return list(range(model.n_base)) + [column for index in chosen for column in found.columns[index]]


def _kept_scores(parts_scores: Sequence[BatchScores], model: IdentificationModel, chosen: Sequence[int],
                 found: StreamedCandidates, columns: Sequence[int]) -> list[BatchScores]:
    """The covariance pass's batch scores (on :func:`_full_columns`, at the estimate with a term held at zero
    there) on the ``columns`` fitted: the rows and columns of the held terms dropped."""
    full = _full_columns(model, chosen, found)
    if list(columns) == full:
        return list(parts_scores)
    keep = [full.index(column) for column in columns]
    return [replace(part, meat=part.meat[:, keep][:, :, keep], partial=part.partial[:, keep])
            for part in parts_scores]


def _full_theta(model: IdentificationModel, chosen: Sequence[int], found: StreamedCandidates,
                columns: Sequence[int], values: np.ndarray) -> np.ndarray:
    """``values`` (on ``columns``) on :func:`_full_columns`: a term held at zero is zero."""
    full = _full_columns(model, chosen, found)
    theta = np.zeros(len(full))
    theta[[full.index(column) for column in columns]] = values
    return theta


def _batch_means(model: IdentificationModel, after: SummedEstimate, parts_scores, normal: np.ndarray
                 ) -> tuple[SummedEstimate, dict[str, Any]]:
    """The augmented estimate with its batch-means covariance (residuals correlated in time), and the
    report's ``covariance`` entry (the batch length, the classical standard deviations of the effects)."""
    cov, batch = sandwich(parts_scores, normal, after.cov, after.weights)
    std = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    with np.errstate(divide="ignore", invalid="ignore"):
        relative_std = np.where(after.values != 0, 100.0 * std / np.abs(after.values), np.inf)
    classical = dict(zip(after.names[model.n_base:], map(float, after.std[model.n_base:])))
    covariance = {"method": "batch_means", "batch_length": batch, "classical_std": classical}
    return replace(after, cov=cov, std=std, relative_std=relative_std), covariance


#: the finest batches the search's robust covariance is summed on (:func:`robust_covariance`): the memory it holds is
#: this many copies of the training sums, whatever the record's length
MAX_BATCHES = 256


def andrews_length(n_samples: int, rho: float) -> int:
    """Andrews' AR(1) batch length ``1.1447 (α N)^{1/3}``, ``α = 4ρ²/(1−ρ)⁴``, at least 1 and at most ``N/20``
    (:func:`estimation.uncertainty.batch_means.batch_length`'s rule)."""
    alpha = 4 * rho**2 / (1 - rho) ** 4
    return int(np.clip(round(1.1447 * (alpha * n_samples) ** (1 / 3)), 1, max(1, n_samples // 20)))


def robust_covariance(model: IdentificationModel, sums: SumsPass, found: StreamedCandidates,
                      batches: Sequence[ChannelSums], lags: LagSums):
    """``robust(indices, weights) -> (θ, cov θ)`` for :class:`~estimation.streaming.selection.SummedFits`: the declared
    columns and the candidates ``indices`` fitted from the training sums at ``weights``, with the batch-means
    covariance of their residuals (``H⁻¹ M H⁻¹ · N/(N − p)``, never below the classical one on the diagonal, as
    :func:`~estimation.streaming.covariance.sandwich` and the in-memory
    :func:`~estimation.diagnosis.rules.robust_test.fit_covariance`). ``batches``: the training sums on consecutive
    stretches of the record (:func:`~estimation.streaming.diagnosis_passes.stretch_pass`, at most
    :data:`MAX_BATCHES`); each stretch's score sum ``S_b = Σ_c w_c (X_{b,c}ᵀy_{b,c} − X_{b,c}ᵀX_{b,c} θ)`` is exact
    from its sums, and the stretches are joined into batches of about Andrews' length for this model's residual
    (its lag-1 autocorrelation from ``lags``, :class:`~estimation.streaming.diagnosis_passes.LagSums`; a length
    shorter than a stretch is a stretch). Every model of the search is so tested without another pass. The in-memory
    search tests its candidates with the HAC covariance (:mod:`estimation.diagnosis.rules.robust_test`): with the
    classical one, residuals correlated in time made effects within their noise significant (20 effects on the KUKA
    LWR4+ log against 14 in memory)."""
    train, found_columns = sums.train, found.columns
    n_rows, n_samples, n_fine = train.n_samples * train.layout.n_channels, train.n_samples, len(batches)

    def robust(indices: tuple[int, ...], weights: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        weights = np.asarray(weights, dtype=float)
        columns = list(range(model.n_base)) + [column for index in indices for column in found_columns[index]]
        normal = train.normal_system(columns, weights)[0]
        theta, rss = train.solve(columns, weights)
        scale = np.sqrt(np.diag(normal))
        inverse = np.linalg.pinv(normal / np.outer(scale, scale), hermitian=True) / np.outer(scale, scale)
        classical = rss / max(n_rows - len(columns), 1) * inverse
        fine = np.zeros((n_fine, len(columns)))
        for b, batch in enumerate(batches):
            for c, w in enumerate(weights):
                outer, inner = batch._positions(c, columns)
                fine[b, outer] += w * (batch.moment[c][inner, 0] - batch.gram[c][np.ix_(inner, inner)] @ theta[outer])
        length = andrews_length(n_samples, lags.rho(train, columns, theta, weights))
        group = max(1, int(round(length * n_fine / max(n_samples, 1))))
        scores = np.add.reduceat(fine, np.arange(0, n_fine, group), axis=0)
        p = len(columns)
        cov = inverse @ (scores.T @ scores) @ inverse * n_samples / max(n_samples - p, 1)
        diagonal = np.maximum(np.diag(cov), np.diag(classical))
        ratio = np.sqrt(np.clip(diagonal, 0.0, None) / np.clip(np.diag(classical), np.finfo(float).tiny, None))
        return theta, classical * np.outer(ratio, ratio)

    return robust


def _at_recorded_stamps(sample: Measurements, validate: Sequence[str], model: IdentificationModel,
                        settings: StreamedSettings) -> Measurements:
    """The validation subsample with its channels as recorded those of the samples as logged, as in memory
    (:func:`estimation.preprocessing.plan.at_recorded_stamps`: the torques at their own time stamps, the derived
    motion interpolated there), when it holds the whole of one validation file the reader resampled onto a grid
    (a jittered log): the search then confirms its candidates on the samples memory confirms them on (on the Panda's
    jittered validation record the grid's 3 360 samples against its 3 110 rows as logged). Else ``sample``."""
    recorded = sample.recorded
    if len(validate) != 1 or recorded is None or settings.frequency_hz is not None \
            or sample.metadata.get("resampled_from") is None or sample.metadata.get("segments_in_file", 1) != 1:
        return sample
    chunks = list(logged_chunks(validate[0], model, chunk_size=settings.chunk_size, load=settings.load))
    if not chunks:
        return sample
    stamps = concatenate(chunks) if len(chunks) > 1 else chunks[0]
    # the grid's last point may round below the last stamp: the tolerance at_recorded_stamps keeps stamps within
    # (without it the search confirmed its candidates on the grid's interpolated torques: a sigmoid on the jittered
    # PUMA of tests/test_streamed_block_errors.py where memory finds Coulomb friction)
    tolerance = 1e-9 * (recorded.t[-1] - recorded.t[0])
    if stamps.n_samples != int(sample.metadata["resampled_from"]) or recorded.t[0] > stamps.t[0] + tolerance \
            or recorded.t[-1] < stamps.t[-1] - tolerance:  # not the whole file as logged
        return sample
    return at_recorded_stamps(sample, stamps)


def _declared(model: IdentificationModel, sums: SumsPass) -> SummedEstimate:
    """The declared model estimated from the training sums (channel-weighted least squares)."""
    base = list(range(model.n_base))
    return SummedLeastSquares(method="wls", passive=passive_channels(model)).fit(normal_equations(sums.train, base, model.base.names,
                                                                 model.base.expressions)).estimate_


def _weakest(model: IdentificationModel, found: StreamedCandidates, chosen: Sequence[int], after: SummedEstimate,
             threshold: float) -> tuple[int, str] | None:
    """``(position in chosen, reason)`` of the finding whose coefficients are within their noise in the final fit
    (Wald p not below ``threshold`` from its batch-means covariance; the weakest, lowest ``W``, first), as the
    in-memory :func:`estimation.diagnosis.final_refit.refit_significant` drops it; ``None`` when every one is
    significant."""
    records = {record["name"]: record for record in after.records()}
    weak = []
    for position, index in enumerate(chosen):
        block = found.blocks[index]
        test = estimate_test(after, block.names)
        if test.p_value >= threshold:
            weak.append((test.statistic, candidate_label(block.effect), position, test, block))
    if not weak:
        return None
    _, _, position, test, block = min(weak, key=lambda entry: entry[:2])
    values = ", ".join(f"{name} = {records[name]['value']:.4g} ± {records[name]['std']:.2g}" for name in block.names
                       if name in records)
    return position, (f"added, but in the final fit its coefficients are within their noise ({values}; Wald p = "
                      f"{test.p_value:.2g}): dropped")


def diagnose_files(*args: Any, **kwargs: Any) -> Diagnosis:
    """Diagnose ``model`` on the training ``paths``, confirmed on the ``validate`` files, in bounded memory: the
    :class:`~estimation.diagnosis.results.Diagnosis` of :func:`diagnose_files_run` (the same arguments)."""
    return diagnose_files_run(*args, **kwargs)[0]


def diagnose_files_run(
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
    floor_window: int | None = None,
    executor: Any = None,
    preprocessing: Preprocessing | None = None,
    findings: FindingsSaid | None = None,
    still: bool = False,
    transmission: Transmission | None = None,
    delay: DelayBounds | None = DelayBounds(),
    jobs: int | None = 1,
    screen: Callable[[tuple[Effect, ...], Measurements, Measurements | None], tuple[Effect, ...]] | None = None,
    load: SubtractedLoad | None = None,
) -> tuple[Diagnosis, StreamedRun]:
    """Diagnose ``model`` on the training ``paths``, confirmed on the ``validate`` files, in bounded memory; the
    diagnosis and the :class:`~estimation.streaming.diagnosis_result.StreamedRun` behind it (its sums: what the
    consistent refit of the adopted model needs, :mod:`estimation.streaming.diagnosis_selection`).

    The settings are those of :func:`estimation.diagnosis.search.diagnose`; ``chunk_size``, ``cutoff_hz``,
    ``decimation``, ``held_torques`` and ``executor`` those of
    :func:`estimation.streaming.identification.identify_files`; ``subsample`` and ``floor_window``:
    module docstring. ``noise_floor``: the floor of the validation record as recorded (default: memory's, of
    every row, or of the first ``floor_window`` rows of each file). ``preprocessing``: a plan chosen beforehand (as the in-memory path chooses it,
    :func:`estimation.streaming.cutoff_choice.choose_streamed_preprocessing`) sets the derivatives instead of
    ``cutoff_hz``, ``decimation`` and ``held_torques``: a filter, or a Fourier fit of averaged periods
    (:func:`estimation.streaming.periods.plan_chunks`). ``findings``: what the run has said about its files
    (:class:`~estimation.data.input_findings.FindingsSaid`; default a new one): the readers' warnings of each pass
    are said as it ends, one line per finding across files, each finding of a file once. ``still``: the validation
    record is at rest (:func:`~estimation.streaming.model_selection.streamed_still_motion`): the candidates are
    compared on the stretches of the training record their fits did not see, as in memory (one more pass over the
    training files, :func:`~estimation.streaming.diagnosis_passes.stretch_pass`; not on the Fourier path, whose
    sums hold averaged periods: there they are compared on the record at rest, ``streaming.still_search``).
    ``transmission``: its coupled motors' friction laws are candidates, as in memory. ``delay``: where a delay between
    torques and motion is searched, as in memory (on the subsamples, with the search: its grid, trials and adoption
    rule; ``None``: not tried); an adopted delay moves the motion of every file in the passes after the search
    (:func:`~estimation.streaming.delayed_chunks.moved_chunks`), the declared model's fit staying along the motion as
    read, as in memory. ``jobs``: the processes the search's rounds fit their candidates in, as in memory's
    (``None``: the available cores; the same answer at any count). ``screen``: given the candidates and the training
    and validation subsamples, the candidates tried
    (:func:`~estimation.streaming.diagnosis_candidates.streamed_candidates`). ``load``: a load of the description
    the logged torques lack (:mod:`estimation.identification.subtracted_load`), added back to every prepared chunk
    of every pass and to the noise floor's rows (:func:`estimation.streaming.chunks.loaded_chunk`), as memory adds it
    to its prepared records: the diagnosis of the robot's torques (on the Fourier path at the fit's motion,
    :func:`estimation.streaming.periods.periodic_chunks`).
    """
    paths, validate = [str(path) for path in paths], [str(path) for path in validate]
    findings = FindingsSaid([*paths, *validate]) if findings is None else findings
    settings = StreamedSettings(chunk_size, cutoff_hz, decimation, held_torques, alpha, min_improvement, max_effects,
                                noise_floor, subsample, floor_window, load=load)
    with findings.reading():
        settings = _checked_settings(model, paths, validate, settings if preprocessing is None else
                                     replace(settings, **plan_options(preprocessing, average=True)))
    options, payload, clock = settings.reading(), model_payload(model), Stopwatch()
    with step(f"first pass over {len(paths)} training file(s) (subsample)"), findings.reading():
        first = subsample_pass(executor, payload, paths, options, settings.subsample)  # pass 1 (training files)
    with step(f"a pass over {len(validate)} validation file(s) (subsample)"), findings.reading():
        held = subsample_pass(executor, payload, validate, dict(options, as_recorded=True), settings.subsample)
        held = replace(held, sample=_at_recorded_stamps(held.sample, validate, model, settings))
    with step(f"shape search, refinement and coupling tracing on {first.sample.n_samples} samples"):
        found = streamed_candidates(model, candidates, first.sample, clock.lap, transmission, held.sample,
                                    SearchSettings(alpha, min_improvement, max_effects, 0, same_effect_adopted=True),
                                    delay, jobs, screen)
    if found.delay.value is not None:  # the passes along the motion moved by the adopted delay
        options = dict(options, delay=float(found.delay.value.value))
    with step(f"second pass over {len(paths) + len(validate)} file(s) (sums of {len(found.blocks)} candidates)"), \
            findings.reading():
        sums = sums_pass(executor, payload, found.plan, paths, validate, options, first)  # pass 2 (all files)
    clock.lap("sums_pass")
    if noise_floor is None:
        with findings.reading():
            floor, floor_note = window_floor(validate, model, window=floor_window, frequency_hz=settings.frequency_hz,
                                             load=load, chunk_size=chunk_size)
    else:
        floor, floor_note = noise_floor, f"given ({noise_floor.method})"
    with step("the declared model from the sums"):
        before = _declared(model, sums if sums.declared is None else replace(sums, train=sums.declared[0]))
    outcome = found.outcome  # the search of the subsample (streamed_candidates)
    clock.lap("selection_and_estimates")
    threshold = settings.alpha / max(found.n_candidates + (delay is not None), 1)  # the search's (SearchSettings.threshold)
    whole = first.sample.n_samples == first.seen and held.sample.n_samples == held.seen and outcome is not None
    while True:  # the final fit; a finding within its noise there is dropped and the rest refitted, as in memory
        chosen, columns, after, declared, pinned = _final_estimate(model, sums, found, outcome, min_improvement)
        with step(f"third pass over {len(paths)} training file(s) (covariance)"), findings.reading():  # batch means
            parts_scores = scores_pass(executor, payload, found.final_plan(chosen), paths, options,
                                       _full_theta(model, chosen, found, columns, after.values), after.weights)
        after, covariance = _batch_means(declared, after, _kept_scores(parts_scores, model, chosen, found, columns),
                                         sums.train.normal_system(columns, after.weights)[0])
        # on records taken whole the subsample's final refit made memory's test on the same samples: not again
        weak = None if whole else _weakest(model, found, chosen, after, threshold)
        if weak is None:
            break
        item = outcome.adopted[weak[0]] if len(chosen) == len(outcome.adopted) else next(
            other for other in outcome.adopted  # a finding held at zero is not in chosen: by its parameters
            if set(other.block.names) & set(found.blocks[chosen[weak[0]]].names))
        block = found.blocks[item.index]
        rejected = {**outcome.rejected, item.index: RejectedEffect(
            block.effect.name, tuple(model.channels[row] for row in block.rows), weak[1], candidate_label(block.effect))}
        outcome = replace(outcome, adopted=tuple(other for other in outcome.adopted if other is not item),
                          rejected=rejected)
    runner_up = summed_runner_up(model, sums.train, sums.validation, found, outcome, chosen, after)
    clock.lap("covariance_pass")
    run = StreamedRun(paths, validate, settings, first, sums, found, outcome, chosen, columns,
                      declared=tuple(declared.effects), pinned=pinned)
    result = streamed_result(model, run, before, after, floor, floor_note, streaming_record(run, covariance, clock.seconds))
    if still:
        result = replace(result, streaming={**result.streaming, "still_search": STILL_HELD_OUT
                                            + " (on the training subsample)"})
    return replace(result, runner_up=runner_up[0], runner_up_reason=runner_up[1]), run
