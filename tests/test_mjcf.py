"""Robots read from MuJoCo MJCF models (:mod:`dynamics.mjcf`), checked against MuJoCo's own inverse dynamics,
Pinocchio's MJCF parser and the URDF path; the refusals name the element."""

from __future__ import annotations

import json
import warnings

import numpy as np
import pinocchio as pin
import pytest

from dynamics import MjcfIgnoredWarning, robot_from_mjcf, robot_from_urdf, robot_mjcf, robot_urdf, to_pinocchio
from dynamics.errors import RobotDescriptionError
from dynamics.mjcf import mjcf_joint_terms, mjcf_logged_chain
from dynamics.models import build_model
from dynamics.robots import load_robot
from estimation.identification.model_file import RobotSource
from tests.conftest import random_states

ARM = ("shoulder_pan", "shoulder_lift", "elbow", "wrist")

#: in the style of MuJoCo Menagerie's arms: default classes (nested, childclass), <body pos quat|euler|zaxis>,
#: a <frame>, inertials with fullinertia or diaginertia + quat, joints with axis, pos, range and ref; a gripper
#: whose fingers are coupled by an equality and a fixed tendon
MENAGERIE_STYLE = """
<mujoco model="menagerie_style_arm">
  <compiler angle="radian" autolimits="true"/>
  <option gravity="0 0 -9.81" integrator="implicitfast"/>
  <default>
    <default class="arm">
      <joint axis="0 0 1" armature="0.1" damping="0.5" frictionloss="0.2" actuatorfrcrange="-87 87"/>
      <default class="small">
        <joint armature="0.05" actuatorfrcrange="-12 12"/>
      </default>
      <default class="finger">
        <joint type="slide" axis="0 1 0" range="0 0.04" armature="0"/>
      </default>
      <geom type="capsule" size="0.05 0.1"/>
    </default>
  </default>
  <worldbody>
    <light pos="0 0 3"/>
    <body name="base" childclass="arm" pos="0.1 0 0">
      <geom type="cylinder" size="0.1 0.05"/>
      <body name="link1" pos="0 0 0.333">
        <inertial mass="4.97" pos="0.003875 0.002081 -0.04762"
                  fullinertia="0.70337 0.70661 0.0091170 -0.00013900 0.0067720 0.019169"/>
        <joint name="shoulder_pan" range="-2.8973 2.8973"/>
        <geom/>
        <body name="link2" quat="0.707107 -0.707107 0 0">
          <inertial mass="0.646926" pos="-0.003141 -0.02872 0.003495" quat="0.9 0.1 0.2 0.3"
                    diaginertia="0.0079620 0.028110 0.025995"/>
          <joint name="shoulder_lift" range="-1.7628 1.7628"/>
          <geom/>
          <body name="link3" pos="0 -0.316 0" euler="1.5707963 0 0">
            <inertial mass="3.228604" pos="0.027518 0.039252 -0.066502" diaginertia="0.037242 0.036155 0.01083"/>
            <joint name="elbow" class="small" range="-2.8973 2.8973" ref="0.3"/>
            <geom/>
            <frame pos="0.0825 0 0" xyaxes="1 0 0 0 0 -1">
              <body name="link4">
                <inertial mass="3.587895" pos="-0.05317 0.104419 0.027454" quat="0.7 0.1 -0.1 0.7"
                          diaginertia="0.025853 0.019552 0.028323"/>
                <joint name="wrist" class="small" axis="0 0 -1" pos="0 0 0.01" range="-3.0718 -0.0698"/>
                <geom/>
                <body name="hand" pos="0 0.2 0" zaxis="0 1 0">
                  <inertial mass="0.73" pos="0 0 0.017" diaginertia="0.001 0.0025 0.0017"/>
                  <geom/>
                  <body name="left_finger" pos="0 0 0.0584">
                    <inertial mass="0.015" pos="0 0 0" diaginertia="2.375e-6 2.375e-6 7.5e-7"/>
                    <joint name="finger_joint1" class="finger"/>
                  </body>
                  <body name="right_finger" pos="0 0 0.0584" quat="0 0 0 1">
                    <inertial mass="0.015" pos="0 0 0" diaginertia="2.375e-6 2.375e-6 7.5e-7"/>
                    <joint name="finger_joint2" class="finger"/>
                  </body>
                </body>
              </body>
            </frame>
          </body>
        </body>
      </body>
    </body>
  </worldbody>
  <tendon>
    <fixed name="split">
      <joint joint="finger_joint1" coef="0.5"/>
      <joint joint="finger_joint2" coef="0.5"/>
    </fixed>
  </tendon>
  <equality>
    <joint joint1="finger_joint1" joint2="finger_joint2" solimp="0.95 0.99 0.001" solref="0.005 1"/>
  </equality>
  <actuator>
    <general name="actuator1" joint="shoulder_pan" gainprm="4500" biasprm="0 -4500 -450"/>
  </actuator>
</mujoco>
"""

#: MuJoCo's defaults: angles in degrees, Euler sequence set by the compiler, axisangle, a body with two joints
DEGREES = """
<mujoco model="degrees">
  <compiler eulerseq="zyx"/>
  <option gravity="0 -9.81 0"/>
  <worldbody>
    <body name="a" pos="0 0 0.2" euler="10 20 30">
      <inertial mass="2" pos="0.1 0 0.05" diaginertia="0.02 0.03 0.04" axisangle="1 1 0 40"/>
      <joint name="q1" axis="0 0 1" range="-170 170"/>
      <joint name="q2" axis="0 1 0" pos="0.05 0 0" range="-90 45" ref="15"/>
      <body name="b" pos="0.3 0 0" axisangle="0 1 1 -35">
        <inertial mass="1.2" pos="0.05 0.01 0" fullinertia="0.01 0.012 0.008 0.001 -0.0005 0.0002"/>
        <joint name="q3" type="slide" axis="1 0 0" range="-0.2 0.3"/>
      </body>
    </body>
  </worldbody>
</mujoco>
"""


@pytest.fixture
def menagerie(tmp_path):
    path = tmp_path / "arm.xml"
    path.write_text(MENAGERIE_STYLE)
    return path


def _write(tmp_path, text, name="model.xml"):
    path = tmp_path / name
    path.write_text(text)
    return path


def _mujoco_rne(path, names, q, dq, ddq, *, inverse=False):
    """MuJoCo's rigid-body inverse dynamics (``M q̈ + c``, no armature or passive forces) of the joints ``names``,
    the file's other joints at 0 and still; ``inverse``: ``mj_inverse`` with constraints off instead (no friction
    loss, no equality), ``M q̈ + c`` with the armature less the passive forces (damping, springs)."""
    mujoco = pytest.importorskip("mujoco")
    model = mujoco.MjModel.from_xml_path(str(path))
    if inverse:
        model.opt.disableflags |= mujoco.mjtDisableBit.mjDSBL_CONSTRAINT
    data = mujoco.MjData(model)
    index = [model.jnt_dofadr[model.joint(name).id] for name in names]
    address = [model.jnt_qposadr[model.joint(name).id] for name in names]
    torques = []
    for qi, dqi, ddqi in zip(q, dq, ddq):
        data.qpos[:], data.qvel[:], data.qacc[:] = 0.0, 0.0, 0.0
        data.qpos[address], data.qvel[index] = qi, dqi
        if inverse:
            data.qacc[index] = ddqi
            mujoco.mj_inverse(model, data)
            torques.append(data.qfrc_inverse[index].copy())
            continue
        mujoco.mj_forward(model, data)
        data.qacc[:] = 0.0
        data.qacc[index] = ddqi
        out = np.zeros(model.nv)
        mujoco.mj_rne(model, data, 1, out)
        torques.append(out[index])
    return np.array(torques)


def _predicted(robot, q, dq, ddq):
    return build_model(robot, "internal", effects=None).predict(robot.standard_parameters, q, dq, ddq)


def test_menagerie_style_model_matches_mujoco_inverse_dynamics(menagerie):
    """Default classes, frames, orientations, inertial frames, joint pos and ref as MuJoCo compiles them: the
    torques of the named joints equal MuJoCo's ``mj_rne`` (the fingers locked at 0 merged into the hand)."""
    with warnings.catch_warnings():
        warnings.simplefilter("error", MjcfIgnoredWarning)  # armature, damping and frictionloss are read
        robot = robot_from_mjcf(menagerie, joint_names=ARM)
    assert robot.joint_names == list(ARM)
    assert [(joint.armature, joint.damping, joint.friction) for joint in robot.joints] == [
        (0.1, 0.5, 0.2), (0.1, 0.5, 0.2), (0.05, 0.5, 0.2), (0.05, 0.5, 0.2)]
    q, dq, ddq = random_states(robot.n_joints, 20, seed=3)
    expected = _mujoco_rne(menagerie, ARM, q, dq, ddq)
    np.testing.assert_allclose(_predicted(robot, q, dq, ddq), expected, rtol=0, atol=1e-9 * np.abs(expected).max())
    np.testing.assert_allclose(robot.lower, [-2.8973, -1.7628, -2.8973, -3.0718])
    np.testing.assert_allclose(robot.upper, [2.8973, 1.7628, 2.8973, -0.0698])
    assert [joint.effort for joint in robot.joints] == [87.0, 87.0, 12.0, 12.0]
    # the total mass moved: every body below the base
    assert robot.standard_parameters.reshape(-1, 10)[:, 0].sum() == pytest.approx(
        4.97 + 0.646926 + 3.228604 + 3.587895 + 0.73 + 0.03, rel=1e-12)


def test_mujoco_defaults_degrees_euler_sequence_axisangle_and_two_joints_in_one_body(tmp_path):
    path = _write(tmp_path, DEGREES)
    robot = robot_from_mjcf(path)
    assert robot.joint_names == ["q1", "q2", "q3"]
    np.testing.assert_allclose(robot.gravity, [0, -9.81, 0])  # the file's <option gravity>
    np.testing.assert_allclose(robot.lower, [np.deg2rad(-170), np.deg2rad(-90), -0.2])
    q, dq, ddq = random_states(3, 20, seed=5)
    expected = _mujoco_rne(path, robot.joint_names, q, dq, ddq)
    np.testing.assert_allclose(_predicted(robot, q, dq, ddq), expected, rtol=0, atol=1e-9 * np.abs(expected).max())


def test_a_serial_menagerie_style_model_matches_pinocchios_mjcf_parser(menagerie, tmp_path):
    """Pinocchio 4's ``buildModelFromMJCF``, an independent reader, on the model cut to a serial chain without
    ``<frame>`` (which it does not read: it drops the bodies inside one)."""
    text = MENAGERIE_STYLE.replace('<frame pos="0.0825 0 0" xyaxes="1 0 0 0 0 -1">', "").replace("</frame>", "")
    text = text.replace('<body name="link4">', '<body name="link4" pos="0.0825 0 0" xyaxes="1 0 0 0 0 -1">')
    start, end = text.index('<body name="left_finger"'), text.index("</body>\n                </body>\n              </body>")
    text = text[:start] + text[end + len("</body>\n"):]
    start, end = text.index("<tendon>"), text.index("</equality>")
    path = _write(tmp_path, text[:start] + text[end + len("</equality>"):])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", MjcfIgnoredWarning)
        robot = robot_from_mjcf(path)
    assert robot.joint_names == list(ARM)
    theirs = pin.buildModelFromMJCF(str(path))
    assert list(theirs.names)[1:] == list(ARM)
    theirs.armature[:] = 0.0  # Pinocchio reads the joints' armature into its inverse dynamics; not read here
    q, dq, ddq = random_states(robot.n_joints, 20, seed=4)
    ours = to_pinocchio(robot)
    for qi, dqi, ddqi in zip(q, dq, ddq):
        expected = pin.rnea(theirs, theirs.createData(), qi, dqi, ddqi)
        np.testing.assert_allclose(pin.rnea(ours, ours.createData(), qi, dqi, ddqi), expected, rtol=0,
                                   atol=1e-9 * max(1.0, np.abs(expected).max()))


@pytest.mark.parametrize("name", ["puma560", "servo_arm"])
def test_one_robot_written_as_urdf_and_as_mjcf_reads_the_same(name, tmp_path):
    """``robot_urdf`` and ``robot_mjcf`` of one robot, read back: the same base parameters and regressors (1e-9),
    and Pinocchio's inverse dynamics of the URDF. The robot is first read from its URDF, so that its link frames
    are its joint frames (a DH table's link frames, written to MJCF as they are, would give other base parameters
    with the same inverse dynamics: checked last)."""
    described = load_robot(name)
    as_urdf = _write(tmp_path, robot_urdf(described), "robot.urdf")
    from_urdf = robot_from_urdf(as_urdf)
    as_mjcf = _write(tmp_path, robot_mjcf(from_urdf, from_urdf.standard_parameters.reshape(-1, 10)), "robot.xml")
    from_mjcf = load_robot(urdf=as_mjcf)  # recognised by its root element
    assert from_mjcf.joint_names == from_urdf.joint_names == described.joint_names
    q, dq, ddq = random_states(described.n_joints, 15, seed=2)
    for kind in ("internal", "combined"):
        ours, theirs = build_model(from_mjcf, kind, effects=None), build_model(from_urdf, kind, effects=None)
        assert ours.base.names == theirs.base.names
        np.testing.assert_allclose(ours.base.to_base(from_mjcf.standard_parameters),
                                   theirs.base.to_base(from_urdf.standard_parameters), rtol=1e-9, atol=1e-12)
        np.testing.assert_allclose(ours.predict(from_mjcf.standard_parameters, q, dq, ddq),
                                   theirs.predict(from_urdf.standard_parameters, q, dq, ddq), rtol=1e-9, atol=1e-9)
    pinocchio_urdf = pin.buildModelFromUrdf(str(as_urdf))
    expected = np.array([pin.rnea(pinocchio_urdf, pinocchio_urdf.createData(), *state) for state in zip(q, dq, ddq)])
    np.testing.assert_allclose(_predicted(from_mjcf, q, dq, ddq), expected, rtol=0,
                               atol=1e-9 * np.abs(expected).max())
    in_link_frames = robot_from_mjcf(_write(tmp_path, robot_mjcf(described, described.standard_parameters.reshape(
        -1, 10)), "link_frames.xml"))
    np.testing.assert_allclose(_predicted(in_link_frames, q, dq, ddq), expected, rtol=0,
                               atol=1e-9 * np.abs(expected).max())


def test_round_trip_export_then_read(tmp_path):
    """``robot_mjcf`` of new bodies and joint terms, read back: the same bodies, limits and friction terms."""
    robot = load_robot("puma560")
    links = robot.standard_parameters.reshape(-1, 10) * np.random.default_rng(1).uniform(0.8, 1.2, (6, 10))
    terms = {name: {"damping": 0.1 * index + 0.1, "frictionloss": 0.05 * index}
             for index, name in enumerate(robot.joint_names)}
    path = _write(tmp_path, robot_mjcf(robot, links, terms))
    again = robot_from_mjcf(path)
    np.testing.assert_allclose(again.standard_parameters.reshape(-1, 10), links, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(again.lower, robot.lower)
    np.testing.assert_allclose(again.upper, robot.upper)
    read = mjcf_joint_terms(path, again)
    assert read == {name: {"viscous": value["damping"], "coulomb": value["frictionloss"]}
                    for name, value in terms.items()}


def test_the_log_determines_the_chain_and_the_locked_fingers_are_merged(menagerie):
    assert mjcf_logged_chain(menagerie, 4) == (ARM, ("finger_joint1", "finger_joint2"))
    with pytest.raises(RobotDescriptionError, match="no chain of 6 joint"):
        mjcf_logged_chain(menagerie, 6)
    closed, open_ = (robot_from_mjcf(menagerie, joint_names=ARM, locked_at=locks)
                     for locks in ({}, {"finger_joint1": 0.04}))
    moved = closed.standard_parameters.reshape(-1, 10)[-1] - open_.standard_parameters.reshape(-1, 10)[-1]
    assert np.abs(moved[1:4]).max() > 1e-5  # the fingers' opening moves the hand's first moments
    np.testing.assert_allclose(moved[0], 0.0, atol=1e-15)


def test_includes_are_read_and_the_model_file_embeds_them(menagerie, tmp_path):
    """A Menagerie scene (``scene.xml`` including the arm): read through the include; the model file holds the
    text with the include in place, so that ``oed predict`` reads it alone elsewhere."""
    scene = _write(tmp_path, '<mujoco model="scene">\n  <include file="arm.xml"/>\n  <worldbody>\n    '
                             '<geom name="floor" type="plane" size="1 1 0.1"/>\n  </worldbody>\n</mujoco>\n',
                   "scene.xml")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", MjcfIgnoredWarning)
        robot = load_robot(urdf=scene, joint_names=ARM)
        source = RobotSource.from_description(robot, builtin=None, urdf=scene, joints=None, joint_names=ARM)
        menagerie.unlink()
        again = RobotSource.from_dict(json.loads(json.dumps(source.to_dict()))).load()
    np.testing.assert_allclose(again.standard_parameters, robot.standard_parameters, rtol=1e-14)


@pytest.mark.parametrize("old, new, message", [
    ('<body name="base" childclass="arm" pos="0.1 0 0">', '<body name="base" childclass="arm" pos="0.1 0 0">'
     '<freejoint name="root"/>', "joint 'root' of body 'base' is a free joint: a floating base"),
    ('<joint name="elbow" class="small" range="-2.8973 2.8973" ref="0.3"/>', '<joint name="elbow" type="ball"/>',
     "joint 'elbow' is a ball joint"),
    ('<joint joint="finger_joint2" coef="0.5"/>', '<joint joint="wrist" coef="0.5"/>',
     "tendon <fixed name='split'> couples joints finger_joint1, wrist"),
    ('joint2="finger_joint2" solimp', 'joint2="elbow" solimp', "equality <joint> couples joints finger_joint1, elbow"),
    ("</equality>", '<connect body1="hand" body2="link1" anchor="0 0 0"/></equality>',
     "equality <connect>: a closed loop"),
    ("</tendon>", '<spatial name="cable"><site site="s1"/><site site="s2"/></spatial></tendon>',
     "tendon <spatial name='cable'>: a spatial tendon"),
    ('<inertial mass="0.73" pos="0 0 0.017" diaginertia="0.001 0.0025 0.0017"/>', "",
     "body 'hand' moves with joint 'wrist' and MuJoCo computes its inertia from its geoms"),
    ('pos="0 -0.316 0"', 'pos="0 -0.316"', "<body name='link3' pos=\"0 -0.316\"> is not 3 finite number"),
    ('mass="3.228604"', 'mass="3.2 kg"', "is not 1 finite number"),
    ('class="small" axis="0 0 -1"', 'class="tiny" axis="0 0 -1"', "names class 'tiny', which no <default> defines"),
    ('<body name="link2" quat="0.707107 -0.707107 0 0">', '<body name="link2" quat="0.707107 -0.707107 0 0" '
     'euler="0 0 1">', "several orientations"),
    ('range="-3.0718 -0.0698"', 'range="0.1 -0.1"', "joint 'wrist': range '0.1 -0.1': lower above upper"),
    ('<compiler angle="radian"', '<compiler settotalmass="10" angle="radian"', "settotalmass='10'> rescales"),
    ("<geom/>\n            <frame", '<geom/>\n            <replicate count="2" offset="0 0 0.1"><body/></replicate>'
     "\n            <frame", "<replicate> in the worldbody"),
])
def test_what_a_serial_chain_cannot_take_is_refused_by_name(tmp_path, old, new, message):
    assert old in MENAGERIE_STYLE
    path = _write(tmp_path, MENAGERIE_STYLE.replace(old, new))
    with warnings.catch_warnings(), pytest.raises(RobotDescriptionError, match=message.replace("(", r"\(")):
        warnings.simplefilter("ignore", MjcfIgnoredWarning)
        robot_from_mjcf(path, joint_names=ARM)


@pytest.mark.parametrize("names, locked, message", [
    (None, None, "joint 'finger_joint2' .* hangs from 'wrist', not from the previous joint 'finger_joint1': several "
                 "chains .* --joint-names shoulder_pan,shoulder_lift,elbow,wrist"),
    (("shoulder_pan", "elbow", "shoulder_lift"), None, "not one chain from the base to the tip in this order"),
    (("shoulder_pan", "nope"), None, "'nope' is not a joint of the file"),
    (("shoulder_pan", "finger_joint1"), None, "tendon <fixed name='split'> couples joints finger_joint1, finger_joint2"),
    (ARM, {"wrist": 0.1}, "both named"),
    (ARM, {"hand": 0.1}, "locked joint 'hand' is not a joint of the file"),
])
def test_bad_joint_selections_are_refused_by_name(menagerie, names, locked, message):
    with warnings.catch_warnings(), pytest.raises(RobotDescriptionError, match=message):
        warnings.simplefilter("ignore", MjcfIgnoredWarning)
        robot_from_mjcf(menagerie, joint_names=names, locked_at=locked)


def test_a_ball_joint_in_a_chain_without_names_is_refused(tmp_path):
    path = _write(tmp_path, DEGREES.replace('<joint name="q3" type="slide"', '<joint name="q3" type="ball"'))
    with pytest.raises(RobotDescriptionError, match="joint 'q3' of body 'b' is a ball joint"):
        robot_from_mjcf(path)


def test_a_urdf_is_not_read_as_mjcf_and_the_reverse(tmp_path):
    robot = load_robot("puma560")
    urdf = _write(tmp_path, robot_urdf(robot), "robot.urdf")
    with pytest.raises(RobotDescriptionError, match="root element is <robot>, not <mujoco>.*give --urdf"):
        robot_from_mjcf(urdf)
    with pytest.raises(RobotDescriptionError, match="MJCF file not found"):
        robot_from_mjcf(tmp_path / "missing.xml")
    with pytest.raises(RobotDescriptionError, match="not both"):
        load_robot(urdf=urdf, mjcf=urdf)


def test_cli_refuses_a_urdf_given_as_mjcf_and_both_options(tmp_path, capsys):
    from oed.cli import main

    robot = load_robot("puma560")
    urdf = _write(tmp_path, robot_urdf(robot), "robot.urdf")
    mjcf = _write(tmp_path, robot_mjcf(robot, robot.standard_parameters.reshape(-1, 10)), "robot.xml")
    for arguments, message in ((["--mjcf", str(urdf)], "not a MuJoCo MJCF model .*a URDF goes to --urdf"),
                               (["--mjcf", str(mjcf), "--urdf", str(urdf)], "not allowed with argument")):
        with pytest.raises(SystemExit) as exit_:
            main(["model", *arguments])
        assert exit_.value.code == 2
        assert __import__("re").search(message, capsys.readouterr().err)


@pytest.mark.slow
def test_cli_identify_from_the_mjcf_equals_the_urdf_and_predict_and_export_read_it(tmp_path):
    """One robot written as URDF and as MJCF: ``oed simulate`` from the MJCF, ``oed identify`` from each gives the
    same parameters (relative 1e-9); ``oed predict`` reads the robot from the model file alone, ``oed export``
    writes a URDF of the chain that reads back."""
    from oed.cli import main
    from oed.fourier import FourierTrajectory

    as_urdf = _write(tmp_path, robot_urdf(load_robot("puma560", joints=3)), "robot.urdf")
    robot = robot_from_urdf(as_urdf)  # its link frames are its joint frames, as the URDF's (one set of base parameters)
    as_mjcf = _write(tmp_path, robot_mjcf(robot, robot.standard_parameters.reshape(-1, 10)), "robot.xml")
    generator = np.random.default_rng(5)
    trajectory = tmp_path / "trajectory.json"
    FourierTrajectory(0.5, np.zeros(3), generator.uniform(-0.3, 0.3, (3, 3)),
                      generator.uniform(-0.3, 0.3, (3, 3))).save(trajectory)
    data = tmp_path / "data.csv"
    assert main(["simulate", "--mjcf", str(as_mjcf), "--trajectory", str(trajectory), "--periods", "2",
                 "--q-resolution", "none", "--seed", "1", "--out", str(data)]) == 0
    values = {}
    for option, path in (("--urdf", as_urdf), ("--mjcf", as_mjcf)):
        out = tmp_path / f"{path.suffix[1:]}.json"
        assert main(["identify", option, str(path), "--model", "internal", "--friction", "viscous", "--data",
                     str(data), "--out", str(out)]) == 0
        parameters = json.loads(out.read_text())["parameters"]
        values[option] = np.array([entry["value"] for entry in parameters])
        values[option + " names"] = [entry["name"] for entry in parameters]
    assert values["--mjcf names"] == values["--urdf names"]
    np.testing.assert_allclose(values["--mjcf"], values["--urdf"], rtol=1e-9,
                               atol=1e-9 * np.abs(values["--urdf"]).max())
    as_mjcf.unlink()  # the model file holds the description
    assert main(["predict", "--model", str(tmp_path / "xml.json"), "--data", str(data),
                 "--metrics", str(tmp_path / "metrics.json")]) == 0
    exported = tmp_path / "exported.urdf"
    assert main(["export", "--model", str(tmp_path / "xml.json"), "--urdf", str(exported)]) == 0
    assert robot_from_urdf(exported).joint_names == robot.joint_names


def test_design_reads_the_mjcf_friction_and_refuses_its_geometry(menagerie):
    """``oed design --torque-limits``: damping and frictionloss are the description's viscous and Coulomb friction;
    ``--floor`` needs a URDF's collision geometry, refused naming the MJCF file."""
    from oed.design_constraints import ConstraintError, constraints_from_options, declared_friction

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", MjcfIgnoredWarning)
        robot = robot_from_mjcf(menagerie, joint_names=ARM)
    viscous, coulomb = declared_friction(menagerie, robot)
    np.testing.assert_allclose(viscous, [0.5] * 4)
    np.testing.assert_allclose(coulomb, [0.2] * 4)
    (limits,) = constraints_from_options(robot, menagerie, torque_limits=True)
    np.testing.assert_allclose(limits.effort, [87, 87, 12, 12])
    with pytest.raises(ConstraintError, match="geoms of the MJCF model .* are not read"):
        constraints_from_options(robot, menagerie, floor=0.0)
