"""The CasADi Newton–Euler regressors against Pinocchio, the independent reference."""

from __future__ import annotations

import casadi
import numpy as np
import pinocchio as pin
import pytest

from dynamics.models import build_model
from dynamics.pinocchio_bridge import to_pinocchio
from dynamics.robots import load_robot
from dynamics.robots.puma560 import PUMA560_DH
from dynamics.dh import dh_forward_kinematics
from tests.conftest import random_parameters, random_states

ROBOTS = [("puma560", 3), ("puma560", 6), ("servo_arm", None)]


def _robot(name: str, joints: int | None, prismatic_urdf):
    if name == "urdf":
        return load_robot(urdf=prismatic_urdf)
    return load_robot(name, joints=joints)


@pytest.mark.parametrize("name, joints", ROBOTS + [("urdf", None)])
def test_internal_regressor_matches_pinocchio_rnea(name, joints, prismatic_urdf):
    robot = _robot(name, joints, prismatic_urdf)
    model = build_model(robot, "internal", effects=None)
    theta = random_parameters(robot, seed=1)
    pin_model = to_pinocchio(robot, theta=theta)
    pin_data = pin_model.createData()
    q, dq, ddq = random_states(robot.n_joints, 20, seed=2)
    predicted = model.predict(theta, q, dq, ddq)
    expected = np.array([pin.rnea(pin_model, pin_data, *state) for state in zip(q, dq, ddq)])
    np.testing.assert_allclose(predicted, expected, rtol=0, atol=1e-9 * max(1.0, np.abs(expected).max()))


def test_urdf_regressor_matches_pinocchio_model_built_from_the_file(prismatic_urdf):
    """Independent of our bridge: compare with Pinocchio's own parse of the URDF."""
    robot = load_robot(urdf=prismatic_urdf)
    reference = pin.buildModelFromUrdf(str(prismatic_urdf))
    data = reference.createData()
    model = build_model(robot, "internal", effects=None)
    q, dq, ddq = random_states(robot.n_joints, 20, seed=3)
    q[:, 1] = np.clip(q[:, 1] / 10, -0.2, 0.4)
    predicted = model.predict(robot.standard_parameters, q, dq, ddq)
    expected = np.array([pin.rnea(reference, data, *state) for state in zip(q, dq, ddq)])
    np.testing.assert_allclose(predicted, expected, atol=1e-9)


@pytest.mark.parametrize("name, joints", ROBOTS + [("urdf", None)])
def test_external_regressor_matches_pinocchio_base_wrench(name, joints, prismatic_urdf):
    robot = _robot(name, joints, prismatic_urdf)
    model = build_model(robot, "external", effects=None)
    theta = random_parameters(robot, seed=4)
    pin_model = to_pinocchio(robot, free_flyer=True, theta=theta)
    pin_data = pin_model.createData()
    root_at_rest = pin.neutral(pin_model)[:7]
    q, dq, ddq = random_states(robot.n_joints, 20, seed=5)
    expected = np.array(
        [
            pin.rnea(pin_model, pin_data, np.concatenate([root_at_rest, qi]), np.r_[np.zeros(6), dqi], np.r_[np.zeros(6), ddqi])[:6]
            for qi, dqi, ddqi in zip(q, dq, ddq)
        ]
    )
    predicted = model.predict(theta, q, dq, ddq)
    np.testing.assert_allclose(predicted, expected, rtol=0, atol=1e-9 * max(1.0, np.abs(expected).max()))


def test_robot_at_rest_reads_its_weight_upwards():
    robot = load_robot("puma560", joints=6)
    model = build_model(robot, "external", effects=None)
    wrench = model.predict(robot.standard_parameters, np.zeros(6), np.zeros(6), np.zeros(6))[0]
    total_mass = sum(joint.inertial[0] for joint in robot.joints)
    assert wrench[2] == pytest.approx(total_mass * 9.81, rel=1e-12)
    assert abs(wrench[0]) < 1e-12 and abs(wrench[1]) < 1e-12


def test_combined_regressor_stacks_wrench_then_joint_rows_with_friction_on_joints_only():
    robot = load_robot("puma560", joints=3)
    combined = build_model(robot, "combined", "viscous,wrench_offset")
    internal = build_model(robot, "internal", "viscous")
    external = build_model(robot, "external", "wrench_offset")
    q, dq, ddq = random_states(3, 5, seed=6)
    Y = combined.evaluate(q, dq, ddq)
    names = list(combined.parameter_names)
    assert combined.channels[:6] == ("fx", "fy", "fz", "mx", "my", "mz")
    viscous = [names.index(f"fv{i}") for i in (1, 2, 3)]
    offsets = [names.index(f"{c}_off") for c in ("fx", "fy", "fz", "mx", "my", "mz")]
    assert np.all(Y[:, :6, viscous] == 0)
    assert np.all(Y[:, 6:, offsets] == 0)
    np.testing.assert_allclose(Y[:, 6:, : len(internal.parameter_names)], internal.evaluate(q, dq, ddq))
    rigid = slice(0, 30)
    np.testing.assert_allclose(Y[:, :6, rigid], external.evaluate(q, dq, ddq)[:, :, rigid])


def test_effect_columns_follow_their_definitions():
    robot = load_robot("servo_arm")
    model = build_model(robot, "internal", "viscous,coulomb,offset,armature")
    q, dq, ddq = random_states(4, 3, seed=7)
    Y = model.evaluate(q, dq, ddq)
    slices = model.effect_slices
    np.testing.assert_allclose(Y[:, :, slices["viscous"]], dq[:, :, None] * np.eye(4))
    np.testing.assert_allclose(Y[:, :, slices["coulomb"]], np.sign(dq)[:, :, None] * np.eye(4))
    np.testing.assert_allclose(Y[:, :, slices["offset"]], np.broadcast_to(np.eye(4), (3, 4, 4)))
    np.testing.assert_allclose(Y[:, :, slices["armature"]], ddq[:, :, None] * np.eye(4))


def test_regressor_functions_are_named_and_cached():
    robot = load_robot("puma560", joints=3)
    model = build_model(robot, "combined")
    assert build_model(robot, "combined") is model
    assert model.regressor.name() == "combined_regressor"
    assert model.regressor.name_in() == ["q", "dq", "ddq"] and model.regressor.name_out() == ["Y"]
    assert model.base_regressor.name_out() == ["Y_base"]
    q, dq, ddq = random_states(3, 4, seed=8)
    single = np.array(model.regressor(q[2], dq[2], ddq[2]))
    np.testing.assert_allclose(model.evaluate(q, dq, ddq)[2], single)
    assert isinstance(model.regressor, casadi.Function)


def test_dh_conversion_reproduces_the_dh_product_and_corke_zero_pose():
    robot = load_robot("puma560")
    pin_model = to_pinocchio(robot)
    data = pin_model.createData()
    generator = np.random.default_rng(9)
    for q in generator.uniform(-np.pi, np.pi, (5, 6)):
        pin.forwardKinematics(pin_model, data, q)
        tip = data.oMi[6].homogeneous @ robot.joints[5].link_transform
        np.testing.assert_allclose(tip, dh_forward_kinematics(PUMA560_DH, q), atol=1e-12)
    # Corke, Robotics Toolbox: p560.fkine(qz) puts the wrist centre at (0.4521, -0.15005, 0.4318)
    np.testing.assert_allclose(dh_forward_kinematics(PUMA560_DH, np.zeros(6))[:3, 3], [0.4521, -0.15005, 0.4318])


def test_stribeck_and_spring_columns_follow_their_definitions():
    from dynamics.effects.linear import Spring, StribeckFriction

    robot = load_robot("puma560", joints=3)
    model = build_model(robot, "internal", (StribeckFriction(velocity=0.1, joints=(1,)), Spring(reference=0.3, joints=(0, 2))))
    assert [name for name in model.parameter_names[30:]] == ["fs2", "k1", "k3"]
    q, dq, ddq = random_states(3, 4, seed=10)
    Y = model.evaluate(q, dq, ddq)
    np.testing.assert_allclose(Y[:, 1, 30], np.exp(-((dq[:, 1] / 0.1) ** 2)) * np.sign(dq[:, 1]))
    np.testing.assert_allclose(Y[:, [0, 2], [31, 32]], q[:, [0, 2]] - 0.3)
    assert np.all(Y[:, [1, 2], 31] == 0) and np.all(Y[:, [0, 2], 30] == 0)


def test_effects_sharing_a_name_keep_their_own_columns_and_values():
    from dynamics.effects.linear import CoulombFriction

    robot = load_robot("puma560", joints=3)
    model = build_model(robot, "internal", ["viscous", CoulombFriction(joints=(0,)), CoulombFriction(joints=(2,))])
    slices = model.effect_slices
    assert slices["coulomb(fc1)"] == slice(33, 34) and slices["coulomb(fc3)"] == slice(34, 35)
    np.testing.assert_array_equal(model.nominal_parameters(coulomb=[5.0, 7.0])[-2:], [5.0, 7.0])
    np.testing.assert_array_equal(model.nominal_parameters(coulomb=2.0)[-2:], [2.0, 2.0])
    with pytest.raises(ValueError, match="give one value or 2"):
        model.nominal_parameters(coulomb=[1.0, 2.0, 3.0])
    with pytest.raises(ValueError, match="fc1 already in the model"):
        build_model(robot, "internal", ["coulomb", CoulombFriction(joints=(0,))])
