"""Candidate effects on combinations of joint velocities, for the residual diagnosis.

A residual that follows friction or inertia on a combination of joints (a motor turning with
``q5 + q6`` in a coupled wrist, a belt, a differential) cannot be described by per-joint effects:
the torque appears on two rows at once with a law of the combined velocity,
``τ = r (fc sign(r q̇))`` with ``r = e5 + e6``. :func:`coupling_candidates` proposes

* for each adjacent pair of joints, friction (viscous, Coulomb) and inertia on ``qj + qj+1`` and
  ``qj − qj+1`` (:func:`dynamics.motor_effects.pair_combinations`): named ``coulomb[q5+q6]``;
* for each coupled motor of a declared transmission, friction and inertia on that motor
  (:func:`dynamics.motor_effects.motor_effects`): named ``motor_coulomb[m6]``.

The forward selection of :func:`estimation.diagnosis.diagnose` tests them beside the per-joint
candidates (F test, identifiability, physical sign, confirmation on held-out data), so a coupling
is reported only when it explains the residual better than any per-joint effect.
"""

from __future__ import annotations

from dynamics.effects import Effect
from dynamics.models import IdentificationModel, ModelKind
from dynamics.motor_effects import KINDS, motor_effects, pair_combinations
from dynamics.transmission import Transmission


def coupling_candidates(model: IdentificationModel, transmission: Transmission | None = None, *,
                        pairs: bool = True) -> tuple[Effect, ...]:
    """Friction and inertia on adjacent joint pairs (``pairs``) and on the coupled motors of
    ``transmission``; none for the external model (friction is internal) or a one-joint robot.
    Candidates already in the model are left out."""
    if model.kind is ModelKind.EXTERNAL:
        return ()
    declared = {effect.name for effect in model.effects}
    candidates: list[Effect] = []
    for kind in KINDS:
        if pairs:
            candidates.extend(pair_combinations(model.robot.n_joints, kind))
        if transmission is not None:
            transmission.check(model.robot)
            candidates.extend(motor_effects(transmission, kind, transmission.coupled_motors()))
    return tuple(candidate for candidate in candidates if candidate.name not in declared)
