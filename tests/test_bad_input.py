"""Bad input raises an error that names the problem."""

from __future__ import annotations

import numpy as np
import pytest

from dynamics.errors import RobotDescriptionError, SampleShapeError
from dynamics.models import build_model
from dynamics.robots import load_robot

LINK = """<link name="{name}"><inertial><mass value="1"/><inertia ixx="0.1" ixy="0" ixz="0" iyy="0.1" iyz="0" izz="0.1"/></inertial></link>"""


def _urdf(tmp_path, joints: str, links=("base", "a", "b", "c")) -> str:
    path = tmp_path / "robot.urdf"
    path.write_text('<robot name="r">' + "".join(LINK.format(name=name) for name in links) + joints + "</robot>")
    return str(path)


def test_unknown_robot_name():
    with pytest.raises(RobotDescriptionError, match="unknown robot 'kuka'"):
        load_robot("kuka")


def test_joint_count_may_be_a_numpy_integer():
    assert load_robot("puma560", joints=np.int64(3)).n_joints == 3


def test_too_many_joints_requested():
    with pytest.raises(RobotDescriptionError, match="has 6 joints"):
        load_robot("puma560", joints=7)


def test_floating_joint_in_urdf(tmp_path):
    path = _urdf(tmp_path, '<joint name="float" type="floating"><parent link="base"/><child link="a"/></joint>', ("base", "a"))
    # a floating joint from the root link is the base's motion, read as fixed (h-unseen18): nothing moves then
    with pytest.raises(RobotDescriptionError, match="no movable joint.*'float' .*floating.*fixed base"):
        load_robot(urdf=path)


def test_planar_joint_in_urdf(tmp_path):
    path = _urdf(tmp_path, '<joint name="plane" type="planar"><parent link="base"/><child link="a"/><axis xyz="0 0 1"/></joint>', ("base", "a"))
    with pytest.raises(RobotDescriptionError, match="no movable joint.*'plane' .*planar.*fixed base"):
        load_robot(urdf=path)


def test_spherical_joint_in_urdf(tmp_path):
    path = _urdf(tmp_path, '<joint name="ball" type="spherical"><parent link="base"/><child link="a"/></joint>', ("base", "a"))
    with pytest.raises(RobotDescriptionError, match="ball|parse|spherical|Spherical"):
        load_robot(urdf=path)


def test_branching_chain_in_urdf(tmp_path):
    joints = "".join(
        f'<joint name="{name}" type="revolute"><parent link="{parent}"/><child link="{child}"/><axis xyz="0 0 1"/>'
        '<limit lower="-1" upper="1" effort="1" velocity="1"/></joint>'
        for name, parent, child in (("j1", "base", "a"), ("j2", "a", "b"), ("j3", "a", "c"))
    )
    with pytest.raises(RobotDescriptionError, match="branching"):
        load_robot(urdf=_urdf(tmp_path, joints))


def test_missing_urdf_file(tmp_path):
    with pytest.raises(RobotDescriptionError, match="not found"):
        load_robot(urdf=tmp_path / "absent.urdf")


def test_wrong_array_shapes_and_nan_are_named():
    model = build_model(load_robot("puma560", joints=3), "internal")
    with pytest.raises(SampleShapeError, match=r"q must have shape \(N, 3\)"):
        model.evaluate(np.zeros((5, 4)), np.zeros((5, 3)), np.zeros((5, 3)))
    with pytest.raises(SampleShapeError, match="same number of samples"):
        model.evaluate(np.zeros((5, 3)), np.zeros((4, 3)), np.zeros((5, 3)))
    ddq = np.zeros((5, 3))
    ddq[2, 1] = np.nan
    with pytest.raises(SampleShapeError, match=r"ddq holds NaN or inf \(sample 2, joint 2\)"):
        model.evaluate(np.zeros((5, 3)), np.zeros((5, 3)), ddq)
    with pytest.raises(ValueError, match="theta has 4 values"):
        model.predict(np.ones(4), np.zeros(3), np.zeros(3), np.zeros(3))


def test_unknown_model_and_effect():
    robot = load_robot("puma560", joints=3)
    with pytest.raises(ValueError, match="unknown model 'reaction'"):
        build_model(robot, "reaction")
    with pytest.raises(ValueError, match="unknown effect 'stiction'"):
        build_model(robot, "internal", "viscous,stiction")


@pytest.mark.parametrize(
    "make,error,message",
    [
        (lambda t, q: dict(t=t[:10], q=q), ValueError, "t has 10 samples, q 50"),
        (lambda t, q: dict(t=t, q=q, tau=q[:, :2]), ValueError, r"tau has shape \(50, 2\), expected \(50, 3\)"),
        (lambda t, q: dict(t=t, q=q, wrench=q), ValueError, r"wrench has shape \(50, 3\), expected \(50, 6\)"),
        (lambda t, q: dict(t=t.reshape(-1, 1), q=q), ValueError, "t must be 1-D"),
        (lambda t, q: dict(t=t, q=q.astype(complex)), TypeError, "q must hold real numbers"),
        (lambda t, q: dict(t=t, q=q.astype(str)), TypeError, "q must hold real numbers"),
    ],
)
def test_measurements_refuse_mismatched_or_non_numeric_arrays(make, error, message):
    from dynamics.measurements import Measurements

    t, q = np.arange(50) * 1e-3, np.zeros((50, 3))
    with pytest.raises(error, match=message):
        Measurements(**make(t, q))


def test_measurements_take_lists_and_a_single_joint_as_one_column():
    from dynamics.measurements import Measurements

    one_axis = Measurements([0.0, 0.1, 0.2], [1.0, 2.0, 3.0], tau=[0.0, 0.0, 1.0])
    assert one_axis.q.shape == (3, 1) and one_axis.tau.shape == (3, 1) and one_axis.n_joints == 1


def test_complex_states_are_refused_not_truncated():
    model = build_model(load_robot("puma560", joints=3), "internal")
    with pytest.raises(TypeError, match="q must be real"):
        model.evaluate_base(np.ones((2, 3)) + 1j, np.zeros((2, 3)), np.zeros((2, 3)))


@pytest.mark.parametrize(
    "link,limit,message",
    [
        ('<link name="a"><inertial><mass value="nan"/></inertial></link>', 'lower="-1" upper="1"',
         "link 'a': <mass value=\"nan\"> is not one finite number"),
        ('<link name="a"><inertial><mass value="1"/><inertia ixx="inf" ixy="0" ixz="0" iyy="1" iyz="0" izz="1"/>'
         '</inertial></link>', 'lower="-1" upper="1"', "<inertia ixx=\"inf\"> is not one finite number"),
        ('<link name="a"><inertial><mass value="1"/></inertial></link>', 'lower="1" upper="-1"',
         "joint 'j1': lower limit 1 is above upper limit -1"),
        ('<link name="a"><inertial><mass value="1_0"/></inertial></link>', 'lower="-1" upper="1"',
         "<mass value=\"1_0\"> is not one finite number"),  # Python's float() takes it, urdfdom does not
        ('<link name="a"><inertial><mass value="2 "/></inertial></link>', 'lower="-1" upper="1"',
         "<mass value=\"2 \"> is not one finite number"),  # urdfdom skips leading blanks, not trailing ones
        ('<link name="a"><inertial><mass value="1"/><inertia ixx="1e400" ixy="0" ixz="0" iyy="1" iyz="0" izz="1"/>'
         '</inertial></link>', 'lower="-1" upper="1"', "<inertia ixx=\"1e400\"> is not one finite number"),
    ],
)
def test_urdf_numbers_that_urdfdom_would_turn_into_zero_are_named(tmp_path, link, limit, message):
    path = tmp_path / "robot.urdf"
    path.write_text('<robot name="r"><link name="base"/>' + link + '<joint name="j1" type="revolute"><parent link="base"/>'
                    f'<child link="a"/><axis xyz="0 0 1"/><limit {limit} effort="1" velocity="1"/></joint></robot>')
    with pytest.raises(RobotDescriptionError, match=message.replace("(", r"\(")):
        load_robot(urdf=str(path))


def test_urdf_parser_errors_are_one_readable_line(tmp_path, capfd):
    path = _urdf(tmp_path, '<joint name="j1" type="revolute"><parent link="base"/><child link="nope"/><axis xyz="0 0 1"/>'
                           '<limit lower="-1" upper="1" effort="1" velocity="1"/></joint>', ("base", "a"))
    with pytest.raises(RobotDescriptionError, match=r"child link \[nope\] of joint \[j1\] not found"):
        load_robot(urdf=path)
    assert "model.cpp" not in capfd.readouterr().err  # urdfdom's C++ location lines are not printed


def test_masses_read_are_checked_against_the_file(tmp_path):
    from dynamics.urdf import _check_total_mass

    _urdf(tmp_path, '<joint name="j1" type="revolute"><parent link="base"/><child link="a"/><axis xyz="0 0 1"/>'
                           '<limit lower="-1" upper="1" effort="1" velocity="1"/></joint>', ("base", "a"))
    from dynamics.urdf import _check_numbers

    root = _check_numbers(tmp_path / "robot.urdf")
    _check_total_mass(tmp_path / "robot.urdf", root, 2.0)  # base and a: 1 kg each, as LINK writes them
    with pytest.raises(RobotDescriptionError, match="add up to 2 kg in the file but to 1 kg as read"):
        _check_total_mass(tmp_path / "robot.urdf", root, 1.0, "Inertial: mass [x] is not a float")
