"""Each joint's diagnosed effects against the plain friction law, judged on that joint's validation error.

The search (:mod:`estimation.diagnosis.forward_selection`) moves one effect at a time, ranked by the training
record: on a joint it can adopt a law that validates (a coupled ``coulomb:tanh[q2-q3]`` that lowers joint 3's
validation error by a quarter) and then refuse every law of the joint's own (against the adopted one, each turns
negative), although the plain law, Coulomb friction and an offset on the joint, validates far better there (the
Stäubli TX40's joint 3: 13.4 against 4.8 N²m², and 37 against 8.4 on the test record, ``benchmarks/README.md``).
The forward search never compares the two models; this step does, once the search is over.

**The plain model** is the declared model plus Coulomb friction and an offset on every joint that does not declare
them (the model class of a plain least-squares fit), fitted on the same training samples (along the records moved
by an adopted delay, shaped laws at their fitted shapes). A joint's torque equation is where its effects act, so
the comparison is joint by joint: a joint whose validation MSE the plain model lowers by at least
``min_improvement`` (relative) against the diagnosed model, and for which swapping only that joint's diagnosed
effects for the plain law lowers it too, takes the plain law; the diagnosed effects acting on it are dropped (with
them the joints a dropped coupled law acts on, which then take the plain law too). The model so **mixed** is
adopted when it predicts the validation record better than the diagnosed one by the criterion of the default
answer (:mod:`estimation.consistent.model_selection`: the geometric mean over channels of the validation MSE) and
no friction or inertia term of it is below zero; a plain term within its noise there (Wald test at the search's
threshold), of the wrong sign or absorbed by the base parameters is left out and the model refitted without it.
The declared effects are those the diagnosis left (a declared term it held at zero stays so). Only when the
validation record is another motion: on a repeat of the training motion the validation error does not measure
how a law extrapolates, and the diagnosis is kept as the search left it.

**A shaped law's shape must be measured.** A joint whose diagnosed friction law has a shape beyond the plain law's
levels (``coulomb:tanh``, ``sigmoid``, a shaped Stribeck law) keeps it only when the validation record measures its
gain over the plain law, by more than :data:`~estimation.preprocessing.plan.TIED_SE` standard errors of the
difference (means of :data:`~estimation.identification.preprocessing_on_validation.BLOCKS` contiguous blocks,
:func:`measured_gain`). The shape is one more effect over the plain law, and no effect is adopted unless it lowers
the error on data its choice did not see: on a simulated servo arm whose truth is the sign law, the torques fitted as
recorded, a ``sigmoid`` on joint 3 fitted its shift to the few training samples at the zero crossings (its sign change
at +0.0034 rad/s), validated 0.2 standard errors from the plain law, and predicted the test record's joint 3 3.4
times worse than the plain fit (``benchmarks/README.md``, h-band). This comes after the swap above (which it leaves
as it is) and costs a fit only where it can change the answer: the screen reads the plain model's fit (no new fit),
the diagnosed model's gain over it on each shaped joint not taken by the swap, then on those joints together (the
mean over their channels of the log MSE); on the joints it leaves, each shaped law gives way to its plain limit in one
mixed model (beside the swap's joints; the joints' other diagnosed effects stay), the simplest first: Coulomb friction
on each joint it acts on, then, on a sigmoid's joint, Coulomb friction and an offset (its two levels); a joint whose
gain the mixed model measures keeps its law (the model refitted without it). The mixed model
is refused only when the validation record measures the gain of the model it would replace (the log of the score; the
model is judged before its weak plain terms are left out, and again after); a refused one is not kept for the
default answer's candidates (the swap's ``keep_refused`` below), since the validation record measured its loss.

**The plain law completed on a repeat** (:func:`plain_completion`). On a repeat of the training motion the search's
refusals were not measured on another motion either: a joint's Coulomb law that lowers the validation error can be
refused by the Wald test at the search's Bonferroni threshold (the KUKA LWR4+'s joint 1 from positions only: Wald
p = 8e-4 against a threshold near 1e-5; its test error 2.0x the plain fit's without it, 1.0x with it,
``benchmarks/README.md``). The default answer of ``oed diagnose`` then takes the diagnosed model with the plain law
added on each joint the diagnosis left without one (Coulomb friction where no friction law with a Coulomb level acts
on the joint, an offset where none does), when its consistent refit predicts the validation record better than the
diagnosed model's (:func:`oed.workflows.diagnose.completed_selection`): the model class of a plain least-squares fit is the least the answer holds when nothing
measured the extrapolation of what the search left out. The added laws are not named as findings. On a validation
record of another motion the completed model is a candidate too: its answer (the better of as fitted and its
consistent refit) replaces the adopted model's when it predicts the validation record better (the KUKA LWR4+
trained on run 2 and validated on run 3: no law on tau3 left its test error 1.5x the plain fit's, 0.9x completed).

**Refused on the fits, judged on the answer.** The comparison above is between the two unconstrained fits, but the
default answer of ``oed diagnose`` is the better of the adopted model as fitted and its consistent refit. The shared
rigid-body parameters of an unconstrained fit move with the laws (a joint's validation error can rise when another
joint takes the plain law), which the description's bodies as prior hold in place. So a mixed model refused only
on its score is returned with ``keep_refused=True``, marked ``adopted=False``: the caller that makes the default
answer (:func:`oed.workflows.diagnose.judged_swap`) compares the better of {as fitted, consistent refit} of each
model by the same criterion on the same validation samples, and adopts it only when it wins there. A mixed model
with a negative friction or inertia term stays refused.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from dynamics.effects.linear import CoulombFriction, Effect, JointOffset, StribeckFriction
from dynamics.effects.shaped import FRICTION_LAWS, shape_parameters
from dynamics.measurements import Measurements
from dynamics.models import IdentificationModel, ModelKind, build_model
from estimation.diagnosis.candidates.delay_search import with_delay
from estimation.diagnosis.rules.robust_test import estimate_test
from estimation.diagnosis.sign_constraints import negative_terms
from estimation.estimators.effect_blocks import ShapeSearchError, effect_rows
from estimation.identification.fit import IdentificationResult, identify
from estimation.identification.preprocessing_choice import geometric_mean
from estimation.identification.preprocessing_on_validation import BLOCKS
from estimation.identification.repeated_motion import REPEAT_FRACTION, repeated_motion
from estimation.preprocessing.plan import TIED_SE
from estimation.preprocessing.delay import delayed

__all__ = ["PlainLawChoice", "completion_laws", "plain_completion", "plain_law_choice", "plain_model", "plain_model_effects"]


@dataclass(frozen=True)
class PlainLawChoice:
    """The mixed model and why (module docstring).

    Attributes
    ----------
    after
        The mixed model's fit (carrying the diagnosis's delay, if any).
    effects
        Its effects beyond the declared ones: the diagnosed effects kept, then the plain laws.
    plain
        The plain laws added, each a per-joint Coulomb law or offset.
    dropped
        ``[(effect, reason)]``: the diagnosed effects the plain law replaced.
    scores
        ``(diagnosed, mixed)``: the validation scores compared.
    adopted
        Whether the mixed model scores lower than the diagnosed one as fitted (``False``: refused on the
        unconstrained fits, returned only with ``keep_refused=True``, module docstring).
    """

    after: IdentificationResult
    effects: tuple[Effect, ...]
    plain: tuple[Effect, ...]
    dropped: tuple[tuple[Effect, str], ...]
    scores: tuple[float, float]
    adopted: bool = True


def _score(result: IdentificationResult) -> float:
    mse = result.validation.mse
    return geometric_mean(np.array([mse[channel] for channel in result.validation.channels]))


def _blocks(values: NDArray[np.float64]) -> NDArray[np.float64]:
    """Means of ``values`` (samples along axis 0) on :data:`BLOCKS` contiguous blocks."""
    return np.array([part.mean(axis=0) for part in np.array_split(values, BLOCKS, axis=0)])


def measured_gain(better: IdentificationResult, other: IdentificationResult, row: int | None = None, *,
                  rows: Sequence[int] | None = None) -> bool:
    """Whether the validation record measures ``better``'s gain over ``other``: on channel ``row`` its validation MSE
    (``None``: the log of the score, :func:`_score`, over the channels ``rows``, ``None``: all) lower by more than
    :data:`TIED_SE` standard errors of the difference, the standard error that of a mean of the :data:`BLOCKS`
    contiguous blocks' differences (as the derivative candidates' ties,
    :func:`estimation.identification.preprocessing_on_validation.with_standard_errors`). Without the samples (errors
    from sums): whether it is lower."""
    ours, theirs = better.validation, other.validation
    residuals = (getattr(ours, "residuals", None), getattr(theirs, "residuals", None))
    columns = list(range(len(ours.channels)) if rows is None else sorted(rows))
    if row is not None:
        channel = ours.channels[row]
        difference = theirs.mse[channel] - ours.mse[channel]
    else:  # the mean over the channels of the log MSE
        difference = float(np.mean([np.log(theirs.mse[ours.channels[column]]) - np.log(ours.mse[ours.channels[column]])
                                    for column in columns]))
    if any(values is None for values in residuals) or residuals[0].shape != residuals[1].shape \
            or residuals[0].shape[0] < 2 * BLOCKS:
        return difference > 0
    if row is not None:
        blocks = _blocks(residuals[1][:, row] ** 2) - _blocks(residuals[0][:, row] ** 2)
    else:  # the log score on each block: the mean over channels of the log MSE
        floor = np.finfo(float).tiny
        blocks = np.mean(np.log(np.maximum(_blocks(residuals[1][:, columns] ** 2), floor))
                         - np.log(np.maximum(_blocks(residuals[0][:, columns] ** 2), floor)), axis=1)
    return difference > TIED_SE * float(np.std(blocks, ddof=1)) / np.sqrt(BLOCKS)


def _shaped_law(model: IdentificationModel, effect: Effect) -> bool:
    """Whether ``effect`` is a friction law with a shape fitted beyond the plain law's levels (``coulomb:tanh``,
    ``sigmoid``, a shaped Stribeck law)."""
    return effect.name in FRICTION_LAWS and bool(shape_parameters(effect, model.robot))


def plain_model_effects(model: IdentificationModel, joints: Sequence[int], *,
                        level: bool = False) -> tuple[Effect, ...]:
    """Coulomb friction and an offset on each of ``joints`` that the declared ``model`` does not give them;
    ``level``: the linear Stribeck law (:class:`dynamics.effects.linear.StribeckFriction`, the static-friction bump
    at low speed alone) does not count as its joint's friction law, since it holds no Coulomb level at speed."""
    declared = {(effect.name, parameter) for effect in model.effects for parameter in effect.parameter_names(model.robot)}
    laws = {joint for effect in model.effects if effect.name in FRICTION_LAWS
            and not (level and isinstance(effect, StribeckFriction))
            for joint in (range(model.robot.n_joints) if getattr(effect, "joints", None) is None else effect.joints)}
    added: list[Effect] = []
    for joint in joints:
        for effect in (CoulombFriction(joints=(joint,)), JointOffset(joints=(joint,))):
            if effect.name == "coulomb" and joint in laws:
                continue
            if not {(effect.name, name) for name in effect.parameter_names(model.robot)} & declared:
                added.append(effect)
    return tuple(added)


def plain_model(model: IdentificationModel) -> IdentificationModel:
    """The plain model of ``model`` (module docstring): its effects plus Coulomb friction and an offset on every
    joint that does not declare them (:func:`plain_model_effects`); ``model`` itself when nothing is added (the
    external model, where friction has no rows)."""
    added = plain_model_effects(model, range(model.robot.n_joints)) if model.kind is not ModelKind.EXTERNAL else ()
    return build_model(model.robot, model.kind, (*model.effects, *added)) if added else model


def completion_laws(model: IdentificationModel) -> tuple[Effect, ...]:
    """The plain laws a completion adds to ``model`` (:func:`plain_completion`, and the streamed one of
    :mod:`estimation.streaming.diagnosis_selection`): Coulomb friction and an offset on each joint that holds none
    (:func:`plain_model_effects` with ``level=True``); none on the external model."""
    if model.kind is ModelKind.EXTERNAL:
        return ()
    return plain_model_effects(model, range(model.robot.n_joints), level=True)


def plain_completion(after: IdentificationResult, train: Measurements, validate: Measurements | None
                     ) -> tuple[IdentificationResult, tuple[Effect, ...]] | None:
    """The diagnosed model ``after`` (declared plus found effects) with the plain law added on every joint that has
    none (:func:`plain_model_effects`: Coulomb friction where no friction law with a Coulomb level acts on the joint,
    the linear Stribeck bump alone holding none; an offset where none does), fitted on the same records as ``after``
    (the same weighting; shaped laws held at their fitted shapes; along the records moved by its
    delay), and the laws added; ``None`` when nothing is added (the external model, or every joint already holds
    both) or the fit fails (module docstring: on a repeat of the training motion)."""
    model = after.model
    added = completion_laws(model)
    if not added:
        return None
    if after.delay is not None:  # along the records moved by the diagnosis's delay, held at its value
        train = delayed(train, after.delay.value)
        validate = None if validate is None else delayed(validate, after.delay.value)
    starts = {value.name: value.value for value in after.shapes if value.name != "delay"}
    try:
        completed = identify(build_model(model.robot, model.kind, (*model.effects, *added)), train, validate,
                             weighted=after.estimate.method == "wls", shape_starts=starts or None, shape_search=False)
    except (ShapeSearchError, ValueError, np.linalg.LinAlgError):
        return None
    return with_delay(completed, after.delay), added


def plain_law_choice(model: IdentificationModel, after: IdentificationResult, found: Sequence[Effect],
                     train: Measurements, validate: Measurements, *, min_improvement: float,
                     max_effects: int | None = None, threshold: float | None = None,
                     keep_refused: bool = False) -> PlainLawChoice | None:
    """The mixed model when it validates better than the diagnosed one ``after`` (whose effects beyond the declared
    ``model``'s are ``found``), else ``None`` (module docstring). ``train``, ``validate``: the records as given;
    ``max_effects``: the most effects the diagnosis may name (the delay counted), which the mixed model respects;
    ``threshold``: a plain term whose Wald p-value in the mixed model is not below it, or a Coulomb term estimated
    below zero, is not named (the model is refitted without it), as the joint refit drops a finding within its
    noise and the search a law of the wrong sign; ``keep_refused``: return the mixed model, ``adopted=False``, when
    only its score refuses it (module docstring)."""
    if model.kind is ModelKind.EXTERNAL or after.validation is None or not found:
        return None
    if repeated_motion(train, validate) <= REPEAT_FRACTION:
        return None
    if after.delay is not None:  # along the records moved by the diagnosis's delay, held at its value
        train, validate = delayed(train, after.delay.value), delayed(validate, after.delay.value)
    starts = {value.name: value.value for value in after.shapes if value.name != "delay"}
    n_joints = model.robot.n_joints
    # the declared effects as the diagnosis left them (a declared term of the wrong sign held at zero stays so)
    base = tuple(effect for effect in after.model.effects if effect not in found)
    reached: dict[Effect, tuple[int, ...]] = {}  # each effect's channels, worked out once for this choice

    def rows_of(effect: Effect) -> tuple[int, ...]:
        """The channels ``effect`` reaches (:func:`_rows`: a function of the effect and the model alone)."""
        if effect not in reached:
            reached[effect] = _rows(model, effect)
        return reached[effect]

    fitted: dict[tuple[Effect, ...], IdentificationResult | None] = {}  # a swap of one joint is the mixed model

    def fit(effects: tuple[Effect, ...]) -> IdentificationResult | None:
        if effects in fitted:  # the same effects, the same records and starts: the same fit
            return fitted[effects]
        names = {parameter.name for effect in effects for parameter in shape_parameters(effect, model.robot)}
        try:
            result = identify(build_model(model.robot, model.kind, base + effects), train, validate,
                              weighted=after.estimate.method == "wls",
                              shape_starts={name: value for name, value in starts.items() if name in names} or None,
                              shape_search=False)
        except (ShapeSearchError, ValueError, np.linalg.LinAlgError):
            result = None
        fitted[effects] = result
        return result

    plain = fit(plain_model_effects(model, range(n_joints)))
    if plain is None:
        return None
    channels = model.channels
    diagnosed_mse, plain_mse = after.validation.mse, plain.validation.mse

    def better(result: IdentificationResult, row: int) -> bool:
        return result.validation.mse[channels[row]] < (1.0 - min_improvement) * diagnosed_mse[channels[row]]

    def closure(rows: set[int]) -> set[int]:  # a dropped coupled law leaves its other joints: they take the plain law
        while True:
            touched = set().union(*(set(rows_of(effect)) for effect in found if set(rows_of(effect)) & rows))
            grown = rows | {row for row in touched if row < n_joints}
            if grown == rows:
                return rows
            rows = grown

    shaped = {row for effect in found if _shaped_law(model, effect) for row in rows_of(effect) if row < n_joints}

    def plain_laws(rows: set[int], levels: set[int]) -> tuple[Effect, ...]:
        # the plain law, Coulomb friction and an offset; a shaped row not in ``levels`` takes its simplest limit,
        # Coulomb friction alone
        with_offset = (rows - shaped) | (rows & levels)
        laws = plain_model_effects(model, sorted(with_offset)) + tuple(
            effect for effect in plain_model_effects(model, sorted(rows - with_offset)) if effect.name == "coulomb")
        return tuple(sorted(laws, key=lambda effect: (effect.joints, effect.name != "coulomb")))  # one order: one fit

    def swapped(rows: set[int]) -> tuple[Effect, ...]:
        return tuple(effect for effect in found if not set(rows_of(effect)) & rows) + plain_laws(rows, rows)

    def mixed_fit(joints: set[int], levels: set[int], *, weak: bool = True
                  ) -> tuple[tuple[Effect, ...], tuple[Effect, ...], IdentificationResult] | None:
        """The diagnosed model with the plain law on ``joints`` (kept effects, plain laws, fit); ``weak``: its plain
        terms within their noise or of the wrong sign left out (``threshold``)."""
        kept = tuple(effect for effect in found if not set(rows_of(effect)) & joints)
        return laws_fit(kept, (), plain_laws(joints, levels), weak=weak)

    def laws_fit(kept: tuple[Effect, ...], held: tuple[Effect, ...], laws: tuple[Effect, ...], *, weak: bool = True
                 ) -> tuple[tuple[Effect, ...], tuple[Effect, ...], IdentificationResult] | None:
        """The model of the diagnosed effects ``kept``, the plain laws ``held`` and ``laws`` (the latter left out
        when weak): (kept, plain laws, fit)."""
        if max_effects is not None and len(kept) + len(held) + len(laws) + (after.delay is not None) > max_effects:
            return None
        mixed = fit(kept + held + laws)
        if mixed is None:
            return None
        if threshold is not None and weak:  # a plain term within its noise (an offset on a joint that has none) or
            # of the wrong sign is not named
            values = dict(zip(mixed.estimate.names, mixed.estimate.values))
            weak_laws = [law for law in laws  # (a term the base parameters absorb has no estimate of its own: not named)
                         if not set(law.parameter_names(model.robot)) <= set(values)
                         or estimate_test(mixed.estimate, law.parameter_names(model.robot)).p_value >= threshold
                         or (law.name == "coulomb"
                             and any(values[name] < 0 for name in law.parameter_names(model.robot)))]
            if weak_laws:
                laws = tuple(law for law in laws if law not in weak_laws)
                mixed = fit(kept + held + laws)
                if mixed is None:
                    return None
        return kept, held + laws, mixed

    # 1. screened by the plain model, confirmed joint by joint: the diagnosed model with only that joint's effects
    # swapped for the plain law must predict that joint better (the plain model's other laws also move the shared
    # rigid-body parameters, which can lower a joint's error that its own law does not)
    joints: set[int] = set()
    for row in (row for row in range(n_joints) if better(plain, row)):
        swap = fit(swapped(closure({row})))
        if swap is not None and better(swap, row):
            joints |= closure({row})
    outcome = None
    if joints:
        made = mixed_fit(joints, joints)
        if made is not None:
            scores = (_score(after), _score(made[2]))
            outcome = (joints, *made, scores, scores[1] < scores[0])
            if (not outcome[-1] and not keep_refused) or negative_terms(made[2]):  # a friction or inertia below
                outcome = None  # zero: not physical
    # 2. a shaped law's shape stands only when the validation record measures its gain over the plain law: the
    # screen reads the plain model's fit (no new fit), and only a joint it leaves costs fits, all of them in one
    # mixed model (its shaped rows confirmed there), the simplest limit first; adopted unless the validation record
    # measures the gain of the model it would replace
    taken = joints if outcome is not None and outcome[-1] else set()
    reference = outcome[3] if outcome is not None and outcome[-1] else after
    screened = {row for row in shaped - taken if not measured_gain(after, plain, row)}
    if screened and measured_gain(after, plain, rows=screened):  # the shapes' gain measured on those joints together
        screened = set()

    def adopted(made: tuple[tuple[Effect, ...], tuple[Effect, ...], IdentificationResult] | None) -> bool:
        # refused only when the validation record measures the gain of the model it would replace
        return made is not None and not negative_terms(made[2]) and (
            _score(made[2]) < _score(reference) or not measured_gain(reference, made[2]))

    # the model the shaped laws' limits start from: the swap's, when adopted, else the diagnosed one
    current = (tuple(effect for effect in found if effect in outcome[1]), outcome[2]) if taken else (tuple(found), ())

    def limited(rows: set[int], levels: set[int], *, weak: bool = True
                ) -> tuple[set[int], tuple[tuple[Effect, ...], tuple[Effect, ...], IdentificationResult] | None]:
        """The shaped laws acting on ``rows`` replaced by their plain limit, Coulomb friction on each joint they act on
        (with an offset on a joint of ``levels``) that the effects kept leave without it: (their joints, fit)."""
        limits = [effect for effect in current[0] if _shaped_law(model, effect) and set(rows_of(effect)) & rows]
        kept = tuple(effect for effect in current[0] if effect not in limits)
        acted = {row for effect in limits for row in rows_of(effect) if row < n_joints}
        left = plain_model_effects(build_model(model.robot, model.kind, base + kept + current[1]), sorted(acted),
                                   level=True)
        laws = tuple(effect for effect in left if effect.name == "coulomb" or set(effect.joints) & levels)
        return acted, laws_fit(kept, current[1], laws, weak=weak)

    rows = set(screened)
    sigmoids = {row for effect in found if effect.name == "sigmoid" for row in rows_of(effect) if row < n_joints}
    for levels in (set(), sigmoids):  # Coulomb friction alone, then with an offset on a sigmoid's joint (its levels)
        if levels and not rows & levels:
            break
        made = None
        while rows:  # the shaped rows confirmed in the mixed model: one whose gain it measures keeps its law
            acted, made = limited(rows, levels, weak=False)
            confirmed = set() if made is None else {row for row in rows if not measured_gain(after, made[2], row)}
            if confirmed == rows:
                break
            rows = confirmed
        if not rows or not adopted(made):  # judged before the weak terms are left out: a refusal costs no refit
            continue
        acted, made = limited(rows, levels)
        if adopted(made):
            outcome = (taken | acted, *made, (_score(after), _score(made[2])), True)
            break
    if outcome is None:
        return None
    joints, kept, laws, mixed, scores, adopted = outcome
    mixed = with_delay(mixed, after.delay)
    why = ", ".join(f"{channels[row]} {diagnosed_mse[channels[row]]:.4g} -> {plain_mse[channels[row]]:.4g}"
                    + ("" if better(plain, row) else " (the shaped law's gain not measured there)")
                    for row in sorted(joints) if better(plain, row) or row in screened)
    verdict = (f"the model with it instead scores {scores[1]:.4g} against {scores[0]:.4g}" if adopted else
               f"the model with it instead scores {scores[1]:.4g} against {scores[0]:.4g} as fitted, but the better "
               "of it as fitted and its consistent refit validates better than the diagnosed model's "
               "(the default answer's candidates)")
    dropped = tuple((effect, f"added, but on {', '.join(channels[row] for row in rows_of(effect))} the plain "
                             f"law (Coulomb friction and an offset) validates better (validation MSE {why}); "
                             f"{verdict}: replaced")
                    for effect in found if effect not in kept)
    return PlainLawChoice(mixed, kept + laws, laws, dropped, scores, adopted)


def _rows(model: IdentificationModel, effect: Effect) -> tuple[int, ...]:
    return tuple(effect_rows(model.kind, model.robot, effect, model.n_channels))
