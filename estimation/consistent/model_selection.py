"""The default answer of ``oed identify``: of the principled candidate models, the one that predicts another motion best.

Users identify a robot to use the model on other motions (feed-forward, simulation, collision detection), so the
answer is chosen by its error on a motion the fit did not see (issue 34). The candidates:

``ols``
    ordinary least squares on the base parameters (PUMA paper, section IV, eq. 13);
``wls``
    channel-weighted least squares, each channel weighted by the inverse of its residual variance (eq. 20);
``consistent``
    the physically consistent fit (:func:`estimation.consistent.identification.identify_consistent`: every link a
    rigid body under the log-Cholesky map, friction and armature ``>= 0``) refitted from the unconstrained fit that
    predicts a validation record of another motion best (:func:`validation_base`), else from the one the training
    record's blocked cross-validation prefers (:mod:`estimation.identification.weighting_choice`), with the
    robot description's bodies as prior, the prior's weight chosen by the validation error
    (:func:`choose_prior_weight`; :data:`DEFAULT_PRIOR_WEIGHT` without a validation record).

**Comparison.** Every candidate predicts the same validation samples and is scored against the channels as recorded
by the criterion of every choice on a validation record (:mod:`estimation.identification.relative_error`): the
mean over channels of its MSE over the smallest any candidate reaches on that channel (no channel's unit dominates
it, and no candidate wins by trading one joint's large loss for another's gain); the smallest wins, a tie going to
the candidate that regularises most (:data:`PREFERENCE`, a fixed order: the answer does not depend on the order of
a list).

**Within the validation record's sampling error** (:func:`paired_difference`). A short validation record ranks
candidates by differences that another stretch of the same motion would reverse: on a real Franka Panda whose
validation record was cut to 2 s, WLS scored 1.021 against the consistent fit's 1.063 and predicted the test record
1.6 to 4.6 times worse on one joint (``benchmarks/README.md``, h-shortval). The score is a weighted sum of the
channels' MSE (:mod:`estimation.identification.relative_error`), so the difference between the best candidate's
score and the consistent one's is the mean of a per-sample difference on the same samples; its standard error is
that of a mean of batch means over :data:`~estimation.identification.preprocessing_on_validation.BLOCKS`
contiguous blocks of the validation record (the residuals are correlated in time within a block; paired, the two
candidates' common error cancels, so the difference is known far better than either score). When the difference is
not above :data:`NOISE_QUANTILE` standard errors (a one-sided test at :data:`NOISE_LEVEL`: Student's t with
``BLOCKS - 1`` degrees of freedom, since the standard error is estimated from that many blocks), the validation
record does not tell the candidates apart. This is **reported** (``paired_difference`` in ``result.json``, a line
of the summary; not the reason, which the streamed path gives alike); the smallest score is still chosen. Choosing the consistent candidate then (the toolkit's preference when
nothing measured extrapolation) fixed the Panda's identify on the short records but made the Panda at 100 Hz
worse (``benchmarks/README.md``, h-shortval: the rule is kept on a side branch). The streamed path holds no samples,
but it sums each block's squared errors on its validation pass (:mod:`estimation.streaming.block_errors`, the
blocks cut as here), so it reports the same figures (``benchmarks/README.md``, h-streamsel), a validation file it
resampled onto a uniform grid at its recorded stamps as here.

**The weighting** (:func:`weighting_difference`). The channel-weighted fit is ordinary least squares plus one
estimated quantity per channel (the weights, each the inverse of the channel's training residual variance: PUMA
paper, eq. 20). When it scores lower, how much lower is **reported** as the paired difference of the two on the
same validation blocks (``weighting_difference`` in ``result.json``, a line of the summary), as the consistent
candidate's is; the smallest score is still chosen. Acting on it was measured and not kept (``benchmarks/README.md``,
h-sag2): choosing ordinary least squares when the weighted fit's lead is within :data:`NOISE_QUANTILE` standard
errors flips the real Franka Panda's identify (wls 1.006 against ols 1.02, within the error), and the flip predicts
its test record worse (the mean of the joints' ratios to a plain fit 0.905 to 0.939, joint 7 0.999 to 1.024); on
the sagging arm of ``tests/test_unseen_robot_days.py``, where the weighted fit predicts the test worse, its lead is
5 standard errors and the rule does not fire. The validation record's sampling error is not what separates the two
on another kind of motion.

**No comparison.** When there is no validation record, or it repeats the training motion
(:func:`estimation.identification.repeated_motion.repeated_motion`), nothing measured how a candidate extrapolates
to another motion: the consistent candidate is chosen, since it regularises toward the description where the data
say nothing, and the summary says why. A candidate that cannot be fitted (IPOPT failing from every start) is no candidate: it is listed with the reason.

A choice given by the user (``--method ols|wls``, ``--consistent``) is kept: the selection is then ``given``.

**Already-fitted candidates.** :func:`select_fitted` makes the same choice among candidates fitted elsewhere;
:func:`select_refit` takes one unconstrained fit (``oed diagnose``'s adopted model, with its effects, shaped laws
and delay) and its consistent refit (:func:`estimation.consistent.identification.consistent_fit`, shaped laws and
the delay held at their fitted values) as the two candidates: the default answer of ``oed diagnose``.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, replace
from typing import Any, Literal

import numpy as np
from numpy.typing import NDArray

from dynamics.measurements import Measurements
from dynamics.models import IdentificationModel
from estimation.consistent.identification import (
    DEFAULT_PRIOR_WEIGHT,
    PRIOR_WEIGHT_GRID,
    PRIOR_WEIGHT_TOLERANCE,
    ConsistentResult,
    choose_prior_weight,
    consistent_fit,
    prior_weight_choice,
)
from estimation.identification.fit import IdentificationResult, identify
from estimation.identification.model_file import alternative_entry, effect_entries, model_file_document, with_model
from estimation.identification.preprocessing_on_validation import BLOCKS, block_mse
from estimation.identification.preprocessing_on_validation import paired_difference as blocks_difference
from estimation.identification.relative_error import CRITERION, relative_scores
from estimation.identification.repeated_motion import REPEAT_FRACTION, repeated_motion, still_motion
from estimation.identification.validation import ChannelErrors, Comparison

__all__ = ["CANDIDATES", "CONSISTENT_FAILURES", "DEFAULT_PRIOR_WEIGHT", "PREFERENCE", "PRIOR_WEIGHT_GRID", "PRIOR_WEIGHT_TOLERANCE",
           "Candidate", "ConsistentSettings", "ModelSelection", "NOISE_LEVEL", "NOISE_QUANTILE", "PairedDifference", "answers_scored", "candidate_answer", "choose_prior_weight", "consistent_entry",
           "paired_difference", "prior_weight_choice", "select_fitted", "weighting_difference", "select_model", "select_refit", "select_scored",
           "selection_model_file"]

CandidateName = Literal["ols", "wls", "consistent"]
Selection = Literal["validation", "given", "no-validation", "repeated-motion", "still-validation"]

#: the candidates, in the order they are listed
CANDIDATES: tuple[CandidateName, ...] = ("ols", "wls", "consistent")
#: ties go to the first of these: the candidate that regularises most
PREFERENCE: tuple[CandidateName, ...] = ("consistent", "wls", "ols")
#: errors that make the consistent fit no candidate (a failure of the toolkit's own choice never ends the run)
CONSISTENT_FAILURES = (ValueError, RuntimeError, NotImplementedError, np.linalg.LinAlgError)
_CONSISTENT_FAILURES = CONSISTENT_FAILURES
#: the one-sided level at which the validation record is said to show the best candidate better than the consistent
#: one (module docstring: *Within the validation record's sampling error*)
NOISE_LEVEL = 0.05
#: the one-sided :data:`NOISE_LEVEL` quantile of Student's t with ``BLOCKS - 1 = 4`` degrees of freedom (the standard
#: error is a batch-means estimate from :data:`~estimation.identification.preprocessing_on_validation.BLOCKS` blocks)
NOISE_QUANTILE = 2.132


@dataclass(frozen=True)
class PairedDifference:
    """How much better the best-scoring candidate is than the consistent one on the validation record, and whether
    that is beyond the record's sampling error (module docstring).

    Attributes
    ----------
    best
        The candidate of the smallest validation score.
    regularised
        The candidate compared with it (``consistent``).
    difference
        ``score[regularised] - score[best]`` (``>= 0``), the scores of :data:`CRITERION`.
    standard_error
        Its standard error, batch means over ``blocks`` contiguous blocks of the validation record.
    blocks
        How many blocks.
    """

    best: CandidateName
    regularised: CandidateName
    difference: float
    standard_error: float
    blocks: int = BLOCKS

    @property
    def threshold(self) -> float:
        """The difference the validation record must show: :data:`NOISE_QUANTILE` standard errors."""
        return NOISE_QUANTILE * self.standard_error

    @property
    def within_noise(self) -> bool:
        """Whether the validation record does not tell the two apart (the difference not above :attr:`threshold`)."""
        return self.difference <= self.threshold

    @property
    def ratio(self) -> float:
        """The difference in standard errors (``inf`` for a difference with no spread over the blocks)."""
        return self.difference / self.standard_error if self.standard_error > 0 else (
            0.0 if self.difference == 0 else float("inf"))

    def to_dict(self) -> dict[str, Any]:
        """The key ``model_selection.paired_difference`` of ``result.json``."""
        return {"best": self.best, "regularised": self.regularised, "difference": self.difference,
                "standard_error": self.standard_error, "blocks": self.blocks, "level": NOISE_LEVEL,
                "quantile": NOISE_QUANTILE, "within_noise": self.within_noise}

    def sentence(self) -> str:
        """What the comparison found, for the summary."""
        told = ("within its sampling error: the validation record does not tell them apart" if self.within_noise
                else "beyond its sampling error")
        return (f"{self.regularised} {self.difference:.3g} above {self.best}, {self.ratio:.3g} standard errors of the "
                f"paired difference over {self.blocks} blocks of the validation record (one-sided "
                f"{100 * NOISE_LEVEL:g} %: {NOISE_QUANTILE:g}), {told}")


@dataclass(frozen=True)
class ConsistentSettings:
    """How the consistent candidate is fitted.

    Attributes
    ----------
    prior_weight
        A number, ``"auto"`` (chosen by the validation error) or ``None`` (auto with a validation record, else
        :data:`DEFAULT_PRIOR_WEIGHT`).
    prior
        The ``10 n`` link parameters of the prior (``None``: the robot description's).
    prior_source
        What the prior is, for the result.
    bounds
        Link bounds by link name (:class:`dynamics.physical_parameters.LinkBounds`), or ``None``.
    """

    prior_weight: float | str | None = None
    prior: NDArray[np.float64] | None = None
    prior_source: str = "robot description"
    bounds: Mapping[str, Any] | None = None

    def refit(self, result: IdentificationResult, train: Measurements,
              validation: Measurements | None) -> ConsistentResult:
        """The consistent fit of ``result`` (:func:`estimation.consistent.identification.consistent_fit`: its prior
        weight chosen on ``validation``; shaped laws and a delay held at their fitted values)."""
        if self.prior_weight == "auto" and validation is None:
            raise ValueError("the prior weight 'auto' chooses the weight by the validation error: give a "
                             "validation record")
        return consistent_fit(result, train, validation, prior_weight=self.prior_weight, prior=self.prior,
                              prior_source=self.prior_source, bounds=self.bounds)


@dataclass(frozen=True)
class Candidate:
    """One candidate model and its error on the validation record.

    Attributes
    ----------
    name
        ``ols``, ``wls`` or ``consistent``.
    fit
        Its :class:`IdentificationResult` (``ols``, ``wls``) or :class:`ConsistentResult`, ``None`` when it could
        not be fitted.
    unavailable
        Why it is no candidate (``None``: it is one).
    note
        What the candidate holds beside its name, appended to its description (``"with the diagnosed effects"``).
    """

    name: CandidateName
    fit: IdentificationResult | ConsistentResult | None
    unavailable: str | None = None
    note: str = ""

    @property
    def train(self) -> Comparison | None:
        return None if self.fit is None else self.fit.train

    @property
    def validation(self) -> Comparison | None:
        return None if self.fit is None else self.fit.validation

    @property
    def description(self) -> str:
        if self.name == "consistent":
            text = "physically consistent, the robot description's bodies as prior"
        else:
            text = {"ols": "ordinary least squares", "wls": "channel-weighted least squares"}[self.name]
        return f"{text}, {self.note}" if self.note else text

    def to_dict(self, score: float | None = None) -> dict[str, Any]:
        """``{name, description, available, reason, validation_mse, train_mse, score[, prior_weight]}``; ``score``:
        its score among the candidates it was compared with (:func:`scores`)."""
        document: dict[str, Any] = {
            "name": self.name, "description": self.description, "available": self.fit is not None,
            "reason": self.unavailable,
            "validation_mse": None if self.validation is None else self.validation.mse,
            "train_mse": None if self.train is None else self.train.mse,
            "score": score,
        }
        if isinstance(self.fit, ConsistentResult):
            document["prior_weight"] = self.fit.estimate.prior_weight
        return document


@dataclass(frozen=True)
class ModelSelection:
    """The candidates, which was chosen, and why (module docstring).

    Attributes
    ----------
    chosen
        The chosen candidate's name.
    selection
        ``validation`` (smallest validation error), ``given`` (the user's option), ``no-validation`` or
        ``repeated-motion`` (the consistent candidate preferred since nothing measured the extrapolation), or
        ``still-validation`` (as ``repeated-motion``: the validation record hardly moves).
    reason
        One sentence saying why.
    candidates
        Every candidate tried, in :data:`CANDIDATES` order.
    base
        The name of the unconstrained fit the consistent candidate is refitted from.
    repeat_ratio
        :func:`estimation.identification.repeated_motion.repeated_motion` of the validation record (``None``:
        none given).
    paired
        The best-scoring candidate against the consistent one on the validation record (:func:`paired_difference`,
        reported: the choice is the smallest score's; ``None`` when not compared: the consistent one best or missing, no samples held, no choice on a record of
        another motion).
    weighting
        The channel-weighted fit against ordinary least squares on the validation record when the weighted one scores
        lower (:func:`weighting_difference`, reported: the choice is the smallest score's; ``None`` when not
        compared).
    """

    chosen: CandidateName
    selection: Selection
    reason: str
    candidates: tuple[Candidate, ...]
    base: CandidateName
    repeat_ratio: float | None = None
    paired: PairedDifference | None = None
    weighting: PairedDifference | None = None

    def candidate(self, name: str) -> Candidate:
        for candidate in self.candidates:
            if candidate.name == name:
                return candidate
        raise KeyError(f"no candidate {name!r}; the candidates are {[c.name for c in self.candidates]}")

    @property
    def chosen_candidate(self) -> Candidate:
        return self.candidate(self.chosen)

    @property
    def unconstrained(self) -> IdentificationResult:
        """The unconstrained fit behind the answer: the chosen one, or the one the consistent fit starts from."""
        name = self.chosen if self.chosen != "consistent" else self.base
        fit = self.candidate(name).fit
        assert isinstance(fit, IdentificationResult)
        return fit

    @property
    def consistent(self) -> ConsistentResult | None:
        """The consistent candidate's fit, if there is one."""
        for candidate in self.candidates:
            if candidate.name == "consistent" and isinstance(candidate.fit, ConsistentResult):
                return candidate.fit
        return None

    @property
    def scores(self) -> dict[str, float]:
        """Each candidate's validation score among the others (:func:`scores`), by name."""
        return scores(self.candidates)

    @property
    def alternatives(self) -> tuple[Candidate, ...]:
        """The fitted candidates other than the chosen one."""
        return tuple(c for c in self.candidates if c.fit is not None and c.name != self.chosen)

    def to_dict(self) -> dict[str, Any]:
        """The key ``model_selection`` of ``result.json``::

            {chosen, selection, reason, criterion, base, repeat_ratio,
             candidates: [{name, description, available, reason, validation_mse, train_mse, score[, prior_weight]}],
             paired_difference: {best, regularised, difference, standard_error, blocks, level, quantile,
                                 within_noise} or null,
             weighting_difference: the same keys (best wls, regularised ols) or null}
        """
        return {"chosen": self.chosen, "selection": self.selection, "reason": self.reason, "criterion": CRITERION,
                "base": self.base, "repeat_ratio": self.repeat_ratio,
                "candidates": [candidate.to_dict(self.scores.get(candidate.name)) for candidate in self.candidates],
                "paired_difference": None if self.paired is None else self.paired.to_dict(),
                "weighting_difference": None if self.weighting is None else self.weighting.to_dict()}

    def lines(self) -> list[str]:
        """The summary: each candidate's validation MSE side by side, the choice and why."""
        lines = [f"model: {self.chosen} ({self.chosen_candidate.description}); {self.reason}"]
        channels = next((_channels(c.validation) for c in self.candidates if c.validation is not None
                         and c.validation.mse is not None), None)
        scored = self.scores
        if channels is not None:
            lines.append("  validation MSE (vs recorded)  " + "  ".join(f"{c:>10s}" for c in channels)
                         + f"  {'score':>10s}")
        for candidate in self.candidates:
            mark = "*" if candidate.name == self.chosen else " "
            if candidate.fit is None:
                lines.append(f"  {mark} {candidate.name:<27s} not a candidate: {candidate.unavailable}")
            elif candidate.validation is not None and candidate.validation.mse is not None:
                mse = candidate.validation.mse
                lines.append(f"  {mark} {candidate.name:<27s} " + "  ".join(f"{mse[c]:10.4g}" for c in channels)
                             + f"  {scored.get(candidate.name, float('inf')):10.4g}")
            else:
                lines.append(f"  {mark} {candidate.name:<27s} (no validation record)")
        if self.paired is not None:  # in memory only (the streamed path holds no samples): not in the reason
            lines.append(f"  paired difference: {self.paired.sentence()}")
        if self.weighting is not None:
            lines.append(f"  weighting: {self.weighting.sentence()}")
        return lines


def select_model(model: IdentificationModel, train: Measurements, validation: Measurements | None = None, *,
                 base: Literal["ols", "wls"] = "wls", given: CandidateName | None = None,
                 consistent: ConsistentSettings | None = None, delay: Any = None,
                 fits: Mapping[str, IdentificationResult] | None = None) -> ModelSelection:
    """Fit the candidates on ``train``, score them on ``validation`` and choose (module docstring).

    Parameters
    ----------
    model
        The identification model.
    train, validation
        Prepared records (``q, dq, ddq`` present); ``validation`` may be ``None``.
    base
        The unconstrained weighting the consistent fit starts from (the training record's own choice,
        :func:`estimation.identification.weighting_choice.choose_weighting`, or the user's); with no choice given
        and a validation record of another motion, the weighting that predicts it better instead
        (:func:`validation_base`).
    given
        A candidate the user asked for (``--method ols|wls``, ``--consistent``): it is chosen, and only what it
        needs is fitted.
    consistent
        How the consistent candidate is fitted (default :class:`ConsistentSettings`).
    delay
        A delay search (:mod:`estimation.preprocessing.delay`) for the unconstrained fits; the consistent fit holds the fitted delay.
    fits
        Unconstrained fits already made, by name (``ols``, ``wls``), reused instead of refitted.
    """
    if given is not None and given not in CANDIDATES:
        raise ValueError(f"given must be one of {CANDIDATES}, got {given!r}")
    if base not in ("ols", "wls"):
        raise ValueError(f"base must be 'ols' or 'wls', got {base!r}")
    settings = ConsistentSettings() if consistent is None else consistent
    known = dict(fits or {})

    def unconstrained(name: str) -> IdentificationResult:
        if name not in known:
            known[name] = identify(model, train, validation, weighted=name == "wls", delay=delay)
        return known[name]

    if given is None and validation is not None and repeated_motion(train, validation) > REPEAT_FRACTION \
            and not still_motion(train, validation):
        base = validation_base(unconstrained, base)
    wanted = wanted_candidates(given, base, validated=validation is not None)
    candidates = []
    for name in CANDIDATES:
        if name not in wanted:
            continue
        if name != "consistent":
            candidates.append(Candidate(name, unconstrained(name)))
            continue
        start = unconstrained(base)
        reason = _no_consistent_fit(start, delay)
        if reason is not None and given == "consistent":
            raise ValueError(f"the consistent fit: {reason}")
        if reason is None:
            try:
                candidates.append(Candidate("consistent", settings.refit(start, train, validation)))
                continue
            except _CONSISTENT_FAILURES as error:
                if given == "consistent":
                    raise
                reason = f"the consistent fit failed ({error})"
        candidates.append(Candidate("consistent", None, reason))
    return select_fitted(candidates, train, validation, base=base, given=given)


def wanted_candidates(given: CandidateName | None, base: str, *, validated: bool) -> tuple[str, ...]:
    """The candidates a selection fits: the weighting ``given`` alone; the consistent refit from ``base`` beside
    ``base`` when it is ``given``; else every one of :data:`CANDIDATES` with a validation record to compare them on
    (``validated``), and without one ``base`` and its refit (the refit preferred, :data:`PREFERENCE`)."""
    if given in ("ols", "wls"):
        return (given,)
    if given == "consistent" or not validated:
        return (base, "consistent")
    return CANDIDATES


def validation_base(unconstrained: Callable[[str], IdentificationResult],
                    base: Literal["ols", "wls"]) -> Literal["ols", "wls"]:
    """The unconstrained fit the consistent candidate is refitted from when the validation record is another
    motion: of ``ols`` and ``wls`` (``unconstrained(name)`` fits them), the one of the smaller validation score
    (:data:`CRITERION`, between the two; a tie to ``base``, the training record's own preference). The weighting is
    a choice like the others, made on the motion the choice did not see when there is one."""
    finite = scores([Candidate(name, unconstrained(name)) for name in ("ols", "wls")])
    if len(finite) < 2 or finite["ols"] == finite["wls"]:
        return base
    return min(finite, key=finite.__getitem__)  # type: ignore[return-value]


def scores(candidates: Sequence[Candidate]) -> dict[str, float]:
    """The finite validation scores (:data:`CRITERION`) of the fitted ``candidates`` with a validation record,
    each relative to the others' errors, by name; the others are left out."""
    errors = {c.name: c.validation.mse for c in candidates
              if c.fit is not None and c.validation is not None and c.validation.mse is not None}
    if not errors:
        return {}
    channels = tuple(next(iter(errors.values())))
    return {name: score for name, score in relative_scores(errors, channels).items() if math.isfinite(score)}


def select_fitted(candidates: Sequence[Candidate], train: Measurements, validation: Measurements | None = None, *,
                  base: Literal["ols", "wls"], given: CandidateName | None = None) -> ModelSelection:
    """The choice among candidates already fitted and scored on ``validation`` (module docstring: the criterion,
    the preference without another motion, ``given``); ``base`` names the unconstrained candidate the consistent
    one was refitted from, and is kept when nothing else can be chosen.

    The candidates are listed in :data:`CANDIDATES` order whatever the order given."""
    ratio = None if validation is None else repeated_motion(train, validation)
    still = validation is not None and still_motion(train, validation)
    return select_scored(candidates, base=base, given=given, ratio=ratio, still=still)


def select_scored(candidates: Sequence[Candidate], *, base: Literal["ols", "wls"], given: CandidateName | None = None,
                  ratio: float | None, still: bool = False) -> ModelSelection:
    """:func:`select_fitted` of candidates whose records are not held (the streamed path: their errors from sums,
    :class:`~estimation.identification.validation.ChannelErrors`), ``ratio`` the
    :func:`~estimation.identification.repeated_motion.repeated_motion` of the validation record (``None``: none);
    ``still``: the validation record hardly moves (:func:`~estimation.identification.repeated_motion.still_motion`),
    and chooses nothing, as a repeat does not."""
    by_name = {candidate.name: candidate for candidate in candidates}
    if len(by_name) != len(candidates):
        raise ValueError(f"two candidates share a name: {[candidate.name for candidate in candidates]}")
    if given is None and (base not in by_name or by_name[base].fit is None):
        raise ValueError(f"the base candidate {base!r} must be among the fitted candidates {sorted(by_name)}")
    ordered = tuple(by_name[name] for name in CANDIDATES if name in by_name)
    chosen, selection, reason = _choose(ordered, given, base, ratio, still)
    paired = paired_difference(ordered, chosen) if selection == "validation" else None  # reported, not acted on
    weighting = weighting_difference(ordered) if selection == "validation" else None  # reported, not acted on
    return ModelSelection(chosen, selection, reason, ordered, base, ratio, paired, weighting)


def paired_difference(candidates: Sequence[Candidate], best: str, regularised: CandidateName = "consistent"
                      ) -> PairedDifference | None:
    """The difference of the validation scores of ``regularised`` and ``best`` (the smallest score) among the
    fitted ``candidates``, with its batch-means standard error (module docstring: *Within the validation record's
    sampling error*); ``None`` when ``best`` is ``regularised``, either is missing or has neither its validation
    samples held nor their per-block sums (a :class:`~estimation.identification.validation.ChannelErrors` of sums
    without ``block_mse``), they were compared on other samples, or the record has fewer samples than blocks.

    The streamed path's errors come from sums: each block's squared errors summed on its validation pass, the blocks
    cut by sample count as memory cuts the samples it holds (:mod:`estimation.streaming.block_errors`), so the same
    record gives the same figures either way."""
    by_name = {candidate.name: candidate for candidate in candidates}
    if best == regularised or best not in by_name or regularised not in by_name:
        return None
    pair = (by_name[best].validation, by_name[regularised].validation)
    if any(item is None or item.mse is None or _blocked_samples(item) is None for item in pair) \
            or not _same_samples(pair[0], pair[1]) or _blocked_samples(pair[0]) < BLOCKS:
        return None
    blocks = [_blocks(item) for item in pair]
    if any(not block for block in blocks):
        return None
    channels = _channels(pair[0])
    errors = {c.name: c.validation.mse for c in candidates
              if c.fit is not None and c.validation is not None and c.validation.mse is not None}
    table = np.array([[mse[channel] for channel in channels] for mse in errors.values()], dtype=float)
    finite = np.all(np.isfinite(table), axis=1)
    floors = table[finite].min(axis=0) if np.any(finite) else np.zeros(len(channels))
    if not np.all(floors > 0):
        return None
    sizes = np.array([part.shape[0] for part in np.array_split(np.empty(_blocked_samples(pair[0])), BLOCKS)],
                     dtype=float)
    difference, error = blocks_difference(blocks[1], blocks[0], floors, channels, sizes)
    if not (math.isfinite(difference) and math.isfinite(error)):
        return None
    return PairedDifference(best, regularised, difference, error)  # type: ignore[arg-type]


def _same_samples(first: Comparison | ChannelErrors, second: Comparison | ChannelErrors) -> bool:
    """Whether two validation errors were measured on the same samples: the same time stamps of two held
    comparisons, or the same count of two from sums of one validation pass (a scorer of several parameter
    vectors scores them all on its samples)."""
    if isinstance(first, Comparison) and isinstance(second, Comparison):
        return first.t.shape == second.t.shape and bool(np.array_equal(first.t, second.t))
    if isinstance(first, Comparison) or isinstance(second, Comparison):
        return False
    return _blocked_samples(first) == _blocked_samples(second)


def _blocked_samples(errors: Comparison | ChannelErrors) -> int | None:
    """How many samples the validation blocks are cut from: a comparison's, or those summed by block."""
    if isinstance(errors, ChannelErrors) and errors.block_samples is not None:
        return errors.block_samples
    return errors.n_samples


def _blocks(errors: Comparison | ChannelErrors) -> dict[str, tuple[float, ...]]:
    """Per channel, the MSE of each validation block: of the samples held, or summed by block (empty: none)."""
    if isinstance(errors, Comparison):
        return block_mse(errors)
    return dict(errors.block_mse or {})


def answers_scored(selection: ModelSelection, other: ModelSelection) -> tuple[float, float] | None:
    """The scores of two selections' answers on the same validation record, ``(selection's, other's)``, by the
    default answer's criterion (:func:`~estimation.identification.relative_error.relative_scores`): how a candidate
    model (with motor-side friction, with torque gains) is judged against the declared one. ``None`` unless both
    were chosen on a validation record of another motion and both answers have validation errors."""
    answers = (selection.chosen_candidate, other.chosen_candidate)
    if selection.selection != "validation" or other.selection != "validation" \
            or any(answer.fit is None or answer.validation is None or answer.validation.mse is None
                   for answer in answers):
        return None
    scored = relative_scores({index: answer.validation.mse for index, answer in enumerate(answers)},
                             _channels(answers[0].validation))
    return scored[0], scored[1]


def candidate_answer(selection: ModelSelection, other: ModelSelection, *, tolerance: float, added: str
                     ) -> ModelSelection:
    """The default answer with a model of added laws a candidate: ``other`` (the selection of the declared model with
    the laws ``added`` describes) when its answer scores lower on the validation record than the declared model's
    (``selection``, :func:`answers_scored`) by more than ``tolerance`` (relative; a tie keeps the declared model),
    else ``selection``; its reason gives both scores. ``selection`` unchanged unless both were chosen on a
    validation record of another motion (nothing measured how the added laws extrapolate)."""
    scored = answers_scored(selection, other)
    if scored is None:
        return selection
    declared, candidate = scored
    taken = (1.0 + tolerance) * candidate < declared
    why = (f"; {added}: its answer ({other.chosen}) validates {candidate:.4g} against {declared:.4g} for the declared "
           f"model's ({selection.chosen}; the mean relative validation error), " + ("taken" if taken else "not taken"))
    return replace(other, reason=other.reason + why) if taken else replace(selection, reason=selection.reason + why)


def _channels(errors: Comparison | ChannelErrors) -> tuple[str, ...]:
    """The channels of a record's errors (a :class:`Comparison`'s, or the keys of sums' errors)."""
    return tuple(getattr(errors, "channels", None) or errors.mse)


def select_refit(result: IdentificationResult, train: Measurements, validation: Measurements | None = None, *,
                 given: Literal["consistent"] | None = None, consistent: ConsistentSettings | None = None,
                 note: str = "") -> ModelSelection:
    """The choice between ``result`` (an unconstrained fit, named by its method ``ols`` or ``wls``) and its
    consistent refit (``consistent``: how, default :class:`ConsistentSettings`: the prior's weight chosen on
    ``validation``), by :func:`select_fitted`: the default answer of ``oed diagnose`` (``result``: its adopted
    model). A refit that fails is no candidate (listed with the reason), unless ``given="consistent"`` asked for it
    (the error is raised then). ``note``: appended to both candidates' descriptions."""
    if given not in (None, "consistent"):
        raise ValueError(f"given must be None or 'consistent', got {given!r}")
    base = result.estimate.method
    if base not in ("ols", "wls"):
        raise ValueError(f"the unconstrained fit's method must be 'ols' or 'wls', got {base!r}")
    settings = ConsistentSettings() if consistent is None else consistent
    try:
        refit = Candidate("consistent", settings.refit(result, train, validation), note=note)
    except _CONSISTENT_FAILURES as error:
        if given == "consistent":
            raise
        refit = Candidate("consistent", None, f"the consistent fit failed ({error})", note=note)
    return select_fitted((Candidate(base, result, note=note), refit), train, validation, base=base, given=given)


def _no_consistent_fit(result: IdentificationResult, delay: Any) -> str | None:
    """Why the consistent fit cannot start from ``result``, or ``None``: it always can (shaped laws and a delay are
    held at their fitted values, :mod:`estimation.consistent.fixed_shapes`); a failure is caught where it is fitted."""
    return None


def _choose(candidates: tuple[Candidate, ...], given: CandidateName | None, base: str,
            ratio: float | None, still: bool = False) -> tuple[CandidateName, Selection, str]:
    available = {candidate.name: candidate for candidate in candidates if candidate.fit is not None}
    if given is not None:
        return given, "given", "chosen by the options given"
    if ratio is None or ratio <= REPEAT_FRACTION or still:
        why = "no validation record" if ratio is None else \
            ("the validation record hardly moves (every joint within 5 % of its range in training)" if still else
             f"the validation record repeats the training motion (positions within {100 * ratio:.2g} % of their spread)")
        kind = "no-validation" if ratio is None else "still-validation" if still else "repeated-motion"
        if "consistent" in available:
            return ("consistent", kind,
                    f"{why}: nothing measured how the candidates extrapolate to another motion, so the fit that "
                    "regularises toward the robot description where the data say nothing is chosen")
        return (base, kind,  # type: ignore[return-value]
                f"{why}, and {available_reason(candidates)}: the weighting the training record's blocked "
                "cross-validation prefers is kept")
    scored = scores(tuple(available.values()))
    if not scored:
        return (base, "validation",  # type: ignore[return-value]
                "no candidate has a finite validation error: the weighting the training record's blocked "
                "cross-validation prefers is kept")
    best = min(scored.values())
    chosen = next(name for name in PREFERENCE if name in scored and scored[name] == best)
    others = ", ".join(f"{name} {score:.3g}" for name, score in scored.items() if name != chosen)
    return chosen, "validation", (f"the smallest validation error on another motion ({CRITERION}: {chosen} "
                                  f"{best:.3g}; the others: {others or 'none'})")


def weighting_difference(candidates: Sequence[Candidate]) -> PairedDifference | None:
    """How much better the channel-weighted fit predicts the validation record than ordinary least squares, when
    it scores lower (module docstring: *The weighting*; reported, not acted on): :func:`paired_difference` of
    ``ols`` against ``wls``, ``None`` when ordinary least squares scores lower or the two are not compared."""
    scored = scores(candidates)
    if "wls" not in scored or "ols" not in scored or scored["wls"] >= scored["ols"]:
        return None
    return paired_difference(candidates, "wls", regularised="ols")


def available_reason(candidates: tuple[Candidate, ...]) -> str:
    """Why the consistent candidate is missing, in a few words."""
    for candidate in candidates:
        if candidate.name == "consistent" and candidate.unavailable:
            return f"no consistent candidate ({candidate.unavailable})"
    return "no consistent candidate"


def selection_model_file(selection: ModelSelection, **settings: Any) -> dict[str, Any]:
    """The ``model_file`` document (:mod:`estimation.identification.model_file`) of ``selection``: the chosen
    model as the file's model, every other fitted candidate as a named alternative.

    ``settings``: the keyword arguments of :func:`estimation.identification.model_file.model_file_document`
    but ``consistent`` (``robot``, ``preprocessing``, ``transmission``, ``rest``, ``max_gap``).
    """
    consistent = selection.consistent
    extra = {} if consistent is None else {
        "consistent": consistent.estimate,
        "consistent_validation_mse": None if consistent.validation is None else consistent.validation.mse}
    documents = {candidate.name: model_file_document(candidate.fit, **settings, **extra)
                 for candidate in selection.candidates if isinstance(candidate.fit, IdentificationResult)}
    return selection_file(selection, documents)


def selection_file(selection: ModelSelection, documents: Mapping[str, Mapping[str, Any]]) -> dict[str, Any]:
    """:func:`selection_model_file` of the ``model_file`` documents of the unconstrained candidates, by name (made
    from sums on the streamed path: :func:`estimation.identification.model_file.summed_model_file_document`)."""
    consistent = selection.consistent
    entries = {name: alternative_entry(document) for name, document in documents.items()}
    if consistent is not None:
        entries["consistent"] = consistent_entry(consistent, documents[selection.base])
    for candidate in selection.candidates:  # each model's own warnings (an unconstrained fit's implausible values)
        if candidate.name in entries:
            entries[candidate.name]["warnings"] = list(getattr(candidate.fit, "warnings", ()))
    unconstrained = selection.chosen if selection.chosen != "consistent" else selection.base
    document = with_model(documents[unconstrained], entries[selection.chosen])
    document["chosen"] = selection.chosen
    document["alternatives"] = {name: entry for name, entry in entries.items() if name != selection.chosen}
    return document


def consistent_entry(consistent: ConsistentResult, base: Mapping[str, Any]) -> dict[str, Any]:
    """The model-file entry of the consistent fit, refitted from the unconstrained fit whose ``model_file``
    document is ``base`` (its channel weights and variances)."""
    estimate, model = consistent.estimate, consistent.unconstrained.model
    if tuple(estimate.names) != tuple(base["base"]["names"]):
        raise ValueError("the consistent estimate's base parameters are not those of the fit it was refitted from")
    entry = alternative_entry(base)
    channels = list(model.channels)
    entry.update({
        "theta": np.asarray(estimate.values, dtype=float).tolist(), "cov": np.asarray(estimate.cov, dtype=float).tolist(),
        "recorded_variance": None if consistent.train.mse is None  # sums of filtered channels: as the base's
        else {channel: consistent.train.mse[channel] for channel in channels},
        "validation_mse": None if consistent.validation is None else dict(consistent.validation.mse),
        "shape_std": {},  # the shapes and the delay: held at the unconstrained fit's (base's) values
        "effect_values": list(effect_entries(model, estimate.names, estimate.expressions, estimate.values,
                                             dict(base.get("shape") or {}))),
    })
    return entry
