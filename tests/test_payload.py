"""Payload identification (estimation.payload, `oed payload`): a 2 kg body of non-diagonal inertia on the last link
of the 6-joint PUMA 560, torque noise 1 % of each joint's range, the robot's model identified first and held fixed.
Checked against the body put in: mass within 0.5 %, centre of mass within 1 mm, principal moments within 10 %, mass
and centre of mass within 3 standard deviations; on the model's own regressor and on Pinocchio's forward dynamics."""

from __future__ import annotations

import json

import numpy as np
import pytest

from dynamics.models import build_model
from dynamics.robot import inertial_parameters
from dynamics.robots import load_robot
from dynamics.simulation.synthetic import simulate
from estimation.identification.fit import identify
from estimation.identification.identified_model import IdentifiedModel
from estimation.identification.model_file import ModelFile, RobotSource, model_file_document
from estimation.payload import PayloadBody, PayloadError, identify_payload, resolve_link
from estimation.payload.fit import _consistent
from dynamics.physical_parameters import is_consistent
from oed.cli import main
from oed.fourier import random_fourier

RATE_HZ = 1000.0
FREQUENCY_HZ = 0.1  # one period: 10 s
#: 2 kg, centre of mass off every axis, inertia about it with products of inertia
PAYLOAD = inertial_parameters(2.0, [0.01, -0.02, 0.08],
                              np.array([[0.012, 0.002, -0.001], [0.002, 0.010, 0.0015], [-0.001, 0.0015, 0.006]]))
VISCOUS = [4.0, 4.0, 3.0, 1.0, 1.0, 1.0]


def robot_model_file(model, train) -> IdentifiedModel:
    """The robot identified on ``train`` (no payload), as ``oed identify`` would save it."""
    result = identify(model, train, covariance="classical")
    document = model_file_document(result, robot=RobotSource("puma560", "puma560", None), preprocessing=None)
    return IdentifiedModel(ModelFile.from_dict(document))


def noise_of(model, theta) -> dict[str, float]:
    """1 % of each joint's torque range along a random motion."""
    clean = simulate(model, theta, random_fourier(model.robot, seed=1, frequency_hz=FREQUENCY_HZ), rate_hz=RATE_HZ)
    return {f"tau{j + 1}": 0.01 * span for j, span in enumerate(np.ptp(clean.tau, axis=0))}


def puma_with_payload():
    """``(model, theta, loaded, noise)``: the PUMA's viscous internal model, its parameters without and with
    :data:`PAYLOAD` on link 6, and the torque noise (1 % of each joint's range)."""
    model = build_model(load_robot("puma560"), "internal", "viscous")
    theta = model.nominal_parameters(viscous=VISCOUS)
    loaded = theta.copy()
    loaded[50:60] += PAYLOAD
    return model, theta, loaded, noise_of(model, loaded)


@pytest.fixture(scope="module")
def puma():
    model, theta, loaded, noise = puma_with_payload()
    robot = model.robot
    train = simulate(model, theta, random_fourier(robot, seed=1, frequency_hz=FREQUENCY_HZ), rate_hz=RATE_HZ,
                     periods=3, noise=noise, seed=3)
    records = [simulate(model, loaded, random_fourier(robot, seed=seed, frequency_hz=FREQUENCY_HZ), rate_hz=RATE_HZ,
                        noise=noise, seed=10 + seed) for seed in (7, 8)]
    return {"model": model, "theta": theta, "loaded": loaded, "noise": noise, "identified": robot_model_file(model, train),
            "records": records, "train": train}


def check_body(result, truth=PAYLOAD):
    true = PayloadBody(truth, np.zeros((10, 10)))
    body = result.body
    std = body.values_std
    assert abs(body.mass / true.mass - 1) < 0.005
    assert np.max(np.abs(body.com - true.com)) < 1e-3
    assert np.max(np.abs(body.principal_moments / true.principal_moments - 1)) < 0.10
    assert abs(body.mass - true.mass) <= 3 * std[0]
    assert np.all(np.abs(body.com - true.com) < 3 * std[1:4])
    assert is_consistent(body.parameters)


def test_payload_of_a_six_joint_arm_is_found_within_its_standard_deviations(puma):
    result = identify_payload(puma["identified"], puma["records"][0], validate=puma["records"][1])
    check_body(result)
    assert result.link == "joint6" and result.link_index == 6 and not result.constraint_active
    assert result.undetermined == ()
    # the robot model's share of the uncertainty is reported apart, and both add to the total
    assert np.allclose(result.body.cov, result.cov_noise + result.cov_robot)
    assert 0 < result.std_part(result.cov_robot)["mass"] < result.body.values_std[0]
    # the validation error falls to the noise with the payload
    before, after = result.validation_before, result.validation_after
    for channel, std in puma["noise"].items():
        assert after[channel] < 1.5 * std ** 2 < before[channel]


def test_known_mass_identifies_the_nine_others(puma):
    result = identify_payload(puma["identified"], puma["records"][0], mass=2.0)
    assert result.mass_known and result.body.mass == 2.0
    assert result.body.cov[0, 0] == 0.0 or result.cov_noise[0, 0] == 0.0
    check_body(result)


def test_payload_on_pinocchio_forward_dynamics():
    """The independent simulator: Pinocchio's ABA under a PD controller, the robot's model identified there too."""
    from dynamics.simulation.sensors import NoiseModel
    from dynamics.simulation.simulator import Simulator

    robot = load_robot("puma560")
    model = build_model(robot, "internal", "viscous")
    theta = model.nominal_parameters()[:60].copy()
    loaded = theta.copy()
    loaded[50:60] += PAYLOAD
    spans = np.ptp(Simulator(robot, "viscous", tuple(loaded), NoiseModel.none()).run(
        random_fourier(robot, seed=1, frequency_hz=0.2), with_derivatives=True).tau, axis=0)
    noise = NoiseModel(tau_std=tuple(0.01 * spans), q_resolution=None)

    def record(parameters, seed, periods=1):
        return Simulator(robot, "viscous", tuple(parameters), noise).run(
            random_fourier(robot, seed=seed, frequency_hz=0.2), periods=periods, with_derivatives=True,
            seed=seed).measurements

    identified = robot_model_file(model, [record(theta, 1), record(theta, 2)])
    result = identify_payload(identified, [record(loaded, 3), record(loaded, 4)])
    check_body(result)


def test_payload_on_pinocchio_rnea_with_the_payload_a_body_of_its_own():
    """The independent simulator, straight: Pinocchio's rnea, the payload appended to link 6 as a ``pinocchio.Inertia``
    of its own (mass, centre of mass in the link frame, inertia about it: not the toolkit's standard parameters nor its
    conversion of them), viscous friction ``f_v q̇`` added by hand; the robot's model identified on rnea records
    without the payload. Mass within 0.5 %, centre of mass within 1 mm, principal moments within 10 %, within 3 std."""
    import pinocchio as pin

    from dynamics.measurements import Measurements
    from dynamics.pinocchio_bridge import to_pinocchio

    robot = load_robot("puma560")
    model = build_model(robot, "internal", "viscous")
    theta = model.nominal_parameters(viscous=VISCOUS)
    com, inertia = [0.01, -0.02, 0.08], np.array([[0.012, 0.002, -0.001], [0.002, 0.010, 0.0015],
                                                  [-0.001, 0.0015, 0.006]])
    unloaded, loaded = to_pinocchio(robot, theta=theta[:60]), to_pinocchio(robot, theta=theta[:60])
    loaded.appendBodyToJoint(6, pin.Inertia(2.0, np.array(com), inertia), pin.SE3(robot.joints[5].link_transform))

    def torques(pinocchio_model, q, dq, ddq):
        data = pinocchio_model.createData()
        rigid = np.array([pin.rnea(pinocchio_model, data, *sample) for sample in zip(q, dq, ddq)])
        return rigid + dq * np.asarray(VISCOUS)

    def record(pinocchio_model, seed, periods=1, noise=None):
        t, q, dq, ddq = random_fourier(robot, seed=seed, frequency_hz=FREQUENCY_HZ).sample(RATE_HZ, periods)
        tau = torques(pinocchio_model, q, dq, ddq)
        if noise is not None:
            tau = tau + np.random.default_rng(100 + seed).normal(size=tau.shape) * noise
        return Measurements(t, q, dq, ddq, tau, None, {"frequency_hz": FREQUENCY_HZ})

    clean = record(unloaded, 1)
    # the two simulators agree on the robot without the payload (friction's convention included)
    assert np.allclose(clean.tau, model.predict(theta, clean.q, clean.dq, clean.ddq), atol=1e-8)
    noise = 0.01 * np.ptp(record(loaded, 1).tau, axis=0)
    identified = robot_model_file(model, record(unloaded, 1, periods=3, noise=noise))
    result = identify_payload(identified, [record(loaded, 7, noise=noise), record(loaded, 8, noise=noise)])
    check_body(result, inertial_parameters(2.0, com, inertia))
    assert not result.constraint_active and result.undetermined == ()


def test_a_consistent_body_when_least_squares_gives_none():
    """An estimate with a negative principal moment: the body found is consistent and no farther, in the fit's
    metric, than any consistent body at hand (the truth, the eigenvalue-clipped projection)."""
    from dynamics.physical_parameters import project_link

    estimate = PAYLOAD.copy()
    estimate[9] -= 0.05  # Izz about the origin far below what the body needs
    assert not is_consistent(estimate)
    scales = np.array([2.0] + [0.2] * 3 + [0.02] * 6)
    metric = np.diag(1.0 / scales ** 2)

    def cost(body):
        return (body - estimate) @ metric @ (body - estimate)

    body = _consistent(estimate, metric, scales, None)
    assert is_consistent(body)
    assert cost(body) <= 1.0001 * min(cost(PAYLOAD), cost(project_link(estimate)))
    known = _consistent(estimate, metric, scales, 2.0)
    assert known[0] == pytest.approx(2.0) and is_consistent(known)
    assert cost(known) <= 1.0001 * cost(PAYLOAD)


def test_links_by_joint_name_index_and_unknown(puma):
    identified = puma["identified"]
    assert resolve_link(identified, None) == (6, "joint6")
    assert resolve_link(identified, "joint4") == (4, "joint4")
    assert resolve_link(identified, "link5") == (5, "joint5")
    assert resolve_link(identified, 3) == (3, "joint3")
    with pytest.raises(PayloadError, match="no link 'gripper'.*joint1"):
        resolve_link(identified, "gripper")


def test_records_without_the_payload_are_refused(puma):
    empty = simulate(puma["model"], puma["theta"], random_fourier(puma["model"].robot, seed=7, frequency_hz=FREQUENCY_HZ),
                     rate_hz=RATE_HZ, noise=puma["noise"], seed=21)
    with pytest.raises(PayloadError, match="show no payload"):
        identify_payload(puma["identified"], empty)


def test_another_robots_model_is_refused(puma):
    other = puma["loaded"].copy()
    other[10:40] *= 1.5  # heavier upper arm and forearm: not the robot the model was identified on
    records = simulate(puma["model"], other, random_fourier(puma["model"].robot, seed=7, frequency_hz=FREQUENCY_HZ),
                       rate_hz=RATE_HZ, noise=puma["noise"], seed=22)
    with pytest.raises(PayloadError, match="does not explain these records"):
        identify_payload(puma["identified"], records)


def test_a_model_file_of_another_robot_is_refused(puma, tmp_path, capsys):
    """The model file of another 6-joint robot (another URDF: other kinematics and bodies) against the PUMA's records
    with the payload; and the PUMA's model against a 3-joint robot's record: each refused, naming the problem."""
    from pathlib import Path

    urdf = (Path(__file__).parents[1] / "dynamics" / "robots" / "arm6_collision.urdf").resolve()
    other = load_robot(urdf=urdf)
    other_model = build_model(other, "internal", "viscous")
    train = simulate(other_model, other_model.nominal_parameters(viscous=VISCOUS),
                     random_fourier(other, seed=1, frequency_hz=FREQUENCY_HZ), rate_hz=200.0, periods=2,
                     noise={f"tau{j}": 0.05 for j in range(1, 7)}, seed=3)
    document = model_file_document(identify(other_model, train, covariance="classical"),
                                   robot=RobotSource("arm6", None, None, str(urdf), "0" * 64, urdf.read_text()),
                                   preprocessing=None)
    with pytest.raises(PayloadError, match="model of arm6 does not explain these records"):
        identify_payload(IdentifiedModel(ModelFile.from_dict(document)), puma["records"][0])
    other_json, loaded = tmp_path / "arm6.json", tmp_path / "loaded.csv"
    other_json.write_text(json.dumps({"model_file": document}))
    puma["records"][0].write(loaded)
    assert main(["payload", "--model", str(other_json), "--data", str(loaded), "--out", str(tmp_path / "x.json")]) != 0
    assert "does not explain these records" in capsys.readouterr().err
    small = load_robot(urdf=Path(__file__).parent / "data" / "prismatic_arm.urdf")
    small_model = build_model(small, "internal", "viscous")
    simulate(small_model, small_model.nominal_parameters(viscous=[1.0, 1.0, 1.0]),
             random_fourier(small, seed=7, frequency_hz=FREQUENCY_HZ), rate_hz=200.0, seed=4).write(tmp_path / "small.csv")
    robot_json = tmp_path / "robot.json"
    robot_json.write_text(json.dumps({"model_file": puma["identified"].file.to_dict()}))
    assert main(["payload", "--model", str(robot_json), "--data", str(tmp_path / "small.csv"),
                 "--out", str(tmp_path / "y.json")]) != 0
    assert "missing column(s) q4, q5, q6" in capsys.readouterr().err
    assert not (tmp_path / "x.json").exists() and not (tmp_path / "y.json").exists()


def test_cli_writes_payload_json_and_predict_uses_it(puma, tmp_path, capsys):
    robot_json = tmp_path / "robot.json"
    robot_json.write_text(json.dumps({"model_file": puma["identified"].file.to_dict()}))
    loaded, held_out = tmp_path / "loaded.csv", tmp_path / "loaded2.csv"
    puma["records"][0].write(loaded)
    puma["records"][1].write(held_out)
    out = tmp_path / "payload.json"
    assert main(["payload", "--model", str(robot_json), "--data", str(loaded), "--validate", str(held_out),
                 "--out", str(out)]) == 0
    assert "mass 1.99" in capsys.readouterr().out or "mass 2.00" in capsys.readouterr().out
    document = json.loads(out.read_text())
    payload = document["payload"]
    assert set(payload["inertia"]) == {"ixx", "iyy", "izz", "ixy", "ixz", "iyz"}
    assert set(payload["std"]) == {"mass", "com", "inertia"} and set(payload["std"]["inertia"]) == set(payload["inertia"])
    assert len(payload["com"]) == 3 and abs(payload["mass"] - 2.0) < 0.01 and payload["undetermined"] == []
    assert "robot model" in payload["std_note"] and set(payload["std_parts"]) == {"record_noise", "robot_model"}
    assert set(document["validation"]) == {"before", "after"}
    # the model with the payload predicts the held-out record as payload.json says
    metrics = tmp_path / "metrics.json"
    assert main(["predict", "--model", str(out), "--data", str(held_out), "--metrics", str(metrics)]) == 0
    predicted = json.loads(metrics.read_text())["mse"]
    for channel, value in document["validation"]["after"]["mse"].items():
        assert predicted[channel] == pytest.approx(value, rel=1e-6)
    # bad input: an unknown link, a model file that carries a payload already, a record of a 7-joint robot
    assert main(["payload", "--model", str(robot_json), "--data", str(loaded), "--link", "tool0",
                 "--out", str(tmp_path / "x.json")]) != 0
    assert "no link 'tool0'" in capsys.readouterr().err
    assert main(["payload", "--model", str(out), "--data", str(loaded), "--out", str(tmp_path / "y.json")]) != 0
    assert "carries a payload already" in capsys.readouterr().err
    seven = tmp_path / "seven.csv"
    frame = puma["records"][0].to_frame()
    frame["q7"], frame["tau7"] = 0.0, 0.0
    frame.to_csv(seven, index=False)
    assert main(["payload", "--model", str(robot_json), "--data", str(seven), "--out", str(tmp_path / "z.json")]) != 0
    assert "more joints" in capsys.readouterr().err


def test_export_adds_the_payload_to_its_links_body(puma, tmp_path):
    """A consistent model with a payload: the exported URDF's link 6 is the link's body plus the payload (read back by
    the URDF parser, against the same model exported without it: the difference is the payload's body, in the URDF's
    frame of the link)."""
    from estimation.identification.export import exported_urdf
    from dynamics.robots import load_robot as load

    result = identify_payload(puma["identified"], puma["records"][0])
    exported = []
    for document in (puma["identified"].file.to_dict(), result.model_file_document(puma["identified"])):
        document["consistent"] = {"links": puma["theta"][:60].reshape(6, 10).tolist(), "effects": {},
                                  "theta": document["theta"], "cov": document["cov"], "validation_mse": None}
        urdf = tmp_path / f"exported{len(exported)}.urdf"
        urdf.write_text(exported_urdf(IdentifiedModel(ModelFile.from_dict(document), estimate="consistent")))
        exported.append(load(urdf=urdf))
    without, with_payload = exported
    assert np.allclose(with_payload.joints[4].inertial, without.joints[4].inertial)
    added = PayloadBody(with_payload.joints[5].inertial - without.joints[5].inertial, np.zeros((10, 10)))
    assert added.mass == pytest.approx(result.body.mass, rel=1e-9)
    assert np.allclose(added.principal_moments, result.body.principal_moments, rtol=1e-6)


def test_urdf_link_names_name_the_payloads_link():
    """A URDF robot: its child-link names, its joint names and link<k> name links; a fixed link (merged into its
    parent, in a frame of its own) is not one."""
    from pathlib import Path
    from types import SimpleNamespace

    path = Path(__file__).parent / "data" / "prismatic_arm.urdf"
    robot = load_robot(urdf=path)
    source = RobotSource("arm", None, None, str(path), "0" * 64, path.read_text())
    model = SimpleNamespace(file=SimpleNamespace(robot=source), robot=robot)
    assert resolve_link(model, "link2") == (2, "j2")
    assert resolve_link(model, "j3") == (3, "j3")
    assert resolve_link(model, None) == (3, "j3")
    with pytest.raises(PayloadError, match="no link 'tool'.*link1, link2, link3, j1"):
        resolve_link(model, "tool")
