"""Close the loop on measured data: find what an identified model lacks, add it, report before/after.

Procedure (a search over nested linear models: additions, replacements, removals):

1. Identify the declared model by channel-weighted least squares; its channel weights
   ``w_c = 1/σ_c²`` serve the tests of a round and are re-estimated from the residuals of each
   model the search adopts.
2. For every candidate effect (one column block per joint or plate channel: ``coulomb``,
   ``offset``, ``armature``, ``stribeck``, ``spring``, ``viscous:direction`` (a viscous slope differing by
   direction), ``wrench_offset``; the shaped laws
   ``coulomb:tanh``, ``stribeck:velocity``, ``sigmoid``, ``ripple``; or a user's own effect)
   find its rows at several random states, then fit it against the current columns
   (:mod:`estimation.diagnosis.candidates.trials`): plain ones by the linear solve on per-channel Gram
   matrices, shaped ones by variable projection (:mod:`estimation.estimators.variable_projection`). A
   candidate the current columns absorb (rank-deficient) is reported as such, never added.
3. Screen each candidate by the F statistic ``F = ((RSS₀ − RSS₁)/q) / (RSS₁/(N m − p₁))`` on
   weighted residual sums of squares (``q`` linear plus shape parameters); the threshold is
   ``alpha`` divided by the number of candidates (Bonferroni). Rank the moves by their BIC against
   the current model, ties by what they add (never by the order of the candidate list).
4. The best-ranked move is taken only if the Wald test of its coefficients from the HAC covariance
   is significant at the same threshold (:mod:`estimation.diagnosis.rules.robust_test`), its estimate is
   physical (friction, armature positive, each term of a several-term law significant; a spring's
   stiffness positive, and a spring alone only when it explains more than an offset on its joint
   does), and it lowers the weighted validation error on the held-out data by at least
   ``min_improvement``, summed over every channel or over the channels it acts on
   (:func:`estimation.diagnosis.confirmation.own_rows_gain`; there also at least half the sum's gain) with the sum not rising, the move's model and the current model both trained and compared at the
   weights the move's own residuals give (:func:`estimation.diagnosis.confirmation.reweighted_comparison`).
   A move adds a candidate, or replaces the Coulomb-like law the search adopted on a joint by another
   (a law on a joint whose law was declared is refused); before each round an adopted effect is
   removed when its coefficients are within their noise in the current model
   (:mod:`estimation.diagnosis.search_moves`); a law another law replaced does not return, an effect removed returns at most once,
   after the model gained another effect. The search repeats until no move
   is confirmed (or a user's stopping rule, :func:`provisional_stopping_rule` by default, ends it).
5. Re-identify the augmented model (all shapes refit jointly, :mod:`estimation.diagnosis.final_refit`),
   each finding's p-value the Wald test from the covariance its standard deviations come from (a
   finding not significant there dropped), and report the validation MSE per channel before and after.
   When the validation record is another motion, each joint's diagnosed effects are compared with the plain
   law (Coulomb friction and an offset) on that joint's validation error, and the model mixed so is kept when
   it validates better (:mod:`estimation.diagnosis.plain_laws`).
6. Keep the runner-up: the best-ranked rival of the last adopted move (another law on the joint, or the
   model without the effect), fitted as the chosen model was (:mod:`estimation.diagnosis.runner_up`).

Steps 2–4 are one object, :class:`estimation.diagnosis.forward_selection.DiagnosisSearch`, its fits on
the records in memory (:class:`estimation.diagnosis.record_fits.RecordFits`); the streamed diagnosis
(:func:`estimation.streaming.diagnosis.diagnose_files`) runs the same search on summed normal equations.
"""

from __future__ import annotations

import functools
from collections.abc import Callable, Iterable, Sequence
from dataclasses import replace
from typing import Any

import numpy as np
from numpy.typing import NDArray

from dynamics.runtime.progress import step
from dynamics.effects.linear import (
    WRENCH_CHANNELS,
    Armature,
    CoulombFriction,
    DirectionalViscousFriction,
    Effect,
    JointOffset,
    Spring,
    StribeckFriction,
    WrenchOffset,
)
from dynamics.effects.shaped import PositionRipple, ShapedStribeckFriction, SigmoidFriction, TanhCoulombFriction
from dynamics.measurements import Measurements
from dynamics.models import IdentificationModel, ModelKind, build_model
from dynamics.runtime.processes import run_tasks, worker_count
from dynamics.runtime.threads import single_threaded_blas
from estimation.data.channel_mask import whole_rows
from estimation.diagnosis.candidates.trials import candidate_label
from estimation.diagnosis.candidates.coupling import coupling_candidates
from estimation.diagnosis.candidates.delay_search import DelaySearch
from estimation.diagnosis.final_refit import refit_significant
from estimation.diagnosis.plain_laws import PlainLawChoice, plain_law_choice
from estimation.diagnosis.rules.robust_test import estimate_test
from estimation.diagnosis.forward_selection import SearchOutcome, SearchSettings, candidate_blocks
from estimation.diagnosis.record_fits import RecordFits, declared_regressor
from estimation.diagnosis.results import Diagnosis, FoundEffect, RejectedEffect, found_delay, found_effect
from estimation.diagnosis.rules.selection_rules import candidate_groups
from estimation.diagnosis.runner_up import RivalAhead, RunnerUpSearch, in_memory_fitter, with_runner_up
from estimation.diagnosis.statistics import floor_for_validation, residual_report
from estimation.diagnosis.rules.stopping_rules import SearchState, provisional_stopping_rule
from estimation.estimators.effect_blocks import Block, States, effect_columns, effect_rows
from estimation.identification.fit import IdentificationResult, identify
from estimation.identification.repeated_motion import REPEAT_FRACTION, repeated_motion
from estimation.preprocessing.delay import DelayBounds
from estimation.uncertainty.noise_floor import NoiseFloor
from estimation.uncertainty.whiteness import autocorrelation

__all__ = ["Diagnosis", "FoundEffect", "RejectedEffect", "candidate_columns", "candidate_groups", "default_candidates",
           "diagnose", "effect_channels", "provisional_stopping_rule", "residual_statistics"]

JOINT_CANDIDATES: tuple[type, ...] = (CoulombFriction, JointOffset, Armature, StribeckFriction, Spring,
                                      DirectionalViscousFriction)
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
    jobs: int | None = None,
    unseen_stretches: bool = False,
) -> Diagnosis:
    """Find, by a search over models, the effects ``model`` lacks in ``train``, confirmed on ``validate``.

    Parameters
    ----------
    model
        The declared model (internal, external or combined, with its effects).
    train, validate
        Measurements with ``q, dq, ddq`` and the model's channels, from different experiments.
    candidates
        Effects to try, plain or shaped (default: :func:`default_candidates` and the joint pairs the
        residual traces, :func:`estimation.diagnosis.candidates.coupling.coupling_candidates`).
    alpha
        Family-wise significance level of the tests (Bonferroni over the candidates): the F screen
        and the Wald test from the HAC covariance.
    min_improvement
        Smallest relative decrease of the weighted validation MSE for an effect to be added.
    max_effects
        Most effects added.
    stopping_rule
        ``rule(SearchState) -> bool``: keep searching while it says ``True`` (default
        :func:`provisional_stopping_rule`: until no move is significant and confirmed;
        :func:`estimation.diagnosis.rules.stopping_rules.floor_stopping_rule` stops once no channel is
        significantly above its noise floor, sooner but blind to an effect smaller than that test sees).
    delay
        Where a delay between torques and motion is searched as a candidate (one for the records,
        :mod:`estimation.diagnosis.candidates.delay`); ``None``: not tried.
    noise_floor
        Noise floor of the validation record as recorded (:func:`estimation.uncertainty.noise_floor.noise_floor`,
        before preprocessing). ``None``: estimated from the recorded validation channels when they
        can give one (:mod:`estimation.diagnosis.statistics`), the method said in the report.
    jobs
        Processes that fit a round's candidates side by side, each a fork sharing the records
        (:mod:`dynamics.runtime.processes`), and, when no delay is adopted, the best rival beside the joint refit
        (:class:`~estimation.diagnosis.runner_up.RivalAhead`); ``None``: the cores this process may use, at most 4;
        1: in turn. The diagnosis is the same bit for bit whatever the number.
    unseen_stretches
        When ``validate`` repeats the training motion (positions within 5 % of their spread sample by sample,
        :mod:`estimation.identification.repeated_motion`), also refuse a candidate that raises the error on the
        stretches of the motion its fit did not see (fifths of the record or of its period, each predicted by the
        fit without it: :class:`estimation.diagnosis.confirmation.HeldOutBlocks`). Off by default: on the KUKA
        LWR4+ (run 2 repeats run 1) the fits without a fifth of the motion extrapolate the rigid body, which
        refuses the shoulder's friction law, and run 3 is predicted worse (``benchmarks/README.md``).

    The validation errors that confirm a candidate, and those reported, are measured against the
    validation channels as recorded (``validate.recorded`` when preprocessing filtered or averaged
    them), along the derived motion.
    """
    # the search's candidate columns have no per-channel mask: a sample with a masked channel leaves it whole
    train, validate = whole_rows(train), whole_rows(validate)
    candidates = _checked_candidates(model, train, validate, candidates, alpha, min_improvement)
    floor_for_validation(validate, model.channels, noise_floor)  # a floor of the wrong kind refused before the search
    worker_count(jobs, 0)  # so is a wrong number of processes
    if stopping_rule is None:
        stopping_rule = provisional_stopping_rule
    with step("declared model identified"):
        before = identify(model, train, validate)
    weights = before.estimate.weights if before.estimate.method == "wls" else 1.0 / before.estimate.channel_variance
    # errors against the channels as recorded, along the derived motion
    fits = RecordFits(model, declared_regressor(model, before), train, validate.as_recorded, delay, stopping_rule,
                      shaped=before.shaped_fit is not None, jobs=jobs, unseen_stretches=unseen_stretches)
    blocks, rejected = candidate_blocks(model, candidates,  # a law even in speed needs another motion
                                        repeated=repeated_motion(train, validate) <= REPEAT_FRACTION)
    settings = SearchSettings(alpha, min_improvement, max_effects, len(candidates) + (delay is not None),  # the delay too
                              same_effect_adopted=True)
    with step("forward selection"):
        outcome = RunnerUpSearch(model, blocks, rejected, fits, weights, settings).run()
    final = functools.partial(_diagnosis, model, before, outcome, blocks, fits.delay, train, validate, noise_floor,
                              len(candidates), settings)
    ahead = None if fits.delay.adopted is not None else RivalAhead.planned(
        model, outcome, blocks, build_model(model.robot, model.kind, model.effects + tuple(
            item.effect for item in outcome.adopted)))
    with step("joint refit of the chosen model, residual statistics and the runner-up"):
        if ahead is None:
            return with_runner_up(final(), outcome, blocks, train, validate)  # the best rival not chosen, fitted
        # with no delay to move the records, the best rival's fit does not wait for the joint refit: side by side
        diagnosis, ahead = run_tasks([final, functools.partial(ahead.fitted, in_memory_fitter(train, validate, None))],
                                     worker_count(jobs, 2), shared=[model, model.robot, ahead.model, *blocks.values()])
        return with_runner_up(diagnosis, outcome, blocks, train, validate, ahead)


def _checked_candidates(model: IdentificationModel, train: Measurements, validate: Measurements,
                        candidates: Iterable[Effect] | None, alpha: float, min_improvement: float) -> tuple[Effect, ...]:
    """The candidates (by default :func:`default_candidates` and the traced joint pairs), the
    settings checked."""
    for name, data in (("train", train), ("validate", validate)):
        if not isinstance(data, Measurements):
            raise TypeError(f"{name} must be Measurements (diagnose confirms every effect on held-out data), "
                            f"got {type(data).__name__}")
    if not 0 < alpha < 1:
        raise ValueError(f"alpha must lie in (0, 1), got {alpha}")
    if not 0 <= min_improvement < 1:
        raise ValueError(f"min_improvement must lie in [0, 1), got {min_improvement}")
    candidates = tuple(default_candidates(model) + coupling_candidates(model, train=train, held_out=validate)  # coulomb[q5+q6]
                       if candidates is None else candidates)
    for candidate in candidates:
        if not isinstance(candidate, Effect):
            raise TypeError(f"candidate {candidate!r} is not an effect")
    return candidates


def _diagnosis(model: IdentificationModel, before: IdentificationResult, outcome: SearchOutcome,
               blocks: dict[int, Block], moved: DelaySearch, train: Measurements, validate: Measurements,
               noise_floor: NoiseFloor | None, n_candidates: int, settings: SearchSettings) -> Diagnosis:
    """Step 5: the joint refit of what the search adopted (the delay searched again along the records
    as given), findings within their noise there dropped; the terms it pinned, the findings dropped and
    the delay not adopted reported with the rejected candidates."""
    selected, after, pinned, dropped = refit_significant(model, before, outcome.adopted, moved, train, validate,
                                                         outcome.weights, outcome.current.validation_error,
                                                         settings.min_improvement, settings.threshold)
    # each joint's diagnosed effects against the plain law, on that joint's validation error (another motion only);
    # a mixed model refused only on the unconstrained fits' score is kept as the diagnosis's ``swap``, to be judged
    # on the default answer's candidates (:mod:`estimation.diagnosis.plain_laws`)
    mixed = plain_law_choice(model, after, [effect for effect, _, _ in selected], train, validate,
                             min_improvement=settings.min_improvement, max_effects=settings.max_effects,
                             threshold=settings.threshold, keep_refused=True)
    if mixed is not None and not mixed.adopted:
        return replace(_built(model, before, moved, train, validate, noise_floor, n_candidates, blocks, outcome,
                              selected, after, pinned, dropped, None),
                       swap=_built(model, before, moved, train, validate, noise_floor, n_candidates, blocks, outcome,
                                   selected, after, pinned, dropped, mixed))
    return _built(model, before, moved, train, validate, noise_floor, n_candidates, blocks, outcome, selected, after,
                  pinned, dropped, mixed)


def _built(model: IdentificationModel, before: IdentificationResult, moved: DelaySearch, train: Measurements,
           validate: Measurements, noise_floor: NoiseFloor | None, n_candidates: int, blocks: dict[int, Block],
           outcome: SearchOutcome, selected: list, after: IdentificationResult, pinned: Any, dropped: Any,
           mixed: PlainLawChoice | None) -> Diagnosis:
    """The diagnosis of the joint refit ``after`` (its ``selected`` effects), or, with ``mixed``, of the mixed
    model that replaces diagnosed effects by the plain law (step 5 of :func:`_diagnosis`)."""
    rejected = dict(outcome.rejected)
    if mixed is not None:
        after = mixed.after
        selected = [(effect, test.p_value, test.f_statistic) for effect in mixed.effects
                    for test in (estimate_test(after.estimate, effect.parameter_names(model.robot)),)]
        for position, (effect, reason) in enumerate(mixed.dropped):
            index = next((index for index, block in blocks.items() if block.effect == effect),
                         n_candidates + len(pinned) + 1 + position)
            rejected[index] = RejectedEffect(effect.name, effect_channels(effect, model), reason,
                                             candidate_label(effect))
    final = [effect for effect, _, _ in selected]
    for item, reason in dropped:
        rejected[item.index] = RejectedEffect(item.effect.name, effect_channels(item.effect, model), reason,
                                              candidate_label(item.effect))
    for index, block in blocks.items():  # removed or dropped, then back in the mixed model's plain law: not rejected
        if block.effect in final:
            rejected.pop(index, None)
    for position, term in enumerate(term for term in pinned if term.found):
        effect = next((block.effect for block in blocks.values() if term.parameter in block.names
                       and candidate_label(block.effect) == term.effect), None)  # a law simplified after selection: none
        rejected[n_candidates + position] = RejectedEffect(
            term.effect if effect is None else effect.name, () if effect is None else effect_channels(effect, model),
            "added, but its estimate turned negative in the joint refit "
            f"({term.parameter} = {term.value:.4g} ± {term.std:.2g}): dropped", term.effect)
    untested = outcome.untested
    delay_reason = moved.not_adopted_reason(untested=untested if untested.startswith("not tested") else
                                            "not tested: the search ended before a round tried it")
    if delay_reason is not None:
        rejected[n_candidates + len(pinned)] = RejectedEffect("delay", tuple(model.channels), delay_reason, "delay")
    return Diagnosis(
        effects=tuple(found_effect(after, effect, p_value, statistic, model) for effect, p_value, statistic in selected)
        + found_delay(after, moved.adopted, model),
        rejected=tuple(rejected[index] for index in sorted(rejected)),
        before=before,
        after=after,
        residuals=residual_statistics(before),
        statistics=residual_report(before, after, train, validate, noise_floor),
        pinned=pinned,
    )
