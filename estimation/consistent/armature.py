"""The rotors' reflected inertia (armature) as a candidate of the default answer.

A geared joint's motor turns ``N`` times faster than the joint, so its rotor's inertia ``J_m`` reaches the joint as
``I_a = N² J_m`` (PUMA paper, the motor inertias of its dynamic model): ``τ_j += I_a,j q̈_j``, on joint ``j``'s row
alone. On a geared industrial arm it is as large as the links' own inertia about the joint, or far larger at the
wrist (a PUMA 560: 1.14, 4.71, 0.83, 0.2, 0.18, 0.19 kg m²), and a URDF seldom holds it: its inertials are the
links'. The rigid body's parameters cannot hold it (a link's inertia about joint ``j`` also acts on the joints
below ``j``), so a model without it trades the joints against each other: on a simulated PUMA 560 with those
rotors, the default ``oed identify`` predicted a test record at 5-40 times the noise floor, the wrist 2.4 times a
plain least-squares fit's error; with the armature declared, at the floor (``benchmarks/README.md``, h-unseen8).

So when the declared model of joint torques holds no armature, the default ``oed identify`` fits the declared model
with ``armature`` added on every joint (:func:`armature_laws`) beside it, chooses that model's answer among its own
candidates as it chooses the declared model's (:func:`estimation.consistent.model_selection.select_model`), and
compares the two answers on the same validation samples by the criterion of the default answer in
:func:`armature_answer`: the model with the armature is taken only when it scores lower by more than
:data:`ARMATURE_TOLERANCE` (a tie keeps the declared model), and only on a validation record of another motion (on a
repeat, or without a validation record, nothing measured how the added column extrapolates: the declared model is
kept), as motor-side friction is (:mod:`estimation.consistent.motor_friction`).
"""

from __future__ import annotations

from typing import Any

from dynamics.channels import is_joint_torque
from dynamics.effects.linear import Armature
from dynamics.models import IdentificationModel, ModelKind
from estimation.consistent.model_selection import ModelSelection, candidate_answer

__all__ = ["ARMATURE_TOLERANCE", "armature_answer", "armature_laws"]

#: the relative score by which the model with the armature must beat the declared one (a tie keeps the declared)
ARMATURE_TOLERANCE = 0.01


def armature_laws(model: IdentificationModel) -> tuple[Any, ...]:
    """``(Armature(),)``, the rotors' reflected inertia on every joint, when ``model`` models joint torques (not the
    external model: the base reaction holds no rotor term of its own) and declares no armature on any joint; else
    none."""
    if model.kind is ModelKind.EXTERNAL or any(getattr(effect, "name", "") == "armature" for effect in model.effects) \
            or not any(map(is_joint_torque, model.channels)):
        return ()
    return (Armature(),)


def armature_answer(selection: ModelSelection, other: ModelSelection) -> ModelSelection:
    """The default answer with the armature a candidate (module docstring): ``other`` (the selection of the model
    with ``armature`` added) when its answer scores lower on the validation record than the declared model's
    (``selection``) by more than :data:`ARMATURE_TOLERANCE`, else ``selection``; the reason gives both scores.
    Compared only when both selections were made on a validation record of another motion."""
    joints = [effect.joints for effect in other.unconstrained.model.effects
              if getattr(effect, "name", "") == "armature"]
    where = ("every joint" if not joints or joints[0] is None
             else "joints " + ", ".join(str(joint + 1) for joint in joints[0]))  # a still joint's left out
    return candidate_answer(selection, other, tolerance=ARMATURE_TOLERANCE,
                            added=f"the rotors' reflected inertia (armature on {where})")
