"""The gravity a model was fitted with, held by its result file (estimation.identification.model_file ``gravity``;
estimation.consistent.mounted_gravity): a mount the check finds is a candidate of the default answer, taken only when
it predicts the validation record better, and `oed predict` and `oed export` then use the file's gravity.

Checked against models built with the true gravity (the regressor of :mod:`dynamics.models`, itself checked against
Pinocchio for a mounted URDF in ``tests/test_unseen_robot_mounts.py``), and by `oed predict` reproducing the
validation error each verb reported (relative 1e-6)."""

from __future__ import annotations

import json
import re

import numpy as np
import pytest

from dynamics.models import build_model
from dynamics.robots import load_robot
from dynamics.simulation.synthetic import simulate, true_parameters
from estimation.identification.export import gravity_note
from estimation.identification.fit import identify
from estimation.identification.identified_model import IdentifiedModel
from estimation.identification.model_file import ModelFile, ModelFileError, RobotSource, model_file_document
from oed.cli import main
from oed.fourier import random_fourier

#: a PUMA 560 on a wall: gravity along the base's +x (the description says -z)
WALL = (9.81, 0.0, 0.0)
NOISE = {"tau1": 0.2, "tau2": 0.2, "tau3": 0.1}


def wall_records(folder, seeds=(5, 6, 7)):
    """Records of a 3-joint PUMA on a wall (viscous and Coulomb friction), positions, velocities and torques."""
    robot = load_robot("puma560", joints=3)
    model = build_model(robot.with_gravity(WALL), "internal", "viscous,coulomb")
    theta = true_parameters(model, seed=1, coulomb=[3.0, 2.0, 1.0])
    paths = []
    for seed in seeds:
        data = simulate(model, theta, random_fourier(robot, seed=seed), rate_hz=200.0, periods=2, noise=NOISE,
                        seed=seed)
        frame = data.to_frame()
        path = folder / f"wall{seed}.csv"
        frame[[column for column in frame.columns if not column.startswith("ddq")]].to_csv(path, index=False)
        paths.append(path)
    return model, theta, paths


def test_the_model_file_holds_the_gravity_it_was_fitted_with(tmp_path):
    model, theta, _ = wall_records(tmp_path, seeds=())
    q, dq, ddq = (np.random.default_rng(0).normal(size=(50, 3)) for _ in range(3))
    data = simulate(model, theta, random_fourier(model.robot, seed=5), rate_hz=200.0, periods=1, noise=NOISE, seed=5)
    result = identify(model, data, covariance="classical")
    document = model_file_document(result, robot=RobotSource("puma560", "puma560", 3), preprocessing=None)
    assert document["gravity"] == list(WALL)
    loaded = IdentifiedModel(ModelFile.from_dict(document))
    assert np.array_equal(loaded.robot.gravity, WALL)
    assert np.allclose(loaded.predict(q, dq, ddq), model.predict(np.asarray(result.estimate.values), q, dq, ddq),
                       rtol=1e-12, atol=1e-12)
    assert loaded.fitted_gravity is not None and "9.81, 0, 0" in loaded.fitted_gravity
    note = gravity_note(loaded)  # a URDF holds no gravity: the mount to write is said
    assert note is not None and re.search(r'rpy="[-.\d]+ 1\.5708 0\.0000"', note), note  # the roll free at 90°
    # the description's gravity: nothing said; a file of an earlier release (no key) reads as the description's
    upright = build_model(load_robot("puma560", joints=3), "internal", "viscous,coulomb")
    plain = model_file_document(identify(upright, data, covariance="classical"),
                                robot=RobotSource("puma560", "puma560", 3), preprocessing=None)
    assert IdentifiedModel(ModelFile.from_dict(plain)).fitted_gravity is None
    del plain["gravity"]
    old = IdentifiedModel(ModelFile.from_dict(plain))
    assert np.array_equal(old.robot.gravity, upright.robot.gravity) and gravity_note(old) is None
    with pytest.raises(ModelFileError, match="gravity must be three finite numbers"):
        ModelFile.from_dict({**plain, "gravity": [0.0, "up"]})


@pytest.mark.slow  # three identify runs (about 20 s quiet): the fast suite's budget is spent
def test_a_mount_found_is_taken_when_it_validates_better_and_predict_uses_it(tmp_path, capsys):
    """A PUMA 3 on a wall, its description on the floor: `oed identify` finds the mount, fits the model with it, takes
    it on the validation record, and the result file holds it; `oed predict` on the validation record gives the
    reported error, and predicts the test record better on every joint than the fit with the description's gravity."""
    _, _, (train, validate, test) = wall_records(tmp_path)
    result, metrics = tmp_path / "result.json", tmp_path / "metrics.json"
    assert main(["identify", "--joints", "3", "--data", str(train), "--validate", str(validate),
                 "--friction", "viscous,coulomb", "--out", str(result)]) == 0
    document = json.loads(result.read_text())
    gravity = np.array(document["model_file"]["gravity"])
    angle = np.degrees(np.arccos(gravity @ WALL / (np.linalg.norm(gravity) * 9.81)))
    # 11° off here (a 3-joint arm's short records; the 6-joint PUMA's within 0.7°, tests/test_unseen_robot_mounts.py)
    assert angle < 15.0 and np.linalg.norm(gravity) == pytest.approx(9.81), gravity
    assert "the gravity the mount check found" in document["model_selection"]["reason"]
    said = [text for text in document["warnings"] if "gravity load points elsewhere" in text]
    assert said and "the answer is fitted with the found gravity" in said[0], said
    assert main(["predict", "--model", str(result), "--data", str(validate), "--metrics", str(metrics)]) == 0
    measured = json.loads(metrics.read_text())["mse"]
    reported = document["model_file"]["reported"]["validation_mse"]
    assert max(abs(measured[channel] / reported[channel] - 1.0) for channel in reported) < 1e-6
    assert "not the description's" in capsys.readouterr().out
    # on the test record, against the same class fitted with the description's gravity (an estimator given: no
    # candidate), each joint
    described = tmp_path / "described.json"
    assert main(["identify", "--joints", "3", "--data", str(train), "--validate", str(validate), "--method", "wls",
                 "--friction", "viscous,coulomb", "--out", str(described)]) == 0
    assert "gravity" not in json.loads(described.read_text())["model_selection"]["reason"]
    test_mse = {}
    for name, path in (("found", result), ("described", described)):
        assert main(["predict", "--model", str(path), "--data", str(test), "--metrics", str(metrics)]) == 0
        test_mse[name] = json.loads(metrics.read_text())["mse"]
    # measured: tau1 2.38 against 2819 N²m², tau2 0.67 against 1.40, tau3 0.078 against 0.102
    assert all(test_mse["found"][channel] < test_mse["described"][channel] for channel in NOISE), test_mse
    assert test_mse["found"]["tau1"] < 0.01 * test_mse["described"]["tau1"], test_mse


@pytest.mark.slow  # the 6-joint models of the check built (about 20 s quiet)
def test_torques_without_the_descriptions_gravity_are_said_to_hold_none():
    """A PUMA 6 whose logged torque is the motor torque minus the description's gravity torque (an arm in
    gravity-compensation mode), its true friction and bodies: the check finds that the fit without gravity predicts
    the validation record far better than with the description's (and better than any turned direction), and says
    gravity (0, 0, 0); the same arm logged with gravity is not said to hold none."""
    from dynamics.measurements import Measurements
    from estimation.identification.mount import check_mount
    from tests.test_unseen_robots import FRICTION
    from tests.test_unseen_robots import NOISE as SPREAD
    from tests.test_unseen_robots import truth

    robot = load_robot("puma560", joints=6)
    model = build_model(robot, "internal", FRICTION)
    theta, described = truth(model), model.nominal_parameters()
    described[robot.standard_parameters.shape[0]:] = 0.0  # the controller's gravity model: the bodies only
    for compensated in (True, False):
        records = []
        for seed, seconds in ((11, 10.0), (12, 4.0)):
            t = np.arange(0.0, seconds, 0.004)
            q, dq, ddq = random_fourier(robot, seed=seed, frequency_hz=0.2).evaluate(t)
            tau = model.predict(theta, q, dq, ddq) - (model.predict(described, q, 0 * q, 0 * q) if compensated else 0)
            tau = tau + np.random.default_rng(seed).normal(0.0, 1.0, tau.shape) * SPREAD * tau.std(axis=0)
            records.append(Measurements(t, q, dq, ddq, tau, None, {}))
        check = check_mount(model, *records)
        print(f"\ncompensated {compensated}: validation MSE without gravity {check.zero_mse:.4g}, turned "
              f"{check.found_mse:.4g} ({check.angle_deg:.0f}°), the description's {check.declared_mse:.4g}")
        if compensated:  # measured: 0.300, 0.733 (57° off) and 3.30 N²m²
            assert check.absent and check.marked and not np.any(check.gravity)
            assert check.zero_mse < 0.2 * check.declared_mse and check.zero_mse < check.found_mse
            assert "hold no gravity load" in check.message()
        else:
            assert not check.absent and not check.marked
            assert check.zero_mse > 10.0 * check.declared_mse
