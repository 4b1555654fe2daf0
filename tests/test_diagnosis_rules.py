"""Wrong effects out: springs that are offsets or negative, coupled inertias that are armatures, candidates' rows at
several states."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from dynamics.effects.linear import Armature, JointOffset, Spring, StribeckFriction, ViscousFriction
from dynamics.effects.motor import pair_combinations
from dynamics.effects.specs import build_effects
from dynamics.models import build_model
from dynamics.robots import load_robot
from estimation.diagnosis.forward_selection import candidate_blocks
from estimation.diagnosis.rules.selection_rules import own_laws_lacking
from estimation.diagnosis.search import diagnose, effect_channels
from dynamics.simulation.synthetic import simulate, true_parameters


from oed.fourier import random_fourier


@pytest.fixture(scope="module")
def robot():
    return load_robot("puma560", joints=3)


def _records(robot, extra):
    declared = build_model(robot, "internal", "viscous")
    theta = true_parameters(declared, seed=0)
    records = []
    for seed in (3, 4):
        data = simulate(declared, theta, random_fourier(robot, seed=seed), rate_hz=250.0, periods=2,
                        noise={f"tau{j}": 0.1 for j in (1, 2, 3)}, seed=seed)
        records.append(dataclasses.replace(data, tau=data.tau + extra(data)))
    return declared, records


def test_a_stribeck_candidate_with_a_small_velocity_keeps_its_rows(robot):
    model = build_model(robot, "internal", "viscous")
    assert effect_channels(StribeckFriction(joints=(1,), velocity=0.01), model) == ("tau2",)


def test_a_negative_stiffness_is_not_added_as_a_spring(robot):
    def anti_spring(data):
        extra = np.zeros_like(data.tau)
        extra[:, 2] = -8.0 * (data.q[:, 2] - data.q[:, 2].mean())
        return extra

    declared, (train, validate) = _records(robot, anti_spring)
    diagnosis = diagnose(declared, train, validate)
    assert all(effect.name != "spring" for effect in diagnosis.effects), [e.name for e in diagnosis.effects]
    reasons = {(r.name, r.channels): r.reason for r in diagnosis.rejected}
    assert "negative stiffness" in reasons[("spring", ("tau3",))]


def test_an_offset_is_not_taken_for_a_spring(robot):
    def offset(data):
        extra = np.zeros_like(data.tau)
        extra[:, 0] = 2.5
        return extra

    declared, (train, validate) = _records(robot, offset)
    diagnosis = diagnose(declared, train, validate,
                         candidates=[Spring(joints=(0,)), JointOffset(joints=(0,))])
    assert [(e.name, e.channels) for e in diagnosis.effects] == [("offset", ("tau1",))]
    diagnosis = diagnose(declared, train, validate, candidates=[Spring(joints=(0,))])
    assert diagnosis.effects == ()  # alone, the stiffness has no offset to beat: not a spring


def test_a_coupled_law_is_compared_with_the_per_joint_laws_of_its_kind_its_model_lacks():
    robot = load_robot("puma560", joints=6)
    model = build_model(robot, "internal", "viscous")
    inertia56 = next(pair for pair in pair_combinations(6, "inertia") if pair.labels == ("q5+q6",))
    viscous56 = next(pair for pair in pair_combinations(6, "viscous") if pair.labels == ("q5+q6",))
    candidates = [Armature(joints=(joint,)) for joint in range(6)] + [inertia56, viscous56]
    blocks, _ = candidate_blocks(model, candidates)
    every = [(effect, tuple(range(6))) for effect in model.effects]
    # the armatures on joints 5 and 6 (indices 4, 5), and no per-joint viscous law: the declared model holds them
    assert own_laws_lacking([blocks[6]], blocks, model, every) == (4, 5)
    assert own_laws_lacking([blocks[7]], blocks, model, every) == ()
    # an armature the model holds is not asked for again; a per-joint law is no coupled law
    assert own_laws_lacking([blocks[6]], blocks, model, every + [(candidates[5], (5,))]) == (4,)
    assert own_laws_lacking([blocks[4]], blocks, model, every) == ()


@pytest.mark.slow
@pytest.mark.parametrize("truth_spec, values, named", [
    # a geared 7-joint arm, its rotors' inertia on every joint (those on joints 1, 2 and 7 in the base parameters):
    # at 4d50ebf inertia[q2+q3] was named for the armature on joint 3 (0.1002 for 0.1)
    ("armature", {"armature": [0.2, 0.4, 0.1, 0.3, 0.04, 0.05, 0.006]},
     {("armature", ("tau3",)), ("armature", ("tau4",)), ("armature", ("tau5",)), ("armature", ("tau6",))}),
    # a motor turning with q5 + q6 beside the wrist's own armatures: at 4d50ebf inertia[q5+q6] and inertia[q5-q6]
    # were named (a second coupled law in the span of the armatures with the first)
    ("inertia[q5+q6],armature@5+6", {"inertia[q5+q6]": [0.05], "armature": [0.04, 0.05]},
     {("inertia[q5+q6]", ("tau5", "tau6")), ("armature", ("tau5",)), ("armature", ("tau6",))}),
], ids=["armatures", "a coupled motor beside armatures"])
def test_a_geared_arms_armatures_are_named_as_armatures_and_a_coupled_motor_as_coupled(truth_spec, values, named,
                                                                                       tmp_path):
    from tests.test_unseen_robot_changes import motion_limits
    from tests.test_unseen_robot_rigs import seven_joint_urdf

    urdf = tmp_path / "arm.urdf"
    urdf.write_text(seven_joint_urdf())
    robot = load_robot(urdf=urdf)
    truth = build_model(robot, "internal", (ViscousFriction(),) + build_effects(truth_spec, robot))
    theta = true_parameters(truth, seed=0, **values)
    noise = {channel: 0.1 for channel in truth.channels}
    train, validate = (simulate(truth, theta, random_fourier(motion_limits(robot), seed=motion), noise=noise, seed=seed)
                       for motion, seed in ((3, 1), (4, 2)))
    diagnosis = diagnose(build_model(robot, "internal", "viscous"), train, validate)
    assert {(effect.name, effect.channels) for effect in diagnosis.effects} == named
    found = {(effect.name, effect.channels): effect for effect in diagnosis.effects}
    for (name, channels), effect in found.items():
        if name == "armature":
            joint = int(channels[0][3:]) - 1
            expected = values["armature"][joint if len(values["armature"]) == 7 else joint - 4]
        else:
            expected = values[name][0]
        assert abs(effect.values[0] - expected) < 4 * effect.std[0] + 0.005, (name, channels, effect.values, expected)
