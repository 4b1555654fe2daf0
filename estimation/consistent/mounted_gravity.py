"""A gravity the mount check found, as a candidate of the default answer.

A robot on a wall, on the ceiling or off level whose description gives no mount has a gravity load the model with
the description's gravity cannot hold (on a simulated PUMA 560 on a wall, both the toolkit and a plain least-squares
fit predicted joint 1 at 4500 times the noise floor: ``benchmarks/README.md``, h-unseen8). The mount check
(:func:`estimation.identification.mount.check_mount`) finds the direction of gravity in the base frame that predicts
the validation record best, and marks it only under conditions that keep a floor-standing robot from being told
otherwise (half the validation error or less, no channel worse, the description's own bodies no worse with it).

The check also scores the fit without gravity: a log whose torques hold no gravity load (a controller that
subtracts its gravity model before logging, a logger of torques without gravity) is predicted better by it, and it
is said and tried as the mount is, as gravity ``(0, 0, 0)``. The regressor is linear in gravity, so the model with
the found gravity is the same model of a robot whose description says that mount: :func:`turned_model` builds it (the description's robot with that gravity vector). The
verbs then choose that model's answer among its own candidates as they choose the declared model's
(:func:`estimation.consistent.model_selection.select_model`, ``select_refit``), and :func:`gravity_answer` compares
the two answers on the same validation samples by the default answer's criterion: the found gravity is taken only
when its answer scores lower by more than :data:`GRAVITY_TOLERANCE` (a tie keeps the description's gravity), and only
on a validation record of another motion, as the armature and motor-side friction are
(:mod:`estimation.consistent.armature`). The result file then holds that gravity (``gravity``, the base frame) for
``oed predict`` and ``oed export``.

Where the check says the torques hold no gravity load, a third candidate is the exact model of the commonest such
log, a controller that subtracts the description's gravity model before logging: the declared model with the
description's gravity fitted to the torques with the description's gravity torque added back
(:mod:`estimation.identification.subtracted_load`). No gravity holds the part of the load the description's bodies
give; this model holds also the difference between the true bodies' load and the description's (on a simulated
PUMA 6 with bodies ±20 % off: 0.180 against 0.296 N²m² on a test record, the floor 0.177: ``benchmarks/README.md``).
:func:`subtracted_answer` compares it with the answer chosen between the description's gravity and none, on the
same validation samples (the errors of the model less the load against the torques as logged are those of the model
against the torques with the load added back), by the same criterion and :data:`GRAVITY_TOLERANCE`; the result file
then holds ``subtracted`` for ``oed predict`` and ``oed export``.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import ArrayLike

from dynamics.models import IdentificationModel, build_model
from estimation.consistent.model_selection import ModelSelection, answers_scored, candidate_answer

__all__ = ["GRAVITY_TOLERANCE", "gravity_answer", "gravity_words", "subtracted_answer", "turned_model"]

#: the relative score by which the answer with the found gravity must beat the description's (a tie keeps it)
GRAVITY_TOLERANCE = 0.01


def turned_model(model: IdentificationModel, gravity: ArrayLike) -> IdentificationModel:
    """``model`` (its kind and effects) of its robot with the gravity vector ``gravity`` (m/s², the base frame)."""
    gravity = np.asarray(gravity, dtype=float).reshape(-1)
    if gravity.shape != (3,) or not np.all(np.isfinite(gravity)):
        raise ValueError(f"gravity must be a finite 3-vector, got {gravity!r}")
    return build_model(model.robot.with_gravity(gravity), model.kind, model.effects)


def gravity_words(gravity: Sequence[float]) -> str:
    """``(gx, gy, gz) m/s² in the base frame``, four significant digits each (``none`` when zero)."""
    if not np.any(np.asarray(gravity, dtype=float)):
        return "none (the torques hold no gravity load)"
    return f"({', '.join(f'{float(value):.4g}' for value in gravity)}) m/s² in the base frame"


def gravity_answer(selection: ModelSelection, other: ModelSelection, gravity: Sequence[float]
                   ) -> tuple[ModelSelection, bool]:
    """The default answer with the found ``gravity`` a candidate (module docstring): ``(other, True)`` (the selection
    of the model with that gravity) when its answer scores lower on the validation record than ``selection``'s (the
    description's gravity) by more than :data:`GRAVITY_TOLERANCE`, else ``(selection, False)``; the reason gives both
    scores. ``selection`` unchanged unless both were chosen on a validation record of another motion."""
    scored = answers_scored(selection, other)
    if scored is None:
        return selection, False
    answer = candidate_answer(selection, other, tolerance=GRAVITY_TOLERANCE,
                              added=f"the gravity the mount check found, {gravity_words(gravity)}")
    return answer, bool((1.0 + GRAVITY_TOLERANCE) * scored[1] < scored[0])


def subtracted_answer(selection: ModelSelection, other: ModelSelection) -> tuple[ModelSelection, bool]:
    """The default answer with the description's gravity torque subtracted by the logger a candidate (module
    docstring): ``(other, True)`` (the selection of the declared model fitted to the torques with that load added
    back) when its answer scores lower on the validation record than ``selection``'s (the answer chosen between the
    description's gravity and none, :func:`gravity_answer`) by more than :data:`GRAVITY_TOLERANCE`, else
    ``(selection, False)``; the reason gives both scores."""
    scored = answers_scored(selection, other)
    if scored is None:
        return selection, False
    answer = candidate_answer(selection, other, tolerance=GRAVITY_TOLERANCE,
                              added="the description's gravity torque subtracted by the logger (added back to the "
                                    "torques before fitting, subtracted from the model's when predicting)")
    return answer, bool((1.0 + GRAVITY_TOLERANCE) * scored[1] < scored[0])
