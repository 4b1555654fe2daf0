"""The default answer with the plain law completed where the diagnosis named none, judged on the validation record.

The diagnosis's search can leave a joint without the terms of the plain law (Coulomb friction and an offset) that a
plain least-squares fit holds (:func:`estimation.diagnosis.plain_laws.plain_completion` builds the completed
model). These rules decide whether the default answer of the completed model replaces the adopted model's: on a
validation record of another motion the two answers (each the better of as fitted and consistent refit) are
compared there, the lower score taking it (:data:`COMPLETION_TOLERANCE`, zero); on a repeat of the
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

#: on a validation record of another motion, the plain law completed is taken when its answer's validation score is
#: below the adopted model's by more than this fraction. Zero since h-tie20 (it was 1 %, a tie kept by the model with
#: fewer laws): the completed laws are not findings, so no band against naming a law by chance is needed, and a plain
#: term left out was an omission the validation record did not measure (the one-sided pendulum's offset, 38.8x the
#: plain fit on the test, validated 0.8 % worse than its completion); the lower score decides, as on a repeat
COMPLETION_TOLERANCE = 0.0


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
    and any lower score takes it; on another motion a score lower by more than :data:`COMPLETION_TOLERANCE` (zero:
    any lower score)."""
    answers = {"diagnosed": selection.chosen_candidate, "completed": other.chosen_candidate}
    if (repeat and other.chosen != "consistent") or any(answer.validation is None for answer in answers.values()):
        return selection
    validation = answers["diagnosed"].validation  # a streamed fit's errors hold their channels in order
    channels = getattr(validation, "channels", None) or tuple(validation.mse)
    scored = relative_scores({name: answer.validation.mse for name, answer in answers.items()}, channels)
    taken = (1.0 + (0.0 if repeat else COMPLETION_TOLERANCE)) * scored["completed"] < scored["diagnosed"]
    why = (f"; the plain law completed ({laws}): its answer ({other.chosen}) validates {scored['completed']:.4g} "
           f"against {scored['diagnosed']:.4g} for the diagnosed model's ({selection.chosen}; the mean relative "
           f"validation error{note}), " + ("taken" if taken else "not taken"))
    return replace(other, reason=other.reason + why) if taken else replace(selection, reason=selection.reason + why)
