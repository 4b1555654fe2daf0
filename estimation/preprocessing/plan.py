"""One preprocessing for a whole identification: chosen once on the training data, stated, reused.

:func:`choose_preprocessing` decides, from the training segments, how ``dq, ddq`` are derived:

* ``measured`` — the data hold ``dq`` and ``ddq``;
* ``fourier`` — a periodic excitation: ``--frequency`` given (checked against the period the data
  show: a sub-harmonic or a frequency the data do not repeat at is warned about), or detected
  (:mod:`estimation.preprocessing.periodicity`) when no cut-off was given; Fourier fit on the time stamps,
  periods averaged as ``average_periods`` says;
* ``butterworth`` — otherwise: the cut-off given, or five times the training motion's bandwidth
  (the widest over the segments), fixed here so that validation is filtered alike. The filter
  covers each segment whole (its ends extended by their odd reflection over the filter's settling
  time): no sample is dropped, so a record of any length takes any cut-off above ``1 / duration``.
  A plan with ``trimmed_s > 0`` (written by earlier versions) trims the settling at each edge.

:func:`prepare` applies it to each segment of a record on its own (never across a boundary),
with the hold compensation and decimation, and stacks the segments. The plan is written to the
result documents as ``preprocessing`` (:meth:`Preprocessing.to_dict`).
"""

from __future__ import annotations

import warnings
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from typing import Any, Literal

import numpy as np

from dynamics.runtime.threads import single_threaded_blas
from dynamics.measurements import Measurements
from estimation.preprocessing.periodicity import REPEAT_THRESHOLD, detect_fundamental, frequency_mismatch, repeat_error
from estimation.preprocessing.differentiation import (
    AverageChoice,
    ButterworthDifferentiation,
    FourierDifferentiation,
    compensate_hold,
    decimate,
    motion_bandwidth,
    sampling_rate,
)
from estimation.data.segments import as_segments, check_same_columns, column_set, concatenate

Method = Literal["measured", "fourier", "butterworth"]
#: the instants the samples are placed at: their stamps as recorded, or the regular clock the stamps jitter around
#: (:func:`estimation.data.sampling_clock.regular_clock`; :mod:`estimation.identification.time_base_choice`)
TimeBase = Literal["stamps", "regular"]

#: harmonics of the fit for a given frequency, unless told (the PUMA paper's 5)
GIVEN_HARMONICS = 5
#: harmonics of the fit for a detected frequency, unless told: the reference's count is unknown, and a
#: robot under feedback adds harmonics above it (three times the paper's 5: :func:`fill_derivatives`)
DETECTED_HARMONICS = 15
#: a derivative candidate whose validation score is within this many standard errors of the best's (and within the
#: training choice's margin of equivalence) is tied with it: the validation record does not tell them apart
#: (:func:`estimation.identification.preprocessing_on_validation.with_standard_errors`; reported, not acted on)
TIED_SE = 2.0


class PreprocessingWarning(UserWarning):
    """What the preprocessing decided from the data (a detected fundamental)."""


class FrequencyMismatchWarning(UserWarning):
    """A given excitation frequency disagrees with the period the data show."""


class SegmentTooShortForFilterError(ValueError):
    """A segment shorter than its preprocessing needs (the filter's settling at both edges, one period)."""


@dataclass(frozen=True)
class CandidateEvidence:
    """One derivative candidate scored on held-out training data
    (:mod:`estimation.identification.preprocessing_choice`).

    Attributes
    ----------
    preprocessing
        The candidate.
    score
        Geometric mean over the channels of the held-out MSE (``inf`` when the candidate could not run).
    held_out_mse
        Per channel, the held-out MSE against the channels as recorded.
    error
        Why the candidate could not run, or ``None``.
    seconds
        What scoring it cost.
    samples
        The recorded samples of the training window its score is taken on (every candidate scored on the
        same ones: one that drops samples is not compared).
    """

    preprocessing: Preprocessing
    score: float
    held_out_mse: dict[str, float]
    error: str | None = None
    seconds: float = 0.0
    samples: int = 0

    def to_dict(self) -> dict[str, Any]:
        """The candidate's keys (as :meth:`Preprocessing.to_dict`) with ``score``, ``held_out_mse``, ``error``."""
        document = self.preprocessing.to_dict()
        document.update(score=self.score if np.isfinite(self.score) else None, held_out_mse=self.held_out_mse,
                        seconds=round(self.seconds, 3), samples=self.samples)
        if self.error is not None:
            document["error"] = self.error
        return document


@dataclass(frozen=True)
class ValidationEvidence:
    """One derivative candidate scored on a validation record of another motion
    (:mod:`estimation.identification.preprocessing_on_validation`): the model fitted on the training record
    prepared by the candidate predicts the validation record prepared alike, against its channels as recorded.

    Attributes
    ----------
    preprocessing
        The candidate.
    score
        The score of the better of the fits tried: the mean over the channels of the validation MSE, each over the
        smallest any candidate's fit reaches on it (:mod:`estimation.identification.relative_error`; ``inf``
        when the candidate could not run or was not scored on the same samples as the others).
    validation_mse
        Per channel, that fit's validation MSE against the channels as recorded, at the recorded time stamps.
    fit
        The fit that gave the score (``ols`` or ``wls``), ``None`` when none did.
    fit_scores
        Each fit's score.
    error
        Why the candidate was not compared, or ``None``.
    seconds
        What scoring it cost.
    samples
        The recorded validation samples its score is taken on (the same for every candidate compared).
    fit_mse
        Each fit's validation MSE per channel (what the scores are computed from).
    fit_block_mse
        Each fit's MSE per channel on each of the validation record's contiguous blocks
        (:data:`estimation.identification.preprocessing_on_validation.BLOCKS`; what the score's standard error is
        taken from); empty when it was not scored.
    standard_error
        The standard error of the difference of its score to the best's, from the blocks (``0`` for the best,
        ``None`` when not scored).
    tied
        Whether the validation record does not tell it from the best: the difference within :data:`TIED_SE`
        standard errors and within the training choice's margin of equivalence.
    """

    preprocessing: Preprocessing
    score: float
    validation_mse: dict[str, float]
    fit: str | None = None
    fit_scores: dict[str, float] = field(default_factory=dict)
    error: str | None = None
    seconds: float = 0.0
    samples: int = 0
    fit_mse: dict[str, dict[str, float]] = field(default_factory=dict)
    fit_block_mse: dict[str, dict[str, tuple[float, ...]]] = field(default_factory=dict)
    standard_error: float | None = None
    tied: bool = False

    def to_dict(self) -> dict[str, Any]:
        """The candidate's keys (as :meth:`Preprocessing.to_dict`) with ``score``, ``validation_mse``, ``fit``,
        ``fit_scores``, ``fit_validation_mse``, ``seconds``, ``samples``, ``standard_error``, ``tied`` (and
        ``error``)."""
        document = self.preprocessing.to_dict()
        document.update(score=self.score if np.isfinite(self.score) else None, validation_mse=self.validation_mse,
                        fit=self.fit, fit_scores={name: value if np.isfinite(value) else None
                                                  for name, value in self.fit_scores.items()},
                        fit_validation_mse=self.fit_mse, seconds=round(self.seconds, 3), samples=self.samples,
                        standard_error=self.standard_error, tied=self.tied)
        if self.error is not None:
            document["error"] = self.error
        return document


@dataclass(frozen=True)
class Evidence:
    """How a preprocessing was chosen: ``selection`` is ``held-out`` (the best score on held-out blocks of the
    training data), ``given`` (the user's options decided) or ``validation`` (the smallest error on a validation
    record of another motion, :attr:`validation`) or ``repeat`` (the best score on a validation record that repeats
    the training motion, predicted by the held-out score's model fitted on the whole training record:
    :func:`estimation.identification.preprocessing_choice.choose_on_repeat`; ``candidates`` then hold those scores,
    ``folds`` 0); ``candidates`` sorted best first, each scored on ``folds`` blocks of the training data; ``validation`` sorted best first and ``held_out_choice`` the training record's
    own choice (empty and ``None`` unless chosen on a validation record)."""

    selection: Literal["held-out", "given", "validation", "repeat"]
    folds: int
    candidates: tuple[CandidateEvidence, ...]
    validation: tuple[ValidationEvidence, ...] = ()
    held_out_choice: Preprocessing | None = None


@dataclass(frozen=True)
class Preprocessing:
    """How the motion is derived, decided once.

    Attributes
    ----------
    method
        ``measured``, ``fourier`` or ``butterworth``.
    frequency_hz, harmonics
        Fourier fit (``fourier``).
    frequency_source
        ``given`` or ``detected`` (``fourier``).
    average_periods
        ``auto``, ``yes`` or ``no`` (``fourier``).
    cutoff_hz, order
        Butterworth low-pass (``butterworth``).
    trimmed_s
        Time cut at each edge of each segment (the filter's settling), s: ``0`` (the filter covers the
        segment, its ends extended), unless a plan of an earlier version said otherwise.
    decimation, held_torques
        As :func:`estimation.preprocessing.differentiation.fill_derivatives`.
    velocity_from_positions
        ``butterworth`` on a record that logs ``dq`` (not ``ddq``): ``dq`` derived from the positions instead of
        the logged velocity filtered (a logger's velocity may lag its positions, or be a command).
    evidence
        The candidates scored when the choice was made on held-out data (``None`` for a fixed rule); not part
        of the plan's identity.
    time_base
        ``stamps`` (default): the samples at their time stamps; ``regular``: on the regular clock the stamps
        jitter around, one sample a step (:mod:`estimation.identification.time_base_choice`: a logger's receive
        times), every record read alike (training, validation, test, ``oed predict``'s).
    time_base_evidence
        When both time bases were scored on the validation record: each one's score (``stamps``, ``regular``)
        and the receive-times ratio that called for it (``ratio``); not part of the plan's identity.
    """

    method: Method
    frequency_hz: float | None = None
    harmonics: int | None = None
    frequency_source: Literal["given", "detected"] | None = None
    average_periods: AverageChoice = "auto"
    cutoff_hz: float | None = None
    order: int = 4
    trimmed_s: float = 0.0
    decimation: int = 1
    held_torques: bool = False
    velocity_from_positions: bool = False
    evidence: Evidence | None = field(default=None, compare=False, repr=False)
    time_base: TimeBase = "stamps"
    time_base_evidence: Mapping[str, float] | None = field(default=None, compare=False, repr=False)

    def without_evidence(self) -> Preprocessing:
        """The plan alone."""
        return replace(self, evidence=None, time_base_evidence=None)

    def to_dict(self) -> dict[str, Any]:
        """``{method, frequency_hz, harmonics, frequency_source, average_periods | cutoff_hz, filter_order,
        trimmed_s, decimation, held_torques}`` (the keys of the method only), with ``selection``, ``folds`` and
        ``candidates`` (best first) when the choice was made on held-out data."""
        document: dict[str, Any] = {"method": self.method}
        if self.method == "fourier":
            document.update(frequency_hz=self.frequency_hz, harmonics=self.harmonics,
                            frequency_source=self.frequency_source, average_periods=self.average_periods)
        elif self.method == "butterworth":
            document.update(cutoff_hz=self.cutoff_hz, filter_order=self.order,
                            velocity_from_positions=self.velocity_from_positions)
        document.update(trimmed_s=self.trimmed_s, decimation=self.decimation, held_torques=self.held_torques)
        if self.evidence is not None:
            document.update(selection=self.evidence.selection, folds=self.evidence.folds,
                            candidates=[candidate.to_dict() for candidate in self.evidence.candidates])
            if self.evidence.validation:
                document["validation_candidates"] = [candidate.to_dict() for candidate in self.evidence.validation]
            if self.evidence.held_out_choice is not None:
                document["held_out_choice"] = self.evidence.held_out_choice.describe_method()
        if self.time_base != "stamps" or self.time_base_evidence is not None:
            document["time_base"] = self.time_base
        if self.time_base_evidence is not None:
            document["time_base_scores"] = {key: float(value) for key, value in self.time_base_evidence.items()
                                            if key in ("stamps", "regular")}
            document["receive_times_ratio"] = float(self.time_base_evidence["ratio"])
        return document

    def describe_time_base(self) -> str:
        """The time base in a few words, with both clocks' validation scores when they were compared; empty for the
        stamps when nothing was compared."""
        evidence = self.time_base_evidence
        if evidence is None:
            return "" if self.time_base == "stamps" else "samples on a regular clock"
        chosen = "samples on a regular clock" if self.time_base == "regular" else "samples at their stamps"
        return (f"{chosen}, chosen on the validation record (the stamps look like receive times: the positions "
                f"{evidence['ratio']:.3g} times smoother on a regular clock; score {evidence['regular']:.4g} on a "
                f"regular clock, {evidence['stamps']:.4g} at the stamps)")

    def describe_method(self) -> str:
        """The derivative method in a few words."""
        if self.method == "fourier":
            return f"a {self.harmonics}-harmonic Fourier fit at {self.frequency_hz:.6g} Hz"
        if self.method == "butterworth":
            return f"a {self.cutoff_hz:.4g} Hz Butterworth filter" + (" (dq from the positions)"
                                                                        if self.velocity_from_positions else "")
        return "measured dq, ddq"

    def describe(self, *, applied: bool = False) -> str:
        """One line for the user; ``applied``: the preprocessing of a model file applied to another record (``oed
        predict``), which says so rather than how a run chose it."""
        if self.method == "fourier":
            text = (f"Fourier fit, {self.frequency_hz:.6g} Hz ({self.frequency_source}), {self.harmonics} harmonics, "
                    f"period averaging {self.average_periods}")
        elif self.method == "butterworth":
            text = (f"Butterworth low-pass, cut-off {self.cutoff_hz:.4g} Hz (order {self.order}, zero phase), "
                    + (f"{1e3 * self.trimmed_s:.0f} ms trimmed at each segment edge" if self.trimmed_s > 0
                       else "ends extended by reflection, no sample dropped"))
        else:
            text = "measured dq, ddq"
        extras = ([f"decimated by {self.decimation}"] if self.decimation > 1 else []) + \
            (["held torques"] if self.held_torques else []) + \
            ([self.describe_time_base()] if self.describe_time_base() else [])
        if applied:
            how = "the model file's preprocessing, applied to this record"
        elif self.evidence is not None and self.evidence.selection in ("validation", "repeat"):
            how = (f"chosen among {len(self.evidence.validation)} candidates by the validation error of the model "
                   "fitted with each, the validation record being another motion"
                   if self.evidence.selection == "validation" else
                   f"chosen among {len(self.evidence.candidates)} candidates by the error on the validation record, a "
                   "repeat of the training motion, of the fit on the training data")
            held_out = self.evidence.held_out_choice
            tied = sum(item.tied for item in self.evidence.validation)
            if self.evidence.selection == "validation" and tied > 1:
                how += (f"; {tied - 1} other(s) within {TIED_SE:g} standard errors of its score: the validation "
                        "record does not tell them apart")
            if held_out is not None and held_out != self.without_evidence():
                preferred = held_out.describe_method()
                if preferred == self.describe_method() and held_out.held_torques != self.held_torques:
                    # the same derivatives, the torques' hold differing: say it, or the sentence names this choice
                    preferred += " with held torques" if held_out.held_torques else " without held torques"
                how += f"; blocked cross-validation on the training data preferred {preferred}"
        elif self.evidence is not None and self.evidence.selection == "held-out":
            how = (f"chosen among {len(self.evidence.candidates)} candidates by held-out error on the training data, "
                   "used for validation")
        elif self.evidence is not None:
            how = f"as given; scored beside {len(self.evidence.candidates) - 1} other candidates, used for validation"
        else:
            how = "chosen on the training data, used for validation"
        return "preprocessing: " + ", ".join([text, *extras]) + f" ({how})"


@single_threaded_blas()  # tall thin least squares: threaded BLAS only loses (dynamics.runtime.threads)
def choose_preprocessing(
    train: Measurements | Sequence[Measurements],
    *,
    frequency_hz: float | None = None,
    harmonics: int | None = None,
    cutoff_hz: float | None = None,
    average_periods: AverageChoice = "auto",
    decimation: int = 1,
    held_torques: bool = False,
    detect: bool = True,
) -> Preprocessing:
    """The preprocessing of a record, decided on its training segments (module docstring).

    ``harmonics``: of the Fourier fit; default :data:`GIVEN_HARMONICS` for a given frequency,
    :data:`DETECTED_HARMONICS` for a detected one (capped below the Nyquist frequency).

    Warns
    -----
    PreprocessingWarning
        When the fundamental was detected (it says which).
    FrequencyMismatchWarning
        When ``frequency_hz`` is a sub-harmonic of the period the data show, or they do not repeat at it.
    """
    segments = as_segments(train, "train")
    check_same_columns(segments, "training data")
    if frequency_hz is not None and cutoff_hz is not None:
        raise ValueError("give --frequency (Fourier fit of periodic data) or --cutoff (Butterworth filter), not both")
    if average_periods not in ("auto", "yes", "no"):
        raise ValueError(f"average_periods must be 'auto', 'yes' or 'no', got {average_periods!r}")
    if int(decimation) != decimation or decimation < 1:
        raise ValueError(f"decimation factor must be a positive integer, got {decimation}")
    common = {"decimation": int(decimation), "held_torques": bool(held_torques)}
    if all(name in column_set(segments[0]) for name in ("dq", "ddq")):
        return Preprocessing("measured", **common)
    longest = max(segments, key=lambda segment: segment.n_samples)
    if frequency_hz is not None:
        harmonics = GIVEN_HARMONICS if harmonics is None else harmonics
        FourierDifferentiation(frequency_hz, harmonics, average_periods)  # checks the numbers
        check_frequency(segments, frequency_hz)
        return Preprocessing("fourier", float(frequency_hz), int(harmonics), "given", average_periods, **common)
    if cutoff_hz is None and detect:
        found = detect_fundamental(longest.t, longest.q).frequency_hz
        if found is not None:
            nyquist_harmonic = int(np.ceil(0.5 * sampling_rate(longest.t) / found)) - 1
            used = max(1, min(int(DETECTED_HARMONICS if harmonics is None else harmonics), nyquist_harmonic))
            warnings.warn(
                f"the positions repeat every {1 / found:.6g} s: periodic excitation of {found:.6g} Hz detected; "
                f"derivatives from a {used}-harmonic Fourier fit (give --frequency to set it, --cutoff for a filter)",
                PreprocessingWarning, stacklevel=3)  # past the BLAS decorator
            return Preprocessing("fourier", found, used, "detected", average_periods, **common)
    rates = [sampling_rate(segment.t) for segment in segments]
    rate = min(rates)
    nyquist = 0.5 * rate
    if cutoff_hz is None:
        bandwidth = max(motion_bandwidth(segment.q, sampling_rate(segment.t)) for segment in segments)
        shortest = min(float(segment.t[-1] - segment.t[0]) for segment in segments)
        cutoff = min(max(5.0 * bandwidth, 1.0 / shortest), 0.8 * nyquist)  # a filter every segment takes
    else:
        cutoff = float(ButterworthDifferentiation(cutoff_hz).cutoff(longest))  # checks it
    return Preprocessing("butterworth", cutoff_hz=cutoff, order=ButterworthDifferentiation().order, **common)


def check_frequency(segments: Sequence[Measurements], frequency_hz: float) -> None:
    """Warn (:class:`FrequencyMismatchWarning`) when a segment long enough to tell disagrees with ``frequency_hz``."""
    for segment in segments:
        message = frequency_mismatch(segment.t, segment.q, frequency_hz)
        if message is not None:
            warnings.warn(f"{segment.metadata.get('source', 'data')}: {message}", FrequencyMismatchWarning, stacklevel=4)


@single_threaded_blas()
def prepare(data: Measurements | Sequence[Measurements], preprocessing: Preprocessing, *,
            role: str = "training data") -> Measurements:
    """Each segment preprocessed on its own by ``preprocessing``, then stacked.

    The result's ``metadata["preprocessing"]`` is ``preprocessing.to_dict()``; its ``recorded``
    holds the torques/wrench as recorded (:class:`~dynamics.measurements.Measurements`). A segment whose torque
    sensor was clipped (``metadata["saturated_samples"]``, :func:`estimation.data.records.clipped_torques`) holds
    those samples of that channel masked (NaN, :mod:`estimation.data.channel_mask`), here as recorded: they are out
    of the fit and of the errors, the other channels' readings of those samples and every position kept.

    Raises
    ------
    SegmentTooShortForFilterError
        A segment shorter than the filter needs, or than one period of the Fourier fit.
    estimation.data.segments.SegmentColumnsError
        Segments with different column sets.
    """
    segments = as_segments(data, role)
    check_same_columns(segments, role)
    measured = all(name in column_set(segments[0]) for name in ("dq", "ddq"))
    if preprocessing.method == "measured" and not measured:
        raise ValueError(f"{role} lacks the measured dq/ddq the training data hold: give both records the same columns")
    if measured and preprocessing.method != "measured":  # measured derivatives are used as they are
        preprocessing = replace(preprocessing, method="measured", held_torques=False)
    prepared = []
    for segment in segments:
        name = _name(segment)
        stamps = segment.recorded if segment.recorded_rows is not None else None  # a resampled log's own samples
        segment = replace(segment, recorded=None)
        derived = _derive(segment, preprocessing, name)
        if preprocessing.held_torques and preprocessing.method != "measured":
            derived = compensate_hold(derived)
        if preprocessing.decimation > 1:
            try:
                derived = decimate(derived, preprocessing.decimation)
            except ValueError as error:
                raise SegmentTooShortForFilterError(f"{name}: {error}") from None
        if stamps is not None:
            derived = at_recorded_stamps(derived, stamps, measured=preprocessing.method == "measured"
                                         and preprocessing.decimation == 1)
        metadata = dict(derived.metadata, preprocessing=preprocessing.to_dict())
        recorded = derived.recorded
        prepared.append(replace(derived, metadata=metadata,
                                recorded=None if recorded is None else replace(recorded, metadata=metadata)))
    return concatenate(prepared)


#: the highest cut-off of a filter, as a fraction of the record's rate (0.8 x Nyquist: the rule's cap and the
#: candidates' top, :data:`estimation.identification.preprocessing_choice.CUTOFF_FRACTIONS`)
HIGHEST_CUTOFF_FRACTION = 0.4


def best_filter(document: Mapping[str, Any] | None) -> Preprocessing | None:
    """The best-scored Butterworth filter among the candidates a plan's choice scored (``document``:
    :meth:`Preprocessing.to_dict`, as the model file holds it): on the validation record when it was chosen there,
    else on held-out blocks of the training data; ``None`` when no filter was scored."""
    for key in ("validation_candidates", "candidates"):
        filters = [candidate for candidate in (document or {}).get(key) or ()
                   if candidate.get("method") == "butterworth" and candidate.get("cutoff_hz")
                   and candidate.get("score") is not None and np.isfinite(float(candidate["score"]))]
        if filters:
            best = min(filters, key=lambda candidate: float(candidate["score"]))  # best first: ties keep the first
            return Preprocessing("butterworth", cutoff_hz=float(best["cutoff_hz"]),
                                 order=int(best.get("filter_order", 4)),
                                 velocity_from_positions=bool(best.get("velocity_from_positions", False)),
                                 decimation=int(best.get("decimation", 1)),
                                 held_torques=bool(best.get("held_torques", False)))
    return None


def prepare_unseen(segments: Sequence[Measurements], preprocessing: Preprocessing, *,
                   role: str = "the data to predict", fallback: Preprocessing | None = None) -> Measurements:
    """:func:`prepare` on records the plan was not chosen on (a validation or test record, ``oed predict``'s), each
    segment by the plan where the plan applies to it, else by ``fallback`` (the best filter the choice scored,
    :func:`best_filter`) or, without one, by the filter the toolkit takes on a record without a choice
    (:func:`choose_preprocessing` without detection: five times the motion's bandwidth), with a
    :class:`PreprocessingWarning` saying which and why:

    - a Fourier fit applies to a segment seen to repeat at its fundamental (its positions one period apart within
      :data:`~estimation.preprocessing.periodicity.REPEAT_THRESHOLD` of their variance, over at least
      :data:`~estimation.preprocessing.periodicity.MIN_PERIODS` periods): on another motion (a point-to-point test
      after periodic excitation) a series at that fundamental is no description of the positions, and its
      derivatives are garbage (115x the plain fit's test error, h-unseen4);
    - logged derivatives (``measured``) apply to a segment that logs them;
    - a filter applies to a segment whose Nyquist frequency lies above its cut-off; one logged at a lower rate is
      filtered at :data:`HIGHEST_CUTOFF_FRACTION` of its rate (the candidates' own ceiling) instead.
    """
    segments = as_segments(segments, role)
    plans = [_applied(segment, preprocessing, role, fallback) for segment in segments]
    if all(plan == preprocessing for plan in plans):
        return prepare(segments, preprocessing, role=role)
    if all(plan == plans[0] for plan in plans):
        return prepare(segments, plans[0], role=role)
    return concatenate([prepare([segment], plan, role=role) for segment, plan in zip(segments, plans)])


def _applied(segment: Measurements, preprocessing: Preprocessing, role: str,
             fallback: Preprocessing | None) -> Preprocessing:
    """The plan for one segment of a record it was not chosen on (:func:`prepare_unseen`)."""
    rate = sampling_rate(segment.t)
    name = _name(segment) if segment.metadata.get("source") else role

    def rule(why: str) -> Preprocessing:
        if fallback is not None:
            plan = fallback
            if plan.cutoff_hz >= 0.5 * rate:
                plan = replace(plan, cutoff_hz=float(f"{HIGHEST_CUTOFF_FRACTION * rate:.6g}"))
            which = "the best filter the choice scored"
        else:
            plan = choose_preprocessing([segment], detect=False, decimation=preprocessing.decimation,
                                       held_torques=preprocessing.held_torques)
            which = "the one the toolkit takes on a record without a choice (five times the motion's bandwidth)"
        warnings.warn(f"{name}: {why}: derivatives from a {plan.cutoff_hz:g} Hz Butterworth filter (order "
                      f"{plan.order}, zero phase), {which}", PreprocessingWarning, stacklevel=4)
        return plan

    measured = segment.dq is not None and segment.ddq is not None
    if preprocessing.method == "measured" and not measured:
        return rule("lacks the logged dq/ddq the model was fitted with")
    if preprocessing.method == "fourier" and not measured:
        error = repeat_error(segment.q, rate / preprocessing.frequency_hz)
        if not (np.isfinite(error) and error <= REPEAT_THRESHOLD):
            return rule(f"does not repeat at the model's fundamental {preprocessing.frequency_hz:.6g} Hz (another "
                        "motion, or too short to tell): a Fourier series there would not describe it")
    if preprocessing.method == "butterworth" and preprocessing.cutoff_hz is not None \
            and preprocessing.cutoff_hz >= 0.5 * rate:
        plan = replace(preprocessing, cutoff_hz=float(f"{HIGHEST_CUTOFF_FRACTION * rate:.6g}"))
        warnings.warn(
            f"{name}: logged at {rate:.4g} Hz, whose Nyquist frequency the model's {preprocessing.cutoff_hz:g} Hz "
            f"filter reaches (chosen on records of a higher rate): filtered at {plan.cutoff_hz:g} Hz, "
            f"{HIGHEST_CUTOFF_FRACTION:g} of its rate", PreprocessingWarning, stacklevel=4)
        return plan
    return preprocessing


def at_recorded_stamps(prepared: Measurements, stamps: Measurements, *, measured: bool = False) -> Measurements:
    """``prepared`` (a segment resampled onto a uniform grid, then preprocessed) with its recorded channels those of
    the samples as logged, ``stamps`` (:func:`estimation.data.records.read_record` keeps them as the segment's
    ``recorded``): the torques and wrench at their own time stamps, never interpolated, and the derived motion
    linearly interpolated there (the motion as logged when ``measured``: derivatives read, not derived). Samples
    outside the prepared span (edges trimmed by a plan that trims) are left out; each kept one stands beside its
    nearest prepared sample (``recorded_rows``). Errors (:func:`estimation.identification.validation.compare`),
    predictions and every score are then taken at the recorded time stamps.
    """
    source = prepared.as_recorded  # the motion on the whole grid (every period of an averaged record)
    beside = prepared.beside_recorded()
    tolerance = 1e-9 * (source.t[-1] - source.t[0])  # the grid's last point may round below the last stamp
    kept = np.flatnonzero((stamps.t >= source.t[0] - tolerance) & (stamps.t <= source.t[-1] + tolerance))
    t = stamps.t[kept]
    nearest = np.clip(np.searchsorted(source.t, t), 1, source.n_samples - 1)
    nearest -= (t - source.t[nearest - 1]) < (source.t[nearest] - t)
    if measured:
        q, dq, ddq = (None if values is None else values[kept] for values in (stamps.q, stamps.dq, stamps.ddq))
    else:
        q, dq, ddq = (np.column_stack([np.interp(t, source.t, column) for column in values.T])
                      for values in (source.q, source.dq, source.ddq))
    recorded = Measurements(t, q, dq, ddq, None if stamps.tau is None else stamps.tau[kept],
                            None if stamps.wrench is None else stamps.wrench[kept],
                            dict(source.metadata, recorded_stamps=True))
    return replace(prepared, recorded=recorded, recorded_rows=beside[nearest])


def _derive(segment: Measurements, preprocessing: Preprocessing, name: str) -> Measurements:
    if preprocessing.method == "measured":
        return segment
    try:
        if preprocessing.method == "fourier":
            return FourierDifferentiation(preprocessing.frequency_hz, preprocessing.harmonics,
                                          preprocessing.average_periods).apply(segment)
        filter_ = ButterworthDifferentiation(preprocessing.cutoff_hz, preprocessing.order,
                                             trim=preprocessing.trimmed_s > 0,
                                             logged_velocity=not preprocessing.velocity_from_positions)
        return filter_.apply(segment)
    except ValueError as error:
        text = str(error)
        if "less than one period" in text or "too few for" in text:
            raise SegmentTooShortForFilterError(f"{name}: {text}") from None
        raise ValueError(f"{name}: {text}") from None


def _name(segment: Measurements) -> str:
    source = str(segment.metadata.get("source", "data"))
    return f"{source} (segment {segment.metadata.get('segment')})" if segment.metadata.get("segments_in_file", 1) > 1 \
        else source
