"""The diagnosis's search as one object: the current model, its fit, the candidates and the last verdict
on each, move by move.

The model is a choice, per joint (and joint combination), among the friction law families (none, the
sign law, ``coulomb:tanh``, ``stribeck:velocity``, ``sigmoid``) plus offset, spring, armature, ripple, a viscous
slope differing by direction (``viscous:direction``) and the delay. :class:`DiagnosisSearch` moves between such
models (steps 2–4 of :mod:`estimation.diagnosis.search`):

* **remove** an adopted effect whose coefficients are within their noise in the current model
  (:func:`estimation.diagnosis.search_moves.removable`) unless removing it raises the validation error of a
  channel it acts on by more than ``min_improvement`` (:func:`estimation.diagnosis.search_moves.removal_raises`:
  an effect leaves on the evidence it was adopted on, training significance and held-out error);
* **add** a candidate group, or **replace** an adopted law by another on its joint
  (:func:`estimation.diagnosis.search_moves.replaced_by`): each group is fitted against the current model
  (without the law it replaces), screened by the nested F test at a Bonferroni threshold, ranked by its
  BIC against the current model (ties by what it adds, never by the order of the candidate list), and
  adopted when the Wald test of its block from the HAC covariance is significant at the same
  threshold (:mod:`estimation.diagnosis.rules.robust_test`: the statistic the reported p-values and
  standard deviations come from), its estimate is physical (:func:`wrong_sign`, a spring that is no
  offset in disguise), a law on a joint combination explains more than the per-joint laws of its kind on
  its joints that the model lacks (:meth:`DiagnosisSearch.own_laws_explain`: no ``inertia[q5+q6]`` where
  the wrist holds two armatures) and it lowers the weighted validation error by ``min_improvement``, summed over every
  channel or over the channels it acts on (:func:`estimation.diagnosis.confirmation.own_rows_gain`: a joint's law
  is not diluted by the other joints) with the sum not rising, without making a channel it acts on worse;

until no move improves the model; a model once left is never returned to, nor a candidate replaced by another
law. A candidate removed as within its noise may return once, after the model gained an effect it did not hold
when the candidate left (so that the search ends: at most four moves a candidate): an effect judged within its
noise beside a model still missing large laws (an offset beside a joint's absent Coulomb law, whose residual
inflates the HAC covariance) is not shut out for good, where a later candidate would stand in for it (an armature
on the parallelogram arm of ``tests/test_unseen_robot_rigs.py``, 14 standard deviations, named in place of the
offset removed three moves before). Every verdict is against the model of the
moment and is reconsidered after each move (a law refused beside another, a spring
without an offset, a candidate the current columns absorbed). The fits themselves come from a
:class:`Fits` strategy:

(:class:`estimation.diagnosis.search_fits.Fits`):

* :class:`estimation.diagnosis.record_fits.RecordFits`: the records in memory (per-channel Gram
  matrices of the current columns, variable projection of shaped laws, the delay candidate);
* :class:`estimation.streaming.selection.SummedFits`: summed normal equations of files read in
  chunks (shapes fixed beforehand).
"""

from __future__ import annotations

import functools
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from dynamics.runtime.progress import step
from dynamics.effects.linear import Effect
from dynamics.effects.shaped import FRICTION_LAWS
from dynamics.models import IdentificationModel
from estimation.diagnosis.candidates.trials import (Trial, candidate_label, direction_slopes, joints_of, nested_test,
                                                    wrong_sign)
from estimation.diagnosis.confirmation import CandidateComparison, channels_made_worse, own_rows_gain
from estimation.diagnosis.candidates.coupling import combination_groups
from estimation.diagnosis.candidates.delay import DelayTrial
from estimation.diagnosis.results import RejectedEffect
from estimation.diagnosis.rules.robust_test import WaldTest
from estimation.diagnosis.search_fits import AdoptedEffect, CurrentFit, Fits, TrialRequest
from estimation.diagnosis.search_moves import (declared_conflict, move_bic, removable, removal_raises, replaced_by,
                                               replaced_in_place, tie_key)
from estimation.diagnosis.rules.selection_rules import candidate_groups, offsets_beat_springs, own_laws_lacking
from estimation.estimators.effect_blocks import Block, NoRowsError

__all__ = ["DiagnosisSearch", "SearchOutcome", "SearchSettings", "candidate_blocks"]

#: trials a round's first batch of confirmations worked out side by side holds (:meth:`DiagnosisSearch.confirmed_ahead`)
FIRST_BATCH = 8

STOPPED_AT_FLOOR = "not tested: the stopping rule ended the search (no channel significantly above its noise floor)"


@dataclass(frozen=True)
class SearchSettings:
    """The search's settings: F-test level ``alpha`` over ``n_tests`` candidates (Bonferroni), the
    smallest relative improvement of the weighted validation error, the cap on effects, whether
    Coulomb and viscous laws on one joint combination compete as one candidate (one Coulomb law a
    combination), and whether a candidate whose effect (the same object) was adopted under another
    index counts as adopted at the end (the in-memory diagnosis's rule; the streamed one's counts
    indices alone: such a candidate is reported with the untested ones)."""

    alpha: float
    min_improvement: float
    max_effects: int
    n_tests: int
    combinations: bool = True
    same_effect_adopted: bool = False

    @property
    def threshold(self) -> float:
        return self.alpha / max(self.n_tests, 1)


@dataclass(frozen=True)
class SearchOutcome:
    """What a search ends with: the adopted effects in order, every other candidate and why it was
    not adopted, the weights and fit of the last adopted model, and the reason given to candidates
    never tested."""

    adopted: tuple[AdoptedEffect, ...]
    rejected: Mapping[int, RejectedEffect]
    stopped_at_floor: bool
    weights: NDArray[np.float64]
    current: CurrentFit
    untested: str


#: why a law even in speed is no candidate where the validation record repeats the training motion
REPEATED_PATH = ("not a candidate: the validation record repeats the training motion, and along one path a law even in "
                 "speed (|dq|, the same both ways) is a function of the path's positions as a position law (an offset, "
                 "a spring, a ripple) is: only a record at other speeds over those positions tells them apart, and a "
                 "law confirmed on the repeat would scale with speed where the effect may not; give the validation a "
                 "record of another trajectory")
#: the candidates even in speed: only another motion tells them from a law of the joint's position
EVEN_IN_SPEED = ("viscous:direction",)


def candidate_blocks(model: IdentificationModel, candidates: Sequence[Effect], repeated: bool = False
                     ) -> tuple[dict[int, Block], dict[int, RejectedEffect]]:
    """Each candidate's column block by index, and the candidates without rows in ``model``; with ``repeated`` (the
    validation record repeats the training motion:
    :func:`estimation.identification.repeated_motion.repeated_motion`), the laws even in speed
    (:data:`EVEN_IN_SPEED`) set aside too (:data:`REPEATED_PATH`: on the real EMPS, whose validation file repeats its
    estimation motion, ``viscous:direction`` took the place of the offset; on the KUKA LWR4+, whose run 2 repeats run
    1, it took that of joint 7's ripple and predicted the twice-as-fast run 3 9x worse on that joint)."""
    blocks: dict[int, Block] = {}
    rejected: dict[int, RejectedEffect] = {}
    for index, candidate in enumerate(candidates):
        if not isinstance(candidate, Effect):
            raise TypeError(f"candidate {candidate!r} is not an effect")
        try:
            block = Block(model.kind, model.robot, candidate, model.n_channels)
        except NoRowsError:
            rejected[index] = RejectedEffect(candidate.name, (), "has no rows in this model", candidate_label(candidate))
            continue
        if repeated and candidate.name in EVEN_IN_SPEED:
            rejected[index] = RejectedEffect(candidate.name, tuple(model.channels[row] for row in block.rows),
                                             REPEATED_PATH, candidate_label(candidate))
            continue
        blocks[index] = block
    return blocks, rejected


def declared_friction_joints(model: IdentificationModel) -> set[int]:
    """The joints the declared model already gives a Coulomb-like friction law."""
    return {joint for effect in model.effects if effect.name in FRICTION_LAWS
            for joint in (range(model.robot.n_joints) if getattr(effect, "joints", None) is None else effect.joints)}


class DiagnosisSearch:
    """The search over models of candidate effects (module docstring).

    Parameters
    ----------
    model
        The declared model.
    blocks, rejected
        The candidates with columns by index, and those already set aside (:func:`candidate_blocks`).
    fits
        How column blocks are fitted (:class:`Fits`).
    weights
        The declared model's channel weights ``w_c = 1/σ_c²``; re-estimated with each move.
    settings
        :class:`SearchSettings`.
    """

    def __init__(self, model: IdentificationModel, blocks: dict[int, Block], rejected: Mapping[int, RejectedEffect],
                 fits: Fits, weights: NDArray[np.float64], settings: SearchSettings) -> None:
        self.model, self.blocks, self.fits, self.settings = model, blocks, fits, settings
        self.rejected: dict[int, RejectedEffect] = dict(rejected)  # no rows: never tried
        self.verdicts: dict[int, str] = {}  # each candidate's last verdict against the model of the moment
        self.failed: dict[tuple[int, ...], str] = {}  # groups the current columns absorb (until a removal)
        self.groups = candidate_groups(blocks, model)
        if settings.combinations:
            self.groups += combination_groups({index: block.effect for index, block in blocks.items()})
        self.friction_joints = declared_friction_joints(model)
        self.adopted: list[AdoptedEffect] = []
        self.weights = weights
        self.current = fits.fit_current(weights)
        self.visited = {self.key(())}
        self.baselines: dict[tuple[int, ...], Trial] = {}  # this round's adopted laws refitted in their places
        self.departed: set[int] = set()  # candidates replaced, or removed a second time: they do not return
        self.removed: dict[int, frozenset[int]] = {}  # removed once: the other effects the model held then
        self.returned: set[int] = set()  # removed once and adopted again
        self.rounds = 0
        self.stopped_at_floor = False

    @property
    def n_effects(self) -> int:
        """Effects in the current model (the delay counts as one)."""
        return len(self.adopted) + self.fits.delay_adopted

    def key(self, indices: Iterable[int], delay: bool | None = None) -> tuple[frozenset[int], bool]:
        """A model of the search: its candidate indices and whether the records move by the delay."""
        return frozenset(indices), self.fits.delay_adopted if delay is None else delay

    def run(self) -> SearchOutcome:
        """Moves until none improves the model: removals first, then, while the stopping rule allows,
        the best-ranked confirmed addition or replacement."""
        for _ in range(4 * (self.settings.max_effects + len(self.groups)) + 4 if self.groups else 0):  # models never repeat
            if self.remove_one():
                continue
            if not self.fits.keep_searching(self.current, tuple(candidate_label(a.effect) for a in self.adopted)):
                self.stopped_at_floor = True
                break
            added = self.one_round()
            if added is None:
                break
            self.adopt(*added)
        return self.outcome()

    def one_round(self) -> tuple[Trial | DelayTrial, Any] | None:
        """One round: every group fitted, the best-ranked confirmed one (with its comparison), or ``None``."""
        with step(f"round {self.rounds + 1} of the search ({len(self.adopted)} effect(s) adopted so far)"):
            trials = self.fit_candidates()
            trials = self.fits.refine(trials, self.current, self.weights, self.rounds == 0)
            self.rounds += 1
            springs_beaten = offsets_beat_springs(trials, self.model, self.offset_joints())
            delay_trials = self.fits.delay_trials(self.adopted, self.weights, self.current.rss, trials)
            return self.choose(trials + delay_trials, springs_beaten)

    def offset_joints(self) -> set[tuple[int, ...]]:
        """The joints whose offset the current model holds (declared or adopted)."""
        offsets = [effect for effect in self.model.effects if effect.name == "offset"]
        joints = {(joint,) for effect in offsets
                  for joint in (range(self.model.robot.n_joints) if effect.joints is None else effect.joints)}
        return joints | {joints_of(item.block, self.model) for item in self.adopted if item.effect.name == "offset"}

    def in_model(self, group: tuple[int, ...]) -> bool:
        adopted = {item.index for item in self.adopted}
        effects = {id(item.effect) for item in self.adopted}
        return any(index in adopted or id(self.blocks[index].effect) in effects for index in group)

    def fit_candidates(self) -> list[Trial]:
        """Each group not in the model fitted against it, or against it without the laws the group
        would replace (a lone candidate that cannot be gets the reason as its verdict). The fits are
        independent of each other (:meth:`Fits.trials` may run them side by side)."""
        requests: list[TrialRequest] = []
        reduced: dict[tuple[int, ...], float] = {}
        for group in self.groups:
            if any(index in self.rejected or index in self.departed or self.held_out(index) for index in group) \
                    or self.in_model(group):
                continue  # a candidate that left the model returns at most once: the search ends
            members = [self.blocks[index] for index in group]
            reason = declared_conflict(members, self.model, self.friction_joints, self.settings.combinations)
            without = replaced_by(members, self.adopted, self.model, self.settings.combinations)
            if reason is None and self.n_effects + len(group) - len(without) > self.settings.max_effects:
                reason = f"not tested: {self.settings.max_effects} effects already added"
            if reason is None and self.after_key(group, without) in self.visited:
                continue  # a model already left: its verdict stands
            if reason is None:
                reason = self.failed.get(group)
            if reason is None:
                if without not in reduced:
                    reduced[without] = self.fits.fit_current(self.weights, without).rss if without else self.current.rss
                requests.append(TrialRequest(group, tuple(members), reduced[without], without))
            else:
                requests.append(TrialRequest(group, tuple(members), np.nan, without, reason))
        fitted = iter(self.fits.trials([request for request in requests if request.reason is None], self.weights,
                                       self.current))
        trials = []
        for request in requests:
            outcome = next(fitted) if request.reason is None else request.reason
            if isinstance(outcome, str):
                if outcome.startswith("not identifiable"):
                    self.failed[request.group] = outcome
                if len(request.group) == 1:
                    self.verdicts[request.group[0]] = outcome
                continue
            trials.append(outcome)
        return trials + self.refreshed(reduced)

    def held_out(self, index: int) -> bool:
        """Whether a candidate removed once waits: the model has gained no effect since it left."""
        return index in self.removed and {item.index for item in self.adopted} <= self.removed[index]

    def refreshed(self, reduced: dict[tuple[int, ...], float]) -> list[Trial]:
        """Each adopted shaped law fitted again in its own place (the current model without it), the
        baseline of the laws that would replace it: its shape was fitted against the model of the moment
        it was adopted, and a replacement must do better than it refitted, not than it stale."""
        trials = []
        for item in self.adopted:
            if not item.block.n_shape:
                continue
            without = (item.index,)
            if without not in reduced:
                reduced[without] = self.fits.fit_current(self.weights, without).rss
            outcome = self.fits.trial(without, [item.block], self.weights, reduced[without], without)
            if not isinstance(outcome, str):
                trials.append(outcome)
        return trials

    def after_key(self, group: tuple[int, ...], without: tuple[int, ...]) -> tuple[frozenset[int], bool]:
        return self.key(({item.index for item in self.adopted} - set(without)) | set(group))

    def rank(self, trial: Trial | DelayTrial) -> tuple[float, tuple[str, ...]]:
        """Moves by their BIC against the current model, ties by what they add (never by list order)."""
        if isinstance(trial, DelayTrial):
            return trial.bic, ("delay",)
        removed = sum(item.block.n_linear + item.block.n_shape for item in self.adopted if item.index in trial.without)
        return (move_bic(trial.rss, self.current.rss, trial.n_parameters, removed, self.fits.n_rows),
                tie_key(trial.blocks))

    def choose(self, trials: list[Trial | DelayTrial], springs_beaten: dict[tuple[int, ...], str]
               ) -> tuple[Trial | DelayTrial, Any] | None:
        """The best-ranked significant trial confirmed on validation, with its comparison (a replacement
        also against the law it replaces refitted in its place: :meth:`refreshed`)."""
        self.baselines = {trial.group: trial for trial in trials
                          if not isinstance(trial, DelayTrial) and trial.without and trial.group == trial.without}
        ranked = [trial for trial in sorted(trials, key=self.rank)  # a p-value of NaN is tried (as it always was)
                  if not (trial.p_value >= self.settings.threshold or (not isinstance(trial, DelayTrial)
                                                                       and trial.group in self.baselines))]
        ahead: dict[int, tuple[Any, Exception | None]] = {}  # confirm's verdicts worked out side by side, by place
        batch = FIRST_BATCH  # the next batch's size: doubled at each
        for place, trial in enumerate(ranked):
            if isinstance(trial, DelayTrial):
                if self.n_effects + 1 > self.settings.max_effects:
                    continue
                outcome = self.fits.confirm_delay(trial, self.adopted, self.weights, self.settings.min_improvement)
                if outcome is not None:
                    return trial, outcome
                continue
            if place in ahead:
                verdict, error = ahead.pop(place)
                if error is not None:
                    raise error
            else:
                verdict = self.confirm(trial, springs_beaten)
            if not isinstance(verdict, str):
                return trial, verdict
            if len(trial.group) == 1:
                self.verdicts[trial.group[0]] = verdict
            if not ahead and self.screened(trial, springs_beaten) is None:  # compared on validation, and refused
                ahead, batch = self.confirmed_ahead(ranked, place + 1, springs_beaten, batch), 2 * batch
        return None

    def confirmed_ahead(self, ranked: Sequence[Trial | DelayTrial], start: int,
                        springs_beaten: dict[tuple[int, ...], str], count: int) -> dict[int, tuple[Any, Exception | None]]:
        """:meth:`confirm`'s verdicts (or the exception it raised) of the next ``count`` trials from ``start`` that
        are compared on validation (:meth:`screened` passes), worked out side by side (:meth:`Fits.side_by_side`), by
        place: once a round has refused one trial on its comparison, the next ones are likely refused too (the
        search's last round refuses every one), and each verdict depends on the model of the moment alone, never on
        another trial's, so the same verdicts as one after another. The batches double (:data:`FIRST_BATCH`, then
        twice as many): a trial confirmed early in a batch wastes at most as much work as was done before it."""
        places = [place for place in range(start, len(ranked)) if not isinstance(ranked[place], DelayTrial)
                  and self.screened(ranked[place], springs_beaten) is None][:count]
        if not places:
            return {}
        outcomes = self.fits.side_by_side([functools.partial(_verdict, self.confirm, ranked[place], springs_beaten)
                                           for place in places])
        return dict(zip(places, outcomes))

    def confirm(self, trial: Trial, springs_beaten: dict[tuple[int, ...], str]
                ) -> tuple[CandidateComparison, WaldTest] | str:
        """The comparison on validation (both models trained at the weights the candidate's residuals
        give) and the robust test when the trial is physical, confirmed and significant by that test, else
        why not (the robust test, the costliest, last)."""
        text = f"significant on training (p = {trial.p_value:.2g}) but "
        reason = self.screened(trial, springs_beaten) or self.own_laws_explain(trial)
        if reason is not None:
            return text + reason
        comparison = self.fits.compare(trial, self.weights)
        error, current_error = comparison.error, comparison.current_error
        min_improvement = self.settings.min_improvement
        where = ")" if comparison.held_out == "the validation record" else f" on {comparison.held_out})"
        if error >= current_error:
            return text + f"raises the validation error ({current_error:.4g} -> {error:.4g}" + where
        # the gain counts in the sum over every channel, or in the equations the effect enters (its joint's
        # torque), where the other joints do not dilute it
        own = own_rows_gain(trial, comparison, min_improvement, self.model, self.replaced_blocks(trial))
        if own and error >= (1.0 - min_improvement) * current_error:
            return (text + f"lowers the validation error by less than {100 * min_improvement:g} % ({current_error:.4g}"
                    f" -> {error:.4g}), and {own}" + where)
        beaten = self.beaten_by_baseline(trial, error / current_error)
        if beaten:
            return text + beaten
        # a trade between channels (a pair acting on two rows, say) is not a confirmed effect
        worse = channels_made_worse(trial, comparison.current_residual, comparison.residual, min_improvement,
                                    self.model, self.replaced_blocks(trial))
        if worse:
            return text + f"raises the validation error of {worse}"
        tested = self.fits.test(trial, self.weights)
        if tested.wald.p_value >= self.settings.threshold:
            return (f"not significant: its coefficients are within their noise (Wald p = {tested.wald.p_value:.2g} "
                    f"from the HAC covariance; the F test of white residuals gave p = {trial.p_value:.2g})")
        # each term of a several-term law, and each direction's viscous slope, against the HAC standard deviations
        reason = wrong_sign(trial, tested.std) or direction_slopes(trial, self.model, tested.std, self.held_blocks(trial))
        if reason is not None:
            return text + reason
        return comparison, tested.wald

    def held_effects(self) -> list[tuple[Effect, tuple[int, ...]]]:
        """The current model's effects (declared and adopted), each with the joints it acts on."""
        n_joints = self.model.robot.n_joints
        declared = [(effect, tuple(range(n_joints)) if getattr(effect, "joints", None) is None else tuple(effect.joints))
                    for effect in self.model.effects]
        return declared + [(item.effect, joints_of(item.block, self.model)) for item in self.adopted]

    def own_laws_explain(self, trial: Trial) -> str | None:
        """Why a law on a joint combination is refused, or ``None``: fitted beside the per-joint laws of its kind on
        its joints that the model lacks (:func:`own_laws_lacking`: an armature on each joint of ``inertia[q5+q6]``),
        its column is not significant (the nested F test at the search's threshold), or lies in their span with the
        current model (a second coupled law beside a first: ``inertia[q5-q6]`` is ``2 (Ia5 + Ia6) − inertia[q5+q6]``
        in columns). A coupled law claims what per-joint laws cannot say, so it must explain more than they do together,
        as a spring must explain more than an offset (:func:`offsets_beat_springs`); on a geared arm whose wrist holds
        two near-equal armatures, ``inertia[q5+q6]`` explains both at once with one parameter and wins its round by
        BIC against either alone."""
        own = [index for index in own_laws_lacking(trial.blocks, self.blocks, self.model, self.held_effects())
               if index not in self.rejected and (index,) not in self.failed and index not in trial.group]
        if not own:
            return None
        reference = self.fits.fit_current(self.weights, trial.without).rss if trial.without else self.current.rss
        members = [self.blocks[index] for index in own]
        alone = self.fits.trial(tuple(own), members, self.weights, reference, trial.without)
        if isinstance(alone, str):
            return None  # the per-joint laws themselves cannot be fitted here: nothing to compare with
        both = self.fits.trial(tuple(own) + trial.group, members + list(trial.blocks), self.weights, reference,
                               trial.without)
        own_laws = ", ".join(f"{candidate_label(block.effect)} on {', '.join(self.model.channels[row] for row in block.rows)}"
                             for block in members)
        rule = "a law on a joint combination must explain more than the per-joint laws on its joints"
        if isinstance(both, str):
            if not both.startswith("not identifiable"):
                return None
            return (f"its column is its joints' own laws' ({own_laws}) with the current model: {rule}")
        count = trial.n_parameters
        n_fixed = both.fit.theta.shape[0] + both.fit.shape.shape[0] - count
        _, p_value, _ = nested_test(alone.rss, both.rss, count, self.fits.n_rows, n_fixed)
        if p_value < self.settings.threshold:
            return None
        return (f"explains nothing significant beyond its joints' own laws of its kind ({own_laws}; F test p = "
                f"{p_value:.2g} at the level {self.settings.threshold:.2g}): {rule}")

    def screened(self, trial: Trial, springs_beaten: dict[tuple[int, ...], str]) -> str | None:
        """Why a trial is refused before any comparison (a non-physical estimate, a viscous slope negative one way in
        the trial's model, its own or a held one, a spring an offset beats), or ``None``."""
        return (wrong_sign(trial) or direction_slopes(trial, self.model, held=self.held_blocks(trial))
                or springs_beaten.get(trial.group))

    def held_blocks(self, trial: Trial) -> tuple[Block, ...]:
        """The adopted blocks the trial's model keeps, in the order of its columns (those it replaces left out)."""
        return tuple(item.block for item in self.adopted if item.index not in trial.without)

    def beaten_by_baseline(self, trial: Trial, ratio: float) -> str | None:
        """Why a replacement is not confirmed against the law it replaces refitted in its place (its
        validation error over the current model's must be ``min_improvement`` lower than the refitted
        law's), or ``None``."""
        for index in trial.without:
            baseline = self.baselines.get((index,))
            if baseline is None:
                continue
            comparison = self.fits.compare(baseline, self.weights)
            reference = comparison.error / comparison.current_error
            if ratio >= (1.0 - self.settings.min_improvement) * reference:
                return (f"validates no better than the law it would replace refitted in its place (validation over "
                        f"the current model's {ratio:.4g} against {reference:.4g})")
        return None

    def replaced_blocks(self, trial: Trial) -> tuple[Block, ...]:
        return tuple(item.block for item in self.adopted if item.index in trial.without)

    def adopt(self, trial: Trial | DelayTrial, outcome: Any) -> None:
        """Move to the trial's model (its effects added, those it replaces removed) and refit it at the
        weights of the comparison."""
        if isinstance(trial, DelayTrial):  # along the delayed motion from now on
            self.weights = self.fits.adopt_delay(trial, outcome).weights
        else:
            comparison, wald = outcome
            label = " + ".join(candidate_label(block.effect) for block in trial.blocks)
            self.departed |= set(trial.without)
            for item in self.adopted:
                if item.index in trial.without and item.index not in trial.group:
                    self.verdicts[item.index] = f"replaced by {label} (validation {comparison.current_error:.4g} -> " \
                                                f"{comparison.error:.4g})"
            added = [AdoptedEffect(index, block, shape, wald.p_value, wald.f_statistic)
                     for index, block, shape in zip(trial.group, trial.blocks, trial.shapes())]
            self.adopted = replaced_in_place(self.adopted, trial.without, added)
            for index in trial.group:
                if self.removed.pop(index, None) is not None:
                    self.returned.add(index)
            self.weights = comparison.weights
            if trial.without:
                self.failed.clear()  # columns left the model: what they absorbed may be identifiable again
        self.moved()

    def moved(self) -> None:
        self.fits.set_model(self.adopted)
        self.current = self.fits.fit_current(self.weights)
        self.visited.add(self.key(item.index for item in self.adopted))

    def remove_one(self) -> bool:
        """Remove the weakest adopted effect that :func:`removable` lets go (the highest Wald p-value
        first), if any, the weights re-estimated from the model without it; ``True`` when one was."""
        if not self.adopted:
            return False
        tests = self.fits.current_tests(self.weights)
        weakest = sorted(self.adopted, key=lambda item: (-tests[item.index].p_value, tests[item.index].statistic,
                                                          tie_key((item.block,))))
        for item in weakest:
            reason = removable(tests[item.index], self.settings.threshold)
            if reason is None:
                break  # the weakest is significant: so are the others
            if self.key({other.index for other in self.adopted} - {item.index}) in self.visited:
                continue
            comparison = self.fits.removal((item.index,), self.weights)
            if removal_raises(comparison, item.block, self.settings.min_improvement):
                continue  # within its noise on the training record, but the validation record needs it
            self.weights = comparison.weights
            self.verdicts[item.index] = reason
            if item.index in self.returned:
                self.departed.add(item.index)
            else:
                self.removed[item.index] = frozenset(other.index for other in self.adopted if other.index != item.index)
            self.adopted = [other for other in self.adopted if other.index != item.index]
            self.failed.clear()
            self.moved()
            return True
        return False

    def reject(self, index: int, reason: str) -> None:
        block = self.blocks[index]
        self.rejected[index] = RejectedEffect(block.effect.name, tuple(self.model.channels[row] for row in block.rows),
                                              reason, candidate_label(block.effect))

    def outcome(self) -> SearchOutcome:
        """Every candidate not in the final model gets its last verdict, or why it was not tested."""
        max_effects = self.settings.max_effects
        full = self.n_effects >= max_effects
        untested = f"not tested: {max_effects} effects already added" if full else "not significant"
        if self.stopped_at_floor:
            untested = STOPPED_AT_FLOOR
        adopted = {item.index for item in self.adopted}
        if self.settings.same_effect_adopted:
            effects = {id(item.effect) for item in self.adopted}
            adopted |= {index for index, block in self.blocks.items() if id(block.effect) in effects}
        for index in self.blocks:
            if index not in self.rejected and index not in adopted:
                self.reject(index, untested if full and index not in self.verdicts else
                            self.verdicts.get(index, untested))
        return SearchOutcome(tuple(self.adopted), dict(self.rejected), self.stopped_at_floor, self.weights,
                             self.current, untested)


def _verdict(confirm: Callable[..., Any], trial: Trial, springs_beaten: dict[tuple[int, ...], str]
             ) -> tuple[Any, Exception | None]:
    """``(confirm(trial, springs_beaten), None)``, or ``(None, the exception it raised)``: raised again only where the
    search reaches the trial, as when the verdicts are worked out one after another."""
    try:
        return confirm(trial, springs_beaten), None
    except Exception as error:  # noqa: BLE001 (raised again in DiagnosisSearch.choose)
        return None, error
