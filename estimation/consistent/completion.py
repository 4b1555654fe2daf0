"""The default answer with the plain law completed where the diagnosis named none, judged on the validation record.

The diagnosis's search can leave a joint without the terms of the plain law (Coulomb friction and an offset) that a
plain least-squares fit holds (:func:`estimation.diagnosis.plain_laws.plain_completion` builds the completed
model). These rules decide whether the default answer of the completed model replaces the adopted model's: on a
validation record of another motion the two answers (each the better of as fitted and consistent refit) are
compared there, a score within :data:`COMPLETION_TOLERANCE` a tie kept by the completed model (the plain class: a
plain term left out must validate its omission, as an added effect its addition); on a repeat of the
training motion only the two consistent refits, since nothing measured the extrapolation. The in-memory and the
streamed diagnosis (``oed.workflows.diagnose``) call the same rules.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace
from typing import Any

from dynamics.models import IdentificationModel
from estimation.consistent.model_selection import ConsistentSettings, ModelSelection
from estimation.identification.relative_error import relative_scores

__all__ = ["COMPLETION_TOLERANCE", "completed_answer", "completed_laws", "completed_note", "completion_repeat",
           "held_completion"]

#: on a validation record of another motion, the adopted model keeps its omissions of the plain law only when its
#: answer's validation score is below the completed model's by more than this fraction: within it is a tie, kept by
#: the completed model, the plain class (an omission of a plain term is a choice against the model class of a plain
#: least-squares fit, and earns its place as an addition does, by validating better beyond the tie)
COMPLETION_TOLERANCE = 0.01


def completion_repeat(selection: ModelSelection, *, consistent: bool) -> bool | None:
    """Whether the plain law's completion is judged on a repeat of the training motion (``True``) or on another
    motion (``False``), or ``None`` when it is not judged (on both paths): a validation record at rest,
    ``consistent`` (``--consistent`` given), or a repeat whose default answer is not the consistent refit."""
    if consistent or selection.selection not in ("repeated-motion", "validation"):
        return None
    repeat = selection.selection == "repeated-motion"
    return None if repeat and selection.chosen != "consistent" else repeat


def held_completion(selection: ModelSelection, settings: ConsistentSettings, laws: str, *, repeat: bool,
                    select: Callable[[ConsistentSettings], ModelSelection]) -> ModelSelection:
    """:func:`completed_answer` of the completed model's selection ``select(settings)`` against ``selection`` (the
    adopted model's), on both paths. On another motion (not ``repeat``) with the prior's weight left to the
    validation record, the completed model's consistent refit takes the weight chosen for the adopted model, and
    carries its choice and search (made, held out, for the adopted model); on a repeat the weight is searched
    again."""
    adopted = selection.consistent
    held = not repeat and adopted is not None and settings.prior_weight in (None, "auto")
    if held:  # the laws are compared, not the prior's weight: the one the validation record chose for the adopted model
        settings = replace(settings, prior_weight=float(adopted.estimate.prior_weight))
    other = select(settings)
    if held and other.consistent is not None:
        refit = replace(other.consistent, prior_weight_choice=adopted.prior_weight_choice,
                        prior_weight_search=adopted.prior_weight_search)  # chosen, held out, for the adopted model
        other = replace(other, candidates=tuple(replace(c, fit=refit) if c.name == "consistent" else c
                                                for c in other.candidates))
    held_note = f"; its consistent refit at the adopted model's prior weight {settings.prior_weight:g}" if held else ""
    return completed_answer(selection, other, laws, repeat=repeat, note=held_note)


def completed_laws(model: IdentificationModel, added: Any) -> str:
    """The plain laws a completion added (:func:`estimation.diagnosis.plain_laws.plain_completion`), in words."""
    return ", ".join(f"{effect.name} on {model.channels[effect.joints[0]]}" for effect in added)


def completed_note(laws: str) -> str:
    """The note of the completed model's candidates (``diagnosis_selection`` of :mod:`oed.workflows.diagnose`)."""
    return f"with the diagnosed effects and the plain law where the diagnosis named none ({laws}; not findings)"


def completed_answer(selection: ModelSelection, other: ModelSelection, laws: str, *, repeat: bool,
                     note: str = "") -> ModelSelection:
    """The default answer with the plain law completed (:func:`held_completion`, on both paths): the completed
    model's selection ``other`` when its answer validates better than the adopted model's (``selection``) by the
    default answer's criterion, else ``selection``; the reason gives both scores and ``note``.

    On a repeat of the training motion (``repeat``) only a consistent refit of the completed model is an answer,
    and any lower score takes it; on another motion a score within :data:`COMPLETION_TOLERANCE` of the adopted
    model's is a tie, which takes the completed model: the plain class is the reference a user compares against,
    and a plain term left out is a choice the validation record must measure, as an added effect must (the
    adopted model is kept only when it validates lower by more than the tolerance)."""
    answers = {"diagnosed": selection.chosen_candidate, "completed": other.chosen_candidate}
    if (repeat and other.chosen != "consistent") or any(answer.validation is None for answer in answers.values()):
        return selection
    validation = answers["diagnosed"].validation  # a streamed fit's errors hold their channels in order
    channels = getattr(validation, "channels", None) or tuple(validation.mse)
    scored = relative_scores({name: answer.validation.mse for name, answer in answers.items()}, channels)
    if repeat:
        taken = scored["completed"] < scored["diagnosed"]
    else:  # a tie keeps the plain class: the omission must validate lower beyond the tolerance
        taken = scored["completed"] <= (1.0 + COMPLETION_TOLERANCE) * scored["diagnosed"]
    tied = not repeat and max(scored.values()) <= (1.0 + COMPLETION_TOLERANCE) * min(scored.values())
    tie = (f"a tie within {COMPLETION_TOLERANCE:.0%}, which keeps the plain class (a plain term left out must "
           "validate lower beyond it), ") if tied else ""
    why = (f"; the plain law completed ({laws}): its answer ({other.chosen}) validates {scored['completed']:.4g} "
           f"against {scored['diagnosed']:.4g} for the diagnosed model's ({selection.chosen}; the mean relative "
           f"validation error{note}), " + tie + ("taken" if taken else "not taken"))
    return replace(other, reason=other.reason + why) if taken else replace(selection, reason=selection.reason + why)
