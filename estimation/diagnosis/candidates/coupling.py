"""Candidate effects on combinations of joint velocities, for the residual diagnosis.

A residual that follows friction or inertia on a combination of joints (a motor turning with
``q5 + q6`` in a coupled wrist, a belt, a differential) cannot be described by per-joint effects:
the torque appears on two rows at once with a law of the combined velocity,
``τ = r (fc sign(r q̇))`` with ``r = e5 + e6``. :func:`coupling_candidates` proposes

* for each adjacent pair of joints, friction (viscous, Coulomb) and inertia on ``qj + qj+1`` and
  ``qj − qj+1`` (:func:`dynamics.effects.motor.pair_combinations`): named ``coulomb[q5+q6]``; each
  Coulomb pair also with its own smoothing, ``coulomb:tanh[q5+q6]``
  (:class:`dynamics.effects.combination_shapes.TanhCombinationCoulomb`), of which the diagnosis adds at
  most one (:func:`combination_taken`);
* for each coupled motor of a declared transmission, friction and inertia on that motor
  (:func:`dynamics.effects.motor.motor_effects`): named ``motor_coulomb[m6]``.

The forward selection of :func:`estimation.diagnosis.search.diagnose` tests them beside the per-joint
candidates (F test, identifiability, physical sign, confirmation on held-out data).

Residual tracing (:func:`traced_pairs`, used when training data are given): a pair is proposed
only when the residual of the declared model follows the combination *rather than* each joint:
the pair's column must be significant (F test, Bonferroni over the pairs) beyond the per-joint
effects of the same kind on both of its joints. Without that gate, on a real arm without any
coupling (the KUKA LWR4+), a pair ``coulomb[qj+qj+1]`` correlates with the per-joint Coulomb
terms it overlaps and was picked instead of them. The tests (:func:`pair_tests`) share one projected Gram
matrix of every pair's and per-joint effect's column
(:class:`~estimation.diagnosis.candidates.projected_columns.ProjectedColumns`): on a 7-joint, 14 000-sample
record 0.1 s, where projecting each pair's columns off a QR factor of the weighted regressor took 1.1 s, with
the same statistics to rounding (``benchmarks/bench_traced_pairs.py``).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
import scipy.stats

from dynamics.effects.combination_shapes import TanhCombinationCoulomb, combination_row
from dynamics.effects.linear import Armature, CoulombFriction, Effect, ViscousFriction
from dynamics.models import IdentificationModel, ModelKind
from dynamics.effects.motor import KINDS, CombinationEffect, motor_effects, pair_combinations
from dynamics.transmission import Transmission
from dynamics.measurements import Measurements
from estimation.estimators.least_squares import stack
from estimation.estimators.effect_blocks import States, effect_columns  # the same columns the diagnosis fits
from estimation.estimators.separable_least_squares import FixedPart
from estimation.diagnosis.candidates.projected_columns import ProjectedColumns, weighted_fit

#: the per-joint effect a pair of each kind must do better than
PER_JOINT: dict[str, type] = {"viscous": ViscousFriction, "coulomb": CoulombFriction, "inertia": Armature}


def coupling_candidates(model: IdentificationModel, transmission: Transmission | None = None, *,
                        pairs: bool = True, train: Measurements | None = None,
                        alpha: float = 1e-3, held_out: Measurements | None = None) -> tuple[Effect, ...]:
    """Friction and inertia on adjacent joint pairs (``pairs``) and on the coupled motors of
    ``transmission``; none for the external model (friction is internal) or a one-joint robot.
    Candidates already in the model are left out. With ``train``, only the pairs its residual
    traces (:func:`traced_pairs`) are proposed, and a Coulomb pair only when the record tells its law from its joints'
    own (:func:`signs_apart`); with ``held_out`` (the validation record that is to confirm them), only when it
    tells them apart too: a pair the held-out record cannot tell from its joints' own laws would be confirmed by what
    the per-joint laws explain (a short record tells fewer pairs apart; the Stäubli TX40 with a 1 s validation record
    took ``coulomb:tanh[q2-q3]``, of the sign of ``q̇_2`` and of ``−q̇_3`` at every sample of both records: 5.4x the
    plain fit on joint 3 of a motion where they differ)."""
    if model.kind is ModelKind.EXTERNAL:
        return ()
    declared = {effect.name for effect in model.effects}
    candidates: list[Effect] = []
    for kind in KINDS:
        if transmission is not None:
            transmission.check(model.robot)
            candidates.extend(motor_effects(transmission, kind, transmission.coupled_motors()))
    if pairs:
        proposed = [pair for kind in KINDS for pair in pair_combinations(model.robot.n_joints, kind)
                    if pair.name not in declared]
        traced = proposed if train is None else traced_pairs(model, train, proposed, alpha=alpha)
        for record in (train, held_out):
            if record is not None and record.dq is not None:
                traced = [pair for pair in traced if pair.kind != "coulomb" or signs_apart(pair, record) >= MIN_APART]
        candidates.extend(traced)
        # each Coulomb pair also with its own smoothing (a motor's smooth law near v = 0; one of the two is added)
        candidates.extend(TanhCombinationCoulomb.from_combination(pair) for pair in traced if pair.kind == "coulomb")
    return tuple(candidate for candidate in candidates if candidate.name not in declared)


#: the least share of a record's samples where a Coulomb pair's sign law differs from its joints' own sign laws for
#: the record to tell them apart (:func:`signs_apart`)
MIN_APART = 0.01
#: velocities within this share of their root mean square are taken as at rest (their sign is the noise's)
AT_REST = 0.05


def signs_apart(pair: CombinationEffect, record: Measurements) -> float:
    """The share of ``record``'s samples where the sign of a pair's combined velocity ``v = r·q̇`` differs from that of
    one of its joints' ``r_j q̇_j`` (both moving: above :data:`AT_REST` of their root mean square).

    Where the signs agree at every sample, the pair's Coulomb column on each of its rows, ``r_j sign(v)``, is the
    joint's own sign law ``sign(q̇_j)`` scaled: the record cannot tell a Coulomb law on the combination from Coulomb
    laws on its joints, and a record where they differ (the joints moving the same way, where ``q̇_2 − q̇_3`` had the
    sign of ``−q̇_3``) receives the pair's law with the wrong sign. A coupled wrist's ``q5 + q6`` differs in sign from
    one of ``q̇_5``, ``q̇_6`` wherever the other dominates (a Stäubli TX40: 15–30 % of the samples)."""
    weights = np.asarray(pair.weights[0], dtype=float)
    dq = np.asarray(record.dq, dtype=float)
    combined = dq @ weights

    def moving(x: NDArray[np.float64]) -> NDArray[np.bool_]:
        return np.abs(x) > AT_REST * np.sqrt(np.mean(x**2))

    apart = np.zeros(dq.shape[0], dtype=bool)
    for joint in np.flatnonzero(weights):
        own = weights[joint] * dq[:, joint]
        apart |= moving(combined) & moving(own) & (np.sign(combined) != np.sign(own))
    return float(np.mean(apart)) if apart.shape[0] else 0.0


def combination_taken(effect: Effect, selected: Sequence[Effect]) -> bool:
    """Whether ``selected`` already holds a Coulomb law (sign or smoothed) on ``effect``'s joint
    combination: one Coulomb law per combination, as one per joint."""
    row = combination_row(effect)
    return row is not None and any(combination_row(other) == row for other in selected)


@dataclass(frozen=True)
class PairTest:
    """A pair's F test in the residual tracing (:func:`pair_tests`).

    Attributes
    ----------
    pair
        The pair effect tested.
    statistic
        Its F statistic beyond the declared model and the per-joint effects of its kind on its joints, or
        ``None`` when it has nothing beyond them (absorbed).
    dof
        The denominator's degrees of freedom (the numerator has one).
    """

    pair: CombinationEffect
    statistic: float | None
    dof: int

    @property
    def p_value(self) -> float:
        """``P(F(1, dof) > statistic)``; 1 for an absorbed pair."""
        return 1.0 if self.statistic is None else float(scipy.stats.f.sf(self.statistic, 1, self.dof))


def per_joint_extra(model: IdentificationModel, pair: CombinationEffect) -> list[Effect]:
    """The per-joint effects of ``pair``'s kind on its joints that the declared model lacks."""
    joints = [int(index) for index in np.flatnonzero(pair.weights[0])]
    present = {(effect.name, tuple(getattr(effect, "joints", None) or range(model.robot.n_joints)))
               for effect in model.effects}
    per_joint = [PER_JOINT[pair.kind](joints=(joint,)) for joint in joints]
    return [effect for effect in per_joint
            if not any(name == effect.name and effect.joints[0] in joints_ for name, joints_ in present)]


def pair_tests(model: IdentificationModel, train: Measurements,
               pairs: Sequence[CombinationEffect]) -> tuple[PairTest, ...]:
    """Each pair's column tested beyond the declared model plus the per-joint effects of the same kind on both
    joints of the pair: channel-weighted (weights from an ordinary fit of the declared model, as WLS's first
    step), one-column F test (:class:`estimation.diagnosis.candidates.projected_columns.ProjectedColumns`:
    each distinct column formed once, on the channels it touches)."""
    if not pairs:
        return ()
    problem = stack(model, train)
    fixed = FixedPart.from_arrays(problem.Y, problem.y)
    residual, _ = weighted_fit(fixed, np.ones(model.n_channels))
    root = 1.0 / np.sqrt(np.maximum(np.mean(residual**2, axis=1), 1e-300))
    extras = {pair: per_joint_extra(model, pair) for pair in pairs}
    effects = list(dict.fromkeys([effect for pair in pairs for effect in extras[pair]] + list(pairs)))
    states = States(train.q, train.dq, train.ddq)
    blocks = [effect_columns(model.kind, model.robot, effect, model.n_channels, states) for effect in effects]
    if any(block.shape[2] != 1 for block in blocks):
        raise ValueError("the pairs (one combination each) and per-joint effects must have one column each; "
                         f"these have more: {[effect.name for effect, block in zip(effects, blocks) if block.shape[2] != 1]}")
    columns = [block[:, :, 0] for block in blocks]
    projected = ProjectedColumns.of(fixed, root, columns)
    place = {effect: index for index, effect in enumerate(effects)}
    return tuple(PairTest(pair, projected.f_statistic([place[effect] for effect in extras[pair]], place[pair]),
                          projected.n_rows - projected.n_fixed - len(extras[pair]) - 1) for pair in pairs)


def traced_pairs(model: IdentificationModel, train: Measurements, pairs: list[CombinationEffect], *,
                 alpha: float = 1e-3) -> list[CombinationEffect]:
    """The ``pairs`` whose column is significant beyond the declared model plus the per-joint
    effects of the same kind on both joints (:func:`pair_tests`, level ``alpha / len(pairs)``)."""
    return [test.pair for test in pair_tests(model, train, pairs)
            if test.statistic is not None and test.p_value < alpha / len(pairs)]


def combination_groups(effects: dict[int, Effect]) -> list[tuple[int, ...]]:
    """Each Coulomb law on a joint combination (sign or smoothed) together with the viscous law on the
    same combination, as one candidate (``effects``: candidate index -> effect).

    A motor's friction is viscous and Coulomb at once. Tried alone, a smoothed Coulomb law with a
    wide smoothing mimics the still missing viscous term: on the simulated PUMA with a ``q5 + q6``
    wrist, ``coulomb:tanh[q5+q6]`` was taken first with ``vc = 1.1 rad/s`` (0.013 true), and
    ``viscous[q5+q6]`` was then refused (it raised tau5's validation error), leaving tau5 and tau6 at
    2.3x and 2.2x their floor.
    """
    viscous = {combination_row(effect, "viscous"): index for index, effect in effects.items()}
    viscous.pop(None, None)
    groups = []
    for index, effect in effects.items():
        row = combination_row(effect)
        if row is not None and row in viscous:
            groups.append((index, viscous[row]))
    return groups
