"""The preprocessing chosen on another motion: each derivative candidate scored by the validation error of the
model fitted with it.

Blocked cross-validation inside the training record
(:mod:`estimation.identification.preprocessing_choice`) scores a derivative candidate by how well a flexible
model predicts held-out blocks of the *same* motion. What a user wants is a model that predicts *another* motion,
and choices made inside one motion do not carry to another (issue 34: a 1.5 Hz cut-off on a KUKA KR300, WLS on
a Schunk arm). On the real Franka Panda of ``benchmarks/README.md`` the training record's cross-validation chose a
10 Hz filter, while a plain least-squares fit whose cut-off was chosen on the validation record predicted the test
record 4 % better. When the user gives a validation record of another motion, the candidates are therefore
compared on it, as the model is (:mod:`estimation.consistent.model_selection`).

**Score** (:class:`ValidationScore`). For each candidate: the training record prepared by it (its derivatives, and
its torques as the fit's targets: as recorded after a Butterworth filter, its default), the declared model fitted by each unconstrained estimator asked
for (``ols``, ``wls``: PUMA paper, eqs. 13 and 20), the validation record prepared by the same candidate, and the
fit's prediction along it compared with the validation torques **as recorded**, at the recorded time stamps
(:func:`estimation.identification.validation.compare_recorded`; never the filtered torques). Memory stays that of
a chunk's regressor whatever the window: the fits are made from sums of the training regressor
(:class:`~estimation.estimators.summed_least_squares.SummedLeastSquares`, the same estimators as accurate as a QR of
the whole regressor), the predictions a chunk at a time, so that scoring the candidates never costs more than the
streamed path (issue 33). The score is the criterion
of every choice on a validation record (:mod:`estimation.identification.relative_error`, the model choice's too):
the mean over the channels of each channel's validation MSE over the smallest that any (candidate, fit) pair
reaches on it, a candidate scored by the better of its fits: the choice is the joint minimum over
(preprocessing, weighting) of one criterion (``oed identify`` without ``--method`` and ``oed diagnose`` ask for OLS
alone, the weighting being chosen afterwards on the same record: over twice as many pairs the minimum takes a lucky
one, 125 Hz by its WLS fit on the TX40 at 2.5 kHz where OLS alone takes 75 Hz; *Weak validation record* below),
and no candidate wins by trading one joint's large loss for another's gain (the geometric mean over channels, used
before, took a 5 Hz filter on a torso and arm that made joint 2's error 0.13 times the plain fit's and the torso's
20 times).

**Same samples.** Every candidate is scored on the same recorded validation samples, checked by their time
stamps: a candidate whose prediction covers other samples than those most candidates cover (one that drops
samples at the edges) is set aside with the reason, so no candidate may win by discarding hard samples.

**Choice** (:func:`choose_on_validation`). The smallest score wins; exact ties (to :data:`TIE_DIGITS` significant
digits) go to the least distorting candidate, as in the training record's choice (a Fourier fit of fewer
harmonics, else the highest cut-off, the logged velocity before the positions', then the description): the
answer does not depend on the order of a list.

**Weak validation record** (:func:`with_standard_errors`). A short validation record may rank candidates by a
fraction of a percent that another stretch of the same motion would reverse: on the Stäubli TX40 at 2.5 kHz
(``benchmarks/README.md``, ``tx40-sub2``) its 1.5 s validation record scored a 125 Hz filter 0.4 % better than
75 Hz, and the test record was predicted 9 % worse with it. The score is a weighted sum of the channels' MSE, so the
difference of two candidates' scores is the mean of their differences on :data:`BLOCKS` contiguous blocks of the
validation record, and its standard error that of a mean of batch means. A candidate within
:data:`~estimation.preprocessing.plan.TIED_SE` standard errors of the best **and** within
:data:`~estimation.identification.preprocessing_choice.EQUIVALENT` of it (the margin within which the training
record's choice calls candidates equivalent) is reported *tied* with it (``standard_error``, ``tied`` in
``result.json``; the summary says how many): the validation record does not tell them apart. The smallest score
is still chosen. Three tie-breaks were measured on the real logs and simulated robots and each made some case
worse (``benchmarks/README.md``, h-weakval2): the training record's held-out blocks (either score) favour
smoothing, since a fit on the same motion absorbs what a low cut-off does to that motion's spectrum (simulated
PUMAs at 1 kHz: 10 Hz taken where the test record preferred the tied 17 Hz by 12 % and 59 %); the median cut-off
of the tied ones took 3.4 Hz on the real Panda where the smallest score's 6 Hz predicts the test record 10 %
better; the median over the blocks keeps the TX40's 125 Hz.

**Nesting with the model choice.** The physically consistent candidate (five prior weights, each an IPOPT
refit) is not fitted for every derivative candidate: the preprocessing is chosen with the cheap unconstrained
fits, and the model among OLS, WLS and the consistent refit is then chosen on the same validation record with the
chosen preprocessing (:func:`estimation.consistent.model_selection.select_model`). The consistent fit is a
regularised refit of the same prepared data; the derivatives decide which data, so they are chosen first.

**When it applies** (:func:`chooses_on_validation`): a validation record is given, it holds another motion
(:func:`estimation.identification.repeated_motion.repeated_motion` above
:data:`~estimation.identification.repeated_motion.REPEAT_FRACTION`), and the training record's choice was made
among candidates (not measured derivatives, not the user's ``--cutoff``/``--frequency``). A validation record
that repeats the training motion measures nothing about another motion: the training record's candidates are
scored on it by the training record's own score, fitted on the whole training record
(:func:`estimation.identification.preprocessing_choice.choose_on_repeat`).
"""

from __future__ import annotations

import functools
import hashlib
import time
import warnings
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import NDArray

from dynamics.measurements import Measurements
from dynamics.models import IdentificationModel
from dynamics.runtime.memory import available_memory
from dynamics.runtime.processes import run_tasks, worker_count
from dynamics.runtime.progress import SECONDS as PROGRESS_SECONDS
from dynamics.runtime.progress import report
from dynamics.runtime.threads import single_threaded_blas
from estimation.data.passive import passive_channels
from estimation.data.segments import concatenate
from estimation.estimators.normal_equations import DEFAULT_CHUNK_SIZE, NormalEquations, accumulate
from estimation.estimators.summed_least_squares import SummedLeastSquares
from estimation.identification.preprocessing_choice import (
    EQUIVALENT,
    MIN_PARALLEL_SCORES,
    SCORED_SAMPLES,
    choose_on_repeat,
    scored_window,
)
from estimation.identification.relative_error import relative_scores
from estimation.identification.repeated_motion import REPEAT_FRACTION, repeated_motion, still_motion
from estimation.identification.validation import Comparison, compare_recorded
from estimation.preprocessing.plan import (
    Evidence,
    Preprocessing,
    TIED_SE,
    SegmentTooShortForFilterError,
    ValidationEvidence,
    prepare,
)

__all__ = ["FITS", "TIE_DIGITS", "ValidationScore", "another_motion", "choose_on_validation", "chooses_on_validation",
           "on_validation"]

#: the unconstrained fits a candidate may be scored with, in the order ties between them are broken
FITS = ("ols", "wls")
#: scores equal to this many significant digits are a tie (the tie rule decides)
TIE_DIGITS = 6
#: contiguous blocks of the validation record whose errors give the standard error of two candidates' difference
BLOCKS = 5
#: what scoring one candidate holds at its peak, bytes a sample and joint or channel (the records prepared, as
#: prepared and as recorded: q, dq, ddq and the channels; the predictions), besides a chunk's regressor (the fits
#: are made from sums, the regressor a chunk at a time: :func:`~estimation.estimators.normal_equations.accumulate`);
#: fewer processes score side by side when memory is short
BYTES_PER_VALUE = 6 * 8


@dataclass(frozen=True)
class ValidationScore:
    """The validation error of the model fitted with a candidate preprocessing (module docstring).

    Attributes
    ----------
    model
        The declared identification model (no shaped laws: their variable projection is not repeated per
        candidate).
    fits
        The unconstrained fits tried, among :data:`FITS`.
    """

    model: IdentificationModel
    fits: tuple[str, ...] = FITS

    def __post_init__(self) -> None:
        if not self.fits or any(fit not in FITS for fit in self.fits):
            raise ValueError(f"fits must be a non-empty tuple of {FITS}, got {self.fits!r}")

    @single_threaded_blas()  # tall thin least squares: threaded BLAS only loses (dynamics.runtime.threads)
    def __call__(self, train: Sequence[Measurements], validation: Sequence[Measurements],
                 preprocessing: Preprocessing, sums: NormalEquations | None = None) -> tuple[ValidationEvidence, str]:
        """The candidate's evidence and a digest of the recorded validation time stamps it was scored on.
        ``sums``: ``train`` as the candidate prepares it, already summed for this model
        (:func:`~estimation.identification.preprocessing_choice.training_sums`, by the blocked cross-validation
        that prepared it): the same sums, not made again."""
        started = time.perf_counter()
        plan = preprocessing.without_evidence()
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")  # said once, for the choice, when the records are prepared again
                weighted = "wls" in self.fits  # its channel weights from the in-band sums (NormalEquations.band)
                if sums is not None and weighted and sums.band is None:
                    sums = None  # the training choice's sums lack them (the OLS scores do not read them)
                prepared_train = prepare(train, plan, role="training data") if sums is None else None
                prepared_validation = prepare(validation, plan, role="validation data")
                if sums is None:
                    # the fits from sums of the regressor made a chunk at a time (the same estimators, as accurate as
                    # a QR of the whole regressor): memory stays that of a chunk, whatever the window (issue 33)
                    sums = accumulate(self.model, concatenate(prepared_train), gram=False,  # the fits use the factors
                                      band=weighted)
                del prepared_train
                estimates = {fit: SummedLeastSquares(method=fit, passive=passive_channels(self.model)).fit(sums).estimate_.values
                             for fit in FITS if fit in self.fits}
                comparisons = compare_recorded(self.model, estimates, prepared_validation, label="validation")
        except (SegmentTooShortForFilterError, ValueError, np.linalg.LinAlgError) as error:
            return ValidationEvidence(plan, float("inf"), {}, error=str(error),
                                      seconds=time.perf_counter() - started), ""
        # the score is relative to the other candidates' errors (rescored): here only whether a fit predicted
        fit_mse = {fit: dict(comparison.mse) for fit, comparison in comparisons.items()}
        finite = [fit for fit, comparison in comparisons.items() if finite_on(comparison.mse, comparison.channels)]
        comparison = comparisons[finite[0] if finite else next(iter(comparisons))]
        stamps = np.ascontiguousarray(comparison.t, dtype=float)
        return (ValidationEvidence(plan, 1.0 if finite else float("inf"), dict(comparison.mse),
                                   finite[0] if finite else None, {}, None, time.perf_counter() - started,
                                   int(stamps.shape[0]), fit_mse,
                                   {fit: block_mse(item) for fit, item in comparisons.items()}),
                hashlib.sha256(stamps.tobytes()).hexdigest())


def block_mse(comparison: Comparison) -> dict[str, tuple[float, ...]]:
    """Per channel, the MSE on each of :data:`BLOCKS` contiguous blocks of the compared samples (as
    :func:`numpy.array_split` cuts them: sizes differ by one sample at most); none when there are fewer samples
    than blocks. A masked sample (NaN: a clipped sensor's, a held channel's repeat) is left out of its channel's
    block, as the comparison's MSE leaves it out (over each channel's valid samples); a block with no valid sample
    of a channel is NaN there."""
    residual = np.asarray(comparison.measured, dtype=float) - np.asarray(comparison.predicted, dtype=float)
    if residual.shape[0] < BLOCKS:
        return {}
    parts = np.array_split(residual ** 2, BLOCKS, axis=0)
    return {channel: tuple(_valid_mean(part[:, column]) for part in parts)
            for column, channel in enumerate(comparison.channels)}


def _valid_mean(squares: NDArray[np.float64]) -> float:
    """The mean of the finite squares (the plain mean when every one is: the same figure to the last digit); NaN
    when none is."""
    valid = ~np.isnan(squares)
    if np.all(valid):
        return float(squares.mean())
    return float(squares[valid].mean()) if np.any(valid) else float("nan")


def finite_on(mse: dict[str, float], channels: Sequence[str]) -> bool:
    """Whether every one of ``channels`` has a finite MSE."""
    return bool(np.all(np.isfinite([mse[channel] for channel in channels])))


def rescored(evidence: Sequence[ValidationEvidence], channels: Sequence[str]) -> list[ValidationEvidence]:
    """The evidence with its scores: every fit of every candidate still compared (finite score) scored by
    :func:`~estimation.identification.relative_error.relative_scores` among all of them, each candidate by its
    better fit (a tie to the first of :data:`FITS`); the others keep ``inf``."""
    pool = {(index, fit): mse for index, item in enumerate(evidence) if np.isfinite(item.score)
            for fit, mse in item.fit_mse.items()}
    scores = relative_scores(pool, channels) if pool else {}
    result = []
    for index, item in enumerate(evidence):
        fit_scores = {fit: scores[(index, fit)] for fit in FITS if (index, fit) in scores}
        if not np.isfinite(item.score) or not fit_scores:
            result.append(replace(item, score=float("inf")) if np.isfinite(item.score) else item)
            continue
        best = min(fit_scores, key=lambda fit: (fit_scores[fit], FITS.index(fit)))
        result.append(replace(item, score=fit_scores[best], validation_mse=dict(item.fit_mse[best]), fit=best,
                              fit_scores=fit_scores))
    return result


def with_standard_errors(evidence: Sequence[ValidationEvidence], channels: Sequence[str]
                         ) -> list[ValidationEvidence]:
    """The evidence (best first, rescored) with each finite candidate's standard error of the difference of its
    score to the best's and whether it is tied with it (module docstring: *Weak validation record*).

    The score is a weighted sum of the channels' MSE (weights ``1 / (n_channels * min_j e[j, c])``,
    :mod:`estimation.identification.relative_error`), so the difference of two candidates' scores is the
    sample-weighted mean of the differences on the validation record's :data:`BLOCKS` contiguous blocks; its
    standard error is that of a mean of batch means (the blocks' differences' spread, the errors being correlated
    in time within a block, not across blocks). Without blocks (too few samples) no candidate is tied."""
    finite = [item for item in evidence if np.isfinite(item.score)]
    if not finite:
        return list(evidence)
    channels = tuple(channels)
    best = finite[0]
    floors = np.array([min(item.fit_mse[fit][channel] for item in finite for fit in item.fit_mse
                           if np.isfinite(item.fit_mse[fit][channel])) for channel in channels])
    if any(len(item.fit_block_mse.get(item.fit, {})) != len(channels) for item in finite) or not np.all(floors > 0):
        return list(evidence)
    sizes = np.array([part.shape[0] for part in np.array_split(np.empty(best.samples), BLOCKS)], dtype=float)
    result = []
    for item in evidence:
        if not np.isfinite(item.score):
            result.append(item)
            continue
        _, error = paired_difference(item.fit_block_mse[item.fit], best.fit_block_mse[best.fit], floors, channels,
                                     sizes)
        result.append(replace(item, standard_error=error, tied=item.score - best.score <= TIED_SE * error
                              and item.score <= (1.0 + EQUIVALENT) * best.score))
    return result


def on_same_samples(scored: Sequence[tuple[ValidationEvidence, str]]) -> list[ValidationEvidence]:
    """The evidence, with any candidate scored on other recorded validation samples than the reference set to
    ``inf`` (with the reason). The reference: the time stamps of the candidates scored on the most samples, the
    digest most of them share (then the smallest digest: not the order of the list)."""
    finite = [(item, digest) for item, digest in scored if np.isfinite(item.score)]
    if not finite:
        return [item for item, _ in scored]
    most = max(item.samples for item, _ in finite)
    digests = [digest for item, digest in finite if item.samples == most]
    reference = min(set(digests), key=lambda digest: (-digests.count(digest), digest))
    return [item if not np.isfinite(item.score) or digest == reference else
            replace(item, score=float("inf"), error=f"scored on {item.samples} recorded validation samples, not the "
                    f"{most} the other candidates predict: not comparable") for item, digest in scored]


def tie_key(plan: Preprocessing) -> tuple:
    """Among candidates of equal score: a Fourier fit of fewer harmonics, else the highest cut-off (the logged
    velocity before the positions'), then the description."""
    return (plan.method != "fourier", plan.harmonics or 0, -(plan.cutoff_hz or 0.0), plan.velocity_from_positions,
            plan.describe())


def choose_on_validation(model: IdentificationModel, train: Sequence[Measurements],
                         validation: Sequence[Measurements], plans: Sequence[Preprocessing], *,
                         fits: tuple[str, ...] = FITS, jobs: int | None = None,
                         training_sums: Mapping[Preprocessing, NormalEquations] | None = None
                         ) -> tuple[Preprocessing | None, tuple[ValidationEvidence, ...]]:
    """The candidate of the smallest validation score and every candidate's evidence, best first (module
    docstring); ``None`` when no candidate could be scored. ``train``, ``validation``: the segments as read.
    ``jobs``: processes that score the candidates side by side (as
    :func:`~estimation.identification.preprocessing_choice.choose_by_evidence`; the same choice whatever the
    number). ``training_sums``: ``train`` as a candidate prepares it, summed for ``model`` by the blocked
    cross-validation that prepared it (:attr:`~estimation.identification.preprocessing_choice.PreprocessingChoice.training_sums`):
    those candidates' fits are made from them, the same sums, without preparing ``train`` again. Each candidate's
    evidence says whether a weak validation record tells it from the best (module docstring: *Weak validation
    record*; reported, the smallest score still chosen)."""
    score = ValidationScore(model, tuple(fits))
    unique = list(dict.fromkeys(plan.without_evidence() for plan in plans))
    started = time.perf_counter()
    samples = sum(segment.n_samples for segment in (*train, *validation))
    task_bytes = (BYTES_PER_VALUE * samples * (model.robot.n_joints + model.n_channels)
                  + 2 * 8 * DEFAULT_CHUNK_SIZE * model.n_channels * model.n_base)  # a chunk's regressor, its QR work
    workers = min(worker_count(jobs, len(unique), min_tasks=MIN_PARALLEL_SCORES),
                  max(1, int(available_memory() // (2 * task_bytes))))  # the same choice whatever the number
    given = {} if training_sums is None else training_sums
    scored = run_tasks([functools.partial(score, tuple(train), tuple(validation), plan,
                                          **({"sums": given[plan]} if plan in given else {})) for plan in unique],
                       workers)
    evidence = tuple(with_standard_errors(sorted(rescored(on_same_samples(scored), model.channels),
                                                 key=lambda item: (item.score, tie_key(item.preprocessing))),
                                          model.channels))
    chosen = decided(evidence)
    if chosen is None:
        return None, evidence
    if time.perf_counter() - started >= PROGRESS_SECONDS:
        report("derivatives: %s chosen on the validation record among %d candidates (%.1f s)",
               chosen.describe_method(), len(evidence), time.perf_counter() - started)
    return chosen, evidence


def paired_difference(first: dict[str, tuple[float, ...]], second: dict[str, tuple[float, ...]],
                      floors: NDArray[np.float64], channels: Sequence[str], sizes: NDArray[np.float64]
                      ) -> tuple[float, float]:
    """The difference of two candidates' scores (the mean over ``channels`` of each block's MSE over the channel's
    ``floors``, the blocks weighted by their ``sizes``) and its standard error as a mean of batch means."""
    weights = np.asarray(sizes, dtype=float) / np.sum(sizes)

    def blocks(item: dict[str, tuple[float, ...]]) -> NDArray[np.float64]:
        return (np.array([item[channel] for channel in channels]) / floors[:, None]).mean(axis=0)

    differences = blocks(first) - blocks(second)
    mean = float(weights @ differences)
    count = differences.shape[0]
    return mean, float(np.sqrt(count / (count - 1) * np.sum(weights ** 2 * (differences - mean) ** 2)))


def decided(evidence: Sequence[ValidationEvidence]) -> Preprocessing | None:
    """The candidate of the smallest score in the evidence (best first), exact ties (:data:`TIE_DIGITS`) to
    :func:`tie_key`, whether or not other candidates are tied with it within the validation record's standard error
    (module docstring: *Weak validation record*); ``None`` when no candidate was scored."""
    finite = [item for item in evidence if np.isfinite(item.score)]
    if not finite:
        return None
    best = float(f"{finite[0].score:.{TIE_DIGITS}g}")
    return min((item.preprocessing for item in finite if float(f"{item.score:.{TIE_DIGITS}g}") == best), key=tie_key)


def chooses_on_validation(chosen: Preprocessing, train: Sequence[Measurements],
                          validation: Sequence[Measurements]) -> bool:
    """Whether the preprocessing is chosen again on the validation record (module docstring: when it applies):
    ``chosen`` was chosen among candidates on the training record, and the validation record holds another
    motion (neither a repeat of it nor a record at rest: :func:`~estimation.identification.repeated_motion.still_motion`)."""
    if not validation or chosen.evidence is None or chosen.evidence.selection != "held-out":
        return False
    return another_motion(train, validation)


def another_motion(train: Sequence[Measurements], validation: Sequence[Measurements]) -> bool:
    """Whether the validation record holds another motion than the training record: neither a repeat of it
    (:func:`~estimation.identification.repeated_motion.repeated_motion` above
    :data:`~estimation.identification.repeated_motion.REPEAT_FRACTION`) nor a record at rest
    (:func:`~estimation.identification.repeated_motion.still_motion`); ``train``, ``validation``: the windows the
    choice scores (:func:`on_validation`)."""
    train_record, validation_record = concatenate(train), concatenate(validation)
    return (repeated_motion(train_record, validation_record) > REPEAT_FRACTION
            and not still_motion(train_record, validation_record))


def window(segment: Measurements) -> Measurements:
    """A validation segment's first :data:`~estimation.identification.preprocessing_choice.SCORED_SAMPLES`
    samples (all of them when it holds fewer): what the streamed path reads of a validation file."""
    return segment if segment.n_samples <= SCORED_SAMPLES else segment.select(slice(0, SCORED_SAMPLES))


def on_validation(chosen: Preprocessing, model: IdentificationModel, train: Sequence[Measurements],
                  validation: Sequence[Measurements], *, fits: tuple[str, ...] = FITS,
                  jobs: int | None = None,
                  training_sums: Sequence[tuple[Preprocessing, NormalEquations]] = ()) -> Preprocessing:
    """``chosen`` (the training record's choice, with its evidence) chosen again among the same candidates on
    the validation record when that is another motion (:func:`chooses_on_validation`), else ``chosen`` as it is.
    Scored on windows, as the training record's choice is: the training record's
    (:func:`~estimation.identification.preprocessing_choice.scored_window`: the whole record up to
    :data:`~estimation.identification.preprocessing_choice.SCORED_SAMPLES` samples) and each validation segment's
    first :data:`~estimation.identification.preprocessing_choice.SCORED_SAMPLES` samples (:func:`window`), so
    that memory stays bounded and the streamed path, which reads those windows, chooses alike.
    The plan returned carries both: ``evidence.candidates`` (the training record's scores) and
    ``evidence.validation`` (the validation scores), with ``evidence.selection`` ``"validation"``.
    ``training_sums``: see :func:`choose_on_validation` (:attr:`~estimation.identification.preprocessing_choice.PreprocessingChoice.training_sums`
    of the choice that made ``chosen``)."""
    train, validation = scored_window(train), [window(segment) for segment in validation]
    if chosen.evidence is None or not validation or chosen.evidence.selection != "held-out":
        return chosen
    if not chooses_on_validation(chosen, train, validation):
        if still_motion(concatenate(train), concatenate(validation)):
            return chosen
        return choose_on_repeat(chosen, model, train, validation, jobs=jobs)  # a repeat of the training motion
    plans = [item.preprocessing for item in chosen.evidence.candidates]
    best, evidence = choose_on_validation(model, train, validation, plans, fits=fits, jobs=jobs,
                                          training_sums=dict(training_sums))
    if best is None:
        return chosen
    return replace(best, evidence=Evidence("validation", chosen.evidence.folds, chosen.evidence.candidates, evidence,
                                           chosen.without_evidence()))
