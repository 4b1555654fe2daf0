"""The moves of the diagnosis's search besides adding an effect: which adopted effects a candidate
replaces, when an adopted effect is removed, and how moves are ranked whatever the order of the
candidate list.

A joint (or a joint combination) carries one Coulomb-like friction law. A candidate law on a joint whose
law was **declared** is set aside; on a joint whose law the search **adopted**, it is tried in its place
(:func:`replaced_by`): the sign law by a Stribeck law, a smoothed law by the sign law. The move is fitted
against the current model without the law it replaces, its block tested in that model, ranked by
:func:`move_bic` against the current model, and confirmed when it lowers the held-out error of the
current model.

An adopted effect is removed (:func:`removable`) when, in the current model, its coefficients are
within their noise (the Wald test of :mod:`estimation.diagnosis.rules.robust_test` not significant): what later
adoptions made redundant does not stay; unless removing it raises the validation error of a channel it acts on
(:func:`removal_raises`): an offset on a gravity-loaded joint whose training motion cannot tell it from the
gravity terms (HAC Wald p 0.0029 to 0.84 on simulated UR10e-like and servo arms) is still needed on another
motion, where the gravity terms that absorbed it extrapolate badly (1.3-1.6x the plain fit on that joint).
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence

import numpy as np

from dynamics.effects.shaped import FRICTION_LAWS
from dynamics.models import IdentificationModel
from estimation.diagnosis.candidates.coupling import combination_taken
from estimation.diagnosis.candidates.trials import joints_of
from estimation.diagnosis.confirmation import CandidateComparison
from estimation.diagnosis.rules.robust_test import WaldTest
from estimation.estimators.effect_blocks import Block

__all__ = ["declared_conflict", "move_bic", "removable", "removal_raises", "replaced_by", "replaced_in_place",
           "tie_key"]


def tie_key(blocks: Iterable[Block]) -> tuple[str, ...]:
    """A key that orders moves of equal rank by what they add, not by where they sit in the candidate list."""
    return tuple(sorted(f"{block.effect.name}:{','.join(block.names)}" for block in blocks))


def _friction_joints(block: Block, model: IdentificationModel) -> set[int]:
    return set(joints_of(block, model)) if block.effect.name in FRICTION_LAWS else set()


def declared_conflict(members: Sequence[Block], model: IdentificationModel, friction_joints: set[int],
                      combinations: bool) -> str | None:
    """Why the group may not join any model of the search (a second Coulomb-like law on a joint, or on
    a joint combination, of the declared model), or ``None``."""
    if any(_friction_joints(block, model) & friction_joints for block in members):
        return "its joint already has a Coulomb-like friction law"
    if combinations and any(combination_taken(block.effect, model.effects) for block in members):
        return "its joint combination already has a Coulomb law"
    return None


def replaced_by(members: Sequence[Block], adopted: Sequence, model: IdentificationModel,
                combinations: bool) -> tuple[int, ...]:
    """The candidate indices of the adopted effects the group replaces: the Coulomb-like law on each
    joint (or joint combination) of the group's laws."""
    joints = set().union(*(_friction_joints(block, model) for block in members))
    replaced = []
    for item in adopted:
        if _friction_joints(item.block, model) & joints:
            replaced.append(item.index)
        elif combinations and any(combination_taken(block.effect, (item.effect,)) for block in members):
            replaced.append(item.index)
    return tuple(replaced)


def replaced_in_place(adopted: Sequence, without: tuple[int, ...], added: Sequence) -> list:
    """The adopted effects after a move: the first one replaced (by candidate index ``without``) gives its
    place to the added ones (the order of the findings stays the order of adoption), the other replaced
    ones leave; without a replaced one the added ones come last."""
    kept, placed = [], False
    for item in adopted:
        if item.index in without:
            if not placed:
                kept.extend(added)
                placed = True
            continue
        kept.append(item)
    return kept if placed else kept + list(added)


def move_bic(rss: float, current_rss: float, added: int, removed: int, n_rows: int) -> float:
    """``N m log(RSS₁/RSS₀) + (q_added − q_removed) log(N m)``: the BIC of the model after a move against
    the current model's (lower is better)."""
    return float(n_rows * np.log(max(rss, 1e-300) / max(current_rss, 1e-300)) + (added - removed) * np.log(n_rows))


def removable(test: WaldTest, threshold: float) -> str | None:
    """Why an adopted effect leaves the current model, or ``None``: its coefficients within their noise
    there (the Wald test of its HAC covariance not significant at ``threshold``).

    Only the statistic that adopted it: a held-out comparison judged at the weights of the model without
    the effect (not those of the model that adopted it) let effects leave and come back in turn on the
    KUKA LWR4+ records."""
    if test.p_value >= threshold:
        return (f"removed: in the current model its coefficients are within their noise (Wald p = "
                f"{test.p_value:.2g} from the HAC covariance)")
    return None


def removal_raises(comparison: CandidateComparison, block: Block, tolerance: float) -> bool:
    """Whether removing an adopted effect (``comparison``: the model without it against the current model,
    :func:`estimation.diagnosis.confirmation.removal_comparison`) raises the validation MSE of a channel the effect
    acts on by more than ``tolerance`` (relative): the held-out evidence that adopted it still stands."""
    rows = list(block.rows)
    before = np.mean(np.asarray(comparison.current_residual)[rows] ** 2, axis=1)
    after = np.mean(np.asarray(comparison.residual)[rows] ** 2, axis=1)
    return bool(np.any(after > (1.0 + tolerance) * before))
