"""An MJCF robot all the way: its ``<actuator>`` gears as the joints' transmission (checked against MuJoCo's own
actuator forces), and ``oed export --mjcf`` writing the user's MJCF with the identified bodies and joint terms,
checked by loading it in MuJoCo (``mj_rne`` and ``mj_inverse`` against the toolkit's model at random states)."""

from __future__ import annotations

import json
import warnings

import numpy as np
import pandas as pd
import pytest

from dynamics import MjcfIgnoredWarning, robot_from_mjcf, transmission_from_mjcf
from dynamics.mjcf_export import MjcfBodyError, mjcf_with_inertials
from dynamics.models import build_model
from dynamics.transmission import TransmissionError
from tests.conftest import random_states
from tests.test_mjcf import ARM, MENAGERIE_STYLE, _mujoco_rne

GEARS = (100.0, -80.0, 50.0, 30.0)

#: the test arm with its actuator replaced: a motor of each gear on each arm joint (two through default classes), a
#: position servo on the gripper's tendon (locked fingers: not the chain's)
ACTUATORS = """  <actuator>
    <motor name="m_shoulder_pan" joint="shoulder_pan" gear="100"/>
    <general name="m_shoulder_lift" joint="shoulder_lift" gear="-80 0 0 0 0 0" gainprm="2"/>
    <motor name="m_elbow" class="geared" joint="elbow"/>
    <position name="m_wrist" class="servo" joint="wrist" kp="100"/>
    <position name="fingers" tendon="split" kp="100"/>
  </actuator>
"""


def _arm(tmp_path, actuators=ACTUATORS, name="arm.xml"):
    text = MENAGERIE_STYLE.replace(MENAGERIE_STYLE[MENAGERIE_STYLE.index("  <actuator>"):
                                                   MENAGERIE_STYLE.index("</mujoco>")], actuators)
    text = text.replace("  <default>\n", '  <default>\n    <default class="geared"><motor gear="50"/></default>\n'
                        '    <default class="servo"><general gear="30"/></default>\n', 1)
    path = tmp_path / name
    path.write_text(text)
    return path


def _robot(path):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", MjcfIgnoredWarning)
        return robot_from_mjcf(path, joint_names=ARM)


def test_gears_are_the_transmission_and_match_mujocos_actuator_forces(tmp_path):
    """Each joint's ratio is its actuator's ``gear`` (given, or from a default class, whatever the actuator's gain):
    MuJoCo's joint forces of unit actuator forces (``qfrc_actuator`` with the motors' ``ctrl``) are ``Rᵀ τ_m``."""
    mujoco = pytest.importorskip("mujoco")
    path = _arm(tmp_path)
    transmission = transmission_from_mjcf(path, _robot(path))
    np.testing.assert_array_equal(transmission.ratios, GEARS)
    assert not transmission.is_coupled
    assert transmission.motor_names == ("m_shoulder_pan", "m_shoulder_lift", "m_elbow", "m_wrist")
    model = mujoco.MjModel.from_xml_path(str(path))
    data = mujoco.MjData(model)
    dofs = [model.jnt_dofadr[model.joint(name).id] for name in ARM]
    forces = np.array([0.5, -0.7, 0.2, 0.3])  # within the joints' actuatorfrcrange
    data.ctrl[:] = 0.0
    data.ctrl[model.actuator("m_shoulder_pan").id] = forces[0]  # a motor's force is its ctrl
    data.ctrl[model.actuator("m_elbow").id] = forces[2]
    data.ctrl[model.actuator("m_shoulder_lift").id] = forces[1] / 2  # gain 2
    mujoco.mj_forward(model, data)
    expected = transmission.joint_torques(forces * np.array([1, 1, 1, 0]))
    np.testing.assert_allclose(data.qfrc_actuator[dofs], expected, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(data.actuator_force[[model.actuator(f"m_{name}").id for name in ARM[:3]]],
                               forces[:3], rtol=1e-12)


def test_joints_without_actuators_are_direct_drive_and_none_without_any(tmp_path):
    only_one = _arm(tmp_path, '  <actuator>\n    <motor joint="elbow" gear="7"/>\n  </actuator>\n')
    transmission = transmission_from_mjcf(only_one, _robot(only_one))
    np.testing.assert_array_equal(transmission.ratios, [1, 1, 7, 1])
    assert transmission.motor_names == ("m1", "m2", "m3", "m4")
    none = _arm(tmp_path, "", "none.xml")
    assert transmission_from_mjcf(none, _robot(none)) is None


@pytest.mark.parametrize("actuators, message", [
    ('<motor name="ee" site="tip" gear="1 0 0 0 0 0"/>',
     r"actuator <motor name='ee'> acts through a site transmission \(site 'tip' on body 'hand'\): its force is not "
     "one joint's torque.*--transmission FILE"),
    ('<motor name="pull" tendon="pull"/>', r"actuator <motor name='pull'> acts through a tendon over joints elbow, "
     "wrist"),
    ('<motor name="a" joint="elbow" gear="50"/><motor name="b" joint="elbow" gear="5"/>',
     r"actuators <motor name='a'> and <motor name='b'> drive joint 'elbow' with gears 50 and 5"),
    ('<motor name="z" joint="wrist" gear="0"/>', "actuator <motor name='z'> on joint 'wrist' has gear 0"),
    ('<motor name="nowhere" gear="3"/>', r"actuator <motor name='nowhere'> names no transmission"),
])
def test_actuators_that_are_not_a_joints_gear_are_refused_by_name(tmp_path, actuators, message):
    path = _arm(tmp_path, f"  <actuator>\n    {actuators}\n  </actuator>\n")
    text = path.read_text().replace('<inertial mass="0.73"', '<site name="tip"/>\n                  <inertial mass="0.73"')
    if "pull" in actuators:  # a tendon over two joints of the chain (read with the robot of the file without it)
        text = text.replace("</tendon>", '<fixed name="pull"><joint joint="elbow" coef="1"/><joint joint="wrist" '
                            'coef="1"/></fixed>\n  </tendon>')
    path.write_text(text)
    robot = _robot(path if "pull" not in actuators else _arm(tmp_path, "", "plain.xml"))
    with pytest.raises(TransmissionError, match=message):
        transmission_from_mjcf(path, robot)


def test_a_site_actuator_on_a_body_the_chain_does_not_move_is_left_out(tmp_path):
    path = _arm(tmp_path, '  <actuator>\n    <motor site="fixed" gear="1"/>\n    <motor joint="wrist" gear="9"/>\n'
                          '  </actuator>\n')
    path.write_text(path.read_text().replace('<light pos="0 0 3"/>', '<light pos="0 0 3"/>\n    <site name="fixed"/>'))
    np.testing.assert_array_equal(transmission_from_mjcf(path, _robot(path)).ratios, [1, 1, 1, 9])


def _mujoco_inverse(path, names, q, dq, ddq):
    return _mujoco_rne(path, names, q, dq, ddq, inverse=True)


@pytest.mark.parametrize("unit", ["radian", "degree"])
def test_the_users_mjcf_with_new_bodies_and_terms_is_that_model_in_mujoco(tmp_path, unit):
    """New links and joint terms written into the user's file (hand and fingers kept, their mass taken out of the
    wrist's link): MuJoCo's ``mj_rne`` of it is the toolkit's rigid body of those links, ``mj_inverse`` adds the
    armature, damping and spring (its reference in the file's angle unit), at random states (1e-9 relative); geoms,
    actuators and the gripper are kept."""
    path = _arm(tmp_path)
    path.write_text(path.read_text().replace('angle="radian"', f'angle="{unit}"'))
    robot = _robot(path)
    links = robot.standard_parameters.reshape(-1, 10) * np.random.default_rng(3).uniform(0.9, 1.1, (4, 1))
    terms = {name: {"armature": 0.2 + index, "damping": 1.5 * (index + 1), "stiffness": 0.3, "springref": 0.1}
             for index, name in enumerate(ARM)}
    text, changes = mjcf_with_inertials(path, robot.with_gravity([0.0, 1.0, -9.7]), links, terms, joint_names=ARM,
                                        header="test")
    assert changes == tuple(f"joint {name}: frictionloss 0.2 of the file set to 0 (the model holds none)"
                            for name in ARM)
    exported = tmp_path / "exported.xml"
    exported.write_text(text)
    assert text.count("<geom") == MENAGERIE_STYLE.count("<geom") and 'name="fingers"' in text and "split" in text
    with pytest.warns(MjcfIgnoredWarning, match="stiffness"):  # the spring written is not read back
        again = robot_from_mjcf(exported, joint_names=ARM)
    np.testing.assert_allclose(again.standard_parameters.reshape(-1, 10), links, rtol=1e-12, atol=1e-14)
    q, dq, ddq = random_states(4, 25, seed=4)
    rigid = build_model(again, "internal", effects=None).predict(links.reshape(-1), q, dq, ddq)
    np.testing.assert_allclose(again.gravity, [0.0, 1.0, -9.7])
    np.testing.assert_allclose(_mujoco_rne(exported, ARM, q, dq, ddq), rigid, rtol=0, atol=1e-9 * np.abs(rigid).max())
    value = {key: np.array([terms[name][key] for name in ARM]) for key in ("armature", "damping", "stiffness")}
    expected = rigid + value["armature"] * ddq + value["damping"] * dq + value["stiffness"] * (q - 0.1)
    np.testing.assert_allclose(_mujoco_inverse(exported, ARM, q, dq, ddq), expected, rtol=0,
                               atol=1e-9 * np.abs(expected).max())


def test_a_link_lighter_than_the_bodies_fixed_to_it_is_refused(tmp_path):
    path = _arm(tmp_path)
    robot = _robot(path)
    links = robot.standard_parameters.reshape(-1, 10).copy()
    links[-1] *= 0.1  # the wrist's link lighter than the hand and fingers it carries
    with pytest.raises(MjcfBodyError, match="link 'wrist' .* less the bodies that move with it in the file"):
        mjcf_with_inertials(path, robot, links, joint_names=ARM)


def test_asset_folders_point_at_the_users_model(tmp_path):
    path = _arm(tmp_path)
    path.write_text(path.read_text().replace("<worldbody>", '<asset><mesh name="m" file="link.stl"/></asset>\n  '
                                             "<worldbody>").replace('angle="radian"', 'angle="radian" meshdir="meshes"'))
    robot = _robot(path)
    text, changes = mjcf_with_inertials(path, robot, robot.standard_parameters.reshape(-1, 10), joint_names=ARM,
                                        assets=tmp_path)
    assert f'meshdir="{tmp_path / "meshes"}"' in text and f'texturedir="{tmp_path}"' in text
    assert changes[-1] == f"asset files (meshes, textures) are read from {tmp_path} (the folder of the model identified)"


@pytest.mark.slow
def test_cli_actuator_forces_identify_as_joint_torques_and_export_loads_in_mujoco(tmp_path):
    """``oed simulate --mjcf`` (joint torques), the same record as actuator forces ``taum = τ / gear``: ``oed
    identify --mjcf`` gives the same parameters from either (relative 1e-6), ``oed predict`` reads the actuator
    forces, and ``oed export --mjcf`` writes the user's file whose MuJoCo inverse dynamics is the model's prediction
    at random states (1e-9), actuators kept; ``--urdf`` writes the chain's URDF."""
    from estimation.identification import IdentifiedModel
    from oed.cli import main
    from oed.fourier import FourierTrajectory

    arm = _arm(tmp_path)
    generator = np.random.default_rng(5)
    trajectory = tmp_path / "trajectory.json"
    FourierTrajectory(0.2, np.zeros(4), generator.uniform(-0.3, 0.3, (4, 3)),
                      generator.uniform(-0.3, 0.3, (4, 3))).save(trajectory)
    chain = ["--mjcf", str(arm), "--joint-names", ",".join(ARM)]
    for label, seed in (("train", 1), ("validate", 2)):
        out = tmp_path / f"{label}.csv"
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", MjcfIgnoredWarning)
            assert main(["simulate", *chain, "--trajectory", str(trajectory), "--periods", "2", "--warmup-periods",
                         "1", "--effect-values", json.dumps({"viscous": [3.0, 3.0, 1.0, 1.0]}), "--q-resolution",
                         "none", "--seed", str(seed), "--noise-tau", "0.01", "--rate", "200", "--out", str(out)]) == 0
        frame = pd.read_csv(out)
        for joint, gear in enumerate(GEARS, 1):
            frame[f"taum{joint}"] = frame.pop(f"tau{joint}") / gear
        frame.to_csv(tmp_path / f"{label}_motors.csv", index=False)
    values = {}
    for suffix in ("", "_motors"):
        out = tmp_path / f"result{suffix}.json"
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", MjcfIgnoredWarning)
            assert main(["identify", *chain, "--data", str(tmp_path / f"train{suffix}.csv"), "--validate",
                         str(tmp_path / f"validate{suffix}.csv"), "--consistent", "--prior-weight", "1",
                         "--out", str(out)]) == 0
        document = json.loads(out.read_text())
        values[suffix] = np.array([entry["value"] for entry in document["parameters"]])
    np.testing.assert_allclose(values["_motors"], values[""], rtol=1e-6, atol=1e-6 * np.abs(values[""]).max())
    assert document["transmission"]["matrix"] == np.diag(GEARS).tolist()
    result = tmp_path / "result_motors.json"
    assert main(["predict", "--model", str(result), "--data", str(tmp_path / "validate_motors.csv"),
                 "--metrics", str(tmp_path / "metrics.json")]) == 0
    exported, as_urdf = tmp_path / "exported.xml", tmp_path / "exported.urdf"
    assert main(["export", "--model", str(result), "--mjcf", str(exported), "--urdf", str(as_urdf)]) == 0
    text = exported.read_text()
    assert 'gear="100"' in text and "m_wrist" in text and text.count("<geom") == MENAGERIE_STYLE.count("<geom")
    model = IdentifiedModel.load(result)
    assert model.estimate == "consistent"
    q, dq, ddq = random_states(4, 25, seed=6)
    predicted = model.predict(q, dq, ddq)
    np.testing.assert_allclose(_mujoco_inverse(exported, ARM, q, dq, ddq), predicted, rtol=0,
                               atol=1e-9 * np.abs(predicted).max())
    viscous = np.array([model.file.consistent_effects[f"fv{joint}"] for joint in range(1, 5)])
    np.testing.assert_allclose(_mujoco_rne(exported, ARM, q, dq, ddq), predicted - viscous * dq, rtol=0,
                               atol=1e-9 * np.abs(predicted).max())
    from dynamics import robot_from_urdf
    assert robot_from_urdf(as_urdf).joint_names == list(ARM)
    # a wrist lighter than the hand and fingers fixed to it: the chain's MJCF, the reason in a note
    import dataclasses

    from estimation.identification.export import exported_mjcf
    links = np.array(model.file.consistent_links, dtype=float)
    links[-1] *= 0.05
    light = IdentifiedModel(dataclasses.replace(model.file, consistent_links=links), estimate="consistent")
    chain = exported_mjcf(light)
    assert chain.source is None and "<geom" not in chain.text and "m_wrist" not in chain.text
    assert any("not written into the user's MJCF (link 'wrist'" in note for note in chain.notes)


@pytest.fixture(scope="module")
def weak_record(tmp_path_factory):
    """The test arm (armature 0.1/0.05, damping 0.5, frictionloss 0.2 in its classes) with the laws of those terms,
    one short noisy record of their true values (0.8, 0.3, 0.15/0.075): the stacked problem, its WLS estimate and
    ``G``."""
    from dynamics.simulation.synthetic import simulate
    from estimation.estimators.identification_problem import stack
    from estimation.estimators.least_squares import WeightedLeastSquares, channel_gram
    from oed.fourier import random_fourier

    path = tmp_path_factory.mktemp("arm") / "arm.xml"
    path.write_text(MENAGERIE_STYLE)
    robot = _robot(path)
    model = build_model(robot, "internal", "viscous,coulomb,armature")
    theta = np.concatenate([robot.standard_parameters, [0.8] * 4, [0.3] * 4, [0.15, 0.15, 0.075, 0.075]])
    data = simulate(model, theta, random_fourier(robot, seed=3), rate_hz=200.0, periods=1,
                    noise={f"tau{joint}": 0.5 for joint in range(1, 5)}, seed=3)
    problem = stack(model, data)
    unconstrained = WeightedLeastSquares().fit(problem).estimate_
    gram, _ = channel_gram(problem)
    return model, problem, unconstrained, np.tensordot(unconstrained.weights, gram, axes=1)


def test_the_mjcf_joint_terms_are_the_prior_of_armature_viscous_and_coulomb(weak_record):
    """With a prior weight ``w``, the consistent optimum is stationary for the data term plus ``w ½ Σ ((θ−μ)/μ)²``
    on the 12 laws (μ the file's armature, damping, frictionloss), checked from ``G`` and ``θ̂`` outside the solver
    (relative 1e-5 of the data term's gradient), and moves toward μ as ``w`` grows; without a weight, no prior."""
    from estimation.consistent.least_squares import ConsistentLeastSquares

    model, problem, unconstrained, G = weak_record
    names = list(model.parameter_names)[40:]
    described = dict(zip(names, [0.5] * 4 + [0.2] * 4 + [0.1, 0.1, 0.05, 0.05]))
    distances = []
    for weight in (0.0, 1.0, 1e4):
        estimate = ConsistentLeastSquares(prior_weight=weight).fit(model, problem, unconstrained=unconstrained).estimate_
        assert estimate.effect_prior == ({} if weight == 0 else described)
        effects = estimate.theta[40:]
        mean = np.array([described[name] for name in names])
        gradient = (model.base.K.T @ (G @ (model.base.K @ estimate.theta - unconstrained.values)))[40:]
        stationarity = gradient + (weight * (effects - mean) / mean**2 if weight else 0.0)
        assert np.abs(stationarity).max() <= 1e-5 * max(np.abs(gradient).max(), 1.0)
        distances.append(np.abs((effects - mean) / mean).max())
    assert distances[0] > 0.4 and distances[2] < 0.5 * distances[0]  # 1e4 pulls the laws toward the file's values


def test_stiffness_is_not_read_and_said(tmp_path):
    path = tmp_path / "spring.xml"
    path.write_text(MENAGERIE_STYLE.replace('armature="0.1" damping="0.5"', 'armature="0.1" stiffness="3" damping="0.5"'))
    with pytest.warns(MjcfIgnoredWarning, match="stiffness values are not read"):
        robot_from_mjcf(path, joint_names=ARM)


def test_a_description_without_joint_terms_gives_no_prior(weak_record):
    from dynamics.robots import load_robot
    from estimation.consistent.effect_prior import effect_prior

    assert effect_prior(build_model(load_robot("puma560", joints=3), "internal", "viscous,coulomb,armature")) is None
    model = weak_record[0]
    prior = effect_prior(build_model(model.robot, "internal", "viscous,offset"))
    assert prior.values == {f"fv{joint}": 0.5 for joint in range(1, 5)} and prior.precision[4:].tolist() == [0] * 4
