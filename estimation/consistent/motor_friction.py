"""Motor-side friction as a candidate of the default answer when the declared transmission couples motors.

Friction acts where the bearings and seals turn: at the motors. Through a diagonal transmission motor ``j`` turns
with joint ``j`` alone, so its viscous and Coulomb friction are the per-joint laws. A coupled transmission (a wrist
whose motor 6 turns with ``q5 + q6``, ``q_m = M q``) puts the friction of such a motor, a law of ``(M q̇)_6``, into
the torques of every joint it turns with (``τ += M_6ᵀ f(M_6 q̇)``, :mod:`dynamics.effects.motor`), which per-joint
laws cannot hold (the Stäubli TX40's joint 5: 1.07x the plain fit's test error with the per-joint laws, 0.044x with
the motor laws, ``benchmarks/README.md``).

So when the user declares a transmission that couples motors (a row of ``M`` with more than one joint) and leaves
their friction undeclared, the default ``oed identify`` fits the declared model with motor-side viscous and Coulomb
friction added on each coupled motor (:func:`motor_friction_laws`) beside it, chooses that model's answer among its
own candidates as it chooses the declared model's (:func:`estimation.consistent.model_selection.select_model`), and
compares the two answers on the same validation samples by the criterion of the default answer
(:func:`estimation.identification.relative_error.relative_scores`) in :func:`motor_friction_answer`: the model with
the motor laws is taken only when it scores lower by more than :data:`MOTOR_FRICTION_TOLERANCE` (a tie keeps the
declared model), and only on a validation record of another motion (on a repeat, or without a validation record,
nothing measured how the added laws extrapolate: the declared model is kept). Without a coupled transmission
nothing is added and nothing changes.
"""

from __future__ import annotations

from typing import Any


from dynamics.effects.motor import motor_effects
from dynamics.models import IdentificationModel, ModelKind
from dynamics.transmission import Transmission
from estimation.consistent.model_selection import ModelSelection, candidate_answer

__all__ = ["MOTOR_FRICTION_TOLERANCE", "motor_friction_answer", "motor_friction_laws"]

#: the relative score by which the model with the motor laws must beat the declared one (a tie keeps the declared)
MOTOR_FRICTION_TOLERANCE = 0.01


def motor_friction_laws(model: IdentificationModel, transmission: Transmission | None) -> tuple[Any, ...]:
    """Motor-side viscous and Coulomb friction (``motor_viscous``, ``motor_coulomb``) on each coupled motor
    (:meth:`dynamics.transmission.Transmission.coupled_motors`) whose law of that kind ``model`` does not declare; none on the external model (friction
    has no rows there) or without a coupled transmission."""
    motors = () if transmission is None else transmission.coupled_motors()
    if not motors or model.kind is ModelKind.EXTERNAL:
        return ()
    declared = {(effect.kind, label) for effect in model.effects if getattr(effect, "motor", False)
                for label in effect.labels}
    return tuple(effect for kind in ("viscous", "coulomb") for effect in motor_effects(transmission, kind, motors)
                 if (kind, effect.labels[0]) not in declared)


def motor_friction_answer(selection: ModelSelection, other: ModelSelection, laws: str) -> ModelSelection:
    """The default answer with motor-side friction a candidate (module docstring): ``other`` (the selection of the
    model with the motor laws ``laws`` added) when its answer scores lower on the validation record than the
    declared model's (``selection``) by more than :data:`MOTOR_FRICTION_TOLERANCE`, else ``selection``; the reason
    gives both scores. Compared only when both selections were made on a validation record of another motion."""
    return candidate_answer(selection, other, tolerance=MOTOR_FRICTION_TOLERANCE,
                            added=f"motor-side friction on the coupled motors ({laws})")
