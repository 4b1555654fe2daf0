"""Rules of the search shared by the in-memory and the streamed diagnosis: which candidates
compete together, which screened shapes are searched again, and when a spring or an armature is an offset in
disguise."""

from __future__ import annotations

import dataclasses

from dynamics.models import IdentificationModel
from dynamics.effects.shaped import FRICTION_LAWS
from estimation.diagnosis.candidates.trials import fit_or_reason, joints_of
from estimation.estimators.effect_blocks import Block

#: screened candidates whose shapes are searched again in each round after the first
SCREEN_REFINED = 2


def refine_best(trials, fixed, states, weights, rss, previous, count: int, traced=None):
    """The ``count`` best-ranked screened trials (by BIC, ties by what they add), and the group ``traced``
    (the one the residual tracing ranks first: :mod:`estimation.diagnosis.traced_refinement`), with
    shapes searched again by Levenberg–Marquardt. ``fixed(trial)``, ``rss(trial)``: the columns and
    weighted RSS of the model the trial joins (the current one, or without the laws it replaces)."""
    ranked = sorted(trials, key=lambda t: (t.bic, tuple(sorted(",".join(block.names) for block in t.blocks))))
    refined = []
    for position, trial in enumerate(ranked):
        if (position < count or trial.group == traced) and trial.fit.shape.size:
            outcome = fit_or_reason(trial.group, list(trial.blocks), fixed(trial), states, weights, rss(trial),
                                    trial.fit, search=True)
            if not isinstance(outcome, str):
                previous[trial.group] = outcome.fit
                trial = dataclasses.replace(outcome, without=trial.without)
        refined.append(trial)
    return refined


def candidate_groups(blocks: dict[int, Block], model: IdentificationModel) -> list[tuple[int, ...]]:
    """Every candidate alone, and each Coulomb-like friction law together with its joint's offset
    (an asymmetric friction: a sigmoid law with a shift mimics a symmetric law plus an offset, so
    the pair must compete with it as one candidate), and each spring with its joint's offset (a spring
    about a rest position, ``k (q − q_ref)``: while the offset is missing, the residual it leaves makes
    the spring alone look no more than noise, and the offset alone is half of the law)."""
    groups = [(index,) for index in blocks]
    offsets = {joints_of(block, model): index for index, block in blocks.items() if block.effect.name == "offset"}
    for index, block in blocks.items():
        joints = joints_of(block, model)
        paired = block.effect.name == "spring" or (block.effect.name in FRICTION_LAWS and block.effect.name != "sigmoid")
        if paired and joints in offsets:
            groups.append((index, offsets[joints]))
    return groups


#: relative difference of two weighted RSS within which they are one (rounding: two candidates whose columns span
#: the same space with the current model's fit alike to ~1e-15; a statistical tie is not one)
SAME_RSS = 1e-9


def offsets_beat_springs(trials, model, offset_joints=frozenset()) -> dict[tuple[int, ...], str]:
    """Springs and armatures whose joint's offset explains as much: a stiffness that is an offset in disguise
    (``k·mean(q)`` equal to the offset) is not a spring, nor an armature one whose column is the offset's with the
    current model (a vertical linear axis: its carried mass's column ``ddq + g`` less the armature's ``ddq`` is a
    constant, so either completes the model alike on every motion, and the constant is the simpler law). A spring
    or an armature on a joint whose offset the current model holds (``offset_joints``) is tested beside it: nothing
    to compare. "As much" is within rounding (:data:`SAME_RSS`)."""
    offsets = {joints_of(t.blocks[0], model): t for t in trials if len(t.blocks) == 1 and t.blocks[0].effect.name == "offset"}
    reasons = {}
    for trial in trials:
        if len(trial.blocks) != 1 or trial.blocks[0].effect.name not in ("spring", "armature"):
            continue
        if joints_of(trial.blocks[0], model) in offset_joints:
            continue
        offset = offsets.get(joints_of(trial.blocks[0], model))
        spring = trial.blocks[0].effect.name == "spring"
        if offset is None:
            if spring:
                reasons[trial.group] = "no offset on its joint to compare it with (a spring must explain more than an offset)"
        elif offset.rss <= trial.rss * (1.0 + SAME_RSS):
            reasons[trial.group] = ("an offset explains as much (a stiffness that is an offset in disguise)" if spring
                                   else "an offset explains as much (an armature that is an offset in disguise: its "
                                        "column is the offset's beside the joint's constant gravity)")
    return reasons
