"""Declared friction a training record cannot separate: the Coulomb and offset columns of a joint that never reverses.

While joint ``i`` moves one way only, ``sign(dq_i)`` is constant and its Coulomb column ``fc_i sign(dq_i)`` is its
offset column ``off_i`` times ``±1``: the record determines their sum (the level it shows), not each (Gautier's
base parameters: a column that is a combination of others on the data is regrouped into them). An unconstrained fit
then stops on a rank-deficient regressor. When the user declared both (``--friction ...,coulomb,offset``), the
identification goes on with the pair merged: the offset keeps the column, so ``off_i`` holds the level the record
shows while the joint moves that way, and ``fc_i`` is left out and reported as not determined (a warning naming the
joint, and ``not_determined`` in ``result.json``). The offset, not the Coulomb term, keeps it because the offset is
the law that asserts nothing about a reversal the record never showed (issue 34: "adding nothing and saying what
remains beats naming the wrong effect"). A record in which the joint reverses determines both.

A per-joint parameter whose column is zero on every training sample (the viscous and Coulomb friction, the
armature of a joint held still through the training records) is not determined either: the records hold nothing of
it, so the identification goes on without it (the effect kept on the other joints), said in a warning naming the
joint, and ``not_determined`` in ``result.json``. It is left at zero, as a minimum-norm least-squares fit leaves it:
nothing is invented for a motion the records never showed, and the prediction of a record where that joint moves
says the record leaves the training range.

Any other parameter the data do not determine stays the error it is (a rigid-body direction, a spring on a joint at
rest: the remedy is the user's).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import Any, TypeVar

from dynamics.effects.linear import CoulombFriction, JointOffset
from dynamics.models import IdentificationModel
from estimation.estimators.least_squares import IdentifiabilityError

__all__ = ["MergedColumn", "UnexcitedColumn", "fitted_without_undetermined", "left_out_unexcited",
           "merged_one_way", "not_determined"]

Fit = TypeVar("Fit")


@dataclass(frozen=True)
class MergedColumn:
    """A Coulomb column left out where the record does not tell it from the offset of the same joint.

    Attributes
    ----------
    joint
        The joint, counted from 1.
    joint_name
        Its name in the robot description.
    parameter, merged_into
        The parameter left out (``fc_i``) and the one holding the pair's sum (``off_i``).
    """

    joint: int
    joint_name: str
    parameter: str
    merged_into: str

    def statement(self) -> str:
        """The warning: what is not determined, why, and what determines it."""
        return (f"joint {self.joint} ({self.joint_name}) does not reverse in the training record: its Coulomb and "
                f"offset columns are one there, so the data do not determine {self.parameter} apart from "
                f"{self.merged_into}; {self.parameter} is left out (not determined) and {self.merged_into} holds "
                f"their sum, the level the record shows; a record in which joint {self.joint} reverses determines "
                "both")

    def to_dict(self) -> dict[str, Any]:
        """``{effect, joint, joint_name, parameter, merged_into, reason}`` (``result.json``'s ``not_determined``)."""
        return {"effect": "coulomb", "joint": self.joint, "joint_name": self.joint_name, "parameter": self.parameter,
                "merged_into": self.merged_into, "reason": self.statement()}


def merged_one_way(model: IdentificationModel,
                   parameters: tuple[str, ...]) -> tuple[tuple[Any, ...], tuple[MergedColumn, ...]] | None:
    """The model's effects with the Coulomb column of each joint whose Coulomb and offset parameters are among the
    undetermined ``parameters`` left out, and what was left out; ``None`` when ``parameters`` hold anything else
    (or nothing to merge): that rank deficiency is not this one.

    Parameters
    ----------
    model
        The declared model.
    parameters
        The parameters the data do not determine, as the rank-deficiency error names them
        (:class:`~estimation.estimators.least_squares.IdentifiabilityError`).
    """
    robot = model.robot
    coulomb = [effect for effect in model.effects if type(effect) is CoulombFriction]
    offset = [effect for effect in model.effects if type(effect) is JointOffset]
    if len(coulomb) != 1 or len(offset) != 1 or not parameters:
        return None
    coulomb_joints = tuple(range(robot.n_joints)) if coulomb[0].joints is None else tuple(coulomb[0].joints)
    offset_joints = tuple(range(robot.n_joints)) if offset[0].joints is None else tuple(offset[0].joints)
    weak = set(parameters)
    merged = []
    for joint in coulomb_joints:
        pair = (f"{CoulombFriction.symbol}{joint + 1}", f"{JointOffset.symbol}{joint + 1}")
        if joint in offset_joints and set(pair) <= weak:
            merged.append(MergedColumn(joint + 1, robot.joints[joint].name, *pair))
            weak -= set(pair)
    if not merged or weak:
        return None
    kept = tuple(joint for joint in coulomb_joints if joint + 1 not in {column.joint for column in merged})
    effects = tuple(effect for effect in model.effects if effect is not coulomb[0] or kept)
    effects = tuple(replace(effect, joints=kept) if effect is coulomb[0] else effect for effect in effects)
    return effects, tuple(merged)


@dataclass(frozen=True)
class UnexcitedColumn:
    """A per-joint parameter (``fv_i``, ``fc_i``, ``Ia_i``, ...) left out because its column is zero on every
    training sample: ``joint`` (from 1) and ``joint_name`` as :class:`MergedColumn`'s, ``effect`` the effect it
    belongs to (``viscous``, ``coulomb``, ``armature``, ...)."""

    joint: int
    joint_name: str
    parameter: str
    effect: str

    def statement(self) -> str:
        """The warning: what is not determined, why, and what determines it."""
        return (f"joint {self.joint} ({self.joint_name}): the {self.effect} column ({self.parameter}) is zero on "
                f"every training sample (the joint does not move there): the data do not determine "
                f"{self.parameter}; it is left out (zero in the model, not determined); a record in which joint "
                f"{self.joint} moves determines it")

    def to_dict(self) -> dict[str, Any]:
        """``{effect, joint, joint_name, parameter, merged_into, reason}`` (``result.json``'s ``not_determined``;
        ``merged_into`` ``None``: nothing holds it)."""
        return {"effect": self.effect, "joint": self.joint, "joint_name": self.joint_name,
                "parameter": self.parameter, "merged_into": None, "reason": self.statement()}


def left_out_unexcited(model: IdentificationModel,
                       parameters: tuple[str, ...]) -> tuple[tuple[Any, ...], tuple[UnexcitedColumn, ...]] | None:
    """The model's effects with each per-joint parameter of ``parameters`` (all-zero columns on the training
    records) left out of its effect's joints, and what was left out; ``None`` when ``parameters`` hold anything
    else (a rigid-body parameter, an effect not of one parameter per joint) or nothing.

    Parameters
    ----------
    model
        The declared model.
    parameters
        The parameters whose columns are zero on every training sample, as the error names them
        (:class:`~estimation.estimators.least_squares.IdentifiabilityError` with ``unexcited``).
    """
    robot = model.robot
    weak = set(parameters)
    if not weak:
        return None
    effects, left = [], []
    for effect in model.effects:
        symbol, joints = getattr(effect, "symbol", ""), getattr(effect, "joints", ())
        names = effect.parameter_names(robot)
        indices = tuple(range(robot.n_joints)) if joints is None else tuple(joints)
        if not symbol or not isinstance(joints, tuple | type(None)) \
                or names != [f"{symbol}{index + 1}" for index in indices] or not weak & set(names):
            effects.append(effect)
            continue
        gone = [index for index in indices if f"{symbol}{index + 1}" in weak]
        left.extend(UnexcitedColumn(index + 1, robot.joints[index].name, f"{symbol}{index + 1}", effect.name)
                    for index in gone)
        weak -= {f"{symbol}{index + 1}" for index in gone}
        kept = tuple(index for index in indices if index not in gone)
        if kept:
            effects.append(replace(effect, joints=kept))
    if weak or not left:
        return None
    return tuple(effects), tuple(left)


def not_determined(model: IdentificationModel, error: Exception
                   ) -> tuple[tuple[Any, ...], tuple[MergedColumn | UnexcitedColumn, ...]] | None:
    """What the identification goes on without after ``error`` (an
    :class:`~estimation.estimators.least_squares.IdentifiabilityError`): the columns of joints the training records
    never move (:func:`left_out_unexcited`) or a Coulomb column one with the offset (:func:`merged_one_way`); the
    model's effects then and what was left out, or ``None`` (the error stands)."""
    parameters = tuple(getattr(error, "parameters", ()))
    if getattr(error, "unexcited", False):
        return left_out_unexcited(model, parameters)
    return merged_one_way(model, parameters)


def fitted_without_undetermined(
        fit: Callable[[tuple[Any, ...], IdentificationModel, tuple[MergedColumn | UnexcitedColumn, ...]], Fit],
        effects: tuple[Any, ...], model: IdentificationModel, rebuild: Callable[[tuple[Any, ...]], IdentificationModel]
) -> tuple[Fit, tuple[MergedColumn | UnexcitedColumn, ...]]:
    """``fit(effects, model, ())``, the declared model's fit, and while it stops on a rank-deficient regressor whose
    undetermined parameters are Coulomb and offset pairs of joints that never reverse, or per-joint columns of joints
    the training records never move (:func:`not_determined`), the same fit of the model with those columns left out
    (``rebuild(effects)``): the fit and the columns left out, in the order they were (``()`` when none). Any other
    rank deficiency is raised as it is.

    Parameters
    ----------
    fit
        The verb's fit of a model built from the effects given (both given: the fit may need either), and the
        columns left out so far.
    effects, model
        The declared effects and the model built from them.
    rebuild
        The model of other effects, built as ``model`` was.
    """
    merged: tuple[MergedColumn | UnexcitedColumn, ...] = ()
    while True:
        try:
            return fit(effects, model, merged), merged
        except IdentifiabilityError as error:
            change = not_determined(model, error)
            if change is None:
                raise
            effects = change[0]
            model, merged = rebuild(effects), (*merged, *change[1])
