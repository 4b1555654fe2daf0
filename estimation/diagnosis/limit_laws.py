"""A shaped law whose shape runs to the limit where it is a plain law is that plain law.

The smoothed Coulomb law ``fc tanh(dq / vc)`` (:class:`dynamics.effects.shaped.TanhCoulombFriction`)
tends to ``fc sign(dq)`` as ``vc → 0``. When the rows the data keep never come near ``|dq| ≲ vc``
(rows at rest dropped, a smoothing below the velocity resolution), the data cannot tell ``vc`` from
any smaller value: the least-squares optimum sits at the lower bound of ``vc``, and the joint refit
of the diagnosis (:func:`estimation.diagnosis.search.diagnose`) reports the shape as not determined.

Why it matters (issue 18, the simulated PUMA 560 whose last motor turns with ``q5 + q6``): the forward
selection took a joint-5 ``coulomb:tanh`` *before* the coupled viscous law ``viscous[q5+q6]``, and
its smoothing (0.28 rad/s) absorbed part of that still-missing viscous term. Once
``viscous[q5+q6]`` was added, the joint refit moved ``vc5`` to its bound (the sign law), was refused
as undetermined, and the diagnosis kept the stale 0.28 rad/s: joint 5 ended at 2.5x its noise floor,
against 1.1x for the same effects with the plain Coulomb law.

Since the Coulomb and viscous laws of a joint combination are tried as one candidate
(:func:`estimation.diagnosis.candidates.coupling.combination_groups`) the diagnosis no longer takes that stale
law on this example; the rule stands for any shaped law selected before the effect it stood in for
(``tests/test_asbuilt_puma.py::test_a_stale_tanh_smoothing_is_replaced_by_the_sign_law``).

:func:`replace_limit_laws` (called when the joint refit fails or stops at a bound) replaces each such
law, one at a time, by its limit (``coulomb:tanh`` by ``coulomb``), refits the others' shapes, and
keeps the replacement when the refit succeeds and the weighted validation error, against the
channels as recorded, does not grow by more than ``min_improvement``.
"""

from __future__ import annotations

from collections.abc import Sequence
import numpy as np
from numpy.typing import NDArray

from dynamics.effects.linear import CoulombFriction, Effect
from dynamics.models import IdentificationModel, build_model
from dynamics.effects.shaped import TanhCoulombFriction, shape_parameters
from estimation.diagnosis.confirmation import weighted_validation
from estimation.identification.fit import IdentificationResult, identify
from dynamics.measurements import Measurements
from estimation.estimators.effect_blocks import ShapeSearchError

__all__ = ["limit_law", "replace_limit_laws"]


def limit_law(effect: Effect) -> Effect | None:
    """The plain law ``effect`` tends to at the small end of its shape (``coulomb:tanh`` → ``coulomb``
    as ``vc → 0``), or ``None``."""
    if isinstance(effect, TanhCoulombFriction):
        return CoulombFriction(joints=effect.joints)
    return None


def _shape_names(effect: Effect, model: IdentificationModel) -> set[str]:
    return {parameter.name for parameter in shape_parameters(effect, model.robot)}


def replace_limit_laws(selected: Sequence[tuple[Effect, float, float]], after: IdentificationResult,
                       model: IdentificationModel, train: Measurements, validate: Measurements,
                       starts: dict[str, float], weights: NDArray[np.float64], min_improvement: float
                       ) -> tuple[list[tuple[Effect, float, float]], IdentificationResult, dict[str, float]]:
    """``(selected, after, starts)`` with the found laws of :func:`limit_law` replaced, one at a time,
    by their limits where that does not raise the weighted validation error by more than
    ``min_improvement`` (relative) and the other shapes refit (a failed or at-bound refit keeps the law).

    A replacement is first screened with the other shapes where they are (no shape search): only one
    that already validates within the bound is refit with every shape searched (that refit costs
    seconds on seven joints; on the KUKA LWR4+ the refits of all eight smoothed laws took 35 of the
    diagnosis' 64 s, none kept; the stale joint-5 law of the coupled PUMA wrist screens at 0.80 of
    the bound).

    ``selected`` holds ``(effect, p_value, F)`` as in :func:`estimation.diagnosis.search.diagnose`; ``after``
    is the current final fit (shapes as selected), ``starts`` the shape starts by parameter name.
    """
    selected, starts = list(selected), dict(starts)
    for position in range(len(selected)):
        effect, p_value, statistic = selected[position]
        plain = limit_law(effect)
        if plain is None:
            continue
        trial = selected[:position] + [(plain, p_value, statistic)] + selected[position + 1:]
        kept = {name: value for name, value in starts.items() if name not in _shape_names(effect, model)}
        current = build_model(model.robot, model.kind, model.effects + tuple(e for e, _, _ in trial))
        bound = (1.0 + min_improvement) * weighted_validation(after, weights)
        try:  # a screen at the other shapes as they are (no search): a law the data keep is kept at once
            screened = weighted_validation(identify(current, train, validate, shape_starts=kept or None,
                                                    shape_search=False), weights)
            if screened > bound:
                continue
            candidate = identify(current, train, validate, shape_starts=kept or None)
        except ShapeSearchError:
            continue
        if any(value.at_bound for value in candidate.shapes):
            continue
        if weighted_validation(candidate, weights) <= bound:
            selected, after = trial, candidate
            starts = kept | {value.name: value.value for value in candidate.shapes}
    return selected, after, starts

