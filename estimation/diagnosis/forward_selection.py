"""The diagnosis's forward selection as one object: the current model, its fit, the candidates and
why each was set aside, round by round.

:class:`DiagnosisSearch` holds the rules (steps 2–4 of :mod:`estimation.diagnosis.search`): each round
fits every candidate group against the current model, tests the nested models (F test at a
Bonferroni threshold, ranking by BIC), refuses what is not physical (:func:`wrong_sign`, a spring
that is an offset in disguise, a second Coulomb-like law on a joint) and adopts the best-ranked
candidate confirmed on the validation record (its weighted error lowered by ``min_improvement`` and
no channel it acts on made worse). The fits themselves come from a :class:`Fits` strategy:

* :class:`estimation.diagnosis.record_fits.RecordFits`: the records in memory (per-channel Gram
  matrices of the current columns, variable projection of shaped laws, the delay candidate);
* :class:`estimation.streaming.selection.SummedFits`: summed normal equations of files read in
  chunks (shapes fixed beforehand).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np
from numpy.typing import NDArray

from dynamics.effects.linear import Effect
from dynamics.effects.shaped import FRICTION_LAWS
from dynamics.models import IdentificationModel
from estimation.diagnosis.candidates.trials import Trial, candidate_label, joints_of, wrong_sign
from estimation.diagnosis.confirmation import Comparison, channels_made_worse
from estimation.diagnosis.candidates.coupling import combination_groups, combination_taken
from estimation.diagnosis.candidates.delay import DelayTrial
from estimation.diagnosis.results import RejectedEffect
from estimation.diagnosis.selection_rules import candidate_groups, offsets_beat_springs
from estimation.estimators.effect_blocks import Block, NoRowsError

__all__ = ["AdoptedEffect", "CurrentFit", "DiagnosisSearch", "Fits", "SearchOutcome", "SearchSettings",
           "candidate_blocks"]

STOPPED_AT_FLOOR = "not tested: the stopping rule ended the search (no channel significantly above its noise floor)"


@dataclass(frozen=True)
class AdoptedEffect:
    """One effect of the current model: candidate ``index``, its column block at ``shape``, and the
    test statistics of the round that adopted it."""

    index: int
    block: Block
    shape: NDArray[np.float64]
    p_value: float
    f_statistic: float

    @property
    def effect(self) -> Effect:
        return self.block.effect


class CurrentFit(Protocol):
    """The current model fitted on training: its weighted RSS and weighted validation MSE."""

    rss: float
    validation_error: float


class Fits(Protocol):
    """How a search fits column blocks: from the records in memory or from summed normal equations."""

    def fit_current(self, weights: NDArray[np.float64]) -> CurrentFit: ...

    def keep_searching(self, current: CurrentFit, added: tuple[str, ...]) -> bool: ...

    def trial(self, group: tuple[int, ...], members: Sequence[Block], weights: NDArray[np.float64],
              rss: float) -> Trial | str: ...

    def refine(self, trials: list[Trial], current: CurrentFit, weights: NDArray[np.float64],
               first_round: bool) -> list[Trial]: ...

    def compare(self, trial: Trial, weights: NDArray[np.float64]) -> Comparison: ...

    def extend(self, adopted: Sequence[AdoptedEffect]) -> None: ...

    @property
    def delay_adopted(self) -> bool: ...

    def delay_trials(self, adopted: Sequence[AdoptedEffect], weights: NDArray[np.float64], rss: float,
                     others: Sequence[Trial]) -> list[DelayTrial]: ...

    def confirm_delay(self, trial: DelayTrial, adopted: Sequence[AdoptedEffect], weights: NDArray[np.float64],
                      min_improvement: float) -> Any: ...

    def adopt_delay(self, trial: DelayTrial, outcome: Any) -> Comparison: ...


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


def candidate_blocks(model: IdentificationModel, candidates: Sequence[Effect]
                     ) -> tuple[dict[int, Block], dict[int, RejectedEffect]]:
    """Each candidate's column block by index, and the candidates without rows in ``model``."""
    blocks: dict[int, Block] = {}
    rejected: dict[int, RejectedEffect] = {}
    for index, candidate in enumerate(candidates):
        if not isinstance(candidate, Effect):
            raise TypeError(f"candidate {candidate!r} is not an effect")
        try:
            blocks[index] = Block(model.kind, model.robot, candidate, model.n_channels)
        except NoRowsError:
            rejected[index] = RejectedEffect(candidate.name, (), "has no rows in this model", candidate_label(candidate))
    return blocks, rejected


def declared_friction_joints(model: IdentificationModel) -> set[int]:
    """The joints the declared model already gives a Coulomb-like friction law."""
    return {joint for effect in model.effects if effect.name in FRICTION_LAWS
            for joint in (range(model.robot.n_joints) if getattr(effect, "joints", None) is None else effect.joints)}


class DiagnosisSearch:
    """Forward selection of candidate effects (module docstring).

    Parameters
    ----------
    model
        The declared model.
    blocks, rejected
        The candidates with columns by index, and those already set aside (:func:`candidate_blocks`).
    fits
        How column blocks are fitted (:class:`Fits`).
    weights
        The declared model's channel weights ``w_c = 1/σ_c²``; re-estimated with each adoption.
    settings
        :class:`SearchSettings`.
    """

    def __init__(self, model: IdentificationModel, blocks: dict[int, Block], rejected: Mapping[int, RejectedEffect],
                 fits: Fits, weights: NDArray[np.float64], settings: SearchSettings) -> None:
        self.model, self.blocks, self.fits, self.settings = model, blocks, fits, settings
        self.rejected: dict[int, RejectedEffect] = dict(rejected)
        self.deferred: dict[int, str] = {}  # statistical verdicts: tried again in later rounds
        self.groups = candidate_groups(blocks, model)
        if settings.combinations:
            self.groups += combination_groups({index: block.effect for index, block in blocks.items()})
        self.friction_joints = declared_friction_joints(model)
        self.adopted: list[AdoptedEffect] = []
        self.weights = weights
        self.current = fits.fit_current(weights)
        self.rounds = 0
        self.stopped_at_floor = False

    @property
    def n_effects(self) -> int:
        """Effects adopted so far (the delay counts as one)."""
        return len(self.adopted) + self.fits.delay_adopted

    def run(self) -> SearchOutcome:
        """Rounds until the stopping rule, the cap, or no confirmed candidate ends the search."""
        while self.groups and self.n_effects < self.settings.max_effects:
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
        trials = self.fit_candidates()
        self.drop_rejected()
        trials = self.fits.refine(trials, self.current, self.weights, self.rounds == 0)
        self.rounds += 1
        springs_beaten = offsets_beat_springs(trials, self.model)
        trials = trials + self.fits.delay_trials(self.adopted, self.weights, self.current.rss, trials)
        added = self.choose(trials, springs_beaten)
        self.drop_rejected()
        return added

    def fit_candidates(self) -> list[Trial]:
        """Each group not set aside, fitted against the current model (a lone candidate that cannot
        be is set aside with the reason)."""
        trials = []
        for group in self.groups:
            if any(index in self.rejected for index in group):
                continue
            members = [self.blocks[index] for index in group]
            outcome = self.excluded(members) or self.fits.trial(group, members, self.weights, self.current.rss)
            if isinstance(outcome, str):
                if len(group) == 1:
                    self.reject(group[0], outcome)
                continue
            trials.append(outcome)
        return trials

    def excluded(self, members: Sequence[Block]) -> str | None:
        """Why the group may not join the current model (a second Coulomb-like law on a joint or a
        joint combination), or ``None``."""
        if any(block.effect.name in FRICTION_LAWS and set(joints_of(block, self.model)) & self.friction_joints
               for block in members):
            return "its joint already has a Coulomb-like friction law"
        if self.settings.combinations:
            effects = self.model.effects + tuple(a.effect for a in self.adopted)
            if any(combination_taken(block.effect, effects) for block in members):
                return "its joint combination already has a Coulomb law"
        return None

    def choose(self, trials: list[Trial | DelayTrial], springs_beaten: dict[tuple[int, ...], str]
               ) -> tuple[Trial | DelayTrial, Any] | None:
        """The best-ranked significant trial confirmed on validation, with its comparison."""
        for trial in sorted(trials, key=lambda t: t.bic):
            if (trial.p_value >= self.settings.threshold
                    or self.n_effects + len(trial.group) > self.settings.max_effects):
                continue
            if isinstance(trial, DelayTrial):
                outcome = self.fits.confirm_delay(trial, self.adopted, self.weights, self.settings.min_improvement)
                if outcome is not None:
                    return trial, outcome
                continue
            verdict = self.confirm(trial, springs_beaten)
            if isinstance(verdict, str):
                if len(trial.group) == 1:
                    self.deferred[trial.group[0]] = verdict
                continue
            return trial, verdict
        return None

    def confirm(self, trial: Trial, springs_beaten: dict[tuple[int, ...], str]) -> Comparison | str:
        """The comparison on validation (both models trained at the weights the candidate's residuals
        give) when the trial is physical and confirmed, else why not."""
        text = f"significant on training (p = {trial.p_value:.2g}) but "
        reason = wrong_sign(trial) or springs_beaten.get(trial.group)
        if reason is not None:
            return text + reason
        comparison = self.fits.compare(trial, self.weights)
        error, current_error = comparison.error, comparison.current_error
        min_improvement = self.settings.min_improvement
        if error >= (1.0 - min_improvement) * current_error:
            change = ("raises the validation error" if error > current_error else
                      f"lowers the validation error by less than {100 * min_improvement:g} %")
            return text + f"{change} ({current_error:.4g} -> {error:.4g})"
        # a trade between channels (a pair acting on two rows, say) is not a confirmed effect
        worse = channels_made_worse(trial, comparison.current_residual, comparison.residual, min_improvement,
                                    self.model)
        if worse:
            return text + f"raises the validation error of {worse}"
        return comparison

    def adopt(self, trial: Trial | DelayTrial, outcome: Any) -> None:
        """Add the trial to the current model, refit it at the weights of the comparison, and retire
        the groups sharing a candidate with it."""
        if isinstance(trial, DelayTrial):  # along the delayed motion from now on
            comparison, added = self.fits.adopt_delay(trial, outcome), []
        else:
            comparison = outcome
            added = [AdoptedEffect(index, block, shape, trial.p_value, trial.f_statistic)
                     for index, block, shape in zip(trial.group, trial.blocks, trial.shapes())]
        self.weights = comparison.weights
        self.adopted += added
        for item in added:
            if item.effect.name in FRICTION_LAWS:
                self.friction_joints |= set(joints_of(item.block, self.model))
        self.fits.extend(added)
        self.current = self.fits.fit_current(self.weights)
        # the other candidates restart from their last optima; groups sharing an added effect go
        self.groups = [group for group in self.groups if not set(group) & set(trial.group)]

    def drop_rejected(self) -> None:
        self.groups = [group for group in self.groups if not any(index in self.rejected for index in group)]

    def reject(self, index: int, reason: str) -> None:
        block = self.blocks[index]
        self.rejected[index] = RejectedEffect(block.effect.name, tuple(self.model.channels[row] for row in block.rows),
                                              reason, candidate_label(block.effect))

    def outcome(self) -> SearchOutcome:
        """Every candidate neither adopted nor set aside gets its last verdict, or why it was not tested."""
        max_effects = self.settings.max_effects
        full = len(self.adopted) >= max_effects
        untested = f"not tested: {max_effects} effects already added" if full else "not significant"
        if self.stopped_at_floor:
            untested = STOPPED_AT_FLOOR
        adopted = {item.index for item in self.adopted}
        if self.settings.same_effect_adopted:
            effects = {id(item.effect) for item in self.adopted}
            adopted |= {index for index, block in self.blocks.items() if id(block.effect) in effects}
        for index in self.blocks:
            if index not in self.rejected and index not in adopted:
                self.reject(index, untested if full else self.deferred.get(index, untested))
        return SearchOutcome(tuple(self.adopted), dict(self.rejected), self.stopped_at_floor, self.weights,
                             self.current, untested)
