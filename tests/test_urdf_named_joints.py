"""Any URDF with the logged joints named: a branching tree with a mimic joint, fixed, continuous and
prismatic joints reduced to the named chain, against Pinocchio's RNEA of the whole tree with the
other joints locked, and against a serial URDF reduced by hand."""

from __future__ import annotations

import json

import numpy as np
import pinocchio as pin
import pytest

from dynamics.errors import RobotDescriptionError
from dynamics.models import build_model
from dynamics.robots import load_robot
from dynamics.transmission_files import transmission_from_urdf
from estimation.identification.model_file import RobotSource
from tests.conftest import random_states

NAMED = ("torso_lift", "arm_1", "arm_2", "arm_3")
LOCKED = {"head_pan": 0.3, "gripper_left": 0.01}
MIMIC_MULTIPLIER, MIMIC_OFFSET = -1.0, 0.002
HEAD_YAW, FINGER_Y = 0.2, 0.04  # the fixed parts of the head's and the fingers' origins


def _link(name: str, mass: float, com: str = "0.01 0.02 0.03", rpy: str = "0.1 -0.2 0.3") -> str:
    return (f'<link name="{name}"><inertial><origin xyz="{com}" rpy="{rpy}"/><mass value="{mass}"/>'
            '<inertia ixx="0.05" ixy="0.002" ixz="-0.001" iyy="0.04" iyz="0.003" izz="0.03"/></inertial></link>')


def _joint(name: str, kind: str, parent: str, child: str, xyz: str, rpy: str = "0 0 0", axis: str = "0 0 1",
           extra: str = "") -> str:
    limit = '<limit lower="-2" upper="2" velocity="2" effort="100"/>' if kind in ("revolute", "prismatic") else ""
    axis_element = f'<axis xyz="{axis}"/>' if kind != "fixed" else ""
    return (f'<joint name="{name}" type="{kind}"><parent link="{parent}"/><child link="{child}"/>'
            f'<origin xyz="{xyz}" rpy="{rpy}"/>{axis_element}{limit}{extra}</joint>')


def _common_links() -> list[str]:
    return [
        '<link name="base_footprint"/>', _link("base", 20.0), _link("torso", 8.0), _link("head", 1.5),
        _link("wheel_left", 0.9), _link("wheel_right", 0.9), _link("arm1", 3.0), _link("arm1_cover", 0.4),
        _link("arm2", 2.0), _link("arm3", 1.2), _link("finger_left", 0.1), _link("finger_right", 0.1),
        _joint("base_fixed", "fixed", "base_footprint", "base", "0 0 0.1"),
        _joint("torso_lift", "prismatic", "base", "torso", "0.05 0 0.4", axis="0 0 1"),
        _joint("arm_1", "revolute", "torso", "arm1", "0.1 0.05 0.3", "0.2 0.1 -0.3", "0 0 1"),
        _joint("arm1_cover_joint", "fixed", "arm1", "arm1_cover", "0.02 0 0.1", "0 0.3 0"),
        _joint("arm_2", "continuous", "arm1_cover", "arm2", "0.2 0 0.05", "1.2 0.3 -0.4", "0.3 0.2 0.9"),
        _joint("arm_3", "revolute", "arm2", "arm3", "0.15 0.02 0", "-0.5 0 0.4", "0 1 0"),
    ]


def tree_urdf() -> str:
    """A mobile manipulator on a floating base: wheels and a head beside the arm, a gripper with a mimic finger at
    its tip, transmissions for a named and a locked joint."""
    parts = _common_links() + [
        '<link name="world"/>',  # a floating base, held fixed
        '<joint name="world_joint" type="floating"><parent link="world"/><child link="base_footprint"/></joint>',
        _joint("wheel_left_joint", "continuous", "base", "wheel_left", "0 0.2 -0.05", "1.5707963 0 0", "0 0 1"),
        _joint("wheel_right_joint", "continuous", "base", "wheel_right", "0 -0.2 -0.05", "1.5707963 0 0", "0 0 1"),
        _joint("head_pan", "revolute", "torso", "head", "0 0 0.5", f"0 0 {HEAD_YAW}", "0 0 1"),
        _joint("gripper_left", "prismatic", "arm3", "finger_left", f"0.1 {FINGER_Y} 0", axis="0 1 0"),
        _joint("gripper_right", "prismatic", "arm3", "finger_right", f"0.1 {-FINGER_Y} 0", axis="0 1 0",
               extra=f'<mimic joint="gripper_left" multiplier="{MIMIC_MULTIPLIER}" offset="{MIMIC_OFFSET}"/>'),
    ]
    transmissions = [
        '<transmission name="t_arm1"><type>transmission_interface/SimpleTransmission</type>'
        '<joint name="arm_1"/><actuator name="m_arm1"><mechanicalReduction>100</mechanicalReduction></actuator>'
        '</transmission>',
        '<transmission name="t_gripper"><type>transmission_interface/SimpleTransmission</type>'
        '<joint name="gripper_left"/><actuator name="m_grip"><mechanicalReduction>7</mechanicalReduction></actuator>'
        '</transmission>',
    ]
    return '<?xml version="1.0"?>\n<robot name="tree">' + "".join(parts + transmissions) + "</robot>"


def hand_reduced_urdf() -> str:
    """The same robot written by hand as a serial chain: the locked joints as fixed joints at their positions."""
    left = LOCKED["gripper_left"]
    right = MIMIC_MULTIPLIER * left + MIMIC_OFFSET
    parts = _common_links() + [
        '<link name="world"/>',
        '<joint name="world_joint" type="fixed"><parent link="world"/><child link="base_footprint"/></joint>',
        _joint("wheel_left_joint", "fixed", "base", "wheel_left", "0 0.2 -0.05", "1.5707963 0 0"),
        _joint("wheel_right_joint", "fixed", "base", "wheel_right", "0 -0.2 -0.05", "1.5707963 0 0"),
        _joint("head_pan", "fixed", "torso", "head", "0 0 0.5", f"0 0 {HEAD_YAW + LOCKED['head_pan']}"),
        _joint("gripper_left", "fixed", "arm3", "finger_left", f"0.1 {FINGER_Y + left} 0"),
        _joint("gripper_right", "fixed", "arm3", "finger_right", f"0.1 {-FINGER_Y + right} 0"),
    ]
    return '<?xml version="1.0"?>\n<robot name="tree">' + "".join(parts) + "</robot>"


@pytest.fixture
def urdf_files(tmp_path):
    tree, serial = tmp_path / "tree.urdf", tmp_path / "serial.urdf"
    tree.write_text(tree_urdf())
    serial.write_text(hand_reduced_urdf())
    return tree, serial


def _locked_configuration(model, named_q: np.ndarray) -> np.ndarray:
    """The whole tree's configuration: named joints at ``named_q``, the others locked (the mimic finger following)."""
    q = pin.neutral(model)
    values = dict(zip(NAMED, named_q)) | LOCKED
    values["gripper_right"] = MIMIC_MULTIPLIER * LOCKED["gripper_left"] + MIMIC_OFFSET
    for name, value in values.items():
        joint = model.joints[model.getJointId(name)]
        if joint.nq == 2:
            q[joint.idx_q : joint.idx_q + 2] = np.cos(value), np.sin(value)
        else:
            q[joint.idx_q] = value
    return q


def test_named_joints_regressor_matches_pinocchio_rnea_of_the_tree_with_the_others_locked(urdf_files):
    tree, _ = urdf_files
    robot = load_robot(urdf=tree, joint_names=list(NAMED), locked_at=LOCKED)
    assert robot.joint_names == list(NAMED)
    full = pin.buildModelFromUrdf(str(tree))  # the whole tree, the mimic finger an independent joint
    data = full.createData()
    velocity_index = [full.joints[full.getJointId(name)].idx_v for name in NAMED]
    model = build_model(robot, "internal", effects=None)
    q, dq, ddq = random_states(robot.n_joints, 15, seed=4)
    predicted = model.predict(robot.standard_parameters, q, dq, ddq)
    expected = []
    for qi, dqi, ddqi in zip(q, dq, ddq):
        v, a = np.zeros(full.nv), np.zeros(full.nv)
        v[velocity_index], a[velocity_index] = dqi, ddqi
        expected.append(pin.rnea(full, data, _locked_configuration(full, qi), v, a)[velocity_index])
    expected = np.array(expected)
    np.testing.assert_allclose(predicted, expected, rtol=0, atol=1e-9 * np.abs(expected).max())
    # the locked joints matter: another gripper opening moves the torques of the named joints
    moved = load_robot(urdf=tree, joint_names=list(NAMED), locked_at={"head_pan": 0.3, "gripper_left": 0.3})
    assert not np.allclose(build_model(moved, "internal", effects=None).predict(moved.standard_parameters, q, dq, ddq),
                           predicted, rtol=1e-6)


def test_named_joints_equal_a_hand_reduced_serial_urdf(urdf_files):
    tree, serial = urdf_files
    named = load_robot(urdf=tree, joint_names=",".join(NAMED), locked_at=LOCKED)
    reduced = load_robot(urdf=serial)
    assert named.joint_names == reduced.joint_names
    q, dq, ddq = random_states(named.n_joints, 10, seed=7)
    for kind in ("internal", "combined"):
        assert (build_model(named, kind, effects="viscous,coulomb").base.names
                == build_model(reduced, kind, effects="viscous,coulomb").base.names)
        ours, theirs = build_model(named, kind, effects=None), build_model(reduced, kind, effects=None)
        np.testing.assert_allclose(ours.base.to_base(named.standard_parameters),
                                   theirs.base.to_base(reduced.standard_parameters), rtol=1e-9, atol=1e-12)
        np.testing.assert_allclose(ours.predict(named.standard_parameters, q, dq, ddq),
                                   theirs.predict(reduced.standard_parameters, q, dq, ddq), rtol=1e-9, atol=1e-9)


def test_transmissions_of_locked_joints_are_ignored_those_of_named_joints_kept(urdf_files):
    tree, _ = urdf_files
    robot = load_robot(urdf=tree, joint_names=NAMED, locked_at=LOCKED)
    transmission = transmission_from_urdf(tree, robot)
    np.testing.assert_allclose(np.diag(transmission.matrix), [1, 100, 1, 1])
    assert transmission.motor_names[1] == "m_arm1"


def test_the_model_file_keeps_the_names_and_the_locks(urdf_files):
    tree, _ = urdf_files
    robot = load_robot(urdf=tree, joint_names=NAMED, locked_at=LOCKED)
    source = RobotSource.from_description(robot, builtin=None, urdf=tree, joints=None, joint_names=NAMED,
                                          locked_at=LOCKED)
    again = RobotSource.from_dict(json.loads(json.dumps(source.to_dict()))).load()
    assert again.joint_names == list(NAMED)
    np.testing.assert_allclose(again.standard_parameters, robot.standard_parameters, rtol=1e-14)


@pytest.mark.parametrize("names, locked, message", [
    (("torso_lift", "arm_1", "head_pan"), {}, "not one chain"),
    (("arm_1", "torso_lift"), {}, "from the base to the tip: torso_lift,arm_1"),
    (("torso_lift", "arm_1", "nope"), {}, "not a joint of the file"),
    (("torso_lift", "arm1_cover_joint"), {}, "is a fixed joint"),
    (("torso_lift", "gripper_right"), {}, "name its driver 'gripper_left'"),
    (("torso_lift",), {"torso_lift": 0.1}, "both named"),
    (("torso_lift",), {"head": 0.1}, "not a movable joint"),
    (("arm_1", "arm_2", "arm_3", "gripper_left"), {}, "mimics the named joint 'gripper_left' and carries 0.1 kg"),
])
def test_bad_joint_selections_are_refused_by_name(urdf_files, names, locked, message):
    tree, _ = urdf_files
    with pytest.raises(RobotDescriptionError, match=message):
        load_robot(urdf=tree, joint_names=names, locked_at=locked)


def test_a_tree_without_names_is_refused_as_today(urdf_files):
    tree, _ = urdf_files
    with pytest.raises(RobotDescriptionError, match="mimic"):
        load_robot(urdf=tree)


def test_cli_identify_with_named_joints_equals_the_hand_reduced_urdf_and_predict_needs_no_names(urdf_files, tmp_path):
    """The TIAGo case end to end: simulate, identify from the tree with the joints named and from the serial
    file, the same parameters (relative 1e-6); ``oed predict`` reads the names from the model file."""
    from oed.cli import main
    from oed.fourier import FourierTrajectory

    tree, serial = urdf_files
    generator = np.random.default_rng(5)
    trajectory = tmp_path / "trajectory.json"
    FourierTrajectory(0.5, np.zeros(4), generator.uniform(-0.1, 0.1, (4, 3)),
                      generator.uniform(-0.1, 0.1, (4, 3))).save(trajectory)
    selection = ["--joint-names", ",".join(NAMED), "--locked-at", ",".join(f"{k}={v}" for k, v in LOCKED.items())]
    data = tmp_path / "data.csv"
    assert main(["simulate", "--urdf", str(tree), *selection, "--trajectory", str(trajectory), "--periods", "2",
                 "--q-resolution", "none", "--seed", "1", "--out", str(data)]) == 0
    values = {}
    for label, arguments in (("tree", ["--urdf", str(tree), *selection]), ("serial", ["--urdf", str(serial)])):
        out = tmp_path / f"{label}.json"
        assert main(["identify", *arguments, "--model", "internal", "--friction", "viscous", "--data", str(data),
                     "--out", str(out)]) == 0
        values[label] = np.array([entry["value"] for entry in json.loads(out.read_text())["parameters"]])
    np.testing.assert_allclose(values["tree"], values["serial"], rtol=1e-6, atol=1e-9 * np.abs(values["serial"]).max())
    assert main(["predict", "--model", str(tmp_path / "tree.json"), "--data", str(data),
                 "--metrics", str(tmp_path / "metrics.json")]) == 0


def test_exported_urdf_of_named_joints_reads_back_the_identified_bodies(urdf_files, tmp_path):
    """`oed export` of a model of named joints: the locked joints' bodies are in the identified ones, so their
    links are emptied and the file read again with the same names gives the identified bodies."""
    from dynamics.urdf_export import urdf_with_inertials

    tree, _ = urdf_files
    robot = load_robot(urdf=tree, joint_names=NAMED, locked_at=LOCKED)
    links = robot.standard_parameters.reshape(-1, 10) * np.random.default_rng(1).uniform(0.8, 1.2, (len(NAMED), 10))
    exported = tmp_path / "exported.urdf"
    exported.write_text(urdf_with_inertials(tree.read_text(), robot, links, merge_locked=True))
    for locks in (LOCKED, {}):  # the locked links are empty: where they stand changes nothing
        again = load_robot(urdf=exported, joint_names=NAMED, locked_at=locks)
        np.testing.assert_allclose(again.standard_parameters.reshape(-1, 10), links, rtol=1e-12, atol=1e-12)
