"""``oed identify``/``diagnose`` with the robot as built: per-joint specs, motor-side data and
effects, rest rows, trivial predictors, the parameter vector, and each message and bad input."""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest

from dynamics.models import build_model
from dynamics.robots import load_robot
from dynamics.transmission import puma560_transmission
from oed.cli import main
from dynamics.simulation.synthetic import simulate, true_parameters

from oed.fourier import random_fourier

NOISE = {"tau1": 0.3, "tau2": 0.3, "tau3": 0.2}


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    robot = load_robot("puma560", joints=3)
    model = build_model(robot, "internal", "viscous,coulomb@2")
    theta = true_parameters(model, seed=2, coulomb=[4.0])
    folder = tmp_path_factory.mktemp("asbuilt")
    train = simulate(model, theta, random_fourier(robot, 3), noise=NOISE, seed=11)
    validate = simulate(model, theta, random_fourier(robot, 4), noise=NOISE, seed=12)
    train.write(folder / "train.csv")
    validate.write(folder / "val.csv")
    return folder, model, theta, train


def _identify(folder, *extra, out="result.json", data="train.csv"):
    return main(["identify", "--robot", "puma560", "--joints", "3", "--data", str(folder / data),
                 "--validate", str(folder / "val.csv"), "--out", str(folder / out), *extra])


def test_per_joint_spec_min_speed_and_the_new_keys(files, capsys):
    folder, model, theta, _ = files
    assert _identify(folder, "--friction", "viscous,coulomb@2", "--min-speed", "0.02") == 0
    document = json.loads((folder / "result.json").read_text())
    parameters = document["model_parameters"]
    assert parameters["effects"] == "viscous,coulomb@2" and parameters["model"] == "internal"
    assert "fc2" in parameters["names"] and "fc1" not in parameters["names"]
    assert len(parameters["names"]) == len(parameters["values"]) == len(parameters["std"]) == len(parameters["expressions"])
    index = parameters["names"].index("fc2")
    assert abs(parameters["values"][index] - 4.0) < 3 * parameters["std"][index]
    rest = document["rest"]["train"]
    assert rest["min_speed"] == 0.02 and 0 < rest["dropped"] < rest["total"]
    assert set(document["validation"]) >= {"mse", "zero_mse", "nominal_mse"}
    for channel, value in document["validation"]["mse"].items():
        assert value < document["validation"]["zero_mse"][channel] and value < document["validation"]["nominal_mse"][channel]
    assert document["warnings"] == []
    assert f"rows at rest (slower than 0.02) dropped: train {rest['dropped']} of {rest['total']}" in capsys.readouterr().out
    # the vector reproduces the predictions without the API beyond the spec
    rebuilt = build_model(model.robot, parameters["model"], parameters["effects"])
    assert list(rebuilt.base.names) == parameters["names"]


def test_worse_than_a_zero_prediction_is_a_warning(files, capsys):
    folder, *_ = files
    frame = pd.read_csv(folder / "train.csv")
    frame["tau3"] *= -1  # a torque sign flipped in the training record only
    frame.to_csv(folder / "flipped.csv", index=False)
    assert _identify(folder, "--friction", "viscous,coulomb@2", data="flipped.csv", out="flipped.json") == 0
    document = json.loads((folder / "flipped.json").read_text())
    assert any(message.startswith("tau3:") and "worse" in message for message in document["warnings"])
    assert "oed identify: warning: tau3: the identified model predicts the validation data worse" in capsys.readouterr().err


def test_motor_side_columns_give_the_joint_side_result(files, capsys):
    folder, _, _, train = files
    transmission = puma560_transmission(3)
    frame = pd.read_csv(folder / "train.csv")
    motor = frame.drop(columns=[f"{p}{j}" for p in ("q", "dq", "ddq", "tau") for j in (1, 2, 3)])
    for prefix, values in (("qm", transmission.motor_positions(train.q)), ("dqm", transmission.motor_positions(train.dq)),
                           ("ddqm", transmission.motor_positions(train.ddq)), ("taum", transmission.motor_torques(train.tau))):
        for j in range(3):
            motor[f"{prefix}{j + 1}"] = values[:, j]
    motor.to_csv(folder / "motor.csv", index=False)
    assert _identify(folder, "--friction", "viscous,coulomb@2", data="motor.csv", out="motor.json") == 0
    assert _identify(folder, "--friction", "viscous,coulomb@2", out="joint.json") == 0
    motor_values = json.loads((folder / "motor.json").read_text())["model_parameters"]["values"]
    joint_values = json.loads((folder / "joint.json").read_text())["model_parameters"]["values"]
    np.testing.assert_allclose(motor_values, joint_values, rtol=1e-6, atol=1e-9)


def test_motor_side_angles_fed_as_joint_angles_say_gear_ratio(files, capsys):
    folder, *_ = files
    frame = pd.read_csv(folder / "train.csv")
    frame[["q1", "q2", "q3"]] = puma560_transmission(3).motor_positions(frame[["q1", "q2", "q3"]].to_numpy())
    frame["q1"] += 300.0  # many turns from the zero, as a motor encoder counts
    frame.to_csv(folder / "motor_angles.csv", index=False)
    assert _identify(folder, data="motor_angles.csv", out="never.json") == 2
    error = capsys.readouterr().err
    assert "gear ratio?" in error and "deg2rad" not in error
    assert not (folder / "never.json").exists()
    frame = pd.read_csv(folder / "train.csv")
    frame[["q1", "q2", "q3"]] = np.degrees(frame[["q1", "q2", "q3"]])
    frame.to_csv(folder / "degrees.csv", index=False)
    assert _identify(folder, data="degrees.csv", out="never.json") == 2
    assert "deg2rad" in capsys.readouterr().err


@pytest.mark.parametrize("document, message", [
    ({"matrix": [[1, 0, 0], [0, 1, 1], [0, 1, 1]]}, "singular"),
    ({"matrix": [[1, 0], [0, 1]]}, "must be 3 x 3"),
    ({"ratios": {"joint7": 100}}, "not a joint of"),
])
@pytest.mark.parametrize("verb", ["identify", "diagnose"])
def test_bad_transmissions_exit_2_and_write_nothing(files, capsys, document, message, verb):
    folder, *_ = files
    path = folder / "bad_transmission.json"
    path.write_text(json.dumps(document))
    out = folder / f"never_{verb}.json"
    code = main([verb, "--robot", "puma560", "--joints", "3", "--transmission", str(path), "--data",
                 str(folder / "train.csv"), "--validate", str(folder / "val.csv"), "--out", str(out)])
    assert code == 2
    error = capsys.readouterr().err
    assert error.startswith(f"oed {verb}: error:") and message in error
    assert not out.exists()


def test_torque_constant_of_the_wrong_sign_for_the_data(files, capsys):
    folder, _, _, train = files
    transmission = puma560_transmission(3)
    constants = np.array([-0.2, 0.2, 0.2])  # motor 1's current is counted the other way
    frame = pd.read_csv(folder / "train.csv").drop(columns=["tau1", "tau2", "tau3"])
    currents = transmission.motor_torques(train.tau) / np.abs(constants)
    for j in range(3):
        frame[f"im{j + 1}"] = currents[:, j]
    frame.to_csv(folder / "currents.csv", index=False)
    path = folder / "t_currents.json"
    path.write_text(json.dumps({**transmission.to_dict(), "torque_constants": constants.tolist()}))
    assert _identify(folder, "--transmission", str(path), data="currents.csv", out="never.json") == 2
    error = capsys.readouterr().err
    assert "wrong sign" in error and "joint 1" in error
    assert not (folder / "never.json").exists()
    path.write_text(json.dumps({**transmission.to_dict(), "torque_constants": np.abs(constants).tolist()}))
    assert _identify(folder, "--transmission", str(path), "--friction", "viscous,coulomb@2", data="currents.csv",
                     out="currents.json") == 0


def test_diagnose_reports_the_new_keys(files, capsys):
    folder, *_ = files
    out = folder / "report.json"
    code = main(["diagnose", "--robot", "puma560", "--joints", "3", "--friction", "viscous",
                 "--data", str(folder / "train.csv"), "--validate", str(folder / "val.csv"), "--min-speed", "0.02",
                 "--out", str(out)])
    assert code == 0
    document = json.loads(out.read_text())
    assert [effect["name"] for effect in document["effects"]][:1] == ["coulomb"]
    assert set(document["validation"]) >= {"before", "after", "zero_mse", "nominal_mse"}
    assert document["model_parameters"]["effects"].startswith("viscous,coulomb@2")
    assert document["rest"]["validation"]["dropped"] > 0
    assert "rows at rest" in capsys.readouterr().out


def test_a_whole_robot_transmission_file_with_fewer_joints_kept(files, capsys):
    folder, *_ = files
    path = folder / "t6.json"
    path.write_text(json.dumps(puma560_transmission(6).to_dict()))
    assert _identify(folder, "--transmission", str(path), "--friction", "viscous,motor_coulomb@2", out="t6.json.out.json") == 0
    document = json.loads((folder / "t6.json.out.json").read_text())
    assert document["transmission"]["matrix"] == puma560_transmission(3).matrix.tolist()
    assert document["model_parameters"]["effects"] == "viscous,motor_coulomb@2"
    assert document["model_parameters"]["transmission"]["matrix"] == puma560_transmission(3).matrix.tolist()


def test_urdf_transmission_and_motor_friction_on_a_differential(tmp_path, capsys):
    from dynamics.effects.motor import motor_effects
    from dynamics.transmission_files import transmission_from_urdf
    from tests.test_transmission import DIFFERENTIAL, SIMPLE, transmission_urdf

    path = transmission_urdf(tmp_path, SIMPLE + DIFFERENTIAL)
    robot = load_robot(urdf=path)
    transmission = transmission_from_urdf(path, robot)
    truth = build_model(robot, "internal", ("viscous",) + motor_effects(transmission, "coulomb"))
    theta = truth.nominal_parameters(viscous=[0.5, 0.4, 0.3], **{f"motor_coulomb[m{i}]": value for i, value in
                                                                  enumerate((0.01, 0.02, 0.015), start=1)})
    noise = {"tau1": 0.05, "tau2": 0.05, "tau3": 0.05}
    for name, seed in (("train", 3), ("val", 4)):
        simulate(truth, theta, random_fourier(robot, seed), noise=noise, seed=seed).write(tmp_path / f"{name}.csv")
    out = tmp_path / "result.json"
    assert main(["identify", "--urdf", str(path), "--friction", "viscous,motor_coulomb", "--data", str(tmp_path / "train.csv"),
                 "--validate", str(tmp_path / "val.csv"), "--out", str(out)]) == 0
    parameters = json.loads(out.read_text())["model_parameters"]
    assert parameters["transmission"]["matrix"] == transmission.matrix.tolist()
    for name, value in (("fcm1", 0.01), ("fcm2", 0.02), ("fcm3", 0.015)):
        index = parameters["names"].index(name)
        assert abs(parameters["values"][index] - value) < 3 * parameters["std"][index], (name, parameters["values"][index])


@pytest.mark.parametrize("verb", ["identify", "diagnose"])
def test_a_gear_ratio_of_the_wrong_sign_for_the_data_exits_2_and_writes_nothing(files, capsys, verb):
    folder, _, _, train = files
    transmission = puma560_transmission(3)
    frame = pd.read_csv(folder / "train.csv").drop(columns=["tau1", "tau2", "tau3"])
    torques = transmission.motor_torques(train.tau)  # joint-side encoders, motor torques
    for j in range(3):
        frame[f"taum{j + 1}"] = torques[:, j]
    frame.to_csv(folder / "motor_torques.csv", index=False)
    document = transmission.to_dict()
    document["matrix"][0][0] *= -1  # motor 1's ratio of the wrong sign (joint 1: no gravity to hide it)
    path = folder / "t_wrong_sign.json"
    path.write_text(json.dumps(document))
    out = folder / f"never_{verb}.json"
    code = main([verb, "--robot", "puma560", "--joints", "3", "--transmission", str(path), "--friction", "viscous",
                 "--data", str(folder / "motor_torques.csv"), "--validate", str(folder / "val.csv"), "--out", str(out)])
    assert code == 2
    error = capsys.readouterr().err
    assert error.startswith(f"oed {verb}: error:") and "wrong sign" in error and "joint 1" in error
    assert not out.exists()
