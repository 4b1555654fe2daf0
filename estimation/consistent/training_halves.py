"""Do the training record's halves agree on the torque gains? A stationarity check of a candidate effect.

An unknown gain on a joint's recorded torque (:mod:`estimation.consistent.torque_gains`) is a property of the
sensor: it holds the same over the whole training record. A plant that changed during the training record (a
payload picked up halfway, a tool changed) reads to the gains' fit as a common scale on the torques the heavier arm
loads, and the validation record, taken after the change, may well prefer the scale (h-plants19: a 2 kg payload
picked up halfway gave gains of 1.113 on every torque, which the validation record favoured by 1.2 %). Such a gain
is not a sensor's: fitted on each half of the training record it takes two values.

The check: the training record is cut into :data:`BLOCKS_PER_HALF` contiguous blocks in each half; the gains are
fitted on each block (:func:`~estimation.consistent.torque_gains.gains_from_sums`, the description's scale, as the
whole record's); per channel whose gain every block determines (a short block may determine one joint's only) the logarithms of the first half's blocks' gains are compared with the second half's
by Welch's t statistic, the blocks' spread within each half as the standard error (it holds the noise and what the
model misses along the motion, which the Gauss-Newton error of one fit does not). A channel's halves disagree when
``|t|`` exceeds the two-sided :data:`HALVES_ALPHA` quantile of Student's t (Welch–Satterthwaite degrees of freedom),
Bonferroni over the channels: the change's own uncertainty, no threshold on its size. When they disagree the gains
are not taken, and the verbs say that the plant changed during training.

A model of one plant fitted to a record of two predicts neither. When the plant changed, ``oed diagnose`` makes its
answer on each half of the training record too (:func:`training_part`), and the validation record, a record of
the plant as it is used, chooses among the three answers (:func:`part_answer`: a half taken only when its answer
validates better than the whole record's by more than :data:`PART_TOLERANCE`, as any candidate of the answer).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy.stats import t as student

from dynamics.measurements import Measurements
from dynamics.models import IdentificationModel
from estimation.consistent.model_selection import ModelSelection, answers_scored
from estimation.consistent.torque_gains import channel_sums, gains_from_sums
from estimation.data.channel_mask import whole_rows

__all__ = ["BLOCKS_PER_HALF", "HALVES_ALPHA", "MIN_BLOCK_SAMPLES", "PARTS", "PART_TOLERANCE", "TrainingHalves",
           "gains_halves", "part_answer", "parts_compared", "training_part"]

#: the contiguous blocks of each half whose gains are fitted (their spread the standard error of the half's mean)
BLOCKS_PER_HALF = 4
#: the family-wise level of the check over the channels (two-sided; Bonferroni)
HALVES_ALPHA = 0.001
#: a block shorter than this (samples) is not fitted: the check is not made
MIN_BLOCK_SAMPLES = 100
#: the parts of the training record an answer is made on when the plant changed during it
PARTS = ("first half", "second half")
#: the relative score by which a half's answer must beat the whole record's (a tie keeps the whole record's)
PART_TOLERANCE = 0.01


@dataclass(frozen=True)
class TrainingHalves:
    """Each channel's torque gain on the training record's first half against its second half.

    Attributes
    ----------
    channels
        The torque channels compared (those whose gain every block determines).
    first, second
        The geometric mean of the blocks' gains in each half, per channel.
    t, limit
        Welch's t of the halves' log gains per channel, and the ``|t|`` beyond which they disagree.
    blocks
        The blocks fitted in each half.
    """

    channels: tuple[str, ...]
    first: NDArray[np.float64]
    second: NDArray[np.float64]
    t: NDArray[np.float64]
    limit: NDArray[np.float64]
    blocks: int = BLOCKS_PER_HALF
    #: the part of the training record the answer is fitted on (``"whole"`` or one of :data:`PARTS`), and each
    #: part's answer's validation score (the mean relative validation error) when they were compared
    fitted_on: str = "whole"
    scores: dict[str, float] | None = None

    @property
    def disagree(self) -> NDArray[np.bool_]:
        """Per channel: the halves' gains differ beyond :data:`HALVES_ALPHA` (Bonferroni)."""
        return np.abs(self.t) > self.limit

    @property
    def changed(self) -> bool:
        """Whether any channel's halves disagree: the plant changed during the training record."""
        return bool(self.disagree.any())

    def to_dict(self) -> dict[str, Any]:
        """``result.json``'s ``training_stationarity``: the effect compared, the method, per channel the halves'
        gains, ``t``, its limit and whether they disagree, and whether the plant changed."""
        return {"effect": "torque gains",
                "method": (f"the gains fitted on {self.blocks} contiguous blocks of each half of the training record; "
                           "Welch's t of the halves' log gains, the blocks' spread the standard error"),
                "alpha": HALVES_ALPHA, "changed": self.changed, "answer_fitted_on": self.fitted_on,
                "validation_scores": self.scores,
                "channels": {channel: {"first_half": float(a), "second_half": float(b), "t": float(t),
                                       "t_limit": float(limit), "disagree": bool(d)}
                             for channel, a, b, t, limit, d in zip(self.channels, self.first, self.second, self.t,
                                                                   self.limit, self.disagree)}}

    def message(self) -> str | None:
        """The sentence when the halves disagree, else ``None``."""
        if not self.changed:
            return None
        parts = ", ".join(f"{channel} {a:.4g} against {b:.4g} (t {t:.1f}, limit {limit:.1f})"
                          for channel, a, b, t, limit, d in zip(self.channels, self.first, self.second, self.t,
                                                                self.limit, self.disagree) if d)
        return (f"the training record's halves disagree on the torque gains ({parts}; first half against second): "
                "the plant changed during training (a load picked up or set down, a tool changed?), which no "
                "sensor's gain explains: the gains are not taken; a model of one plant fitted to a record of two "
                "predicts neither well: record the training motion with the plant as it will be used")


def _blocks(n_samples: int, per_half: int) -> list[slice]:
    half = n_samples // 2
    cuts = [*np.linspace(0, half, per_half + 1).astype(int)[:-1], *np.linspace(half, n_samples, per_half + 1).astype(int)]
    return [slice(int(a), int(b)) for a, b in zip(cuts[:-1], cuts[1:])]


def gains_halves(model: IdentificationModel, train: Measurements, *,
                 per_half: int = BLOCKS_PER_HALF) -> TrainingHalves | None:
    """The check of the module docstring on ``train`` with ``model``'s gains (each block's as the whole record's:
    :func:`~estimation.consistent.torque_gains.gains_from_sums`); ``None`` when it cannot be made (blocks under
    :data:`MIN_BLOCK_SAMPLES` samples, a block whose fit fails, or no channel every block
    determines)."""
    train = whole_rows(train)
    if train.n_samples < 2 * per_half * MIN_BLOCK_SAMPLES:
        return None
    logs, determined = [], None
    for rows in _blocks(train.n_samples, per_half):
        try:
            block = train.select(rows)
            gains = gains_from_sums(model, channel_sums(model, block), block.n_samples)[0]
        except (ValueError, np.linalg.LinAlgError):
            return None
        values = np.asarray(gains.values, dtype=float)
        usable = np.isfinite(values) & (values > 0.0)  # a gain fitted at zero or below is not one: not compared
        logs.append(np.log(np.where(usable, values, 1.0)))
        known = np.asarray(gains.determined, dtype=bool) & usable
        determined = known if determined is None else determined & known
    if determined is None or not determined.any():
        return None
    logs_ = np.asarray(logs)[:, determined]
    first, second = logs_[:per_half], logs_[per_half:]
    v1, v2 = first.var(axis=0, ddof=1) / per_half, second.var(axis=0, ddof=1) / per_half
    spread = np.sqrt(v1 + v2)
    t = (second.mean(axis=0) - first.mean(axis=0)) / np.where(spread > 0.0, spread, np.inf)
    # Welch–Satterthwaite degrees of freedom, per channel
    dof = np.where(spread > 0.0, (v1 + v2) ** 2 / np.maximum(v1**2 / (per_half - 1) + v2**2 / (per_half - 1),
                                                             np.finfo(float).tiny), per_half - 1.0)
    channels = tuple(np.asarray(model.channels)[determined])
    limit = student.ppf(1.0 - HALVES_ALPHA / (2.0 * len(channels)), np.maximum(dof, per_half - 1.0))
    return TrainingHalves(channels, np.exp(first.mean(axis=0)), np.exp(second.mean(axis=0)), t, np.asarray(limit,
                                                                                                           float),
                          blocks=per_half)


def training_part(measurements: Measurements, part: str) -> Measurements:
    """The samples of ``measurements`` in ``part`` (one of :data:`PARTS`): the first or the second half of its rows."""
    if part not in PARTS:
        raise ValueError(f"part must be one of {PARTS}, got {part!r}")
    half = measurements.n_samples // 2
    return measurements.select(slice(0, half) if part == PARTS[0] else slice(half, measurements.n_samples))


def part_answer(scores: dict[str, float | None]) -> tuple[str, str]:
    """Which part of the training record the answer is fitted on, from each part's answer's validation score
    (``scores["whole"]`` and those of :data:`PARTS`; ``None``: not compared): the lowest half's when it beats the
    whole record's by more than :data:`PART_TOLERANCE`, else ``"whole"``; and the sentence saying so."""
    whole = scores.get("whole")
    halves = {part: value for part, value in scores.items() if part in PARTS and value is not None}
    if whole is None or not halves:
        return "whole", ""
    best = min(halves, key=lambda part: (halves[part], PARTS.index(part)))
    taken = (1.0 + PART_TOLERANCE) * halves[best] < whole
    shown = ", ".join(f"the {part}'s {value:.4g}" for part, value in halves.items())
    chosen = f"the answer is fitted on the training record's {best}" if taken else \
        "the answer is fitted on the whole training record"
    return (best if taken else "whole"), (f"the answers made on each half of the training record validate {shown} "
                                          f"against {whole:.4g} for the whole record's (the mean relative validation "
                                          f"error): {chosen}")


def parts_compared(whole: ModelSelection | None, parts: dict[str, ModelSelection | None]
                   ) -> tuple[str, str, dict[str, float] | None]:
    """The answers made on the whole training record (``whole``) and on each of its halves (``parts``, keyed by
    :data:`PARTS`) scored on the same validation samples (:func:`~estimation.consistent.model_selection.answers_scored`)
    and chosen among (:func:`part_answer`): ``(part chosen, sentence, scores)``, the scores ``None`` when none was
    compared. The one comparison of ``oed identify`` and ``oed diagnose``."""
    scores: dict[str, float | None] = {"whole": None}
    for part, other in parts.items():
        scored = None if whole is None or other is None else answers_scored(whole, other)
        scores["whole"] = scores["whole"] if scored is None else scored[0]
        scores[part] = None if scored is None else scored[1]
    fitted_on, why = part_answer(scores)
    return fitted_on, why, {part: float(value) for part, value in scores.items() if value is not None} or None
