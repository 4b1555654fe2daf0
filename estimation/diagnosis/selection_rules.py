"""Rules of the forward selection shared by the in-memory and the streamed diagnosis: which candidates
compete together, which screened shapes are searched again, and when a spring is an offset in disguise."""

from __future__ import annotations

from dynamics.models import IdentificationModel
from dynamics.effects.shaped import FRICTION_LAWS
from estimation.diagnosis.candidates.trials import fit_or_reason, joints_of
from estimation.estimators.effect_blocks import Block

#: screened candidates whose shapes are searched again in each round after the first
SCREEN_REFINED = 2


def refine_best(trials, fixed, states, weights, rss, previous, count: int, traced=None):
    """The ``count`` best-ranked screened trials, and the group ``traced`` (the one the residual
    tracing ranks first: :mod:`estimation.diagnosis.traced_refinement`), with shapes searched again by
    Levenberg–Marquardt."""
    ranked = sorted(trials, key=lambda t: t.bic)
    refined = []
    for position, trial in enumerate(ranked):
        if (position < count or trial.group == traced) and trial.fit.shape.size:
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


def offsets_beat_springs(trials, model) -> dict[tuple[int, ...], str]:
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
