"""The candidates of the streamed diagnosis (:mod:`estimation.streaming.diagnosis`): their column
blocks, their shapes and where their columns sit in the sums.

Shaped laws (``coulomb:tanh``, ``stribeck:velocity``, ``sigmoid``, ``ripple``) cannot be summed at an
unknown shape: :func:`shape_search` searches each one's shape parameters on the training subsample,
against the declared model (the in-memory diagnosis's first round,
:func:`estimation.diagnosis.candidates.trials.fit_or_reason`, at the channel weights of the subsample's
identification); :func:`refined_shapes` then runs the in-memory search on the subsample (confirmed on the
validation subsample), whose rounds refine the best-ranked shapes against the model of the moment, and takes each
law's last shape there; the sums are then taken at those shapes (:class:`StreamedCandidates`).
"""

from __future__ import annotations

import pickle
import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace

import numpy as np

from dynamics.channels import is_joint_torque, torque_joint
from dynamics.effects.linear import Effect
from dynamics.effects.shaped import FRICTION_LAWS, shape_parameters
from dynamics.measurements import Measurements
from dynamics.models import IdentificationModel
from dynamics.transmission import Transmission
from estimation.diagnosis.candidates.trials import candidate_label, fit_or_reason
from estimation.diagnosis.candidates.coupling import coupling_candidates
from estimation.diagnosis.forward_selection import (SearchOutcome, SearchSettings, candidate_blocks,
                                                    declared_friction_joints)
from estimation.diagnosis.runner_up import RunnerUpSearch
from estimation.diagnosis.final_refit import refit_significant
from estimation.diagnosis.sign_constraints import PinnedTerm
from estimation.diagnosis.plain_laws import PlainLawChoice, plain_law_choice
from estimation.diagnosis.record_fits import RecordFits, declared_regressor
from estimation.diagnosis.rules.robust_test import estimate_test
from estimation.diagnosis.search_fits import AdoptedEffect
from estimation.diagnosis.rules.stopping_rules import provisional_stopping_rule
from estimation.identification.repeated_motion import REPEAT_FRACTION, repeated_motion
from estimation.diagnosis.results import RejectedEffect
from estimation.diagnosis.search import default_candidates
from estimation.estimators.effect_blocks import Block, States
from estimation.estimators.separable_least_squares import FixedPart, solve_linear
from estimation.identification.fit import identify
from estimation.identification.shaped import ShapeValue
from estimation.preprocessing.delay import DelayBounds
from estimation.streaming.diagnosis_sums import ColumnLayout

__all__ = ["SearchedDelay", "StreamedCandidates", "shape_search", "streamed_candidates", "subsample_search"]


def shape_search(model: IdentificationModel, blocks: dict[int, Block], subsample: Measurements,
                  weights: np.ndarray) -> tuple[dict[int, np.ndarray], dict[int, RejectedEffect]]:
    """Each shaped law's shape on the subsample against the declared model (the in-memory first
    round), and the laws whose search failed."""
    fixed = FixedPart.from_arrays(model.evaluate_base(subsample.q, subsample.dq, subsample.ddq),
                                  subsample.channels(model.channels))
    states = States(subsample.q, subsample.dq, subsample.ddq)
    rss = solve_linear(fixed, [], states, [], weights).rss
    declared = declared_friction_joints(model)
    shapes, failed = {}, {}
    for index, block in blocks.items():
        if block.n_shape == 0:
            shapes[index] = np.zeros(0)
            continue
        joints = {torque_joint(model.channels[row]) for row in block.rows if is_joint_torque(model.channels[row])}
        if block.effect.name in FRICTION_LAWS and joints & declared:
            shapes[index] = np.array([p.starts[0] for p in block.parameters], dtype=float)  # rejected in the loop
            continue
        outcome = fit_or_reason((index,), [block], fixed, states, weights, rss, None, search=False)
        if isinstance(outcome, str):
            failed[index] = RejectedEffect(block.effect.name, tuple(model.channels[r] for r in block.rows),
                                           outcome + " (on the subsample)", candidate_label(block.effect))
        else:
            shapes[index] = outcome.fit.shape
    return shapes, failed


@dataclass(frozen=True)
class SearchedDelay:
    """The delay candidate of the subsample's search (:class:`~estimation.diagnosis.candidates.delay_search.DelaySearch`
    on the subsample, as in memory): the delay its final refit holds (``None``: none adopted) and, when none is, why
    (``None`` too when no delay was searched)."""

    value: ShapeValue | None = None
    reason: str | None = None


def subsample_search(model: IdentificationModel, blocks: dict[int, Block], rejected: dict[int, RejectedEffect],
                     shapes: dict[int, np.ndarray], sample: Measurements, validation: Measurements,
                     search: SearchSettings, delay: DelayBounds | None = None, jobs: int | None = 1
                     ) -> tuple[dict[int, np.ndarray], SearchOutcome, SearchedDelay, tuple[PinnedTerm, ...]]:
    """The in-memory diagnosis's search (:class:`~estimation.diagnosis.runner_up.RunnerUpSearch` on
    :class:`~estimation.diagnosis.record_fits.RecordFits`) and its final refit
    (:func:`~estimation.diagnosis.final_refit.refit_significant`) on the training ``sample`` confirmed on the
    ``validation`` sample (prepared; its channels as recorded for the errors): ``(shapes, outcome, pinned)``, each shaped
    law's shape as that search leaves it and its outcome as the in-memory diagnosis ends it: the findings the final
    refit drops as within their noise moved to the rejected ones, a law it replaces by its simpler law (the sign law
    of a smoothed Coulomb law, Coulomb's of an unsupported Stribeck law) replaced by that law's candidate, and the
    mixed model's findings when it validates better (:func:`~estimation.diagnosis.plain_laws.plain_law_choice`: each
    joint's diagnosed effects against the plain law).

    In each round the best-ranked shapes are searched again against the model of the moment
    (:meth:`~estimation.diagnosis.record_fits.RecordFits.refine`) and the final refit fits the found shapes jointly:
    a law's shape is that of the model it joins, not the declared model's (``shapes``: the first round's, kept where
    the search never fitted the law again). A found law's shape is the final refit's (where the refit kept the law;
    else the one it was adopted at), any other law's its last optimum. The search's Wald tests are those of memory
    (HAC, the shape directions included), on the subsample. ``delay``: where the delay between torques and motion is
    searched, as in memory (its grid, its trials and adoption rule in the rounds, searched again by the final refit;
    ``None``: not tried): the :class:`SearchedDelay` the refit (or the mixed model) holds. ``jobs``: the processes a
    round's candidate fits run in, as in memory (:class:`~estimation.diagnosis.record_fits.RecordFits`; the same
    answer at any count). When both samples hold their whole records, this is the in-memory search and refit.
    ``pinned``: the declared model's terms the final refit held at zero (a negative friction,
    :func:`~estimation.diagnosis.sign_constraints.pin_wrong_signs`), which the mixed model inherits in memory."""
    before = identify(model, sample, validation)
    weights = before.estimate.weights if before.estimate.method == "wls" else 1.0 / before.estimate.channel_variance
    fits = RecordFits(model, declared_regressor(model, before), sample, validation.as_recorded, delay,
                      provisional_stopping_rule, shaped=before.shaped_fit is not None, jobs=jobs)
    outcome = RunnerUpSearch(model, blocks, rejected, fits, weights, search).run()
    refined = dict(shapes)
    for group, fit in fits.previous.items():
        if len(group) == 1 and group[0] in refined and blocks[group[0]].n_shape:
            refined[group[0]] = np.asarray(fit.shape, dtype=float)[:blocks[group[0]].n_shape]
    selected, after, pinned, dropped = refit_significant(model, before, outcome.adopted, fits.delay, sample, validation,
                                                    outcome.weights, outcome.current.validation_error,
                                                    search.min_improvement, search.threshold)
    gone = {id(item): reason for item, reason in dropped}
    rejected_now = {**outcome.rejected, **{item.index: _rejected(model, item, gone[id(item)] + " (on the subsample)")
                                          for item in outcome.adopted if id(item) in gone}}
    kept = [item for item in outcome.adopted if id(item) not in gone]
    found = _as_refitted(kept, selected, blocks)
    for item, law in zip(kept, found):
        if law is not item:
            rejected_now[item.index] = _rejected(model, item, "added, but the final refit (on the subsample) holds its "
                                                 f"simpler law {candidate_label(law.effect)}: replaced")
    # each joint's diagnosed effects against the plain law on that joint's validation error, as in memory
    mixed = plain_law_choice(model, after, [effect for effect, _, _ in selected], sample, validation,
                             min_improvement=search.min_improvement, max_effects=search.max_effects,
                             threshold=search.threshold)
    if mixed is not None and mixed.adopted:
        after, found = mixed.after, _as_mixed(found, mixed, blocks, model, rejected_now)
    fitted = {value.name: float(value.value) for value in after.shapes}
    for item in found:
        names = [parameter.name for parameter in shape_parameters(item.effect, model.robot)]
        if names and item.index in refined and all(name in fitted for name in names):
            refined[item.index] = np.array([fitted[name] for name in names])
    rejected_now = {index: reason for index, reason in rejected_now.items()
                    if index not in {item.index for item in found}}
    untested = outcome.untested
    reason = fits.delay.not_adopted_reason(untested=untested if untested.startswith("not tested") else
                                           "not tested: the search ended before a round tried it")  # as in memory
    searched = SearchedDelay(after.delay if fits.delay.adopted is not None else None,
                             reason)
    return refined, replace(outcome, adopted=tuple(found), rejected=rejected_now), searched, tuple(
        term for term in pinned if not term.found)


def _rejected(model: IdentificationModel, item: AdoptedEffect, reason: str) -> RejectedEffect:
    return RejectedEffect(item.effect.name, tuple(model.channels[row] for row in item.block.rows), reason,
                          candidate_label(item.effect))


def _as_mixed(found: list[AdoptedEffect], mixed: PlainLawChoice, blocks: dict[int, Block],
              model: IdentificationModel, rejected: dict[int, RejectedEffect]) -> list[AdoptedEffect]:
    """The findings of the mixed model (:func:`~estimation.diagnosis.plain_laws.plain_law_choice`): the diagnosed
    effects it keeps, then its plain laws as their candidates (those that are candidates); the diagnosed effects it
    replaced added to ``rejected`` with its reason."""
    by_effect = {block.effect: index for index, block in blocks.items()}
    items = {item.effect: item for item in found}
    for effect, reason in mixed.dropped:
        if effect in items:
            rejected[items[effect].index] = _rejected(model, items[effect], reason + " (on the subsample)")
    adopted = []
    for effect in mixed.effects:
        if effect in items:
            adopted.append(items[effect])
        elif effect in by_effect:
            index = by_effect[effect]
            test = estimate_test(mixed.after.estimate, effect.parameter_names(model.robot))
            adopted.append(AdoptedEffect(index, blocks[index], np.zeros(blocks[index].n_shape), test.p_value,
                                         test.f_statistic))
    return adopted


def _as_refitted(kept: list[AdoptedEffect], selected: Sequence[tuple[Effect, float, float]],
                 blocks: dict[int, Block]) -> list[AdoptedEffect]:
    """The findings ``kept`` with those the final refit replaced by a simpler law (a smoothed Coulomb law by the sign
    law, :mod:`estimation.diagnosis.limit_laws`; an unsupported Stribeck law by Coulomb's) replaced by that law's
    candidate, where it is one (``selected``: the refit's findings, in the order of ``kept``)."""
    if len(selected) != len(kept):
        return kept
    by_effect = {block.effect: index for index, block in blocks.items()}
    found = []
    for item, (effect, p_value, statistic) in zip(kept, selected):
        index = by_effect.get(effect) if effect != item.effect else None
        found.append(item if index is None else
                     AdoptedEffect(index, blocks[index], np.zeros(blocks[index].n_shape), p_value, statistic))
    return found


@dataclass(frozen=True)
class StreamedCandidates:
    """The candidates with columns in the sums, their fixed shapes and where their columns are."""

    blocks: dict[int, Block]
    shapes: dict[int, np.ndarray]
    rejected: dict[int, RejectedEffect]
    n_candidates: int
    layout: ColumnLayout
    plan: bytes  # the pickled effects and shapes the workers evaluate
    outcome: SearchOutcome | None = None  # the search on the subsample (:func:`subsample_search`)
    delay: SearchedDelay = SearchedDelay()  # its delay candidate
    pinned: tuple[PinnedTerm, ...] = ()  # the declared terms its final refit held at zero (:func:`subsample_search`)

    @property
    def columns(self) -> dict[int, tuple[int, ...]]:
        return {index: self.layout.blocks[slot] for slot, index in enumerate(self.blocks)}

    def final_plan(self, chosen: list[int]) -> bytes:
        return pickle.dumps(([self.blocks[i].effect for i in chosen], [self.shapes[i] for i in chosen]))


def streamed_candidates(model: IdentificationModel, candidates: Sequence[Effect] | None, sample: Measurements,
                        lap: Callable[[str], None], transmission: Transmission | None = None,
                        validation: Measurements | None = None, search: SearchSettings | None = None,
                        delay: DelayBounds | None = None, jobs: int | None = 1,
                        screen: Callable[[tuple[Effect, ...], Measurements, Measurements | None],
                                         tuple[Effect, ...]] | None = None) -> StreamedCandidates:
    """The candidates (default: :func:`~estimation.diagnosis.search.default_candidates`, the pairs
    traced on the subsample and the coupled motors' laws of ``transmission``, as in memory) and their shapes
    searched on the ``sample`` (``lap``: called with the name of each stage done); with a ``validation`` sample
    and the ``search`` settings, the in-memory search and final refit on the samples (:func:`subsample_search`):
    the shapes as it leaves them, its outcome kept (:attr:`StreamedCandidates.outcome`), and there the delay searched
    in ``delay`` as in memory (:attr:`StreamedCandidates.delay`; counted among the tests), its rounds' fits in ``jobs``
    processes. ``screen``: given the candidates and the training and validation samples, the candidates tried (the
    caller's checks on the samples, such as the mount's: ``oed diagnose`` tries no law of a joint's position alone
    where a turned gravity explains the load)."""
    searching = validation is not None and search is not None
    candidates = tuple(default_candidates(model) + coupling_candidates(
        model, transmission, train=sample, held_out=validation if searching else None)  # as in memory
                       if candidates is None else candidates)
    if screen is not None:
        candidates = tuple(screen(candidates, sample, validation))
    # a law even in speed needs another motion than the training's (as in memory; here from the subsamples)
    blocks, rejected = candidate_blocks(model, candidates, repeated=validation is not None and repeated_motion(
        sample, validation) <= REPEAT_FRACTION)
    lap("subsample_pass")
    outcome, failed, searched, pinned = None, {}, SearchedDelay(), ()
    if searching:
        # the search's first round searches every shape from its grid, as in memory (a law whose search fails there
        # is tried again in later rounds); a law it never fitted keeps its parameters' starts
        starts = {index: np.array([parameter.starts[0] for parameter in block.parameters], dtype=float)
                  for index, block in blocks.items()}
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # the subsample's own search: its warnings are not the record's
            shapes, outcome, searched, pinned = subsample_search(
                model, blocks, rejected, starts, sample, validation,
                replace(search, n_tests=len(candidates) + (delay is not None)), delay, jobs)  # the delay too
        lap("subsample_search")
    else:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # the subsample's own fit: its warnings are not the record's
            reference = identify(model, sample).estimate
        weights = reference.weights if reference.method == "wls" else 1.0 / reference.channel_variance
        shapes, failed = shape_search(model, blocks, sample, weights)
        lap("shape_search")
        blocks = {index: block for index, block in blocks.items() if index not in failed}
    order = sorted(blocks)
    plan = pickle.dumps(([blocks[i].effect for i in order], [shapes[i] for i in order]))
    return StreamedCandidates({i: blocks[i] for i in order}, shapes, {**rejected, **failed}, len(candidates),
                       ColumnLayout.build(model, [blocks[i] for i in order]), plan, outcome, searched, pinned)
