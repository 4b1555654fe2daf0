"""An unknown gain on each joint's recorded torque as a candidate of the default answer.

A torque sensor's calibration, or a current logged in place of a torque (a torque constant nobody gave), records
joint ``j``'s torque times its own unknown gain: ``τ_rec,j = s_j τ_j`` with ``τ_j = Y_j θ`` (the rigid body, friction
and offsets, linear in ``θ``). Per-joint parameters (friction, offsets) absorb their joint's gain; the rigid body's
parameters are shared between the joints' rows, so they make the gains identifiable relative to each other (the
model is bilinear, gains times ``Y θ``). The overall scale is not: ``(c s, θ / c)`` predicts the same torques. It
is fixed by the robot description's bodies (:func:`description_scale`: the fitted rigid-body parameters matched to
the description's, weighted by their marginal precision).

:func:`fit_torque_gains` fits ``(s, θ)`` by Gauss-Newton (Levenberg-Marquardt, in ``log s``:
:func:`estimation.estimators.channel_gains.fit_channel_gains_on_sums`, the loop the joint-zero check's gains test runs
too) on the channels' Gram sums ``G_j = Y_jᵀ Y_j``, ``b_j = Y_jᵀ τ_j``, ``c_j = τ_jᵀ τ_j`` (no sample held per
iteration), each channel weighted by
the inverse of its residual variance (iterated, as WLS, PUMA paper eq. 20); the standard errors are those of the
Gauss-Newton covariance ``σ² (JᵀJ)⁻¹`` with the scale held at the description's (the relative gains' errors).

The default ``oed identify`` fits the declared model to the torques divided by these gains (the gains then part of
how the records are read, as ``torque_signs``), chooses that model's answer among its own candidates as it chooses
the declared model's, and compares the two answers on the same validation samples in the recorded units by the
criterion of the default answer (:func:`torque_gains_answer`): the gains are taken only when they score lower by
more than :data:`TORQUE_GAINS_TOLERANCE` on a validation record of another motion (on a repeat, or without a
validation record, nothing measured them: the declared model is kept).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
from numpy.typing import NDArray

from dynamics.channels import is_joint_torque, torque_joint
from dynamics.measurements import Measurements
from dynamics.models import IdentificationModel
from estimation.data.channel_mask import whole_rows
from estimation.data.passive import passive_channels
from estimation.consistent.identification import ConsistentResult
from estimation.consistent.model_selection import ModelSelection, answers_scored
from estimation.estimators.channel_gains import (DETERMINED_RELATIVE_STD, channel_residuals, fit_channel_gains_on_sums,
                                                 gains_normal)
from estimation.identification.prepared import PreparedRecord, PreparedRecords
from estimation.identification.relative_error import relative_scores
from estimation.identification.repeated_motion import REPEAT_FRACTION, repeated_motion, still_motion
from estimation.identification.validation import ChannelErrors, Comparison

__all__ = ["DETERMINED_RELATIVE_STD", "SIGNIFICANCE_BLOCKS", "SIGNIFICANCE_Z", "TORQUE_GAINS_TOLERANCE", "TorqueGains", "channel_factors", "channel_sums", "description_scale",
           "block_labels", "diagnosed_gains_answer", "divided_records", "divided_torques", "fit_torque_gains", "gains_checked", "gains_for_records",
           "gains_from_sums", "gains_on_validation", "in_recorded_units", "other_scale", "scale_note", "scale_notes", "torque_gains_answer", "SCALE_NOTE_FACTOR"]

#: the relative score by which the model with the gains must beat the declared one (a tie keeps the declared)
TORQUE_GAINS_TOLERANCE = 0.01
#: the counts of the validation record's contiguous blocks over which the log ratio of the two models' scores is
#: taken, and the mean log ratio (in standard errors of the blocks' mean) that measures the gains, at every count (the
#: residuals are correlated over an unknown time, and a batch-means error grows with the blocks' length until they
#: outlast it): a lowering within the record's sampling spread measures nothing (the Franka Panda's log: gains of
#: 0.93 to 1.07 lowered the score by 1.1 %, benchmarks/README.md)
SIGNIFICANCE_BLOCKS = (40, 20, 10)
SIGNIFICANCE_Z = 2.0
#: samples a block when the regressor is summed (:func:`channel_sums`)
BLOCK = 2048
#: a score below this is taken as this (a block predicted exactly)
TINY = float(np.finfo(float).tiny)


@dataclass(frozen=True)
class TorqueGains:
    """The recorded torque of each channel over the model's: ``τ_rec,j = values[j] τ_j``.

    Attributes
    ----------
    channels
        The torque channels (``tau1``…).
    values, std
        The gains and their standard errors (the Gauss-Newton covariance carried through the description's
        scale by the delta method; the description itself taken as exact).
    scale
        How the overall scale was fixed.
    iterations
        The Gauss-Newton iterations taken.
    """

    channels: tuple[str, ...]
    values: NDArray[np.float64]
    std: NDArray[np.float64]
    scale: str = "the robot description's bodies"
    iterations: int = 0
    #: the gains held at the first channel's, the record not determining them (``None``: none)
    held: NDArray[np.bool_] | None = None

    @property
    def determined(self) -> NDArray[np.bool_]:
        """Whether each gain's standard error is within :data:`DETERMINED_RELATIVE_STD` of it (a held gain is not)."""
        known = self.std <= DETERMINED_RELATIVE_STD * np.abs(self.values)
        return known if self.held is None else known & ~self.held

    def to_dict(self) -> dict[str, Any]:
        """``{channels: {tau1: {value, std, determined}, …}, scale}``."""
        return {"channels": {channel: {"value": float(value), "std": float(std), "determined": bool(known)}
                             for channel, value, std, known in zip(self.channels, self.values, self.std,
                                                                   self.determined)},
                "scale": self.scale}

    def said(self) -> str:
        """The gains in a few words: ``tau1 1.15 ± 0.0005, …`` (``not determined`` beside those that are not)."""
        held = np.zeros(len(self.channels), dtype=bool) if self.held is None else self.held
        return ", ".join(f"{c} {v:.4g}" + (" (not determined: held at the first channel's)" if hold else
                                           f" ± {e:.2g}" + ("" if known else " (not determined)"))
                         for c, v, e, known, hold in zip(self.channels, self.values, self.std, self.determined, held))

    @classmethod
    def from_dict(cls, document: Any) -> TorqueGains:
        channels = tuple(document["channels"])
        return cls(channels, np.array([float(document["channels"][c]["value"]) for c in channels]),
                   np.array([float(document["channels"][c].get("std", np.nan)) for c in channels]),
                   str(document.get("scale", "")))


def channel_sums(model: IdentificationModel, measurements: Measurements, *, block: int = BLOCK
                 ) -> tuple[NDArray, NDArray, NDArray]:
    """Per channel ``G_j = Y_jᵀ Y_j``, ``b_j = Y_jᵀ τ_j``, ``c_j = τ_jᵀ τ_j`` of the base regressor and the torques
    of ``measurements``, summed over blocks of ``block`` samples (the regressor of the whole record never held)."""
    m, r = model.n_channels, model.n_base
    G, b, c = np.zeros((m, r, r)), np.zeros((m, r)), np.zeros(m)
    tau = measurements.channels(model.channels)
    for start in range(0, measurements.n_samples, block):
        rows = slice(start, start + block)
        Y = model.evaluate_base(measurements.q[rows], measurements.dq[rows], measurements.ddq[rows])
        G += np.einsum("nmr,nms->mrs", Y, Y, optimize=True)
        b += np.einsum("nmr,nm->mr", Y, tau[rows], optimize=True)
        c += np.einsum("nm,nm->m", tau[rows], tau[rows])
    return G, b, c


def _predicted(model: IdentificationModel, theta: NDArray, record: Measurements, *, block: int = BLOCK) -> NDArray:
    return np.vstack([model.evaluate_base(record.q[rows], record.dq[rows], record.ddq[rows]) @ theta
                      for rows in (slice(start, start + block) for start in range(0, record.n_samples, block))])


def _solve_theta(G: NDArray, b: NDArray, s: NDArray, w: NDArray) -> NDArray:
    A = np.einsum("m,mrs->rs", w * s**2, G)
    return np.linalg.lstsq(A, np.einsum("m,mr->r", w * s, b), rcond=None)[0]


def _weighted_fit(G: NDArray, b: NDArray, c: NDArray, n: int, rounds: int = 4) -> NDArray:
    """The channel-weighted least-squares fit without gains (the weights from the residual variances, iterated)."""
    s = np.ones(b.shape[0])
    w = 1.0 / np.maximum(c / n, np.finfo(float).tiny)
    for _ in range(rounds):
        theta = _solve_theta(G, b, s, w)
        w = 1.0 / np.maximum(channel_residuals(G, b, c, s, theta) / n, np.finfo(float).tiny)
    return theta


def gains_on_validation(model: IdentificationModel, train: Measurements, validation: Measurements
                        ) -> tuple[TorqueGains, bool, str]:
    """The gains fitted on ``train`` with ``model`` (:func:`fit_torque_gains`, the description's scale) and whether
    they predict ``validation`` (a record of another motion, at its recorded samples) better than the same model's
    channel-weighted fit without them, by the criterion of the default answer (the mean relative validation error,
    :data:`TORQUE_GAINS_TOLERANCE`) and by more than :data:`SIGNIFICANCE_Z` standard errors (the log ratio of the two
    scores over each of :data:`SIGNIFICANCE_BLOCKS` contiguous blocks, at every count): ``(gains, taken, sentence)``. A cheap check (sums, no sample held) before the
    answer's candidates are fitted again to the torques divided by the gains. A sample with a masked channel
    (:mod:`estimation.data.channel_mask`: a clipped sensor's, a held channel's repeat) is left out whole (the gains'
    sums take a sample's channels together)."""
    train, validation = whole_rows(train), whole_rows(validation)
    fitted = gains_from_sums(model, channel_sums(model, train), train.n_samples)
    if isinstance(fitted[1], str):
        return fitted[0], False, fitted[1]
    gains, theta, plain = fitted
    record = validation.as_recorded
    measured = record.channels(model.channels)
    squared = ((measured - _predicted(model, plain, record)) ** 2,
               (measured - gains.values * _predicted(model, theta, record)) ** 2)
    blocks = {count: tuple(np.array([values[part].sum(axis=0) for part in parts]) for values in squared)
              + (np.array([part.size for part in parts]),)
              for count in SIGNIFICANCE_BLOCKS
              for parts in ([part for part in np.array_split(np.arange(measured.shape[0]), count) if part.size],)}
    return (gains, *gains_checked(gains, model.channels, blocks))


def gains_from_sums(model: IdentificationModel, sums: tuple[NDArray, NDArray, NDArray], n_samples: int
                    ) -> tuple[TorqueGains, NDArray, NDArray] | tuple[TorqueGains, str]:
    """The gains fitted from the training record's :func:`channel_sums` (``n_samples`` summed) with ``model``
    (:func:`fit_torque_gains`, the description's scale; those the record does not determine held at the first
    channel's): ``(gains, theta, plain)``, ``plain`` the channel-weighted fit without gains; or ``(gains, sentence)``
    when fewer than two gains are determined (nothing to take)."""
    channels = model.channels
    names = {name for effect in model.effects for name in effect.parameter_names(model.robot)}
    rigid = np.array([name not in names for name in model.base.names])
    description = model.base.to_base(model.nominal_parameters())
    gains, theta = fit_torque_gains(sums, n_samples, channels, rigid=rigid, description=description)
    if gains.determined.sum() < 2:  # no gain relative to another measured: nothing to take
        return gains, (f"an unknown gain on each joint's recorded torque ({gains.said()}): the training "
                       "record determines fewer than two of them, not taken")
    if not gains.determined.all():  # those the record does not determine held at the first channel's
        gains, theta = fit_torque_gains(sums, n_samples, channels, rigid=rigid, description=description,
                                        held=~gains.determined)
    return gains, theta, _weighted_fit(*sums, n_samples)


def block_labels(n_samples: int, count: int) -> NDArray[np.int64]:
    """Each sample's block among ``count`` contiguous blocks of a record of ``n_samples`` (``numpy.array_split``'s)."""
    sizes = np.full(count, n_samples // count) + (np.arange(count) < n_samples % count)
    return np.repeat(np.arange(count), sizes)


def gains_checked(gains: TorqueGains, channels: Sequence[str], blocks: dict[int, tuple[NDArray, NDArray, NDArray]]
                  ) -> tuple[bool, str]:
    """Whether the gains are taken, and the sentence (:func:`gains_on_validation`'s rule), from the validation
    record's squared errors summed over contiguous blocks: ``blocks[count] = (declared, gains, sizes)``, the sums per
    block and channel ``(count, m)`` of the channel-weighted fit without gains and with them, and each block's
    samples (:data:`SIGNIFICANCE_BLOCKS`; empty blocks left out). Sums, so a record read in blocks gives them in one
    pass."""
    first = blocks[SIGNIFICANCE_BLOCKS[0]]
    errors = {"declared": first[0].sum(axis=0) / first[2].sum(), "gains": first[1].sum(axis=0) / first[2].sum()}
    scored = relative_scores({name: dict(zip(channels, mse.tolist())) for name, mse in errors.items()}, channels)
    # the lowering, block by block: the log of the ratio of the two models' scores over each contiguous block (each
    # channel's MSE over the same normaliser as the whole record's score), its standard error from the blocks' spread
    # (the residuals are correlated in time: every block count must measure it). A log ratio, not a difference: where
    # the motion is faster the errors are larger for both models, and a difference of errors would spread with them.
    normaliser = np.minimum(errors["declared"], errors["gains"])
    normaliser = np.where(normaliser > 0.0, normaliser, 1.0)
    weakest = (np.inf, 0.0, 0.0, 0)
    for count in SIGNIFICANCE_BLOCKS:
        declared, with_gains, sizes = blocks[count]
        keep = sizes > 0
        if keep.sum() < 2:
            continue
        declared, with_gains, sizes = declared[keep], with_gains[keep], sizes[keep]
        ratios = np.array([np.log(max(float((d / n / normaliser).mean()), TINY) / max(float((g / n / normaliser).mean()),
                                                                                    TINY))
                           for d, g, n in zip(declared, with_gains, sizes)])
        mean, spread = float(ratios.mean()), float(ratios.std(ddof=1) / np.sqrt(ratios.size))
        standing = mean / spread if spread > 0.0 else (np.inf if mean > 0.0 else -np.inf)
        weakest = min(weakest, (standing, mean, spread, ratios.size))
    standing, mean, spread, count = weakest
    taken = bool((1.0 + TORQUE_GAINS_TOLERANCE) * scored["gains"] < scored["declared"] and count
                 and standing > SIGNIFICANCE_Z)
    sentence = (f"an unknown gain on each joint's recorded torque ({gains.said()}; the scale from {gains.scale}): the "
                f"channel-weighted fit with them validates {scored['gains']:.4g} against {scored['declared']:.4g} "
                f"without (the mean relative validation error; the log ratio of the two scores over {count} blocks "
                f"{mean:.3g} ± {spread:.2g}), " + ("taken" if taken else "not taken"))
    return taken, sentence


def fit_torque_gains(sums: tuple[NDArray, NDArray, NDArray], n_samples: int, channels: Sequence[str], *,
                     rigid: NDArray[np.bool_], description: NDArray[np.float64],
                     held: NDArray[np.bool_] | None = None, rounds: int = 4, max_iterations: int = 100,
                     tolerance: float = 1e-9) -> tuple[TorqueGains, NDArray[np.float64]]:
    """Fit ``τ_rec,j = s_j Y_j θ`` (module docstring): ``(gains, theta)``, ``theta`` in the description's scale.

    Parameters
    ----------
    sums, n_samples
        :func:`channel_sums` of the training record (its base regressor and the torques fitted) and its samples.
    channels
        The ``m`` channel names.
    rigid
        ``(r,)`` which base columns are the rigid body's (the description holds their values).
    description
        ``(r,)`` the description's base parameters (only the rigid body's are used).
    held
        ``(m,)`` the gains held at the first channel's (the record does not determine them); ``None``: none.
    """
    G, b, c = sums
    free = np.flatnonzero(np.ones(b.shape[0], dtype=bool) if held is None else ~np.asarray(held, dtype=bool))
    free = free[free > 0]  # the first channel's gain is the reference
    n = n_samples
    m, r = b.shape
    s = np.ones(m)
    w = 1.0 / np.maximum(c / n, np.finfo(float).tiny)
    iterations = 0
    for _ in range(rounds):  # weights from the residual variances, as WLS; Levenberg-Marquardt on (log s_2.., θ)
        fitted = fit_channel_gains_on_sums((G * w[:, None, None], b * w[:, None], c * w), s, free, sign="held",
                                           max_iterations=max_iterations, tolerance=tolerance)
        s, theta, iterations = fitted.gains, fitted.theta, iterations + fitted.iterations
        w = 1.0 / np.maximum(channel_residuals(G, b, c, s, theta) / n, np.finfo(float).tiny)
    # covariance of (θ, the free log s) at the optimum, s_1 held: σ² (JᵀJ)⁻¹ with the weights 1/σ_j²
    H, _ = gains_normal(G * w[:, None, None], b * w[:, None], s, theta, free, "held")
    cov = np.linalg.pinv(H)
    scale, d_log_k = description_scale(theta, cov[:r, :r], rigid, description)
    # the final log-gains log s_j + log k(θ): their covariance by the delta method through the scale's match
    A = np.zeros((m, r + free.size))
    A[:, :r] = d_log_k
    A[free, r + np.arange(free.size)] = 1.0
    log_std = np.sqrt(np.clip(np.diag(A @ cov @ A.T), 0.0, None))
    values = s * scale
    return TorqueGains(tuple(channels), values, values * log_std, iterations=iterations,
                       held=None if held is None else np.asarray(held, dtype=bool)), theta / scale


#: the factor from 1 beyond which the determined gains' geometric mean says the description's bodies and the recorded
#: torques are not in the same units (:func:`scale_note`): real descriptions in SI and torques in N m give 0.9 to
#: 1.1 (the Franka Panda's log 0.93 to 1.07); a description in grams 0.001, torques in kN m 0.001, a motor's torque
#: before a gear of ratio 50 about 0.02
SCALE_NOTE_FACTOR = 10.0


def other_scale(gains: TorqueGains) -> float | None:
    """The geometric mean of the gains the record determines when it is beyond :data:`SCALE_NOTE_FACTOR` from 1
    (the recorded torques over those the description's bodies give: :func:`scale_note`), else ``None``."""
    known = gains.determined & np.isfinite(gains.values) & (gains.values > 0)
    if not np.any(known):
        return None
    mean = float(np.exp(np.mean(np.log(gains.values[known]))))
    return None if 1.0 / SCALE_NOTE_FACTOR <= mean <= SCALE_NOTE_FACTOR else mean


def scale_note(gains: TorqueGains) -> str | None:
    """A sentence when the recorded torques are on another scale than the one the description's bodies give:
    the geometric mean ``g`` of the gains the record determines beyond :data:`SCALE_NOTE_FACTOR` from 1 (``None``
    otherwise, or when no gain is determined). The gains' overall scale is the description's
    (:func:`description_scale`), so ``g`` is the recorded torque over the description's for the same motion: a
    description whose masses and inertias are in grams and g m² (a CAD export's unit) gives ``g ≈ 0.001``, and so
    do torques in kN m. Its bodies are the consistent fit's prior and the link checks' yardstick: a thousand times
    off, they pull the answer away and the checks name every link; the sentence names the units to check. Said
    whether the gains are taken or not (a common gain is not told from the description's scale)."""
    mean = other_scale(gains)
    if mean is None:
        return None
    known = gains.determined & np.isfinite(gains.values) & (gains.values > 0)
    values = gains.values[known]
    channels = [channel for channel, keep in zip(gains.channels, known) if keep]
    spread = f"{values.min():.3g} to {values.max():.3g}" if values.size > 1 else f"{values[0]:.3g}"
    if mean < 1.0:
        units = (f"the description's masses and inertias {1 / mean:.3g} times too large (in grams and g m^2: 1000)? "
                 "or the torques in larger units (kN m: 0.001), or a motor's before its gear")
    else:
        units = (f"the description's masses and inertias {mean:.3g} times too small (in tonnes: 1000)? or the torques "
                 "in smaller units (N mm, mN m: 1000), or a current")
    return (f"the recorded torques are {mean:.3g} times those the description's bodies give for the same motion "
            f"({', '.join(channels)}: {spread}, the gains the records determine): {units}? URDF masses are kg and "
            "inertias kg m^2; the description's bodies are the consistent fit's prior and the yardstick of its link "
            "checks, so mend whichever is not in SI")


def scale_notes(gains: TorqueGains | None) -> tuple[str, ...]:
    """The sentence of :func:`scale_note` as the verbs' notes (``oed identify``, memory and streamed, and
    ``oed diagnose`` say it alike): one sentence when the fitted gains (taken or not) say the recorded torques and
    the description's bodies are in different units; ``()`` otherwise, or without gains."""
    note = None if gains is None else scale_note(gains)
    return () if note is None else (note,)


def description_scale(theta: NDArray, cov: NDArray, rigid: NDArray[np.bool_], description: NDArray
                      ) -> tuple[float, NDArray]:
    """The overall scale ``k`` of the gains (``s k``, ``θ / k``) at which the fitted rigid-body parameters best
    match the description's, weighted by their marginal precision ``P = C_rb⁻¹`` (the directions the record
    determines; friction and offsets, which the description does not hold, marginalised out):
    ``k = θ_rbᵀ P θ_desc / θ_descᵀ P θ_desc``; and ``d log k / d θ`` (zero off the rigid body)."""
    index = np.flatnonzero(rigid)
    precision = np.linalg.pinv(cov[np.ix_(index, index)])
    fitted, described = theta[index], description[index]
    cross, power = float(fitted @ precision @ described), float(described @ precision @ described)
    if not np.isfinite(cross) or power <= 0.0 or cross <= 0.0:
        raise ValueError("the description's rigid-body parameters do not fix the gains' scale (no positive match)")
    gradient = np.zeros(theta.shape[0])
    gradient[index] = precision @ described / cross
    return cross / power, gradient


def torque_gains_answer(selection: ModelSelection, other: ModelSelection, gains: TorqueGains
                        ) -> tuple[ModelSelection, bool, str]:
    """The default answer with per-joint torque gains a candidate (module docstring): ``(other, True, why)`` (the
    selection of the declared model fitted to the torques divided by ``gains``, its validation errors in the
    recorded units) when its answer scores lower on the validation record than the declared model's
    (``selection``) by more than :data:`TORQUE_GAINS_TOLERANCE`, else ``(selection, False, why)``; ``why`` gives
    both scores (appended to the answer's reason too; empty when they were not compared). Compared only when both
    selections were made on a validation record of another motion."""
    scored = answers_scored(selection, other)
    if scored is None:
        return selection, False, ""
    declared, with_gains = scored
    taken = (1.0 + TORQUE_GAINS_TOLERANCE) * with_gains < declared
    why = (f"an unknown gain on each joint's recorded torque ({gains.said()}; the scale from {gains.scale}): its "
           f"answer ({other.chosen}) validates {with_gains:.4g} against {declared:.4g} for the declared model's ("
           + selection.chosen + "; the mean relative validation error), " + ("taken" if taken else "not taken"))
    return (replace(other, reason=f"{other.reason}; {why}"), True, why) if taken \
        else (replace(selection, reason=f"{selection.reason}; {why}"), False, why)


def diagnosed_gains_answer(without: ModelSelection, with_gains: ModelSelection, gains: TorqueGains
                           ) -> tuple[bool, str]:
    """Whether ``oed diagnose`` keeps the gains its quick check took, by :func:`torque_gains_answer`'s rule:
    ``with_gains`` (the default answer of the diagnosis of the torques divided by ``gains``, its validation errors
    in the recorded units) must score lower on the validation record than ``without`` (the same adopted model
    fitted again to the torques as recorded, its answer chosen alike) by more than :data:`TORQUE_GAINS_TOLERANCE`.
    ``(taken, why)``; kept (``why`` empty) when the two were not both chosen on a validation record of another
    motion. Gains that soak up model error (a payload read as a scale) pass the quick check with the plain model
    yet do not make the diagnosed model's answer predict better."""
    scored = answers_scored(without, with_gains)
    if scored is None:
        return True, ""
    plain, divided = scored
    taken = (1.0 + TORQUE_GAINS_TOLERANCE) * divided < plain
    return taken, (f"the diagnosed model's answer with them ({with_gains.chosen}) validates {divided:.4g} against "
                   f"{plain:.4g} without them ({without.chosen}, the same laws fitted to the torques as recorded; the "
                   "mean relative validation error), " + ("kept" if taken else "not taken"))


def divided_torques(measurements: Measurements, gains: TorqueGains) -> Measurements:
    """``measurements`` with each torque divided by its gain (and the torques as recorded beside them): the
    model's torques, in the description's units."""
    factor = _joint_factors(gains, measurements.n_joints)
    recorded = None if measurements.recorded is None else divided_torques(measurements.recorded, gains)
    return replace(measurements, tau=None if measurements.tau is None else measurements.tau / factor,
                   recorded=recorded)


def _joint_factors(gains: TorqueGains, n_joints: int) -> NDArray[np.float64]:
    factor = np.ones(n_joints)
    for channel, value in zip(gains.channels, gains.values):
        factor[torque_joint(channel)] = value
    return factor


def channel_factors(gains: TorqueGains | None, channels: Sequence[str]) -> NDArray[np.float64]:
    """Each channel's gain (``1`` for a channel without one)."""
    held = {} if gains is None else dict(zip(gains.channels, gains.values))
    return np.array([held.get(channel, 1.0) for channel in channels])


def _recorded_comparison(comparison: Any, factors: NDArray[np.float64],
                         channels: Sequence[str] = ()) -> Any:
    if isinstance(comparison, ChannelErrors):  # errors from sums (the streamed path): each channel's MSE times g²
        squared = dict(zip(channels, factors**2))

        def scaled(mse: Mapping[str, float] | None) -> dict[str, float] | None:
            return None if mse is None else {channel: float(value * squared.get(channel, 1.0)) for channel, value in
                                             mse.items()}
        return replace(comparison, mse=scaled(comparison.mse), mse_filtered=scaled(comparison.mse_filtered))
    if comparison is None or not isinstance(comparison, Comparison):
        return comparison
    return replace(comparison, measured=comparison.measured * factors, predicted=comparison.predicted * factors,
                   filtered=_recorded_comparison(comparison.filtered, factors))


def _recorded_fit(fit: Any, factors: NDArray[np.float64], channels: Sequence[str] = ()) -> Any:
    if fit is None:
        return None
    changes = {"train": _recorded_comparison(fit.train, factors, channels),
               "validation": _recorded_comparison(fit.validation, factors, channels)}
    if isinstance(fit, ConsistentResult):
        changes["unconstrained"] = _recorded_fit(fit.unconstrained, factors, channels)
    return replace(fit, **changes)


def in_recorded_units(selection: ModelSelection, gains: TorqueGains) -> ModelSelection:
    """``selection`` (fitted to the torques divided by ``gains``) with every candidate's training and validation
    comparison back in the recorded units (measured and predicted torques times the gains): its errors are then
    those ``oed predict`` measures against the records as logged (errors from sums, the streamed path's
    :class:`~estimation.identification.validation.ChannelErrors`: each channel's MSE times its gain squared, exact)."""
    first = next(c.fit for c in selection.candidates if c.fit is not None)
    channels = tuple(getattr(first.train, "channels", None) or first.model.channels)  # errors from sums: the model's
    factors = channel_factors(gains, channels)
    return replace(selection, candidates=tuple(replace(candidate, fit=_recorded_fit(candidate.fit, factors, channels))
                                               for candidate in selection.candidates))


def divided_records(records: PreparedRecords, gains: TorqueGains) -> PreparedRecords:
    """``records`` with every record's torques divided by ``gains`` (:func:`divided_torques`: the prepared
    measurements and the segments as read, whose noise floors the diagnosis compares with)."""
    def divided(record: PreparedRecord | None) -> PreparedRecord | None:
        if record is None:
            return None
        files = tuple(replace(file, segments=tuple(divided_torques(segment, gains) for segment in file.segments))
                      for file in record.files)
        return replace(record, files=files, measurements=divided_torques(record.measurements, gains))
    return replace(records, train=divided(records.train), validation=divided(records.validation),
                   test=divided(records.test))


def gains_for_records(model: IdentificationModel, records: PreparedRecords) -> tuple[TorqueGains, bool, str] | None:
    """:func:`gains_on_validation` of the prepared records, or ``None`` when nothing can measure the gains: no
    validation record of another motion (none, a repeat of the training motion, or one that hardly moves), a model
    with channels other than joint torques or with a passive joint's (its zero has no gain), or the fit fails."""
    channels = model.channels
    validation = None if records.validation is None else records.validation.measurements
    train = records.train.measurements
    if validation is None or len(channels) < 2 or passive_channels(model) \
            or not all(map(is_joint_torque, channels)) \
            or repeated_motion(train, validation) <= REPEAT_FRACTION or still_motion(train, validation):
        return None
    try:
        return gains_on_validation(model, train, validation)
    except (ValueError, np.linalg.LinAlgError):
        return None
