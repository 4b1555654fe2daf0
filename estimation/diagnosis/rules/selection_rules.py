"""Rules of the search shared by the in-memory and the streamed diagnosis: which candidates
compete together, which screened shapes are searched again, when a spring or an armature is an offset in
disguise, and which per-joint laws a law on a joint combination must explain more than (:func:`own_laws_lacking`)."""

from __future__ import annotations

import dataclasses
from collections.abc import Iterable, Sequence

import numpy as np

from dynamics.models import IdentificationModel
from dynamics.effects.linear import Effect
from dynamics.effects.motor import CombinationEffect
from dynamics.effects.shaped import FRICTION_LAWS
from estimation.diagnosis.candidates.coupling import PER_JOINT
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


def _law_family(effect: Effect) -> str | None:
    """The per-joint law family an effect is (``inertia``, ``viscous``, ``coulomb``: the kinds of a joint
    combination's law, :data:`estimation.diagnosis.candidates.coupling.PER_JOINT`), or ``None``."""
    if effect.name in FRICTION_LAWS:
        return "coulomb"
    return {law.name: kind for kind, law in PER_JOINT.items()}.get(effect.name)


def own_laws_lacking(members: Sequence[Block], blocks: dict[int, Block], model: IdentificationModel,
                     held: Iterable[tuple[Effect, tuple[int, ...]]]) -> tuple[int, ...]:
    """The candidate indices of the per-joint laws a coupled trial must explain more than: for each member that is
    a plain law on a joint combination (:class:`dynamics.effects.motor.CombinationEffect` of joints, not a declared
    transmission's motor), the per-joint law of its kind on each of its joints (an armature for ``inertia[q5+q6]``)
    that the model of the moment lacks. ``held``: the current model's effects (declared and adopted), whose
    per-joint law families on their joints are what the model holds."""
    holds = {(family, joint) for effect, joints in held for family in [_law_family(effect)] if family
             for joint in joints}
    lacking = []
    for member in members:
        effect = member.effect
        if not isinstance(effect, CombinationEffect) or effect.motor or member.n_shape or effect.kind not in PER_JOINT:
            continue
        joints = {int(joint) for row in effect.weights for joint in np.flatnonzero(row)}
        for index, block in blocks.items():
            if block.effect.name == PER_JOINT[effect.kind].name and len(joints_of(block, model)) == 1 \
                    and joints_of(block, model)[0] in joints and (effect.kind, joints_of(block, model)[0]) not in holds:
                lacking.append(index)
    return tuple(sorted(set(lacking)))
