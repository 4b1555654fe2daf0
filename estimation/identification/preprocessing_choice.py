"""The preprocessing chosen by held-out evidence: derivative candidates scored by blocked cross-validation.

How ``dq`` and ``ddq`` are made from measured positions decides what an identification can reach, and no fixed
rule suits every record: a robot under feedback puts harmonics far above the excitation's into its motion (on a
simulated PUMA 560 under PD control, a 15-harmonic Fourier fit left joint 1 at 110 times its noise floor and 250
harmonics reached it), and a filter cut-off picked from the motion's bandwidth is too low for a real KUKA. So the
derivative method is a choice the data must support.

Candidates (:func:`candidates`): the measured derivatives when the record holds them (then the only candidate);
otherwise Fourier fits (PUMA paper, eq. 18) at the given or detected fundamental over a grid of harmonics, and
zero-phase Butterworth filters over a geometric grid of cut-offs; the rule of
:func:`estimation.preprocessing.plan.choose_preprocessing` (what the toolkit did before) is one of them. A plan
that cannot prepare the validation or test record (a cut-off below ``1 / duration``, a Fourier fit at a
fundamental the record is not seen to repeat at) is not a candidate: the defaults never choose what they must then
refuse, nor a description of the training motion that another motion does not follow.

Same samples: every candidate is scored on every recorded sample of the window. The filters cover the record
(their ends extended by reflection, :class:`~estimation.preprocessing.differentiation.ButterworthDifferentiation`:
a low cut-off may not skip a record's hardest seconds at each edge, as trimming each filter's own settling let it
do), and a period-averaged Fourier fit predicts the samples past its last whole period too; a candidate scored on
fewer samples than the others is set aside (:func:`on_common_samples`).

Score (:class:`HeldOutScore`): the training record (past :data:`SCORED_SAMPLES` samples, a window of its longest
segment), prepared by the candidate and thinned to at most ``max_rows`` samples, is cut into ``folds`` contiguous blocks in time. The declared model plus a flexible friction
on each joint's own torque (an offset, ``dq`` and ``tanh(dq / s)`` at four speeds ``s``) is fitted by least
squares on the other blocks (each channel scaled by its spread) and predicts the held-out block's channels **as
recorded** (not period-averaged nor filtered). The score is the geometric mean over the channels of the held-out
mean squared error, which no channel's unit can dominate. The flexible friction is there so that friction the
declared model lacks is not taken up by the derivatives: scored with the declared viscous model alone on that
PUMA record, 5 harmonics won, because blurred derivatives imitate part of the missing Coulomb friction; with it,
250 harmonics won (held-out MSE 0.108, 0.043, 0.041 N²m² against a noise variance of 0.04).

Choice: among the candidates whose score is within :data:`EQUIVALENT` of the lowest (they predict held-out data
equally well), the best-scored Fourier fit if there is one (fewer harmonics on a tie to four digits: the
simplest description of a periodic motion that predicts as well), else the filter with the highest cut-off (the
least distortion of the motion; on the logged velocity rather than from the positions);
ties by the candidate's description, so the order of the grid does not matter. The flexible friction can take up
what a blurred motion does to a law with a jump at zero speed, so a strongly smoothing candidate may score as
well as the others and still leave a sign or Stribeck law out of reach of the diagnosis: on a simulated PUMA
with Stribeck friction and positions only, a 2.5 Hz filter scored 2 % better than every Fourier fit and left
joint 3 at 200 times its floor. When
the user gave ``--frequency``/``--harmonics`` or ``--cutoff``, that candidate decides, is scored beside the
others, and a :class:`PreprocessingEvidenceWarning` says when another candidate predicts the held-out blocks
clearly better (:data:`CLEARLY_BETTER`).

Window: the whole choice (the fundamental detected, the rule, the candidates and their scores) is made on the
record's :class:`ChoiceWindow`, the scored window and the duration of its shortest segment, so that the same
files read chunk by chunk (:func:`estimation.streaming.cutoff_choice.choose_streamed_preprocessing`) get the same
choice: on a record of a million samples of a 7-joint arm, the record held in memory and the file streamed gave
the same 21 candidates with identical scores.
"""

from __future__ import annotations

import functools
import time
import warnings
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field, replace
from typing import Literal

import numpy as np
from numpy.typing import NDArray

from dynamics.measurements import Measurements
from dynamics.models import IdentificationModel
from dynamics.runtime.processes import run_tasks, worker_count
from dynamics.runtime.progress import SECONDS as PROGRESS_SECONDS
from dynamics.runtime.progress import report
from dynamics.runtime.threads import single_threaded_blas
from estimation.data.segments import as_segments, column_set, concatenate
from estimation.estimators.normal_equations import NormalEquations, accumulate
from estimation.estimators.identification_problem import stack
from estimation.preprocessing.differentiation import ButterworthDifferentiation, motion_bandwidth, sampling_rate
from estimation.preprocessing.periodicity import REPEAT_THRESHOLD, detect_fundamental, repeat_error
from estimation.preprocessing.plan import (
    CandidateEvidence,
    Evidence,
    Preprocessing,
    PreprocessingWarning,
    SegmentTooShortForFilterError,
    choose_preprocessing,
    prepare,
)

#: harmonics of the Fourier candidates (those below the Nyquist frequency are kept)
HARMONICS_GRID = (5, 10, 20, 40, 80, 160, 250, 400)
#: cut-offs of the filter candidates, as fractions of the sampling rate (1 Hz to 400 Hz at 1 kHz); the last is
#: the least smoothing the rule itself applies (0.8 × Nyquist, :func:`~estimation.preprocessing.plan.choose_preprocessing`):
#: a record logged at a low rate may hold the motion up to there (the EMPS at 50 Hz: the validation error fell from
#: 160 N² at 12.5 Hz to 39 N² at 20 Hz, the test error from 1.07 to 0.62 times the plain fit's), and the fit's Coulomb
#: friction is biased low as the cut-off falls (the filtered torques' steps smeared, the sign column sharp), which a
#: grid stopping at 0.25 hid on records at 100 Hz (benchmarks/README.md, "Robot kinds the project has not seen")
CUTOFF_FRACTIONS = (0.001, 0.002, 0.0035, 0.006, 0.01, 0.017, 0.03, 0.05, 0.085, 0.15, 0.25, 0.4)
#: speeds of the flexible friction's tanh columns, as fractions of the joint's root-mean-square speed
FRICTION_SPEEDS = (0.01, 0.03, 0.1, 0.3)
#: a candidate predicts clearly better when its score (geometric-mean held-out MSE) is below this fraction
CLEARLY_BETTER = 0.8
#: candidates whose score is within this fraction of the best predict equally well (the tie rule decides)
EQUIVALENT = 0.05
#: samples of the training record the candidates are prepared on: a long record is scored on a window of its
#: longest segment (time and memory stay bounded; the choice is the window's)
SCORED_SAMPLES = 60_000
#: fewest candidates worth scoring in a process pool
MIN_PARALLEL_SCORES = 8


class PreprocessingEvidenceWarning(UserWarning):
    """The preprocessing a user gave predicts held-out data clearly worse than another candidate."""


@dataclass(frozen=True)
class PreprocessingChoice:
    """The preprocessing chosen and the evidence behind it.

    Attributes
    ----------
    chosen
        The preprocessing used (with its :class:`~estimation.preprocessing.plan.Evidence` attached).
    best
        The candidate the held-out evidence prefers (``chosen`` unless the user's options decided).
    training_sums
        ``(candidate, sums)``: each candidate's training window, as it prepared it, summed for the fits of the choice
        on a validation record (:func:`choose_by_evidence`'s ``sums_model``; empty without it).
    """

    chosen: Preprocessing
    best: Preprocessing
    training_sums: tuple[tuple[Preprocessing, NormalEquations], ...] = field(default=(), repr=False, compare=False)


@dataclass(frozen=True)
class HeldOutScore:
    """Blocked cross-validation of the declared model plus a flexible friction (module docstring).

    Attributes
    ----------
    model
        The declared identification model.
    folds
        Contiguous blocks in time; each is held out once.
    max_rows
        Samples kept (evenly thinned) for the score.
    """

    model: IdentificationModel
    folds: int = 5
    max_rows: int = 6000

    def __post_init__(self) -> None:
        if int(self.folds) != self.folds or self.folds < 2:
            raise ValueError(f"folds must be an integer of at least 2, got {self.folds}")
        if int(self.max_rows) != self.max_rows or self.max_rows < 10 * self.folds:
            raise ValueError(f"max_rows must be an integer of at least {10 * self.folds}, got {self.max_rows}")

    def __call__(self, train: Sequence[Measurements], preprocessing: Preprocessing,
                 sums_model: IdentificationModel | None = None
                 ) -> CandidateEvidence | tuple[CandidateEvidence, NormalEquations | None]:
        """The candidate's held-out MSE per channel and its score (``inf`` with the reason when it cannot run);
        with ``sums_model``, also the training window as the candidate prepared it summed for that model
        (:func:`training_sums`: what the choice on a validation record fits, made here from the same preparation
        rather than preparing the record again there)."""
        started = time.perf_counter()
        try:
            prepared = prepare(train, preprocessing, role="training data")
        except (SegmentTooShortForFilterError, ValueError) as error:
            failed = CandidateEvidence(preprocessing.without_evidence(), float("inf"), {}, str(error),
                                       time.perf_counter() - started)
            return failed if sums_model is None else (failed, None)
        recorded = prepared.as_recorded
        kept = thinned(recorded, self.max_rows)
        problem = stack(self.model, kept)
        Y = with_friction_columns(problem.Y, kept, problem.channels)
        mse = self.held_out_mse(Y, problem.y)
        evidence = CandidateEvidence(preprocessing.without_evidence(), geometric_mean(mse),
                                     dict(zip(problem.channels, map(float, mse))), None, time.perf_counter() - started,
                                     recorded.n_samples)
        return evidence if sums_model is None else (evidence, training_sums(sums_model, prepared))

    def held_out_mse(self, Y: NDArray[np.float64], y: NDArray[np.float64]) -> NDArray[np.float64]:
        """Per channel, the mean squared error of each block predicted from the others.

        Each block is reduced once to the triangular factor of its QR decomposition (:func:`block_factor`); the
        fit on the other blocks is the minimum-norm least squares of their stacked factors (Demmel et al.,
        "Communication-optimal parallel and sequential QR and LU factorizations", SIAM J. Sci. Comput. 34, 2012:
        TSQR), which has the singular values and the solution of the stacked rows themselves, so each block's rows
        are factored once instead of once per fold they are kept in.
        """
        scale = np.std(y, axis=0)
        scale[scale == 0] = 1.0
        squared = np.zeros(y.shape[1])
        blocks = [held for held, _ in blocked_folds(y.shape[0], self.folds)]
        # (m, p): the columns each channel has (``Y.any`` reads ``Y`` in place; ``np.any(Y != 0)`` wrote a boolean copy
        # of it first: the same booleans, NaN nonzero in both)
        support = Y.any(axis=0)
        factors = [block_factor(Y[held], y[held], support, scale) for held in blocks]
        p = Y.shape[2]
        for index, held in enumerate(blocks):
            kept = np.concatenate(factors[:index] + factors[index + 1:], axis=0)
            rows = (y.shape[0] - (held.stop - held.start)) * y.shape[1]  # the rows the kept factors stand for
            theta = np.linalg.lstsq(kept[:, :p], kept[:, p], rcond=np.finfo(float).eps * max(rows, p))[0]
            squared += np.sum((y[held] - Y[held] @ theta) ** 2, axis=0)
        return squared / y.shape[0]

    def on_repeat(self, train: Sequence[Measurements], repeat: Sequence[Measurements],
                  preprocessing: Preprocessing) -> CandidateEvidence:
        """The candidate's score on a record that repeats the training motion (:func:`choose_on_repeat`): the same
        model, fitted on the whole training record prepared by the candidate, predicts the repeat prepared alike,
        against its channels as recorded; every sample of the repeat is predicted by a fit whose data cover it."""
        started = time.perf_counter()
        try:
            fitted = prepare(train, preprocessing, role="training data").as_recorded
            predicted = prepare(repeat, preprocessing, role="validation data").as_recorded
        except (SegmentTooShortForFilterError, ValueError) as error:
            return CandidateEvidence(preprocessing.without_evidence(), float("inf"), {}, str(error),
                                     time.perf_counter() - started)
        fitted, predicted = thinned(fitted, self.max_rows), thinned(predicted, self.max_rows)
        problem, other = stack(self.model, fitted), stack(self.model, predicted)
        speeds = joint_speeds(fitted)
        Y = with_friction_columns(problem.Y, fitted, problem.channels, speeds)
        X = with_friction_columns(other.Y, predicted, problem.channels, speeds)
        scale = np.std(problem.y, axis=0)
        scale[scale == 0] = 1.0
        rows = (Y / scale[None, :, None]).reshape(-1, Y.shape[2])
        theta = np.linalg.lstsq(rows, (problem.y / scale).reshape(-1),
                                rcond=np.finfo(float).eps * max(rows.shape))[0]
        mse = np.mean((other.y - X @ theta) ** 2, axis=0)
        return CandidateEvidence(preprocessing.without_evidence(), geometric_mean(mse),
                                 dict(zip(problem.channels, map(float, mse))), None, time.perf_counter() - started,
                                 predicted.n_samples)

    @staticmethod
    def friction_columns(measurements: Measurements, channels: Sequence[str],
                         speeds: NDArray[np.float64] | None = None) -> NDArray[np.float64]:
        """Per joint, on its own torque channel: an offset, ``dq`` and ``tanh(dq / s)`` (:data:`FRICTION_SPEEDS`),
        the speeds ``s`` fractions of the joint's root-mean-square speed (``speeds``: given, else this record's)."""
        return with_friction_columns(None, measurements, channels, speeds)


Family = Literal["fourier", "butterworth"]


def with_friction_columns(Y: NDArray[np.float64] | None, measurements: Measurements, channels: Sequence[str],
                          speeds: NDArray[np.float64] | None = None) -> NDArray[np.float64]:
    """``Y (N, m, r)`` with :meth:`HeldOutScore.friction_columns` appended along its columns (``Y`` ``None``: those
    columns alone), written into one array: the same values as concatenating them, without a zero block a joint
    and the copies of the concatenation (each candidate of the choice builds them)."""
    speeds = joint_speeds(measurements) if speeds is None else speeds
    joints = [joint for joint in range(measurements.n_joints) if f"tau{joint + 1}" in channels]
    width = 2 + len(FRICTION_SPEEDS)
    base = 0 if Y is None else Y.shape[2]
    columns = np.zeros((measurements.n_samples, len(channels), base + width * len(joints)))
    if Y is not None:
        columns[:, :, :base] = Y
    for position, joint in enumerate(joints):
        dq = measurements.dq[:, joint]
        speed = float(speeds[joint])
        channel = list(channels).index(f"tau{joint + 1}")
        first = base + width * position
        columns[:, channel, first] = 1.0
        columns[:, channel, first + 1] = dq / speed
        for k, fraction in enumerate(FRICTION_SPEEDS):
            columns[:, channel, first + 2 + k] = np.tanh(dq / (fraction * speed))
    return columns


def training_sums(model: IdentificationModel, prepared: Measurements) -> NormalEquations | None:
    """A training record as a candidate prepared it, summed for ``model``'s unconstrained fits (the TSQR factors and
    powers, no Gram sums: :func:`~estimation.estimators.normal_equations.accumulate`), or ``None`` when it cannot
    be (the choice on a validation record then prepares it again and says why). Without the in-band sums: the
    validation record scores the candidates by OLS unless WLS is asked for, which sums them again with it."""
    try:
        return accumulate(model, concatenate(prepared), gram=False, band=False)  # the OLS scores' sums
    except (ValueError, np.linalg.LinAlgError):
        return None


def joint_speeds(measurements: Measurements) -> NDArray[np.float64]:
    """Each joint's root-mean-square speed (1 for a joint at rest)."""
    speeds = np.sqrt(np.mean(measurements.dq**2, axis=0))
    return np.where(speeds > 0, speeds, 1.0)


def thinned(measurements: Measurements, max_rows: int) -> Measurements:
    """``measurements`` evenly thinned to at most ``max_rows`` samples (every k-th)."""
    step = max(1, int(np.ceil(measurements.n_samples / max_rows)))
    return measurements.select(np.arange(0, measurements.n_samples, step))


def blocked_folds(n_samples: int, folds: int) -> Iterator[tuple[slice, NDArray[np.bool_]]]:
    """Each of ``folds`` contiguous blocks of ``n_samples`` in turn: the block held out, and a mask of the rest."""
    edges = np.linspace(0, n_samples, folds + 1).astype(int)
    for start, stop in zip(edges[:-1], edges[1:]):
        kept = np.ones(n_samples, dtype=bool)
        kept[start:stop] = False
        yield slice(start, stop), kept


def block_factor(Y: NDArray[np.float64], y: NDArray[np.float64], support: NDArray[np.bool_],
                 scale: NDArray[np.float64] | None = None) -> NDArray[np.float64]:
    """Triangular factors ``[R, Qᵀy]`` of the rows ``[Y, y]`` of a block ``Y (N, m, p)``, ``y (N, m)``, one per
    channel on the columns it has (``support (m, p)``, zero elsewhere), stacked: least squares on several blocks'
    factors stacked is least squares on their rows. A channel reaches few of the columns (a distal joint's torque,
    its own friction): its factor costs a fraction of the whole block's. ``scale (m,)``: each channel's rows
    ``[Y_c, y_c]`` divided by ``scale[c]`` first (the block's own columns only: the same quotients as dividing the
    whole block, without the division and the copy of the columns a channel does not have)."""
    n_columns = Y.shape[2]
    factors = []
    for channel, columns in enumerate(support):
        where = np.append(np.flatnonzero(columns), n_columns)
        rows = np.concatenate([Y[:, channel, columns], y[:, channel, None]], axis=1)
        if scale is not None:
            rows /= scale[channel]
        triangular = np.linalg.qr(rows, mode="r")
        factor = np.zeros((triangular.shape[0], n_columns + 1))
        factor[:, where] = triangular
        factors.append(factor)
    return np.concatenate(factors, axis=0)


def geometric_mean(mse: NDArray[np.float64]) -> float:
    """The geometric mean of per-channel errors: no channel's unit dominates it."""
    return float(np.exp(np.mean(np.log(np.maximum(mse, np.finfo(float).tiny)))))


def candidates(train: Sequence[Measurements], rule: Preprocessing, given: Preprocessing | None,
               families: Sequence[Family] = ("fourier", "butterworth"), *,
               shortest_s: float | None = None, held_out: Sequence[Measurements] = (),
               velocity_variants: bool = True) -> tuple[Preprocessing, ...]:
    """The derivative candidates of a record without measured ``dq, ddq`` (module docstring), each once, of the
    ``families`` asked for (the rule's and the given plan are candidates whatever their family). Only plans that
    apply to every record: to the training segments (the shortest lasting ``shortest_s``, default: the shortest of
    ``train``) and to the ``held_out`` ones (validation, test): no filter cut-off below ``1 / duration`` of one of
    them nor above 0.4 of the slowest rate, no Fourier fit unless each of them repeats at its fundamental (:func:`repeats_at`).
    The user's plan is kept whatever (it is theirs to refuse); the rule's only when it applies, unless nothing else
    does. A record that logs ``dq`` (not ``ddq``) gets each filter twice (``velocity_variants``): on the logged
    velocity, and with ``dq`` from the positions (``Preprocessing.velocity_from_positions``)."""
    common = {"decimation": rule.decimation, "held_torques": rule.held_torques}
    longest = max(train, key=lambda segment: segment.n_samples)
    rate = min(sampling_rate(segment.t) for segment in (*train, *held_out))
    shortest = min(duration(segment) for segment in train) if shortest_s is None else shortest_s
    shortest = min([shortest, *(duration(segment) for segment in held_out)])

    def applies(plan: Preprocessing) -> bool:
        if plan.method == "fourier":
            return all(repeats_at(segment, plan.frequency_hz) for segment in held_out)
        if plan.method == "butterworth":
            return 1.0 / shortest <= plan.cutoff_hz < 0.5 * rate
        return True

    found: list[Preprocessing] = [rule] + ([given] if given is not None else [])
    frequency, source = fundamental(longest, rule, given) if "fourier" in families else (None, None)
    if frequency is not None:
        nyquist_harmonic = int(np.ceil(0.5 * rate / frequency)) - 1
        average = (given or rule).average_periods
        found += [Preprocessing("fourier", frequency, harmonics, source, average, **common)
                  for harmonics in HARMONICS_GRID if harmonics <= nyquist_harmonic]
    bandwidth = max(motion_bandwidth(segment.q, sampling_rate(segment.t)) for segment in train)
    for fraction in CUTOFF_FRACTIONS if "butterworth" in families else ():
        cutoff = float(f"{fraction * rate:.6g}")
        if cutoff < bandwidth:
            continue
        plan = Preprocessing("butterworth", cutoff_hz=cutoff, order=ButterworthDifferentiation().order, **common)
        found.append(plan)
        if velocity_variants and all(segment.dq is not None for segment in train):
            found.append(replace(plan, velocity_from_positions=True))
    kept = [plan for plan in dict.fromkeys(found) if plan == given or applies(plan)]
    return tuple(kept if any(plan != given for plan in kept) else dict.fromkeys(found))


def repeats_at(segment: Measurements, frequency_hz: float) -> bool:
    """Whether a record's positions are seen to repeat at ``frequency_hz``: it spans
    :data:`~estimation.preprocessing.periodicity.MIN_PERIODS` periods and its positions one period apart differ by
    less than :data:`~estimation.preprocessing.periodicity.REPEAT_THRESHOLD` of their variance. A Fourier series at
    that fundamental describes such a record; of another (a different motion, a record too short to tell) nothing
    says it would, while a filter applies to any record. On the EMPS (training: the first 16 s, 2.6 periods of
    0.16 Hz; validation: the 8.8 s after, 1.4 periods), a 400-harmonic fit won on the training record and on the
    validation record but predicted the pulses record 6.7 times worse than the 85 Hz filter: with the validation
    unable to show the period, the filters decide."""
    error = repeat_error(segment.q, sampling_rate(segment.t) / frequency_hz)
    return bool(np.isfinite(error) and error <= REPEAT_THRESHOLD)


def fundamental(longest: Measurements, rule: Preprocessing, given: Preprocessing | None) -> tuple[float | None, str | None]:
    """The Fourier candidates' frequency: given, else the rule's detected one, else detected here (a user's
    ``--cutoff`` skips the rule's detection)."""
    for plan in (given, rule):
        if plan is not None and plan.method == "fourier":
            return plan.frequency_hz, plan.frequency_source
    return detect_fundamental(longest.t, longest.q).frequency_hz, "detected"


@dataclass(frozen=True)
class ChoiceWindow:
    """What the choice sees of a training record: the scored window, and the record's shortest segment.

    The choice is made on :attr:`segments` alone (the fundamental detected, the rule's cut-off, every candidate
    scored), so that a record read in memory and the same files read chunk by chunk
    (:func:`estimation.streaming.cutoff_choice.streamed_window`) get the same choice.

    Attributes
    ----------
    segments
        All the segments, or, past :data:`SCORED_SAMPLES` samples in all, the first :data:`SCORED_SAMPLES` of
        the longest (:func:`scored_window`).
    shortest_s
        Duration of the record's shortest segment, s: no filter candidate needs longer to settle.
    whole
        Whether the window is the whole record.
    """

    segments: tuple[Measurements, ...]
    shortest_s: float
    whole: bool = True

    @classmethod
    def of(cls, segments: Sequence[Measurements]) -> ChoiceWindow:
        """The window of a record held in memory."""
        return cls(scored_window(segments), min(duration(segment) for segment in segments),
                   sum(segment.n_samples for segment in segments) <= SCORED_SAMPLES)


def duration(segment: Measurements) -> float:
    """Time from a segment's first sample to its last, s."""
    return float(segment.t[-1] - segment.t[0])


@single_threaded_blas()  # tall thin least squares: threaded BLAS only loses (dynamics.runtime.threads)
def choose_by_evidence(
    model: IdentificationModel,
    train: Measurements | Sequence[Measurements] | ChoiceWindow,
    *,
    frequency_hz: float | None = None,
    harmonics: int | None = None,
    cutoff_hz: float | None = None,
    average_periods: str = "auto",
    decimation: int = 1,
    held_torques: bool | None = False,
    folds: int = 5,
    max_rows: int = 6000,
    families: Sequence[Family] = ("fourier", "butterworth"),
    jobs: int | None = None,
    held_out: Sequence[Measurements] = (),
    velocity_variants: bool = True,
    sums_model: IdentificationModel | None = None,
) -> PreprocessingChoice:
    """The preprocessing of ``train`` for ``model``, chosen by held-out error (module docstring).

    The options are those of :func:`estimation.preprocessing.plan.choose_preprocessing` (and checked by it); a
    given ``frequency_hz``, ``harmonics`` or ``cutoff_hz`` decides, scored beside the candidates. ``families``
    restricts the candidates. ``jobs``: processes that score the candidates side by side (``None``: the cores this
    process may use, at most 4; the same choice and scores whatever the number:
    :mod:`dynamics.runtime.processes`). ``held_torques=None``: whether the torques were held over each sample is chosen
    too (:func:`with_held_torques`). Everything is decided on the record's :class:`ChoiceWindow` (a window
    already made may be given: a streamed record's). ``held_out``: the segments of the validation and test
    records, which every candidate must be able to prepare (:func:`candidates`); they are not scored.
    ``velocity_variants``: with a logged ``dq``, filters with ``dq`` from the positions are candidates too (the
    streamed chunks filter the logged velocity only). ``sums_model``: each candidate's training window, as it
    prepared it, also summed for that model (:attr:`PreprocessingChoice.training_sums`: the choice on a validation
    record fits them, and does not prepare the record again).

    Warns
    -----
    PreprocessingEvidenceWarning
        When the user's preprocessing predicts the held-out blocks clearly worse than the best candidate.
    """
    window = train if isinstance(train, ChoiceWindow) else ChoiceWindow.of(as_segments(train, "train"))
    segments = window.segments
    choose_hold, held_torques = held_torques is None, bool(held_torques)
    user_given = frequency_hz is not None or harmonics is not None or cutoff_hz is not None
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", PreprocessingWarning)  # the rule's own choice is a candidate here
        rule = choose_preprocessing(segments, frequency_hz=None if user_given else frequency_hz, harmonics=None,
                                    cutoff_hz=None, average_periods=average_periods, decimation=decimation,
                                    held_torques=held_torques)
    given = choose_preprocessing(segments, frequency_hz=frequency_hz, harmonics=harmonics, cutoff_hz=cutoff_hz,
                                 average_periods=average_periods, decimation=decimation, held_torques=held_torques,
                                 detect=False) if user_given else None
    if rule.method == "measured" or all(name in column_set(segments[0]) for name in ("dq", "ddq")):
        return PreprocessingChoice(rule, rule)
    score = HeldOutScore(model, folds=folds, max_rows=max_rows)
    plans = [plan for plan in candidates(segments, rule, given, families, shortest_s=window.shortest_s,
                                         held_out=tuple(held_out), velocity_variants=velocity_variants)
             if plan.method in families or plan in (rule, given)]
    started = time.perf_counter()
    extra = {} if sums_model is None else {"sums_model": sums_model}
    scored = run_tasks([functools.partial(score, segments, plan, **extra) for plan in plans],
                       worker_count(jobs, len(plans), min_tasks=MIN_PARALLEL_SCORES))
    sums = ()
    if sums_model is not None:
        sums = tuple((plan.without_evidence(), summed) for plan, (_, summed) in zip(plans, scored) if summed is not None)
        scored = [item for item, _ in scored]
    evidence = tuple(sorted(on_common_samples(scored), key=lambda item: (item.score, item.preprocessing.describe())))
    best = preferred(evidence)
    chosen = best if given is None else given
    if choose_hold:
        chosen, evidence = with_held_torques(chosen, evidence, score, segments)
        best = chosen if given is None else best
    selection = "given" if given is not None else "held-out"
    attached = replace(chosen, evidence=Evidence(selection, folds, evidence))
    if time.perf_counter() - started >= PROGRESS_SECONDS:
        # a --validate record may then decide among the same candidates: this line says what the training record's
        # blocks preferred, the summary's ``preprocessing:`` line what was used
        report("derivatives, on held-out blocks of the training record: %s best among %d candidates scored on %d "
               "samples (%.1f s)", attached.describe_method(),
               len(evidence), sum(segment.n_samples for segment in segments), time.perf_counter() - started)
    if given is not None:
        warn_if_clearly_better(attached)
    else:
        say_what_was_chosen(attached, segments)
    return PreprocessingChoice(attached, best, sums)


def choose_on_repeat(chosen: Preprocessing, model: IdentificationModel, train: Sequence[Measurements],
                     repeat: Sequence[Measurements], *, jobs: int | None = None) -> Preprocessing:
    """``chosen`` (the training record's choice among candidates) chosen again on a validation record that repeats
    the training motion: each candidate scored by :meth:`HeldOutScore.on_repeat` (the same model and flexible
    friction as the blocked cross-validation, fitted on the whole training record), the tie rule of
    :func:`preferred`. The blocked cross-validation predicts each block from a fit on the others, and a block the
    others do not cover (a record's slow start) is an extrapolation that can carry the score: on the real KUKA
    LWR4+ without logged derivatives (``benchmarks/bench_sweep.py`` ``kuka-posonly``) its scores put a 0.2 Hz and
    a 50 Hz filter within 1 % of each other (the first of five blocks a third of the score), the tie rule took
    50 Hz and the test record's joint 1 came out at 1.44 times the plain fit's. Scored on the repeat, 50 Hz was
    34 % worse than the best (1.2 Hz) and the tie rule took 17 Hz: joint 1 at 0.74 times
    (benchmarks/README.md, "A validation record that repeats the training motion"). The evidence then holds
    the repeat's scores (``selection`` ``repeat``)."""
    if chosen.evidence is None or chosen.evidence.selection != "held-out":
        return chosen
    score = HeldOutScore(model)
    plans = [item.preprocessing for item in chosen.evidence.candidates]
    scored = run_tasks([functools.partial(score.on_repeat, train, repeat, plan) for plan in plans],
                       worker_count(jobs, len(plans), min_tasks=MIN_PARALLEL_SCORES))
    evidence = tuple(sorted(on_common_samples(scored), key=lambda item: (item.score, item.preprocessing.describe())))
    if not any(np.isfinite(item.score) for item in evidence):
        return chosen
    return replace(preferred(evidence), evidence=Evidence("repeat", 0, evidence, (), chosen.without_evidence()))


def on_common_samples(scored: Sequence[CandidateEvidence]) -> list[CandidateEvidence]:
    """The scores, with any candidate scored on fewer recorded samples than the others set to ``inf`` (with the
    reason): a candidate may not win by leaving out samples the others predict."""
    most = max((item.samples for item in scored if np.isfinite(item.score)), default=0)
    return [item if not np.isfinite(item.score) or item.samples == most else
            replace(item, score=float("inf"), error=f"scored on {item.samples} of the {most} recorded samples the "
                    "other candidates predict: not comparable") for item in scored]


def with_held_torques(chosen: Preprocessing, evidence: tuple[CandidateEvidence, ...], score: HeldOutScore,
                      scored: Sequence[Measurements]) -> tuple[Preprocessing, tuple[CandidateEvidence, ...]]:
    """``chosen`` with the hold compensation (the torques held over each sample, the motion taken half a sample
    later: :func:`estimation.preprocessing.differentiation.compensate_hold`) when that scores more than
    :data:`EQUIVALENT` better; the evidence with that candidate added. On the README's simulated PUMA loop the
    compensated 250-harmonic fit scored 8 % better, and the diagnosis ended at 1.29 times the floor on joint 1
    instead of 1.73."""
    held = replace(chosen, held_torques=True)
    own = next((item for item in evidence if item.preprocessing == chosen), None)
    if chosen.held_torques or own is None:
        return chosen, evidence
    trial = score(scored, held)
    evidence = tuple(sorted((*evidence, trial), key=lambda item: (item.score, item.preprocessing.describe())))
    return (held if trial.score < (1 - EQUIVALENT) * own.score else chosen), evidence


def preferred(evidence: Sequence[CandidateEvidence]) -> Preprocessing:
    """The candidate chosen among those that predict as well as the best (module docstring: the tie rule)."""
    lowest = min(item.score for item in evidence)
    equivalent = [item.preprocessing for item in evidence if item.score <= (1 + EQUIVALENT) * lowest]
    fourier = [item for item in evidence if item.preprocessing in equivalent and item.preprocessing.method == "fourier"]
    if fourier:
        return min(fourier, key=lambda item: (round(item.score / lowest, 4), item.preprocessing.harmonics,
                                              item.preprocessing.describe())).preprocessing
    filters = [plan for plan in equivalent if plan.method == "butterworth"]
    if filters:
        return max(filters, key=lambda plan: (plan.cutoff_hz, not plan.velocity_from_positions, plan.describe()))
    return equivalent[0]


def say_what_was_chosen(chosen: Preprocessing, segments: Sequence[Measurements]) -> None:
    """:class:`~estimation.preprocessing.plan.PreprocessingWarning` naming a detected fundamental and the choice."""
    scored = [item for item in chosen.evidence.candidates if item.preprocessing.method == "fourier"]
    if not scored or scored[0].preprocessing.frequency_source != "detected":
        return
    found = scored[0].preprocessing.frequency_hz
    warnings.warn(
        f"the positions repeat every {1 / found:.6g} s: periodic excitation of {found:.6g} Hz detected; derivatives "
        f"from {chosen.describe_method()}, chosen by held-out error among {len(chosen.evidence.candidates)} candidates "
        "on the training record, unless a --validate record then decides among them (the summary's preprocessing line "
        "and the result's `preprocessing` say what was used; give --frequency or --cutoff to decide)",
        PreprocessingWarning, stacklevel=3)


def scored_window(segments: Sequence[Measurements]) -> tuple[Measurements, ...]:
    """The segments the candidates are scored on: all of them, or, past :data:`SCORED_SAMPLES` in all, the
    first :data:`SCORED_SAMPLES` samples of the longest segment."""
    if sum(segment.n_samples for segment in segments) <= SCORED_SAMPLES:
        return tuple(segments)
    longest = max(segments, key=lambda segment: segment.n_samples)
    return (longest.select(slice(0, min(SCORED_SAMPLES, longest.n_samples))),)


def warn_if_clearly_better(chosen: Preprocessing) -> None:
    """:class:`PreprocessingEvidenceWarning` when the best candidate beats the given preprocessing clearly."""
    scores = chosen.evidence.candidates
    own = next((item.score for item in scores if item.preprocessing == chosen.without_evidence()), None)
    best = scores[0]
    if own is not None and np.isfinite(own) and best.score < CLEARLY_BETTER * own:
        warnings.warn(
            f"the preprocessing given ({chosen.describe_method()}) predicts held-out blocks of the training data "
            f"{own / best.score:.3g} times worse than {best.preprocessing.describe_method()} (geometric-mean MSE "
            f"{own:.4g} against {best.score:.4g}); leave the derivative options out to let the data choose",
            PreprocessingEvidenceWarning, stacklevel=3)
