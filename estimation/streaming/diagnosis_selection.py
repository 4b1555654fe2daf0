"""The default answer of ``oed diagnose`` on the streamed path: the adopted model or its consistent refit, from sums.

In memory, ``oed diagnose`` answers with the model it adopted (the declared model with the diagnosed effects,
shaped laws at their fitted shapes) as fitted, or with its physically consistent refit (the robot description's
bodies as prior, the prior's weight chosen on the validation record), whichever predicts the validation record
better when that record is another motion (:func:`estimation.consistent.model_selection.select_refit`, issue 34). A
record over the memory budget is diagnosed from sums (:mod:`estimation.streaming.diagnosis`), and so is this choice:

* the streamed diagnosis's second pass already holds, per channel, the Gram matrix of the base regressor and of
  every candidate's columns at its fixed shape, with their moments against the prepared channels and the channels
  as recorded, on the training and on the validation records
  (:class:`~estimation.streaming.diagnosis_sums.ChannelSums`); the adopted model's columns, put in its base-parameter
  order (:func:`model_order`), give the consistent fit's Gram statistics
  (:func:`~estimation.streaming.diagnosis_sums.normal_equations`), with the shaped columns at their fitted shapes as
  :func:`~estimation.consistent.fixed_shapes.fixed_problem` gives them in memory;
* the consistent fit is :func:`~estimation.consistent.identification.consistent_fit_sums` (the same solver and
  prior-weight path as in memory), its training errors against the recording from the training sums;
* every candidate's validation error, every weight of the prior's search included, is scored on the same samples
  against the channels as recorded: from the validation sums (:func:`sums_scorer`), or by the caller's scorer (a
  validation file the loader resampled is measured at its recorded samples);
* the choice is the in-memory one (:func:`~estimation.consistent.model_selection.select_scored`), ``ratio`` the
  validation record's :func:`~estimation.streaming.model_selection.streamed_repeated_motion`;
* whether the validation record tells the best candidate from the consistent one
  (:func:`~estimation.consistent.model_selection.paired_difference`, reported as in memory) needs each candidate's
  errors on the contiguous blocks memory cuts the validation samples into: one more pass over the validation files
  sums the same columns on each block (:func:`validation_blocks`,
  :func:`~estimation.streaming.diagnosis_passes.validation_blocks_pass`), and every parameter vector scored from the
  validation sums gets its block errors from them (:func:`sums_scorer`, ``blocks``).

On a validation record that repeats the training motion or is another motion, the in-memory answer also weighs the
adopted model with the plain law completed (:func:`estimation.diagnosis.plain_laws.plain_completion`: Coulomb
friction and an offset on each joint the diagnosis left without one). The streamed sums hold those laws' columns too (they are candidates of the
search, :func:`~estimation.diagnosis.search.default_candidates`), so the completed model is fitted from the same
training sums with the adopted model's weighting (:func:`streamed_completion`) and refitted alike.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import replace
from typing import Any, Literal

import numpy as np

from dynamics.effects.linear import Effect
from dynamics.models import build_model
from estimation.data.passive import passive_channels
from estimation.consistent.identification import Scorer, consistent_fit_sums
from estimation.consistent.model_selection import (
    CONSISTENT_FAILURES,
    Candidate,
    ConsistentSettings,
    ModelSelection,
    select_scored,
)
from estimation.diagnosis.plain_laws import completion_laws
from estimation.diagnosis.results import Diagnosis, SummedFit
from estimation.estimators.summed_least_squares import summed_estimator
from estimation.identification.fit import implausible_estimates
from estimation.identification.validation import ChannelErrors
from estimation.streaming.diagnosis_result import StreamedRun
from estimation.streaming.diagnosis_sums import ChannelSums, normal_equations

__all__ = ["model_order", "refit_selection", "streamed_completion", "streamed_refit_selection", "sums_scorer",
           "scored_blocks", "validation_blocks", "with_blocks"]


def model_order(fit: SummedFit, columns: Sequence[int]) -> tuple[SummedFit, list[int]]:
    """``fit`` (the streamed diagnosis's adopted model, its estimate in the order of the summed columns ``columns``)
    with its estimate in its model's base-parameter order, and the columns in that order: what the consistent fit
    maps through the model's base (``θ_b = K θ``)."""
    estimate, names = fit.estimate, tuple(fit.model.base.names)
    if sorted(estimate.names) != sorted(names) or len(columns) != len(names):
        raise ValueError("the adopted model's estimate does not hold its model's base parameters")
    order = [list(estimate.names).index(name) for name in names]
    index = np.asarray(order, dtype=int)
    ordered = replace(estimate, values=np.asarray(estimate.values)[index],
                      cov=np.asarray(estimate.cov)[np.ix_(index, index)], std=np.asarray(estimate.std)[index],
                      relative_std=np.asarray(estimate.relative_std)[index], names=names,
                      expressions=tuple(estimate.expressions[i] for i in order))
    return replace(fit, estimate=ordered), [columns[i] for i in order]


def _errors(sums: ChannelSums, columns: Sequence[int], theta: np.ndarray) -> ChannelErrors:
    """Errors of ``theta`` (on ``columns``) against the channels as recorded, from ``sums``."""
    return ChannelErrors(dict(zip(sums.layout.channels, map(float, sums.channel_mse(columns, theta, target=1)))),
                         int(sums.n_samples))


def with_blocks(errors: ChannelErrors, blocks: Sequence[ChannelSums] | None, columns: Sequence[int],
                theta: np.ndarray) -> ChannelErrors:
    """``errors`` (of ``theta`` on ``columns``, from the validation sums) with its MSE on each block of the
    validation record (``blocks``: :func:`validation_blocks`), as memory's
    :func:`~estimation.identification.preprocessing_on_validation.block_mse` cuts the samples it holds; unchanged
    without blocks, or when they do not hold the samples ``errors`` counts."""
    if not blocks or sum(block.n_samples for block in blocks) != errors.n_samples \
            or any(block.n_samples == 0 for block in blocks):
        return errors
    theta = np.asarray(theta, dtype=float)
    table = np.array([block.channel_mse(columns, theta, target=1) for block in blocks])  # (blocks, channels)
    channels = blocks[0].layout.channels
    return replace(errors, block_mse={channel: tuple(map(float, table[:, c])) for c, channel in enumerate(channels)})


def scored_blocks(errors: ChannelErrors, score: Scorer, theta: np.ndarray) -> ChannelErrors:
    """``errors`` (a fit's own validation errors) with the per-block errors ``score`` gives for ``theta`` on the
    same samples (a caller's scorer: a resampled validation file measured at its recorded samples); unchanged when
    it gives none or counts other samples."""
    scored = score({"fit": np.asarray(theta, dtype=float)})["fit"]
    if not scored.block_mse or scored.n_samples != errors.n_samples:
        return errors
    return replace(errors, block_mse=scored.block_mse, block_samples=scored.block_samples)


def sums_scorer(validation: ChannelSums, columns: Sequence[int], blocks: Sequence[ChannelSums] | None = None
                ) -> Scorer:
    """The validation errors of several base-parameter vectors (on ``columns``, in that order) against the channels
    as recorded, from the validation sums: every vector on the same samples; with ``blocks``
    (:func:`validation_blocks`), each also on every block of the record (:func:`with_blocks`)."""
    def score(thetas: Mapping[Any, np.ndarray]) -> dict[Any, ChannelErrors]:
        return {key: with_blocks(_errors(validation, columns, np.asarray(theta, dtype=float)), blocks, columns, theta)
                for key, theta in thetas.items()}
    return score


def validation_blocks(diagnosis: Diagnosis, run: StreamedRun, executor: Any = None) -> tuple[ChannelSums, ...] | None:
    """The validation sums of a streamed diagnosis (``run.sums.validation``: every candidate's columns, against the
    channels as recorded, along the motion its adopted delay moved) on each of the
    :data:`~estimation.identification.preprocessing_on_validation.BLOCKS` contiguous blocks memory cuts the
    validation samples into (:func:`~estimation.streaming.block_errors.block_bounds`): one more pass over the
    validation files (:func:`~estimation.streaming.diagnosis_passes.validation_blocks_pass`). ``None`` without
    validation files, with fewer samples than blocks, or when the pass does not count the sums' samples."""
    from estimation.streaming.block_errors import block_bounds
    from estimation.streaming.cluster import model_payload
    from estimation.streaming.diagnosis_passes import validation_blocks_pass
    from estimation.identification.preprocessing_on_validation import BLOCKS

    counts = [part.n_samples for part, _ in run.sums.validate_parts]
    total = sum(counts)
    if not run.validate or total < BLOCKS:
        return None
    options = run.settings.reading()
    if run.found.delay.value is not None:  # the passes after the search along the moved motion
        options = dict(options, delay=float(run.found.delay.value.value))
    blocks = validation_blocks_pass(executor, model_payload(diagnosis.model), run.found.plan, run.validate, options,
                                    counts, block_bounds(total))
    if sum(block.n_samples for block in blocks) != run.sums.validation.n_samples:
        return None
    return tuple(blocks)


def streamed_refit_selection(diagnosis: Diagnosis, run: StreamedRun, *, given: Literal["consistent"] | None = None,
                             consistent: ConsistentSettings | None = None, score: Scorer | None = None,
                             ratio: float | None = None, still: bool = False,
                             note: str = "with the diagnosed effects",
                             blocks: Sequence[ChannelSums] | None = None) -> ModelSelection:
    """:func:`~estimation.consistent.model_selection.select_refit` of a streamed diagnosis (module docstring): its
    adopted model as fitted (``diagnosis.after``, its validation error as the diagnosis measured it) or its
    consistent refit from the sums of ``run``. ``score``: the validation errors of several base-parameter vectors in
    the model's base order (default :func:`sums_scorer`); ``ratio``: the validation record's repeated-motion ratio
    (``None``: no comparison on another motion); ``still``: the validation record is at rest
    (:func:`~estimation.streaming.model_selection.streamed_still_motion`) and chooses nothing, as in memory. A refit that fails is no candidate (listed with the reason), unless
    ``given="consistent"`` asked for it. ``blocks``: the validation sums by block (:func:`validation_blocks`), for
    the paired difference of the candidates' scores, when they are scored from the validation sums."""
    if given not in (None, "consistent"):
        raise ValueError(f"given must be None or 'consistent', got {given!r}")
    if diagnosis.path != "streamed":
        raise ValueError("a streamed diagnosis is needed (diagnosis.path == 'streamed')")
    fit, columns = model_order(diagnosis.after, run.columns)
    return refit_selection(fit, columns, run, given=given, consistent=consistent, score=score, ratio=ratio,
                           still=still, note=note, blocks=blocks)


def refit_selection(fit: SummedFit, columns: Sequence[int], run: StreamedRun, *,
                    given: Literal["consistent"] | None = None, consistent: ConsistentSettings | None = None,
                    score: Scorer | None = None, ratio: float | None = None, still: bool = False,
                    note: str = "with the diagnosed effects",
                    blocks: Sequence[ChannelSums] | None = None) -> ModelSelection:
    """:func:`streamed_refit_selection` of an unconstrained fit ``fit`` from the sums of ``run``, its estimate in its
    model's base order on the summed ``columns`` (the adopted model's, or :func:`streamed_completion`'s); ``blocks``
    (:func:`validation_blocks`): every candidate scored from the validation sums also on each block."""
    if given not in (None, "consistent"):
        raise ValueError(f"given must be None or 'consistent', got {given!r}")
    base = fit.estimate.method
    sums = run.sums
    if score is None:  # from the validation sums: the fit's own errors with their blocks too
        score = sums_scorer(sums.validation, columns, blocks)
        fit = replace(fit, validation=with_blocks(fit.validation, blocks, columns, fit.estimate.values))
    elif fit.validation.block_mse is None:  # the caller's scorer: the fit's own errors with the blocks it gives
        fit = replace(fit, validation=scored_blocks(fit.validation, score, fit.estimate.values))
    settings = ConsistentSettings() if consistent is None else consistent
    names, expressions = fit.estimate.names, fit.estimate.expressions
    try:
        refit = consistent_fit_sums(fit, normal_equations(sums.train, columns, names, expressions),
                                    lambda theta: _errors(sums.train, columns, theta), score,
                                    prior_weight=settings.prior_weight, prior=settings.prior,
                                    prior_source=settings.prior_source, bounds=settings.bounds, shapes_fixed=True)
        candidate = Candidate("consistent", refit, note=note)
    except CONSISTENT_FAILURES as error:
        if given == "consistent":
            raise
        candidate = Candidate("consistent", None, f"the consistent fit failed ({error})", note=note)
    return select_scored((Candidate(base, fit, note=note), candidate), base=base, given=given, ratio=ratio,
                         still=still)


def streamed_completion(diagnosis: Diagnosis, run: StreamedRun, score: Scorer | None = None
                        ) -> tuple[SummedFit, list[int], tuple[Effect, ...]] | None:
    """:func:`estimation.diagnosis.plain_laws.plain_completion` from the sums of a streamed diagnosis: its adopted
    model with Coulomb friction and an offset added on each joint that has none (the linear Stribeck bump holding no
    Coulomb level), fitted from the training sums with the adopted model's weighting (shaped laws at their fixed
    shapes), as ``(fit, columns, added)``: the fit with its estimate in the completed model's base order and its
    validation errors from ``score`` (default: the validation sums against the channels as recorded), its columns in
    the sums in that order, the laws added. ``None`` when nothing is added, a law added has no column in the sums
    (not a candidate of the search), its base parameters are not the adopted model's and the laws' (a column the
    rigid body already holds), or the fit fails."""
    if diagnosis.path != "streamed":
        raise ValueError("a streamed diagnosis is needed (diagnosis.path == 'streamed')")
    after = diagnosis.after
    model = after.model
    added = completion_laws(model)
    if not added:
        return None
    blocks = run.found.blocks
    indices = []
    for effect in added:
        index = next((i for i, block in blocks.items() if block.n_shape == 0 and block.effect == effect), None)
        if index is None:
            return None
        indices.append(index)
    completed = build_model(model.robot, model.kind, (*model.effects, *added))
    columns = list(run.columns) + [column for index in indices for column in run.found.columns[index]]
    names = list(after.estimate.names) + [name for index in indices for name in blocks[index].names]
    if sorted(names) != sorted(completed.base.names):
        return None
    expressions = list(after.estimate.expressions) + names[len(after.estimate.names):]
    sums = run.sums
    try:
        n_shape = sum(run.found.blocks[index].n_shape for index in run.chosen)  # weighted as in memory
        estimate = summed_estimator(after.estimate.method, n_shape, passive_channels(model)).fit(
            normal_equations(sums.train, columns, names, expressions)).estimate_
    except (ValueError, np.linalg.LinAlgError):
        return None
    fit = SummedFit(model=completed, estimate=estimate, train=_errors(sums.train, columns, estimate.values),
                    validation=_errors(sums.validation, columns, estimate.values),
                    warnings=implausible_estimates(completed, estimate), cov_method="classical")
    fit, ordered = model_order(fit, columns)
    if score is not None:  # on the samples every candidate is scored on
        fit = replace(fit, validation=score({"completed": fit.estimate.values})["completed"])
    return fit, ordered, added
