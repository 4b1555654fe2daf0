"""The joint refit of what a diagnosis found (:func:`estimation.diagnosis.search.diagnose`, step 5).

The declared model with the found effects (and the adopted delay) is identified again, every shape
searched jointly from where the forward selection left it. When that refit fails, runs a shape to a
bound or validates worse than the shapes as selected, the shapes stay as selected (and a smoothed
Coulomb law whose smoothing ran to its bound becomes the sign law, :mod:`estimation.diagnosis.limit_laws`); then
a several-term law the fit does not support becomes its simpler law (:func:`simplify_laws`), and a
friction or inertia term below zero is held at zero (:mod:`estimation.diagnosis.sign_constraints`).

The p-value of each finding is the Wald test of its coefficients from the covariance the refit reports
its standard deviations with (:func:`estimation.diagnosis.rules.robust_test.estimate_test`); a finding whose
coefficients are within their noise there is not named (:func:`refit_significant`: the weakest is
dropped and the rest refitted, until every finding is significant).
"""

from __future__ import annotations

import warnings
from collections.abc import Sequence

from dynamics.models import build_model
from dynamics.effects.shaped import shape_parameters
from estimation.diagnosis.confirmation import simplify_laws, weighted_validation
from estimation.diagnosis.candidates.delay_search import with_delay
from estimation.diagnosis.candidates.trials import candidate_label
from estimation.diagnosis.search_fits import AdoptedEffect
from estimation.diagnosis.rules.robust_test import WaldTest, estimate_test
from estimation.identification.fit import ImplausibleEstimateWarning, identify
from estimation.diagnosis.limit_laws import limit_law, replace_limit_laws
from estimation.preprocessing.delay import delayed
from estimation.diagnosis.sign_constraints import pin_wrong_signs
from estimation.estimators.effect_blocks import ShapeSearchError


def refit_found(model, before, adopted: Sequence[AdoptedEffect], moved, train, validate, weights,
                validation_error: float, min_improvement: float):
    """``(selected, after, pinned)``: the findings kept as ``[(effect, p_value, f_statistic)]``, the
    refitted model (carrying the delay, if one was adopted) and the terms held at zero.

    ``adopted``: the effects the search adopted, at their shapes as selected; ``moved``: the
    diagnosis' delay candidate (:class:`estimation.diagnosis.candidates.delay_search.DelaySearch`); ``train``,
    ``validate``: the records as given; ``weights``, ``validation_error``: the last adopted model's
    channel weights and weighted validation error.
    """
    after = before
    selected = [(item.effect, item.p_value, item.f_statistic) for item in adopted]
    if selected or moved.adopted is not None:
        current = build_model(model.robot, model.kind, model.effects + tuple(effect for effect, _, _ in selected))
        starts = {parameter.name: float(value) for item in adopted
                  for parameter, value in zip(shape_parameters(item.effect, model.robot), item.shape)}
        if before.shaped_fit is not None:
            starts.update({value.name: value.value for value in before.shapes})
        try:
            after = identify(current, train, validate, shape_starts=starts, delay=moved.final_bounds())
        except ShapeSearchError:  # the joint refit ran a shape to where the data do not determine it
            after = None
        # a smoothing run to its lower bound is the limit law (the sign law: estimation.diagnosis.limit_laws), not
        # a shape the data leave undetermined: the joint refit's delay stands, the law is replaced below along it
        limits = {name for item in adopted if limit_law(item.effect) is not None
                  for name in (parameter.name for parameter in shape_parameters(item.effect, model.robot))}
        undetermined = after is None or any(value.at_bound and not (value.name in limits and value.value - value.lower
                                                                    <= value.upper - value.value)
                                            for value in after.shapes)
        fallback = undetermined or any(value.at_bound for value in after.shapes) \
            or weighted_validation(after, weights) > 1.05 * validation_error
        # the refits below run along the records moved by the delay of the fit kept (the selection's when
        # the joint refit is rejected, the joint refit's when only a smoothing ran to its limit law), the delay
        # carried over
        limit_only = fallback and not undetermined and weighted_validation(after, weights) <= 1.05 * validation_error
        fitted_delay = after.delay if limit_only and after.delay is not None else \
            moved.adopted_value() if fallback or after.delay is None else after.delay
        if fitted_delay is not None:
            train, validate = delayed(train, fitted_delay.value), delayed(validate, fitted_delay.value)
        if fallback:
            # the joint refit of the shapes wandered off (to a bound, or worse on held-out data than the
            # shapes as selected): keep the shapes as selected, estimate the rest and the covariance there
            after = identify(current, train, validate, shape_starts=starts, shape_search=False)
            # a tanh smoothing run to its bound is the sign law (estimation.diagnosis.limit_laws)
            selected, after, starts = replace_limit_laws(selected, after, model, train, validate, starts, weights,
                                                         min_improvement)
        selected, after = simplify_laws(selected, after, model, train, validate, starts, weights, min_improvement)
    else:
        fitted_delay = None
    selected, after, pinned = pin_wrong_signs(selected, after, model, train, validate,
                                              starts if selected else {value.name: value.value for value in before.shapes})
    after = with_delay(after, fitted_delay)
    return selected, after, pinned


def _tested(selected, after, model) -> list[tuple[object, WaldTest]]:
    return [(effect, estimate_test(after.estimate, effect.parameter_names(model.robot))) for effect, _, _ in selected]


def refit_significant(model, before, adopted: Sequence[AdoptedEffect], moved, train, validate, weights,
                      validation_error: float, min_improvement: float, threshold: float):
    """``(selected, after, pinned, dropped)``: :func:`refit_found`, each finding's p-value and ``W / k``
    the Wald test from the refit's covariance; while a finding's p-value is not below ``threshold`` the
    weakest (lowest ``W``) is dropped from ``adopted`` and the rest refitted. ``dropped``: ``[(adopted
    effect, reason)]``."""
    adopted, dropped = list(adopted), []
    while True:
        with warnings.catch_warnings():  # the refits before the signs are held pass through negative friction;
            warnings.simplefilter("ignore", ImplausibleEstimateWarning)  # what remains is in after.warnings
            selected, after, pinned = refit_found(model, before, adopted, moved, train, validate, weights,
                                                  validation_error, min_improvement)
        tested = _tested(selected, after, model)
        weak = sorted(((test.statistic, candidate_label(effect), effect, test) for effect, test in tested
                       if test.p_value >= threshold), key=lambda entry: entry[:2])
        if weak:
            _, _, effect, test = weak[0]
            names = set(effect.parameter_names(model.robot))
            item = next((item for item in adopted if names & set(item.block.names)), None)
            if item is not None:
                records = {record["name"]: record for record in after.estimate.records()}
                values = ", ".join(f"{name} = {records[name]['value']:.4g} ± {records[name]['std']:.2g}"
                                   for name in effect.parameter_names(model.robot) if name in records)
                dropped.append((item, f"added, but in the final fit its coefficients are within their noise "
                                      f"({values}; Wald p = {test.p_value:.2g}): dropped"))
                adopted.remove(item)
                continue
        return [(effect, test.p_value, test.f_statistic) for effect, test in tested], after, pinned, dropped
