"""The diagnosis's forward selection from accumulated sums (:mod:`estimation.streaming.diagnosis_sums`).

The rules are those of :func:`estimation.diagnosis.search.diagnose`, called, not copied, where they are
functions: groups of candidates (:func:`estimation.diagnosis.search.candidate_groups`: each Coulomb-like
law with its joint's offset), the nested F test and BIC of
:mod:`estimation.diagnosis.candidate_trials` (``F = ((RSS₀ − RSS₁)/q) / (RSS₁/(N m − p₁))``, ``q`` the
candidate's linear and shape parameters, Bonferroni threshold ``alpha / J``), the physical-sign and
shape-at-bound checks (:func:`~estimation.diagnosis.candidate_trials.wrong_sign`), spring against offset
(:func:`estimation.diagnosis.search._offsets_beat_springs`), one Coulomb-like law a joint, confirmation on
the validation record against its channels **as recorded** (weighted MSE lowered by
``min_improvement``, at the weights the in-memory loop compares at: :data:`REWEIGHTED`, and no channel the candidate acts on made worse:
:func:`estimation.diagnosis.confirmation.channels_made_worse`), the noise floor as the stopping rule
(:func:`estimation.uncertainty.noise_floor.above_floor` at :data:`~estimation.diagnosis.statistics.FLOOR_ALPHA`,
as :func:`~estimation.diagnosis.stopping_rules.floor_stopping_rule`).

What this path does differently (said in the report's ``streaming.differences``):

* shapes are fixed: each shaped law's shape parameters were searched once, against the declared
  model, on a subsample (:mod:`estimation.streaming.diagnosis`); the in-memory loop refines the two
  best-ranked shapes again in each round against the current model, and searches a law paired with
  its offset jointly (here the pair uses the law's own shape);
* no joint refit of the shapes at the end: the linear parameters are refitted on all samples at
  the shapes as selected;
* the stopping rule is the noise floor or none (a user's ``rule(SearchState)`` needs per-sample residuals).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from dynamics.effects.linear import CoulombFriction, Effect
from dynamics.models import IdentificationModel
from dynamics.effects.shaped import FRICTION_LAWS, ShapedStribeckFriction
from estimation.diagnosis.candidate_trials import SIGNIFICANT_TERM, Trial, candidate_label, joints_of, nested_test, wrong_sign
from estimation.diagnosis.confirmation import channels_made_worse
from estimation.diagnosis.results import RejectedEffect
from estimation.diagnosis.selection_rules import candidate_groups, offsets_beat_springs
from estimation.diagnosis.statistics import FLOOR_ALPHA
from estimation.streaming.diagnosis_sums import ChannelSums
from estimation.uncertainty.noise_floor import NoiseFloor, above_floor
from estimation.estimators.effect_blocks import Block
from estimation.estimators.variable_projection import ShapeFit

try:  # the in-memory loop's confirmation rule is followed: reweighted when estimation.diagnosis.confirmation reweights
    from estimation.diagnosis.confirmation import REWEIGHTING_PASSES  # type: ignore[attr-defined]
    REWEIGHTED = True
except ImportError:  # the loop compares at the declared model's weights
    REWEIGHTING_PASSES, REWEIGHTED = 0, False

__all__ = ["REWEIGHTED", "Selection", "select_effects", "simpler_laws"]


@dataclass(frozen=True)
class Selection:
    """What the forward selection chose: candidate indices in order with their test statistics."""

    chosen: tuple[int, ...]
    p_values: tuple[float, ...]
    f_statistics: tuple[float, ...]
    rejected: dict[int, RejectedEffect]
    stopped_at_floor: bool
    weights: NDArray[np.float64]  # the channel weights the search ended with


def _columns(sums: ChannelSums, indices: Sequence[int]) -> list[int]:
    return [column for index in indices for column in sums.layout.blocks[index]]


def _trial(group, members, sums: ChannelSums, selection, weights, rss, shapes) -> Trial | str:
    """A :class:`Trial` of ``group`` added to ``selection`` (the in-memory trial's statistics), or why not."""
    columns = list(selection) + _columns(sums, group)
    try:
        theta, rss_augmented = sums.solve(columns, weights)
    except np.linalg.LinAlgError:
        if all(block.n_shape == 0 for block in members):
            return "not identifiable: the base parameters already absorb it"
        return "not identifiable at the shape found on the subsample (its columns are absorbed or singular)"
    except FloatingPointError:
        return "its columns are non-finite"
    count = sum(block.n_linear + block.n_shape for block in members)
    statistic, p_value, bic = nested_test(rss, rss_augmented, count, sums.n_samples * sums.layout.n_channels,
                                          len(selection))
    shape = np.concatenate([np.asarray(shapes[index], dtype=float) for index in group]) if group else np.zeros(0)
    n_total = theta.shape[0] + shape.shape[0]
    fit = ShapeFit(shape, theta, np.full((n_total, n_total), np.nan), rss_augmented,
                   tuple(p.name for block in members for p in block.parameters), 0, None)
    return Trial(tuple(group), tuple(members), fit, rss_augmented, float(statistic), p_value, float(bic))


def _settled_weights(sums: ChannelSums, columns: Sequence[int], n_parameters: int, weights: NDArray[np.float64]
                     ) -> NDArray[np.float64]:
    """``1/σ̂_c²`` from the training residuals on ``columns``, iterated (as
    ``estimation.diagnosis.confirmation.settled_weights``: ``σ̂_c² = ‖ρ_c‖² / (N − r/m)``)."""
    m, n = sums.layout.n_channels, sums.n_samples
    floor = 1e-14 * sums.power[:, 0] / n + np.finfo(float).tiny
    for _ in range(REWEIGHTING_PASSES):
        theta, _ = sums.solve(columns, weights)
        weights = 1.0 / np.maximum(sums.channel_rss(columns, theta, target=0) / (n - n_parameters / m), floor)
    return weights


def _comparison(trial: Trial, train: ChannelSums, validate: ChannelSums, selection: list[int],
                weights: NDArray[np.float64], validate_mse: NDArray[np.float64], validation_error: float):
    """``(weights, candidate's error, its MSEs, current error, current MSEs)`` on validation: at the
    loop's weights, or (:data:`REWEIGHTED`) both models trained and compared at the weights the
    candidate's training residuals give (``estimation.diagnosis.confirmation.reweighted_comparison``)."""
    columns = selection + _columns(train, trial.group)
    if not REWEIGHTED:
        candidate_mse = validate.channel_mse(columns, trial.fit.theta)
        return weights, float(weights @ candidate_mse), candidate_mse, validation_error, validate_mse
    settled = _settled_weights(train, columns, len(selection) + trial.n_parameters, weights)
    candidate_mse = validate.channel_mse(columns, train.solve(columns, settled)[0])
    current_mse = validate.channel_mse(selection, train.solve(selection, settled)[0])
    return settled, float(settled @ candidate_mse), candidate_mse, float(settled @ current_mse), current_mse


def select_effects(model: IdentificationModel, blocks: dict[int, Block], shapes: dict[int, NDArray[np.float64]],
                   rejected: dict[int, RejectedEffect], train: ChannelSums, validate: ChannelSums,
                   weights: NDArray[np.float64], *, alpha: float, min_improvement: float, max_effects: int,
                   floor: NoiseFloor | None, n_candidates: int) -> Selection:
    """Forward selection on the sums (module docstring); ``blocks`` the candidates with columns,
    ``rejected`` those refused before (no rows, a failed shape search), completed here."""
    rejected = dict(rejected)
    selection = list(range(train.layout.n_base))
    theta, rss = train.solve(selection, weights)
    validate_mse = validate.channel_mse(selection, theta)
    validation_error = float(weights @ validate_mse)
    threshold = alpha / max(n_candidates, 1)
    groups = [group for group in candidate_groups(blocks, model) if not any(index in rejected for index in group)]
    friction_joints = {joint for effect in model.effects if effect.name in FRICTION_LAWS
                       for joint in (range(model.robot.n_joints) if getattr(effect, "joints", None) is None
                                     else effect.joints)}
    chosen: list[int] = []
    p_values: list[float] = []
    statistics: list[float] = []
    last_reason: dict[int, str] = {}
    stopped_at_floor = False

    def reject(index: int, reason: str) -> None:
        block = blocks[index]
        rejected[index] = RejectedEffect(block.effect.name, tuple(model.channels[r] for r in block.rows), reason,
                                         candidate_label(block.effect))

    while groups and len(chosen) < max_effects:
        if floor is not None and not any(above_floor(dict(zip(model.channels, validate_mse)), floor,
                                                     validate.n_samples, alpha=FLOOR_ALPHA).values()):
            stopped_at_floor = True
            break
        trials = []
        for group in groups:
            if any(index in rejected for index in group):
                continue
            members = [blocks[index] for index in group]
            if any(block.effect.name in FRICTION_LAWS and set(joints_of(block, model)) & friction_joints
                   for block in members):
                if len(group) == 1:
                    reject(group[0], "its joint already has a Coulomb-like friction law")
                continue
            outcome = _trial(group, members, train, selection, weights, rss, shapes)
            if isinstance(outcome, str):
                if len(group) == 1:
                    reject(group[0], outcome)
                continue
            trials.append(outcome)
        groups = [group for group in groups if not any(index in rejected for index in group)]
        springs_beaten = offsets_beat_springs(trials, model)
        added = None
        for trial in sorted(trials, key=lambda t: t.bic):
            if trial.p_value >= threshold or len(chosen) + len(trial.group) > max_effects:
                continue
            reason = wrong_sign(trial) or springs_beaten.get(trial.group)
            text = f"significant on training (p = {trial.p_value:.2g}) but "
            if reason is not None:
                if len(trial.group) == 1:
                    last_reason[trial.group[0]] = text + reason
                continue
            settled, error, candidate_mse, current_error, current_mse = _comparison(
                trial, train, validate, selection, weights, validate_mse, validation_error)
            if error >= (1.0 - min_improvement) * current_error:
                if len(trial.group) == 1:
                    change = ("raises the validation error" if error > current_error else
                              f"lowers the validation error by less than {100 * min_improvement:g} %")
                    last_reason[trial.group[0]] = text + f"{change} ({current_error:.4g} -> {error:.4g})"
                continue
            # channels_made_worse compares mean squares per channel: one "sample" whose square is the MSE
            worse = channels_made_worse(trial, np.sqrt(current_mse)[:, None], np.sqrt(candidate_mse)[:, None],
                                        min_improvement, model)
            if worse:
                if len(trial.group) == 1:
                    last_reason[trial.group[0]] = text + f"raises the validation error of {worse}"
                continue
            added = (trial, settled)
            break
        groups = [group for group in groups if not any(index in rejected for index in group)]
        if added is None:
            break
        trial, weights = added
        for index, block in zip(trial.group, trial.blocks):
            chosen.append(index)
            p_values.append(trial.p_value)
            statistics.append(trial.f_statistic)
            if block.effect.name in FRICTION_LAWS:
                friction_joints |= set(joints_of(block, model))
        selection = selection + _columns(train, trial.group)
        theta, rss = train.solve(selection, weights)
        validate_mse = validate.channel_mse(selection, theta)
        validation_error = float(weights @ validate_mse)
        groups = [group for group in groups if not set(group) & set(trial.group)]
    reason = f"not tested: {max_effects} effects already added" if len(chosen) >= max_effects else "not significant"
    if stopped_at_floor:
        reason = "not tested: the stopping rule ended the search (no channel significantly above its noise floor)"
    for index in blocks:
        if index not in rejected and index not in chosen:
            reject(index, last_reason.get(index, reason) if len(chosen) < max_effects else reason)
    return Selection(tuple(chosen), tuple(p_values), tuple(statistics), rejected, stopped_at_floor, weights)


def simpler_laws(chosen: Sequence[int], blocks: dict[int, Block], records: dict[str, dict], model: IdentificationModel
                 ) -> dict[int, int]:
    """``{chosen index: plain-Coulomb candidate index}`` for each found Stribeck law whose static
    terms the final fit does not support (within :data:`SIGNIFICANT_TERM` standard deviations of
    zero), when that joint's plain Coulomb candidate has columns in the sums (the rule of
    :func:`estimation.diagnosis.confirmation.simplify_laws`; the caller keeps the replacement only when the
    weighted validation error does not grow by more than ``min_improvement``)."""
    coulomb = {tuple(block.effect.joints): index for index, block in blocks.items()
               if type(block.effect) is CoulombFriction and block.effect.joints is not None}
    replacements = {}
    for index in chosen:
        effect: Effect = blocks[index].effect
        if not isinstance(effect, ShapedStribeckFriction) or effect.joints is None:
            continue
        terms = [name for name in effect.parameter_names(model.robot) if name.startswith("fs")]
        if all(name in records and records[name]["value"] < SIGNIFICANT_TERM * records[name]["std"] for name in terms):
            if tuple(effect.joints) in coulomb:
                replacements[index] = coulomb[tuple(effect.joints)]
    return replacements
