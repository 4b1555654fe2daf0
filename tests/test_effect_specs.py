"""Per-joint effect specs (NAME@JOINTS), motor-side and joint-combination effects."""

from __future__ import annotations

import casadi
import numpy as np
import pytest

from dynamics.effects.joint_lists import EffectSpecError, parse_joint_list, split_joints
from dynamics.effects.specs import build_effects, effect_spec
from dynamics.effects.linear import CoulombFriction, JointOffset, parse_effects
from dynamics.models import build_model
from dynamics.effects.motor import CombinationEffect, motor_effects
from dynamics.robots import load_robot
from dynamics.transmission import puma560_transmission


def test_joint_lists():
    assert parse_joint_list("1-4") == (0, 1, 2, 3)
    assert parse_joint_list("2+5") == (1, 4)
    assert parse_joint_list("1-2+5+4") == (0, 1, 3, 4)
    assert split_joints("coulomb:tanh@1-4") == ("coulomb:tanh", (0, 1, 2, 3))  # @ first, the variant stays
    for bad in ("0", "3-1", "a", "1-", "1++2"):
        with pytest.raises(EffectSpecError):
            parse_joint_list(bad)


def test_parse_effects_restricts_to_joints():
    effects = parse_effects("viscous,coulomb@1-4,offset@2+5")
    assert effects[1] == CoulombFriction(joints=(0, 1, 2, 3)) and effects[2] == JointOffset(joints=(1, 4))
    model = build_model(load_robot("puma560"), "internal", effects)
    assert [name for name in model.parameter_names if name.startswith(("fc", "off"))] == \
        ["fc1", "fc2", "fc3", "fc4", "off2", "off5"]
    with pytest.raises(ValueError, match="no @JOINTS"):
        parse_effects("wrench_offset@1")


def test_joint_beyond_the_robot_is_named():
    with pytest.raises(EffectSpecError, match="joint 7 outside 1..6"):
        build_effects("coulomb@5-7", load_robot("puma560"))


def test_motor_effects_need_a_transmission_and_act_through_R_transposed():
    robot = load_robot("puma560")
    with pytest.raises(EffectSpecError, match="transmission"):
        build_effects("motor_coulomb", robot)
    transmission = puma560_transmission()
    (effect,) = build_effects("motor_viscous@6", robot, transmission)
    assert effect.name == "motor_viscous[m6]" and effect.parameter_names(robot) == ["fvm6"]
    q, dq, ddq = (casadi.SX.sym(name, 6) for name in ("q", "dq", "ddq"))
    joint, _ = effect.columns(robot, q, dq, ddq)
    value = np.asarray(casadi.Function("f", [dq], [joint])(np.arange(1.0, 7.0))).reshape(-1)
    row = transmission.matrix[5]
    np.testing.assert_allclose(value, row * (row @ np.arange(1.0, 7.0)))  # τ = rᵀ (r q̇) for fv = 1
    assert np.count_nonzero(value) == 3  # the coupled wrist: one motor, three joint rows


def test_combination_names_round_trip():
    robot = load_robot("puma560")
    effects = build_effects("viscous,coulomb@2+5,coulomb[q5+q6],motor_coulomb@5-6", robot, puma560_transmission())
    spec = ",".join(effect_spec(effect) for effect in effects)
    assert spec == "viscous,coulomb@2+5,coulomb[q5+q6],motor_coulomb@5,motor_coulomb@6"
    assert build_effects(spec, robot, puma560_transmission()) == effects
    (pair,) = [effect for effect in effects if isinstance(effect, CombinationEffect) and not effect.motor]
    assert pair.name == "coulomb[q5+q6]" and pair.parameter_names(robot) == ["fc[q5+q6]"]
    assert pair.weights == ((0.0, 0.0, 0.0, 0.0, 1.0, 1.0),)
    with pytest.raises(ValueError, match="cannot read"):
        build_effects("coulomb[q5*q6]", robot)


def test_motor_effects_one_per_motor():
    effects = motor_effects(puma560_transmission(), "inertia")
    assert [effect.parameter_names(load_robot("puma560"))[0] for effect in effects] == [f"Jm{i}" for i in range(1, 7)]
    assert effects[0].physical_kind == "armature"
