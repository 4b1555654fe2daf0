"""Close the loop on measured data: find what an identified model lacks, add it, report before/after.

Procedure (forward selection on nested linear models):

1. Identify the declared model by channel-weighted least squares; its channel weights
   ``w_c = 1/σ_c²`` serve the tests of a round and are re-estimated from the residuals of each
   model the search adopts.
2. For every candidate effect (one column block per joint or plate channel: ``coulomb``,
   ``offset``, ``armature``, ``stribeck``, ``spring``, ``wrench_offset``; the shaped laws
   ``coulomb:tanh``, ``stribeck:velocity``, ``sigmoid``, ``ripple``; or a user's own effect)
   find its rows at several random states, then fit it against the current columns
   (:mod:`estimation.diagnosis.candidate_trials`): plain ones by the linear solve on per-channel Gram
   matrices, shaped ones by variable projection (:mod:`estimation.estimators.variable_projection`). A
   candidate the current columns absorb (rank-deficient) is reported as such, never added.
3. Test the nested models with the F statistic ``F = ((RSS₀ − RSS₁)/q) / (RSS₁/(N m − p₁))`` on
   weighted residual sums of squares (``q`` linear plus shape parameters); the threshold is
   ``alpha`` divided by the number of candidates (Bonferroni). Rank the significant ones by BIC.
4. The best-ranked candidate is added only if its estimate is physical (friction, armature
   positive; a spring's stiffness positive, and a spring only when it explains more than an
   offset on its joint does), no other Coulomb-like law is on its joint, and it lowers the
   weighted validation error on the held-out data by at least ``min_improvement``, the candidate
   and the current model both trained and compared at the weights the candidate's own residuals
   give (:func:`estimation.diagnosis.confirmation.reweighted_comparison`); then the
   search repeats while the stopping rule (the noise floor; :func:`provisional_stopping_rule`)
   allows it. It stops when nothing significant and confirmed remains.
5. Re-identify the augmented model (all shapes refit jointly) and report the validation MSE per
   channel before and after.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray

from dynamics.effects.linear import (
    WRENCH_CHANNELS,
    Armature,
    CoulombFriction,
    Effect,
    JointOffset,
    Spring,
    StribeckFriction,
    WrenchOffset,
)
from dynamics.models import IdentificationModel, ModelKind
from dynamics.effects.shaped import (
    FRICTION_LAWS,
    PositionRipple,
    ShapedStribeckFriction,
    SigmoidFriction,
    TanhCoulombFriction,
)
from dynamics.runtime.threads import single_threaded_blas
from estimation.diagnosis.candidate_trials import candidate_label, fit_or_reason, joints_of, weighted_error, wrong_sign
from estimation.diagnosis.confirmation import channels_made_worse, reweighted_comparison
from estimation.diagnosis.coupling_candidates import combination_groups, combination_taken, coupling_candidates
from estimation.diagnosis.delay_candidate import DelayTrial
from estimation.diagnosis.delay_search import DelaySearch
from estimation.diagnosis.results import Diagnosis, FoundEffect, RejectedEffect, found_delay, found_effect
from estimation.diagnosis.statistics import floor_for_validation, residual_report
from estimation.diagnosis.final_refit import refit_found
from estimation.identification.fit import IdentificationResult, identify
from dynamics.measurements import Measurements
from estimation.uncertainty.noise_floor import NoiseFloor
from estimation.preprocessing.delay import DelayBounds
from estimation.diagnosis.stopping_rules import SearchState, floor_stopping_rule, provisional_stopping_rule
from estimation.diagnosis.selection_rules import candidate_groups, offsets_beat_springs, refine_best
from estimation.diagnosis.traced_refinement import traced_first
from estimation.estimators.effect_blocks import Block, NoRowsError, States, effect_columns, effect_rows
from estimation.estimators.separable_least_squares import FixedPart, residuals, solve_linear
from estimation.uncertainty.whiteness import autocorrelation

__all__ = ["Diagnosis", "FoundEffect", "RejectedEffect", "candidate_columns", "candidate_groups", "default_candidates",
           "diagnose", "effect_channels", "provisional_stopping_rule", "residual_statistics"]

#: screened candidates whose shapes are searched again in each round after the first
SCREEN_REFINED = 2
JOINT_CANDIDATES: tuple[type, ...] = (CoulombFriction, JointOffset, Armature, StribeckFriction, Spring)
#: candidates whose shape the data give (:mod:`dynamics.effects.shaped`)
SHAPED_CANDIDATES: tuple[type, ...] = (TanhCoulombFriction, ShapedStribeckFriction, SigmoidFriction, PositionRipple)


def effect_channels(effect: Effect, model: IdentificationModel) -> tuple[str, ...]:
    """The model channels an effect's columns reach (looked for at several random states)."""
    return tuple(model.channels[row] for row in effect_rows(model.kind, model.robot, effect, model.n_channels))


def default_candidates(model: IdentificationModel) -> tuple[Effect, ...]:
    """One candidate per joint for each joint effect, plain and shaped, one per plate channel for
    the offsets.

    Candidates already in the model are left out.
    """
    declared = {(effect.name, parameter) for effect in model.effects for parameter in effect.parameter_names(model.robot)}
    candidates: list[Effect] = []
    if model.kind is not ModelKind.EXTERNAL:
        for effect_type in JOINT_CANDIDATES + SHAPED_CANDIDATES:
            for joint in range(model.robot.n_joints):
                candidate = effect_type(joints=(joint,))
                if not {(candidate.name, name) for name in candidate.parameter_names(model.robot)} & declared:
                    candidates.append(candidate)
    if model.kind is not ModelKind.INTERNAL:
        for channel in WRENCH_CHANNELS:
            candidate = WrenchOffset(channels=(channel,))
            if (candidate.name, candidate.parameter_names(model.robot)[0]) not in declared:
                candidates.append(candidate)
    return tuple(candidates)


def candidate_columns(model: IdentificationModel, effect: Effect, measurements: Measurements) -> NDArray[np.float64]:
    """The candidate's columns over the samples on every channel, ``(N, m, k)`` (a shaped law at the
    first start of its shape parameters)."""
    states = States(measurements.q, measurements.dq, measurements.ddq)
    return effect_columns(model.kind, model.robot, effect, model.n_channels, states)


def residual_statistics(result: IdentificationResult, *, lags: Sequence[int] = (1, 10, 100)) -> dict[str, dict[str, float]]:
    """Per channel: mean, standard deviation, RMS and autocorrelation of the training residuals.

    White residuals have autocorrelations near 0 at every lag; a structured residual (an
    unmodelled effect) keeps them near 1.
    """
    residuals = result.estimate.residuals
    statistics = {}
    for channel, values in zip(result.estimate.channels, residuals.T):
        entry = {"mean": float(values.mean()), "std": float(values.std()), "rms": float(np.sqrt(np.mean(values**2)))}
        correlation = autocorrelation(values, max((lag for lag in lags if lag < values.shape[0]), default=0))
        for lag in lags:
            if lag < values.shape[0]:  # normalised estimator: within [-1, 1] (estimation.uncertainty.whiteness)
                entry[f"autocorrelation_lag{lag}"] = float(correlation[lag])
        statistics[channel] = entry
    return statistics


@single_threaded_blas()
def diagnose(
    model: IdentificationModel,
    train: Measurements,
    validate: Measurements,
    *,
    candidates: Iterable[Effect] | None = None,
    alpha: float = 1e-3,
    min_improvement: float = 0.01,
    max_effects: int = 20,
    stopping_rule: Callable[[SearchState], bool] | None = None,
    noise_floor: NoiseFloor | None = None,
    delay: DelayBounds | None = DelayBounds(),
) -> Diagnosis:
    """Find, by forward selection, the effects ``model`` lacks in ``train``, confirmed on ``validate``.

    Parameters
    ----------
    model
        The declared model (internal, external or combined, with its effects).
    train, validate
        Measurements with ``q, dq, ddq`` and the model's channels, from different experiments.
    candidates
        Effects to try, plain or shaped (default: :func:`default_candidates` and the joint pairs the
        residual traces, :func:`estimation.diagnosis.coupling_candidates.coupling_candidates`).
    alpha
        Family-wise significance level of the F test (Bonferroni over the candidates).
    min_improvement
        Smallest relative decrease of the weighted validation MSE for an effect to be added.
    max_effects
        Most effects added.
    stopping_rule
        ``rule(SearchState) -> bool``: keep searching while it says ``True`` (default:
        :func:`floor_stopping_rule` when a noise floor is had, else :func:`provisional_stopping_rule`).
    delay
        Where a delay between torques and motion is searched as a candidate (one for the records,
        :mod:`estimation.diagnosis.delay_candidate`); ``None``: not tried.
    noise_floor
        Noise floor of the validation record as recorded (:func:`estimation.uncertainty.noise_floor.noise_floor`,
        before preprocessing). ``None``: estimated from the recorded validation channels when they
        can give one (:mod:`estimation.diagnosis.statistics`), the method said in the report.

    The validation errors that confirm a candidate, and those reported, are measured against the
    validation channels as recorded (``validate.recorded`` when preprocessing filtered or averaged
    them), along the derived motion.
    """
    for name, data in (("train", train), ("validate", validate)):
        if not isinstance(data, Measurements):
            raise TypeError(f"{name} must be Measurements (diagnose confirms every effect on held-out data), "
                            f"got {type(data).__name__}")
    if not 0 < alpha < 1:
        raise ValueError(f"alpha must lie in (0, 1), got {alpha}")
    if not 0 <= min_improvement < 1:
        raise ValueError(f"min_improvement must lie in [0, 1), got {min_improvement}")
    candidates = tuple(default_candidates(model) + coupling_candidates(model, train=train)  # coulomb[q5+q6] …
                       if candidates is None else candidates)
    for candidate in candidates:
        if not isinstance(candidate, Effect):
            raise TypeError(f"candidate {candidate!r} is not an effect")
    floor, _ = floor_for_validation(validate, model.channels, noise_floor)
    train_given, validate_given = train, validate
    if stopping_rule is None:
        stopping_rule = provisional_stopping_rule if floor is None else floor_stopping_rule(floor)
    keep_searching = stopping_rule
    before = identify(model, train, validate)
    recorded = validate.as_recorded  # errors against the channels as recorded, along the derived motion
    weights = before.estimate.weights if before.estimate.method == "wls" else 1.0 / before.estimate.channel_variance
    threshold = alpha / max(len(candidates) + (delay is not None), 1)  # the delay is a candidate too
    regressor = (lambda data: before.shaped_fit.regressor(data)) if before.shaped_fit is not None else (
        lambda data: model.evaluate_base(data.q, data.dq, data.ddq))
    fixed_train = FixedPart.from_arrays(regressor(train), train.channels(model.channels))
    fixed_validate = FixedPart.from_arrays(regressor(recorded), recorded.channels(model.channels))
    states_train = States(train.q, train.dq, train.ddq)
    states_validate = States(recorded.q, recorded.dq, recorded.ddq)
    solution = solve_linear(fixed_train, [], states_train, [], weights)
    rss = solution.rss
    validation_error, validate_residual = weighted_error(fixed_validate, [], states_validate, [], solution.theta, weights)
    train_residual = residuals(fixed_train, [], solution)

    rejected: dict[int, RejectedEffect] = {}
    blocks: dict[int, Block] = {}
    for index, candidate in enumerate(candidates):
        try:
            blocks[index] = Block(model.kind, model.robot, candidate, model.n_channels)
        except NoRowsError:
            rejected[index] = RejectedEffect(candidate.name, (), "has no rows in this model", candidate_label(candidate))
    groups = candidate_groups(blocks, model) + combination_groups({index: block.effect for index, block in blocks.items()})
    friction_joints = {joint for effect in model.effects if effect.name in FRICTION_LAWS
                       for joint in _effect_joints(effect, model)}
    selected: list[tuple[Effect, float, float]] = []
    selected_effects: list[Effect] = []
    selected_shapes: list[NDArray[np.float64]] = []
    selected_blocks: list[Block] = []
    moved = DelaySearch(train, recorded, regressor, delay)  # the delay candidate and, once adopted, the moved records
    previous: dict[tuple[int, ...], Any] = {}

    stopped_at_floor = False
    previous_round = False  # the first round searches every shape from its grid: no tracing needed
    last_reason: dict[int, str] = {}  # statistical verdicts: the candidate is tried again in later rounds

    def reject(index: int, reason: str) -> None:
        block = blocks[index]
        rejected[index] = RejectedEffect(block.effect.name, _channels(block, model), reason, candidate_label(block.effect))

    def defer(index: int, reason: str) -> None:
        last_reason[index] = reason

    while groups and len(selected) + (moved.adopted is not None) < max_effects:
        # ---- stopping rule (noise floor): one call, see provisional_stopping_rule ----
        state = SearchState(model.channels, train_residual.T, validate_residual.T, train, recorded,
                            tuple(candidate_label(effect) for effect, _, _ in selected))
        if not keep_searching(state):
            stopped_at_floor = True
            break
        trials = []
        for group in groups:
            if any(index in rejected for index in group):
                continue
            members = [blocks[index] for index in group]
            if any(block.effect.name in FRICTION_LAWS and set(joints_of(block, model)) & friction_joints for block in members):
                if len(group) == 1:
                    reject(group[0], "its joint already has a Coulomb-like friction law")
                continue
            if any(combination_taken(block.effect, model.effects + tuple(selected_effects)) for block in members):
                if len(group) == 1:
                    reject(group[0], "its joint combination already has a Coulomb law")
                continue
            # first round: every shape searched from its grid; later rounds: screened at the last optimum
            outcome = fit_or_reason(group, members, fixed_train, states_train, weights, rss, previous.get(group),
                                    search=False)
            if isinstance(outcome, str):
                if len(group) == 1:
                    reject(group[0], outcome)
                continue
            previous[group] = outcome.fit
            trials.append(outcome)
        groups = [group for group in groups if not any(index in rejected for index in group)]
        traced = traced_first(trials, model.channels, model.robot.n_joints, train, recorded, train_residual,
                              validate_residual) if previous_round else None
        previous_round = True
        trials = refine_best(trials, blocks, fixed_train, states_train, weights, rss, previous, SCREEN_REFINED, traced)
        springs_beaten = offsets_beat_springs(trials, model)
        trials += moved.trials(selected_blocks, selected_shapes, model, weights, rss, fixed_train.n_fixed, trials)
        added = None
        for trial in sorted(trials, key=lambda t: t.bic):
            if trial.p_value >= threshold or len(selected) + (moved.adopted is not None) + len(trial.group) > max_effects:
                continue
            if isinstance(trial, DelayTrial):
                outcome = moved.confirm(trial, selected_blocks, selected_shapes, model, fixed_train, fixed_validate,
                                        weights, min_improvement)
                if outcome is not None:
                    added = (trial, outcome)
                    break
                continue
            reason = wrong_sign(trial) or springs_beaten.get(trial.group)
            text = f"significant on training (p = {trial.p_value:.2g}) but "
            if reason is not None:
                if len(trial.group) == 1:
                    defer(trial.group[0], text + reason)
                continue
            # both models trained and compared at the weights the candidate's residuals give
            comparison = reweighted_comparison(trial, fixed_train, fixed_validate, states_train, states_validate, weights)
            error, current_error = comparison.error, comparison.current_error
            if error >= (1.0 - min_improvement) * current_error:
                if len(trial.group) == 1:
                    change = ("raises the validation error" if error > current_error else
                              f"lowers the validation error by less than {100 * min_improvement:g} %")
                    defer(trial.group[0], text + f"{change} ({current_error:.4g} -> {error:.4g})")
                continue
            worse = channels_made_worse(trial, comparison.current_residual, comparison.residual, min_improvement, model)
            if worse:  # a trade between channels (a pair acting on two rows, say) is not a confirmed effect
                if len(trial.group) == 1:
                    defer(trial.group[0], text + f"raises the validation error of {worse}")
                continue
            added = (trial, comparison)
            break
        groups = [group for group in groups if not any(index in rejected for index in group)]
        if added is None:
            break
        trial, comparison = added
        if isinstance(trial, DelayTrial):  # along the delayed motion from now on
            comparison, fixed_train, fixed_validate = comparison.comparison, comparison.fixed_train, comparison.fixed_validate
            train, recorded = moved.adopt(trial)
            states_train, states_validate = States(train.q, train.dq, train.ddq), States(recorded.q, recorded.dq, recorded.ddq)
        weights = comparison.weights
        for block, shape in zip(getattr(trial, "blocks", ()), trial.shapes() if hasattr(trial, "shapes") else ()):
            selected.append((block.effect, trial.p_value, trial.f_statistic))
            selected_effects.append(block.effect)
            selected_shapes.append(shape)
            selected_blocks.append(block)
            fixed_train = fixed_train.extended(block.evaluate(states_train, shape), block.rows)
            fixed_validate = fixed_validate.extended(block.evaluate(states_validate, shape), block.rows)
            if block.effect.name in FRICTION_LAWS:
                friction_joints |= set(joints_of(block, model))
        solution = solve_linear(fixed_train, [], states_train, [], weights)
        rss = solution.rss
        train_residual = residuals(fixed_train, [], solution)
        validation_error, validate_residual = weighted_error(fixed_validate, [], states_validate, [], solution.theta,
                                                             weights)
        # the other candidates restart from their last optima (LM only); groups sharing an added effect go
        groups = [group for group in groups if not set(group) & set(trial.group)]
    train = train_given  # the final fit searches the delay again along the records as given
    chosen = {id(effect) for effect, _, _ in selected}
    reason = f"not tested: {max_effects} effects already added" if len(selected) >= max_effects else "not significant"
    if stopped_at_floor:
        reason = "not tested: the stopping rule ended the search (no channel significantly above its noise floor)"
    for index, block in blocks.items():
        if index not in rejected and id(block.effect) not in chosen:
            reject(index, last_reason.get(index, reason) if len(selected) < max_effects else reason)

    selected, after, pinned = refit_found(model, before, selected, selected_effects, selected_shapes, moved,
                                          train, validate, weights, validation_error, min_improvement)
    for position, term in enumerate(term for term in pinned if term.found):
        effect = next((block.effect for block in blocks.values() if term.parameter in block.names
                       and candidate_label(block.effect) == term.effect), None)  # a law simplified after selection: none
        rejected[len(candidates) + position] = RejectedEffect(
            term.effect if effect is None else effect.name, () if effect is None else effect_channels(effect, model),
            "added, but its estimate turned negative in the joint refit "
            f"({term.parameter} = {term.value:.4g} ± {term.std:.2g}): dropped", term.effect)
    delay_reason = moved.not_adopted_reason(untested=reason if reason.startswith("not tested") else
                                            "not tested: the search ended before a round tried it")
    if delay_reason is not None:
        rejected[len(candidates) + len(pinned)] = RejectedEffect("delay", tuple(model.channels), delay_reason, "delay")
    return Diagnosis(
        effects=tuple(found_effect(after, effect, p_value, statistic, model) for effect, p_value, statistic in selected)
        + found_delay(after, moved.adopted, model),
        rejected=tuple(rejected[index] for index in sorted(rejected)),
        before=before,
        after=after,
        residuals=residual_statistics(before),
        statistics=residual_report(before, after, train_given, validate_given, noise_floor),
        pinned=pinned,
    )


def _effect_joints(effect: Effect, model: IdentificationModel) -> tuple[int, ...]:
    joints = getattr(effect, "joints", None)
    return tuple(range(model.robot.n_joints)) if joints is None else tuple(joints)


def _channels(block: Block, model: IdentificationModel) -> tuple[str, ...]:
    return tuple(model.channels[row] for row in block.rows)
