"""Transmissions: URDF and JSON sources, the PUMA 560's coupled wrist, conversions, bad input."""

from __future__ import annotations

import json

import numpy as np
import pytest

from dynamics.robots import load_robot
from dynamics.transmission import (
    CouplingShapeError,
    SingularCouplingError,
    Transmission,
    TransmissionSignError,
    UnknownJointError,
    check_power_signs,
    puma560_transmission,
)
from dynamics.transmission_files import transmission_from_json, transmission_from_urdf

URDF = """<?xml version="1.0"?>
<robot name="wrist">
  <link name="base"/>
  <link name="l1"><inertial><mass value="1"/><inertia ixx="0.01" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.01"/></inertial></link>
  <link name="l2"><inertial><origin xyz="0 0 0.1"/><mass value="1"/><inertia ixx="0.01" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.01"/></inertial></link>
  <link name="l3"><inertial><origin xyz="0 0 0.1"/><mass value="0.5"/><inertia ixx="0.01" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.01"/></inertial></link>
  <joint name="j1" type="revolute"><parent link="base"/><child link="l1"/><axis xyz="0 0 1"/><limit lower="-3" upper="3" effort="10" velocity="2"/></joint>
  <joint name="j2" type="revolute"><parent link="l1"/><child link="l2"/><origin xyz="0 0 0.2"/><axis xyz="0 1 0"/><limit lower="-2" upper="2" effort="10" velocity="2"/></joint>
  <joint name="j3" type="revolute"><parent link="l2"/><child link="l3"/><origin xyz="0 0 0.2"/><axis xyz="0 0 1"/><limit lower="-3" upper="3" effort="10" velocity="2"/></joint>
  {transmissions}
</robot>
"""

SIMPLE = """<transmission name="t1"><type>transmission_interface/SimpleTransmission</type>
  <joint name="j1"><hardwareInterface>EffortJointInterface</hardwareInterface></joint>
  <actuator name="motor1"><mechanicalReduction>-50</mechanicalReduction></actuator></transmission>"""
DIFFERENTIAL = """<transmission name="t23"><type>transmission_interface/DifferentialTransmission</type>
  <joint name="j2"><mechanicalReduction>1</mechanicalReduction></joint>
  <joint name="j3"><mechanicalReduction>1</mechanicalReduction></joint>
  <actuator name="motor2"><mechanicalReduction>40</mechanicalReduction></actuator>
  <actuator name="motor3"><mechanicalReduction>30</mechanicalReduction></actuator></transmission>"""
FOUR_BAR = DIFFERENTIAL.replace("DifferentialTransmission", "FourBarLinkageTransmission").replace(
    '<mechanicalReduction>1</mechanicalReduction></joint>\n  <joint name="j3"><mechanicalReduction>1<',
    '<mechanicalReduction>1</mechanicalReduction></joint>\n  <joint name="j3"><mechanicalReduction>2<')


def transmission_urdf(tmp_path, transmissions):
    path = tmp_path / "wrist.urdf"
    path.write_text(URDF.replace("{transmissions}", transmissions))
    return path


def test_urdf_simple_and_differential_transmissions(tmp_path):
    path = transmission_urdf(tmp_path, SIMPLE + DIFFERENTIAL)
    robot = load_robot(urdf=path)
    transmission = transmission_from_urdf(path, robot)
    expected = np.array([[-50, 0, 0], [0, 40, 40], [0, 30, -30]], dtype=float)
    np.testing.assert_allclose(transmission.matrix, expected)
    assert transmission.motor_names == ("motor1", "motor2", "motor3")
    assert transmission.coupled_motors() == (1, 2)
    # ros_control's differential: tau_j2 = jr2 (ar1 tau_a1 + ar2 tau_a2), tau_j3 = jr3 (ar1 tau_a1 - ar2 tau_a2)
    tau_m = np.array([[0.0, 0.5, 0.2]])
    np.testing.assert_allclose(transmission.joint_torques(tau_m), [[0.0, 40 * 0.5 + 30 * 0.2, 40 * 0.5 - 30 * 0.2]])


def test_urdf_four_bar_and_no_transmission(tmp_path):
    path = transmission_urdf(tmp_path, FOUR_BAR)
    robot = load_robot(urdf=path)
    matrix = transmission_from_urdf(path, robot).matrix
    np.testing.assert_allclose(matrix[1:, 1:], [[40, 0], [30, 60]])  # θa1 = jr1 ar1 q1, θa2 = (q1 + jr2 q2) ar2
    assert transmission_from_urdf(transmission_urdf(tmp_path, ""), robot) is None


def test_conversions_conserve_power():
    transmission = puma560_transmission()
    rng = np.random.default_rng(0)
    dq, tau_m = rng.normal(size=(5, 6)), rng.normal(size=(5, 6))
    dtheta = transmission.motor_positions(dq)
    tau = transmission.joint_torques(tau_m)
    np.testing.assert_allclose(np.sum(tau * dq, axis=1), np.sum(tau_m * dtheta, axis=1))
    np.testing.assert_allclose(transmission.joint_positions(dtheta), dq)
    np.testing.assert_allclose(transmission.motor_torques(tau), tau_m)


def test_puma_wrist_coupling_is_lower_triangular_with_the_toolbox_gears():
    matrix = puma560_transmission().matrix
    np.testing.assert_allclose(np.diag(matrix), (-62.6111, 107.815, -53.7063, 76.0364, 71.923, 76.686))
    assert matrix[4, 3] != 0 and matrix[5, 3] != 0 and matrix[5, 4] != 0
    assert np.count_nonzero(matrix) == 9
    assert puma560_transmission(3).matrix.shape == (3, 3)


def test_json_transmission_with_coupling(tmp_path):
    robot = load_robot("puma560")
    path = tmp_path / "t.json"
    path.write_text(json.dumps({"ratios": [-62.6, 107.8, -53.7, 76.0, 71.9, 76.7], "couplings": {"6": {"5": 76.7}},
                                "torque_constants": [0.26] * 6}))
    transmission = transmission_from_json(path, robot)
    assert transmission.matrix[5, 4] == 76.7 and transmission.coupled_motors() == (5,)
    assert transmission.combination_label(5) == "q5+q6"
    np.testing.assert_allclose(transmission.torques_from_currents(np.ones((1, 6))), [[0.26] * 6])


@pytest.mark.parametrize("document, error", [
    ({"matrix": [[1, 0], [0, 1]]}, CouplingShapeError),
    ({"matrix": [[1, 1, 0], [1, 1, 0], [0, 0, 1]]}, SingularCouplingError),
    ({"ratios": [1, 0, 1]}, SingularCouplingError),
    ({"ratios": {"joint9": 50}}, UnknownJointError),
    ({"ratios": [1, 2]}, CouplingShapeError),
])
def test_bad_transmissions_are_named(document, error):
    robot = load_robot("puma560", joints=3)
    with pytest.raises(error):
        transmission_from_json(document, robot)


def test_urdf_transmission_for_a_joint_the_robot_lacks(tmp_path):
    path = transmission_urdf(tmp_path, SIMPLE.replace('joint name="j1"', 'joint name="j7"'))
    with pytest.raises(UnknownJointError, match="j7"):
        transmission_from_urdf(path, load_robot(urdf=path))


def test_wrong_sign_for_the_data_is_named():
    transmission = Transmission(np.diag([50.0, -50.0]))
    t = np.linspace(0, 10, 2001)
    dq = np.column_stack([np.cos(t), np.sin(2 * t)])
    tau = 0.5 * np.sign(dq) + 0.1 * dq
    check_power_signs(transmission, dq, tau)  # dissipating: fine
    tau[:, 1] *= -1
    with pytest.raises(TransmissionSignError, match="joint 2"):
        check_power_signs(transmission, dq, tau)


def test_a_joint_at_rest_is_not_judged_by_its_power_sign():
    """Issue 34's sweep: a Stäubli TX40 record at rest (the robot holding its pose) was refused as 'the gear ratio
    of motor 3 has the wrong sign': at rest the velocity is the encoder's noise differentiated and the sign of the
    mean power is chance. With the positions, a joint that does not move is not judged; a moving one still is."""
    transmission = Transmission(np.diag([50.0, -50.0]))
    t = np.linspace(0, 2, 2001)
    ticks = -np.round(np.linspace(0.0, 3e-4, t.size) / 1e-4) * 1e-4  # three encoder ticks of drift, against τ
    q = np.column_stack([ticks, np.sin(2 * t)])  # joint 1 rests (holding 20 N·m), joint 2 moves
    dq = np.gradient(q, t, axis=0)
    tau = np.column_stack([np.full(t.size, 20.0), 0.5 * np.sign(dq[:, 1]) + 0.1 * dq[:, 1]])
    with pytest.raises(TransmissionSignError, match="joint 1"):
        check_power_signs(transmission, dq, tau)  # without the positions: judged on noise
    check_power_signs(transmission, dq, tau, q=q)  # at rest: not judged
    tau[:, 1] *= -1
    with pytest.raises(TransmissionSignError, match="joint 2"):
        check_power_signs(transmission, dq, tau, q=q)  # a moving joint still is
