"""Close the loop on measured data: find what an identified model lacks, add it, report before/after.

Procedure (forward selection on nested linear models):

1. Identify the declared model by channel-weighted least squares; keep its channel weights
   ``w_c = 1/σ_c²`` fixed for the comparisons that follow.
2. For every candidate effect (one column block per joint or plate channel: ``coulomb``,
   ``offset``, ``armature``, ``stribeck``, ``spring``, ``wrench_offset``; the shaped laws
   ``coulomb:tanh``, ``stribeck:velocity``, ``sigmoid``, ``ripple``; or a user's own effect)
   find its rows at several random states, then fit it against the current columns
   (:mod:`estimation.candidate_trials`): plain ones by the linear solve on per-channel Gram
   matrices, shaped ones by variable projection (:mod:`estimation.variable_projection`). A
   candidate the current columns absorb (rank-deficient) is reported as such, never added.
3. Test the nested models with the F statistic ``F = ((RSS₀ − RSS₁)/q) / (RSS₁/(N m − p₁))`` on
   weighted residual sums of squares (``q`` linear plus shape parameters); the threshold is
   ``alpha`` divided by the number of candidates (Bonferroni). Rank the significant ones by BIC.
4. The best-ranked candidate is added only if its estimate is physical (friction, armature
   positive; a spring's stiffness positive, and a spring only when it explains more than an
   offset on its joint does), no other Coulomb-like law is on its joint, and it lowers the
   weighted validation error on the held-out data by at least ``min_improvement``; then the
   search repeats while the stopping rule (the noise floor; :func:`provisional_stopping_rule`)
   allows it. It stops when nothing significant and confirmed remains.
5. Re-identify the augmented model (all shapes refit jointly) and report the validation MSE per
   channel before and after.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from dynamics.effects import (
    WRENCH_CHANNELS,
    Armature,
    CoulombFriction,
    Effect,
    JointOffset,
    Spring,
    StribeckFriction,
    WrenchOffset,
)
from dynamics.models import IdentificationModel, ModelKind, build_model
from dynamics.shape_effects import (
    FRICTION_LAWS,
    PositionRipple,
    ShapedStribeckFriction,
    SigmoidFriction,
    TanhCoulombFriction,
    shape_parameters,
)
from dynamics.threads import single_threaded_blas
from estimation.candidate_trials import candidate_label, fit_or_reason, joints_of, weighted_error, wrong_sign
from estimation.confirmation import channels_made_worse, simplify_laws, weighted_validation
from estimation.coupling_candidates import coupling_candidates
from estimation.diagnosis_statistics import ResidualReport, floor_for_validation, residual_report
from estimation.identification import IdentificationResult, identify
from estimation.measurements import Measurements
from estimation.noise_floor import NoiseFloor
from estimation.stopping_rules import SearchState, floor_stopping_rule, provisional_stopping_rule
from estimation.variable_projection import (Block, FixedPart, NoRowsError, ShapeSearchError, States, effect_columns,
                                            effect_rows, residuals, solve_linear)
from estimation.whiteness import autocorrelation

#: screened candidates whose shapes are searched again in each round after the first
SCREEN_REFINED = 2
JOINT_CANDIDATES: tuple[type, ...] = (CoulombFriction, JointOffset, Armature, StribeckFriction, Spring)
#: candidates whose shape the data give (:mod:`dynamics.shape_effects`)
SHAPED_CANDIDATES: tuple[type, ...] = (TanhCoulombFriction, ShapedStribeckFriction, SigmoidFriction, PositionRipple)


@dataclass(frozen=True)
class FoundEffect:
    """An effect the data asked for, with its estimates in the augmented model."""

    name: str
    channels: tuple[str, ...]
    parameters: tuple[str, ...]
    values: tuple[float, ...]
    std: tuple[float, ...]
    p_value: float
    f_statistic: float
    spec: str = ""
    shape: dict[str, float] = field(default_factory=dict)
    shape_std: dict[str, float] = field(default_factory=dict)

    def to_dict(self) -> dict[str, Any]:
        return {
            "name": self.name, "channels": list(self.channels), "parameters": list(self.parameters),
            "values": list(self.values), "std": list(self.std), "p_value": self.p_value, "f_statistic": self.f_statistic,
            "spec": self.spec or self.name, "shape": dict(self.shape), "shape_std": dict(self.shape_std),
        }


@dataclass(frozen=True)
class RejectedEffect:
    """A candidate that was not added, and why."""

    name: str
    channels: tuple[str, ...]
    reason: str
    spec: str = ""


@dataclass(frozen=True)
class Diagnosis:
    """Result of :func:`diagnose`."""

    effects: tuple[FoundEffect, ...]
    rejected: tuple[RejectedEffect, ...]
    before: IdentificationResult
    after: IdentificationResult
    residuals: dict[str, dict[str, float]] = field(repr=False)
    statistics: ResidualReport | None = field(default=None, repr=False)

    def to_dict(self) -> dict[str, Any]:
        """The JSON document of ``oed diagnose``."""
        document = {
            "robot": self.before.model.robot.name,
            "model": self.before.model.kind.value,
            "declared_effects": [effect.name for effect in self.before.model.effects],
            "effects": [effect.to_dict() for effect in self.effects],
            "rejected": [{"name": r.name, "spec": r.spec or r.name, "channels": list(r.channels), "reason": r.reason}
                         for r in self.rejected],
            "residuals": self.residuals,
            "warnings": {"before": list(self.before.warnings), "after": list(self.after.warnings)},
            "train": {"before": {"mse": self.before.train.mse}, "after": {"mse": self.after.train.mse}},
            "validation": {
                "before": {"mse": self.before.validation.mse if self.before.validation else None},
                "after": {"mse": self.after.validation.mse if self.after.validation else None},
            },
            "cov_method": self.after.estimate.cov_method,
        }
        if self.statistics is not None:  # noise floor, tracing, whiteness (estimation.diagnosis_statistics)
            document.update(self.statistics.to_dict())
            for which in ("before", "after"):
                document["validation"][which]["mse_over_floor"] = self.statistics.ratios(which) or None
        return document


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
            if lag < values.shape[0]:  # normalised estimator: within [-1, 1] (estimation.whiteness)
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
        residual traces, :func:`estimation.coupling_candidates.coupling_candidates`).
    alpha
        Family-wise significance level of the F test (Bonferroni over the candidates).
    min_improvement
        Smallest relative decrease of the weighted validation MSE for an effect to be added.
    max_effects
        Most effects added.
    stopping_rule
        ``rule(SearchState) -> bool``: keep searching while it says ``True`` (default:
        :func:`floor_stopping_rule` when a noise floor is had, else :func:`provisional_stopping_rule`).
    noise_floor
        Noise floor of the validation record as recorded (:func:`estimation.noise_floor.noise_floor`,
        before preprocessing). ``None``: estimated from the recorded validation channels when they
        can give one (:mod:`estimation.diagnosis_statistics`), the method said in the report.

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
    if stopping_rule is None:
        stopping_rule = provisional_stopping_rule if floor is None else floor_stopping_rule(floor)
    keep_searching = stopping_rule
    before = identify(model, train, validate)
    recorded = validate.as_recorded  # errors against the channels as recorded, along the derived motion
    weights = before.estimate.weights if before.estimate.method == "wls" else 1.0 / before.estimate.channel_variance
    threshold = alpha / max(len(candidates), 1)
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
    groups = candidate_groups(blocks, model)
    friction_joints = {joint for effect in model.effects if effect.name in FRICTION_LAWS
                       for joint in _effect_joints(effect, model)}
    selected: list[tuple[Effect, float, float]] = []
    selected_effects: list[Effect] = []
    selected_shapes: list[NDArray[np.float64]] = []
    previous: dict[tuple[int, ...], Any] = {}

    stopped_at_floor = False
    last_reason: dict[int, str] = {}  # statistical verdicts: the candidate is tried again in later rounds

    def reject(index: int, reason: str) -> None:
        block = blocks[index]
        rejected[index] = RejectedEffect(block.effect.name, _channels(block, model), reason, candidate_label(block.effect))

    def defer(index: int, reason: str) -> None:
        last_reason[index] = reason

    while groups and len(selected) < max_effects:
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
        trials = _refine_best(trials, blocks, fixed_train, states_train, weights, rss, previous, SCREEN_REFINED)
        springs_beaten = _offsets_beat_springs(trials, model)
        added = None
        for trial in sorted(trials, key=lambda t: t.bic):
            if trial.p_value >= threshold or len(selected) + len(trial.group) > max_effects:
                continue
            reason = wrong_sign(trial) or springs_beaten.get(trial.group)
            text = f"significant on training (p = {trial.p_value:.2g}) but "
            if reason is not None:
                if len(trial.group) == 1:
                    defer(trial.group[0], text + reason)
                continue
            error, residual_v = weighted_error(fixed_validate, trial.blocks, states_validate, trial.shapes(),
                                               trial.fit.theta, weights)
            if error >= (1.0 - min_improvement) * validation_error:
                if len(trial.group) == 1:
                    change = ("raises the validation error" if error > validation_error else
                              f"lowers the validation error by less than {100 * min_improvement:g} %")
                    defer(trial.group[0], text + f"{change} ({validation_error:.4g} -> {error:.4g})")
                continue
            worse = channels_made_worse(trial, validate_residual, residual_v, min_improvement, model)
            if worse:  # a trade between channels (a pair acting on two rows, say) is not a confirmed effect
                if len(trial.group) == 1:
                    defer(trial.group[0], text + f"raises the validation error of {worse}")
                continue
            added = (trial, error, residual_v)
            break
        groups = [group for group in groups if not any(index in rejected for index in group)]
        if added is None:
            break
        trial, validation_error, validate_residual = added
        for block, shape in zip(trial.blocks, trial.shapes()):
            selected.append((block.effect, trial.p_value, trial.f_statistic))
            selected_effects.append(block.effect)
            selected_shapes.append(shape)
            fixed_train = fixed_train.extended(block.evaluate(states_train, shape), block.rows)
            fixed_validate = fixed_validate.extended(block.evaluate(states_validate, shape), block.rows)
            if block.effect.name in FRICTION_LAWS:
                friction_joints |= set(joints_of(block, model))
        solution = solve_linear(fixed_train, [], states_train, [], weights)
        rss = solution.rss
        train_residual = residuals(fixed_train, [], solution)
        # the other candidates restart from their last optima (LM only); groups sharing an added effect go
        groups = [group for group in groups if not set(group) & set(trial.group)]
    chosen = {id(effect) for effect, _, _ in selected}
    reason = f"not tested: {max_effects} effects already added" if len(selected) >= max_effects else "not significant"
    if stopped_at_floor:
        reason = "not tested: the stopping rule ended the search (no channel significantly above its noise floor)"
    for index, block in blocks.items():
        if index not in rejected and id(block.effect) not in chosen:
            reject(index, last_reason.get(index, reason) if len(selected) < max_effects else reason)

    after = before
    if selected:
        current = build_model(model.robot, model.kind, model.effects + tuple(effect for effect, _, _ in selected))
        starts = {parameter.name: float(value) for effect, shape in zip(selected_effects, selected_shapes)
                  for parameter, value in zip(shape_parameters(effect, model.robot), shape)}
        if before.shaped_fit is not None:
            starts.update({value.name: value.value for value in before.shapes})
        try:
            after = identify(current, train, validate, shape_starts=starts)
        except ShapeSearchError:  # the joint refit ran a shape to where the data do not determine it
            after = None
        if after is None or any(value.at_bound for value in after.shapes) \
                or weighted_validation(after, weights) > 1.05 * validation_error:
            # the joint refit of the shapes wandered off (to a bound, or worse on held-out data than the
            # shapes as selected): keep the shapes as selected, estimate the rest and the covariance there
            after = identify(current, train, validate, shape_starts=starts, shape_search=False)
        selected, after = simplify_laws(selected, after, model, train, validate, starts, weights, min_improvement)
    return Diagnosis(
        effects=tuple(_found(after, effect, p_value, statistic, model) for effect, p_value, statistic in selected),
        rejected=tuple(rejected[index] for index in sorted(rejected)),
        before=before,
        after=after,
        residuals=residual_statistics(before),
        statistics=residual_report(before, after, train, validate, noise_floor),
    )


def _effect_joints(effect: Effect, model: IdentificationModel) -> tuple[int, ...]:
    joints = getattr(effect, "joints", None)
    return tuple(range(model.robot.n_joints)) if joints is None else tuple(joints)


def _channels(block: Block, model: IdentificationModel) -> tuple[str, ...]:
    return tuple(model.channels[row] for row in block.rows)


def _refine_best(trials, blocks, fixed, states, weights, rss, previous, count: int):
    """The ``count`` best-ranked screened trials with shapes searched again by Levenberg–Marquardt."""
    ranked = sorted(trials, key=lambda t: t.bic)
    refined = []
    for position, trial in enumerate(ranked):
        if position < count and trial.fit.shape.size:
            outcome = fit_or_reason(trial.group, list(trial.blocks), fixed, states, weights, rss, trial.fit, search=True)
            if not isinstance(outcome, str):
                previous[trial.group] = outcome.fit
                trial = outcome
        refined.append(trial)
    return refined


def candidate_groups(blocks: dict[int, Block], model: IdentificationModel) -> list[tuple[int, ...]]:
    """Every candidate alone, and each Coulomb-like friction law together with its joint's offset
    (an asymmetric friction: a sigmoid law with a shift mimics a symmetric law plus an offset, so
    the pair must compete with it as one candidate)."""
    groups = [(index,) for index in blocks]
    offsets = {joints_of(block, model): index for index, block in blocks.items() if block.effect.name == "offset"}
    for index, block in blocks.items():
        joints = joints_of(block, model)
        if block.effect.name in FRICTION_LAWS and block.effect.name != "sigmoid" and joints in offsets:
            groups.append((index, offsets[joints]))
    return groups


def _offsets_beat_springs(trials, model) -> dict[tuple[int, ...], str]:
    """Springs whose joint's offset explains as much: a stiffness that is an offset in disguise
    (``k·mean(q)`` equal to the offset) is not a spring."""
    offsets = {joints_of(t.blocks[0], model): t for t in trials if len(t.blocks) == 1 and t.blocks[0].effect.name == "offset"}
    reasons = {}
    for trial in trials:
        if len(trial.blocks) != 1 or trial.blocks[0].effect.name != "spring":
            continue
        offset = offsets.get(joints_of(trial.blocks[0], model))
        if offset is None:
            reasons[trial.group] = "no offset on its joint to compare it with (a spring must explain more than an offset)"
        elif offset.rss <= trial.rss:
            reasons[trial.group] = "an offset explains as much (a stiffness that is an offset in disguise)"
    return reasons


def _found(after: IdentificationResult, effect: Effect, p_value: float, statistic: float,
           model: IdentificationModel) -> FoundEffect:
    names = list(after.estimate.names)
    parameters = tuple(effect.parameter_names(model.robot))
    indices = [names.index(name) for name in parameters]
    shape_names = {parameter.name for parameter in shape_parameters(effect, model.robot)}
    shapes = {value.name: value for value in after.shapes if value.name in shape_names}
    return FoundEffect(
        name=effect.name,
        channels=tuple(model.channels[row] for row in effect_rows(model.kind, model.robot, effect, model.n_channels)),
        parameters=parameters,
        values=tuple(float(after.estimate.values[i]) for i in indices),
        std=tuple(float(after.estimate.std[i]) for i in indices),
        p_value=p_value,
        f_statistic=float(statistic),
        spec=candidate_label(effect),
        shape={name: value.value for name, value in shapes.items()},
        shape_std={name: value.std for name, value in shapes.items()},
    )
