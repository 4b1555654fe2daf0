"""Physical signs in the final model of a diagnosis: a friction or inertia term estimated below zero is
held at zero (its bound), and the model refitted.

A viscous coefficient, a Coulomb level or a rotor inertia is positive by physics
(:data:`dynamics.effects.linear.POSITIVE_EFFECTS`). When the joint refit of a diagnosis leaves one below zero
(on the KUKA LWR4+, ``fv2 = −0.34 ± 0.20`` once a smoothed Coulomb law is on joint 2: a tanh law of
wide smoothing and a negative viscous term together make a friction that saturates), the estimate
that respects the sign is that of the least squares with the bound ``θ_i ≥ 0``; with the bound
active that is the model without the term. :func:`pin_wrong_signs` is that active-set step: the
term is removed (a declared effect keeps its other joints; a found effect whose coefficient turned
negative is dropped from the findings), the model refitted, and repeated until no positive-by-physics
term is negative. Each pinned term is reported with the estimate it had. A viscous slope differing by direction
(``viscous:direction``) is held the same way when its weaker direction's slope ``fv_j − |fvd_j|`` is at or below
zero (:func:`negative_estimates`). A term once held is not
re-admitted (the full bounded least squares would check its multiplier, Lawson–Hanson): a simpler,
conservative step; terms still negative after :data:`PASSES` passes are named in the result's warnings.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Any

from dynamics.effects.linear import POSITIVE_EFFECTS, Effect
from dynamics.models import IdentificationModel, build_model
from dynamics.effects.shaped import shape_parameters
from estimation.identification.fit import IdentificationResult, identify
from dynamics.measurements import Measurements

#: active-set passes (each refits the model once)
PASSES = 4


@dataclass(frozen=True)
class PinnedTerm:
    """A positive-by-physics term held at zero: the estimate it had, and the effect it belonged to."""

    parameter: str
    effect: str
    value: float
    std: float
    found: bool  # a found effect (dropped from the findings) rather than a declared one

    @property
    def reason(self) -> str:
        if self.effect.startswith("viscous:direction"):
            return (f"the weaker direction's viscous slope fv - |{self.parameter}| estimated {self.value:.4g}, at or "
                    "below zero (a friction pushing the joint along): the direction law on this joint removed and the "
                    "model refitted")
        text = f"estimated {self.value:.4g} ± {self.std:.2g}, below zero: held at its bound 0 and the model refitted"
        if self.std > 0 and self.value < -3.0 * self.std:
            text += (f" ({-self.value / self.std:.0f} standard deviations below zero: the model lacks an effect this "
                     "term was absorbing, or a sign or unit is wrong)")
        return text

    def to_dict(self) -> dict[str, Any]:
        return {"parameter": self.parameter, "effect": self.effect, "value": self.value, "std": self.std,
                "found": self.found, "reason": self.reason}


def _positive(effect: Effect) -> bool:
    return getattr(effect, "physical_kind", effect.name) in POSITIVE_EFFECTS


def negative_terms(result: IdentificationResult) -> dict[str, tuple[float, float]]:
    """Lone base parameters of positive-by-physics effects estimated below zero: name -> (value, std)."""
    return negative_estimates(result.model, result.estimate)


def negative_estimates(model: IdentificationModel, estimate: Any) -> dict[str, tuple[float, float]]:
    """:func:`negative_terms` of ``estimate`` (any estimate with ``records()``: a fit from sums too) of ``model``,
    with each viscous slope differing by direction whose weaker direction's slope ``fv_j − |fvd_j|`` is at or below
    zero (``fvd_j`` -> that slope and ``fvd_j``'s standard deviation; ``fv_j`` 0 where the joint has no viscous law or
    it is negative, held at zero in the same pass): by physics each direction's slope is positive."""
    positive = {name for effect in model.effects if _positive(effect) for name in effect.parameter_names(model.robot)}
    directions = {name for effect in model.effects if effect.name == "viscous:direction"
                  for name in effect.parameter_names(model.robot)}
    negative, values, direction_records = {}, {}, []
    for record in estimate.records():
        expression = record["expression"].strip()
        values[expression] = float(record["value"])
        if expression in positive and record["value"] < 0:
            negative[expression] = (float(record["value"]), float(record["std"]))
        elif expression in directions:
            direction_records.append((expression, float(record["value"]), float(record["std"])))
    for name, value, std in direction_records:
        slope = max(values.get("fv" + name.removeprefix("fvd"), 0.0), 0.0) - abs(value)
        if slope <= 0:
            negative[name] = (slope, std)
    return negative


def _without(effect: Effect, parameters: set[str], model: IdentificationModel) -> Effect | None:
    """``effect`` without the joints whose coefficients are in ``parameters`` (``None``: nothing left)."""
    names = effect.parameter_names(model.robot)
    if not set(names) & parameters:
        return effect
    fields = {field.name for field in dataclasses.fields(effect)} if dataclasses.is_dataclass(effect) else set()
    if "joints" not in fields:
        return None
    joints = effect.joints if effect.joints is not None else tuple(range(model.robot.n_joints))
    per_joint = max(len(names) // max(len(joints), 1), 1)
    kept = tuple(joint for position, joint in enumerate(joints)
                 if not set(names[position * per_joint:(position + 1) * per_joint]) & parameters)
    return dataclasses.replace(effect, joints=kept) if kept else None


def pinned_terms(effects: list[Effect], found: list[Effect], negative: dict[str, tuple[float, float]],
                 declared: IdentificationModel) -> tuple[list[Effect], list[Effect], list[PinnedTerm]]:
    """One pass of :func:`pin_wrong_signs` on effects: ``(declared effects kept, findings kept, terms held)``, the
    declared ``effects`` without the joints of the ``negative`` terms, the ``found`` effects without those holding
    one (dropped from the findings), each term held reported (in the effects' order: the report must not depend on
    the hash seed). The streamed diagnosis takes the same step on its sums (:mod:`estimation.streaming.diagnosis`)."""
    names, found_ids, pinned = set(negative), {id(effect) for effect in found}, []
    for effect in list(effects) + list(found):
        for name in (name for name in effect.parameter_names(declared.robot) if name in names):
            value, std = negative[name]
            pinned.append(PinnedTerm(name, getattr(effect, "spec", effect.name), value, std, id(effect) in found_ids))
    kept = [held for held in (_without(effect, names, declared) for effect in effects) if held is not None]
    return kept, [effect for effect in found if _without(effect, names, declared) is effect], pinned


def pin_wrong_signs(selected: list, after: IdentificationResult, declared: IdentificationModel, train: Measurements,
                    validate: Measurements, starts: dict[str, float]) -> tuple[list, IdentificationResult,
                                                                                 tuple[PinnedTerm, ...]]:
    """Hold every negative positive-by-physics term of ``after`` at zero and refit, until none is left.

    Parameters
    ----------
    selected
        The diagnosis' findings, ``[(effect, p_value, f_statistic)]``.
    after
        The refitted augmented model (declared effects plus findings).
    declared
        The declared model.
    train, validate
        The records, as given to the diagnosis.
    starts
        Shape values to start the refit from, by name.

    Returns
    -------
    selected, after, pinned
        The findings without those dropped, the refitted model, and the terms held at zero.
    """
    pinned: list[PinnedTerm] = []
    effects = list(declared.effects)
    for _ in range(PASSES):
        negative = negative_terms(after)
        if not negative:
            break
        names = set(negative)
        found_names = {id(effect) for effect, _, _ in selected}
        for effect in list(effects) + [effect for effect, _, _ in selected]:
            for name in (name for name in effect.parameter_names(declared.robot) if name in names):  # in order:
                # the report must not depend on the hash seed
                value, std = negative[name]
                pinned.append(PinnedTerm(name, getattr(effect, "spec", effect.name), value, std, id(effect) in found_names))
        effects = [kept for kept in (_without(effect, names, declared) for effect in effects) if kept is not None]
        selected = [entry for entry in selected if _without(entry[0], names, declared) is entry[0]]
        current = build_model(declared.robot, declared.kind, tuple(effects) + tuple(effect for effect, _, _ in selected))
        shape_names = {parameter.name for effect in current.effects for parameter in shape_parameters(effect, current.robot)}
        latest = {**starts, **{value.name: value.value for value in after.shapes}}
        kept_starts = {name: value for name, value in latest.items() if name in shape_names} or None
        # the shapes stay where the joint refit put them: removing a term is a small change, and a
        # search from there could run a shape off to a bound for a term that is no longer there
        after = identify(current, train, validate, shape_starts=kept_starts, shape_search=False)
    left = negative_terms(after)
    if left:  # said, never silent
        after = dataclasses.replace(after, warnings=tuple(after.warnings) + (
            f"after {PASSES} passes holding negative friction or inertia at zero, still negative: "
            + ", ".join(f"{name} = {value:.4g} ± {std:.2g}" for name, (value, std) in left.items()),))
    return selected, after, tuple(pinned)
