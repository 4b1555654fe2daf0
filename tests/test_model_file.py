"""The identified model as a file (estimation.identification.model_file, identified_model; `oed predict`):
saved by `oed identify` and `oed diagnose`, reloaded, and predicting the validation record as reported."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pandas as pd
import pytest

from dynamics.models import build_model
from dynamics.robots import load_robot
from estimation.identification.identified_model import IdentifiedModel
from estimation.identification.model_file import ModelFileError, RobotSource
from estimation.identification.plausibility import assess_plausibility, positive_base_parameters
from oed.cli import main
from dynamics.simulation.synthetic import simulate, true_parameters
from oed.fourier import random_fourier

DELAY = 0.006  # s: the torques lag the motion
NOISE = {"tau1": 0.2, "tau2": 0.2, "tau3": 0.1}


@pytest.fixture(scope="module")
def records(tmp_path_factory):
    """Two records of a 3-joint PUMA with viscous and Coulomb friction and a delay, positions and torques
    only (the motion is derived by the detected Fourier fit)."""
    folder = tmp_path_factory.mktemp("model_file")
    robot = load_robot("puma560", joints=3)
    model = build_model(robot, "internal", "viscous,coulomb")
    theta = true_parameters(model, seed=1, coulomb=[3.0, 2.0, 1.0])
    paths = []
    for seed in (5, 6):
        trajectory = random_fourier(robot, seed=seed)
        data = simulate(model, theta, trajectory, rate_hz=200.0, periods=2, noise=NOISE, seed=seed)
        q, dq, ddq = trajectory.evaluate(data.t + DELAY)
        frame = dataclasses.replace(data, q=q, dq=dq, ddq=ddq).to_frame()
        path = folder / f"record{seed}.csv"
        frame[[column for column in frame.columns if not column.startswith(("dq", "ddq"))]].to_csv(path, index=False)
        paths.append(path)
    return folder, paths


def _relative(metrics: dict, reported: dict) -> float:
    return max(abs(metrics[channel] / reported[channel] - 1) for channel in reported)


def test_predict_reproduces_the_validation_mse_of_a_shaped_fit_with_a_delay(records, capsys):
    folder, (train, validate) = records
    result, metrics, predictions = folder / "result.json", folder / "metrics.json", folder / "predictions.csv"
    assert main(["identify", "--joints", "3", "--data", str(train), "--validate", str(validate),
                 "--friction", "viscous,coulomb:tanh,delay", "--out", str(result)]) == 0
    assert main(["predict", "--model", str(result), "--data", str(validate), "--out", str(predictions),
                 "--metrics", str(metrics)]) == 0
    document, measured = json.loads(result.read_text()), json.loads(metrics.read_text())
    model_file = document["model_file"]
    assert set(model_file["shape"]) == {"vc1", "vc2", "vc3"} and model_file["delay"]["value"] > 0
    chosen = document["model_selection"]["chosen"]  # the model the file holds, at its fitted shapes and delay
    assert _relative(measured["mse"], model_file["reported"]["validation_mse"]) < 1e-6
    assert _relative(measured["mse"], next(candidate["validation_mse"] for candidate in
                                           document["model_selection"]["candidates"] if candidate["name"] == chosen)) < 1e-6
    assert _relative(measured["mse"], document["validation"]["mse"]) < 1e-6  # the top level: the chosen model's
    assert document["validation"]["model"] == chosen
    assert main(["predict", "--model", str(result), "--data", str(validate), "--alternative", "unconstrained",
                 "--metrics", str(metrics)]) == 0  # the unconstrained fit behind the choice: its candidate's errors
    unconstrained = chosen if chosen != "consistent" else document["model_selection"]["base"]
    assert _relative(json.loads(metrics.read_text())["mse"], next(
        candidate["validation_mse"] for candidate in document["model_selection"]["candidates"]
        if candidate["name"] == unconstrained)) < 1e-6
    assert measured["n_samples"] > 0 and set(measured["mse_over_floor"]) == {"tau1", "tau2", "tau3"}
    assert all(measured["mse"][c] < measured["nominal_mse"][c] < measured["zero_mse"][c] for c in measured["mse"])
    table = pd.read_csv(predictions)
    assert list(table.columns) == ["t"] + [f"{c}{s}" for c in ("tau1", "tau2", "tau3") for s in ("", "_lo", "_hi")] \
        + [f"{c}{s}" for c in ("tau1", "tau2", "tau3") for s in ("_measured", "_residual")]
    # the residual is measured minus predicted, and its mean square is the reported MSE
    np.testing.assert_allclose(table["tau2_residual"], table["tau2_measured"] - table["tau2"], atol=1e-9)
    assert np.mean(table["tau2_residual"] ** 2) == pytest.approx(measured["mse"]["tau2"], rel=1e-6)
    assert np.all(table["tau1_lo"] < table["tau1"]) and np.all(table["tau1"] < table["tau1_hi"])
    # the 95 % band holds about 95 % of the recorded torques (the channel noise dominates it)
    # (at the instants predicted: a filter chosen for the derivatives trims each record's edges)
    recorded = pd.read_csv(validate).set_index("t").reindex(table["t"], method="nearest")
    inside = np.mean((recorded["tau2"].to_numpy() >= table["tau2_lo"].to_numpy())
                     & (recorded["tau2"].to_numpy() <= table["tau2_hi"].to_numpy()))
    assert 0.85 < inside <= 1.0
    assert "MSE vs recorded" in capsys.readouterr().out


def test_predict_reproduces_the_diagnosis_after_mse(records):
    folder, (train, validate) = records
    report, metrics = folder / "report.json", folder / "diagnosis_metrics.json"
    # a shaped law declared (with only the viscous model declared, the derivatives chosen on the validation record
    # let the diagnosis name the truth's sign law, no shape): the model file holds its shapes and the delay found
    assert main(["diagnose", "--joints", "3", "--data", str(train), "--validate", str(validate),
                 "--friction", "viscous,coulomb:tanh", "--out", str(report)]) == 0
    document = json.loads(report.read_text())
    assert any(effect["shape"] for effect in document["effects"])  # the delay found
    assert document["model_file"]["delay"] is not None and document["model_file"]["shape"]
    # the report's model is the one its default choice made (model_selection: the adopted model as fitted or its
    # consistent refit); predict reproduces that one's validation error, and the adopted model's ('after') with
    # --alternative unconstrained
    chosen = next(candidate for candidate in document["model_selection"]["candidates"]
                  if candidate["name"] == document["model_selection"]["chosen"])
    assert main(["predict", "--model", str(report), "--data", str(validate), "--metrics", str(metrics)]) == 0
    measured = json.loads(metrics.read_text())
    assert _relative(measured["mse"], chosen["validation_mse"]) < 1e-6
    assert measured["reported_validation_mse"] == chosen["validation_mse"]
    assert main(["predict", "--model", str(report), "--data", str(validate), "--metrics", str(metrics),
                 "--alternative", "unconstrained"]) == 0
    measured = json.loads(metrics.read_text())
    assert _relative(measured["mse"], document["validation"]["after"]["mse"]) < 1e-6
    assert measured["reported_validation_mse"] == document["validation"]["after"]["mse"]


def test_the_loaded_model_predicts_as_the_fit_did(records):
    folder, (train, validate) = records
    result = folder / "plain.json"
    assert main(["identify", "--joints", "3", "--data", str(train), "--validate", str(validate),
                 "--friction", "viscous,coulomb", "--out", str(result)]) == 0
    model = IdentifiedModel.load(result)  # the top-level parameters: the chosen model's
    document = json.loads(result.read_text())
    assert model.estimate == document["chosen"]
    theta = np.array([record["value"] for record in document["parameters"]])
    q, dq, ddq = (np.random.default_rng(0).normal(size=(7, 3)) for _ in range(3))
    expected = model.model.predict(theta, q, dq, ddq)
    assert np.allclose(model.predict(q, dq, ddq), expected, rtol=1e-12, atol=1e-12)
    assert model.interval(q, dq, ddq).shape == (7, 3)


def test_a_urdf_robot_is_embedded_and_a_changed_file_is_refused(tmp_path, prismatic_urdf):
    robot = load_robot(urdf=prismatic_urdf)
    source = RobotSource.from_description(robot, builtin=None, urdf=prismatic_urdf, joints=None)
    assert source.urdf_text is not None and RobotSource.from_dict(source.to_dict()).load().joint_names == robot.joint_names
    copy = tmp_path / "arm.urdf"
    copy.write_text(prismatic_urdf.read_text())
    by_path = dataclasses.replace(RobotSource.from_description(robot, builtin=None, urdf=copy, joints=None), urdf_text=None)
    assert by_path.load().joint_names == robot.joint_names
    copy.write_text(prismatic_urdf.read_text().replace("<robot", "<!-- edited -->\n<robot", 1))
    with pytest.raises(ModelFileError, match="changed since the identification"):
        by_path.load()


def test_predict_refuses_a_file_without_a_model(tmp_path, capsys, records):
    _, (_, validate) = records
    empty = tmp_path / "empty.json"
    empty.write_text(json.dumps({"robot": "puma560"}))
    assert main(["predict", "--model", str(empty), "--data", str(validate)]) == 2
    assert "no key 'model_file'" in capsys.readouterr().err


def test_a_diagonal_inertia_far_below_zero_is_implausible():
    model = build_model(load_robot("puma560"), "internal", "viscous")
    positive = dict(zip(model.base.names, positive_base_parameters(model)))
    # sums of diagonal inertias about the frame origins and friction are never negative; a grouping that
    # subtracts m a² (Izz2R = Izz2 - a2**2*(m2 + m3)) can be
    assert positive["Izz6"] and positive["Iyy5R"] and positive["fv1"] and not positive["Izz2R"]
    index = list(model.base.names).index("Izz6")
    records = [{"name": n, "expression": e, "value": 1.0, "std": 0.1}
               for n, e in zip(model.base.names, model.base.expressions)]
    records[index]["value"] = -1.0
    check = assess_plausibility(model, records, validation_mse={"tau1": 2.0}, nominal_mse={"tau1": 1.0},
                                zero_mse={"tau1": 4.0})
    assert not check.plausible and check.worse_than_nominal
    assert [term["name"] for term in check.negative_terms] == [model.base.names[index]]
    assert all("--consistent" in message for message in check.messages())


def test_a_fit_worse_than_the_nominal_model_says_so(tmp_path, capsys):
    """Identified on a record that hardly moves, the model predicts another worse than the description."""
    robot = load_robot("puma560", joints=3)
    model = build_model(robot, "internal", "viscous")
    poor = simulate(model, true_parameters(model, seed=1), random_fourier(robot, seed=5, fill=0.02, harmonics=1),
                    rate_hz=100.0, periods=1, noise={"tau1": 2.0, "tau2": 2.0, "tau3": 2.0}, seed=5)
    poor.write(tmp_path / "poor.csv")
    validate = tmp_path / "validate.csv"
    simulate(model, true_parameters(model, seed=1), random_fourier(robot, seed=6), rate_hz=100.0, noise=NOISE,
             seed=6).write(validate)
    result = tmp_path / "result.json"  # the unconstrained fit (by default the consistent fit, far better, is chosen)
    assert main(["identify", "--joints", "3", "--data", str(tmp_path / "poor.csv"), "--validate", str(validate),
                 "--method", "wls", "--out", str(result)]) == 0
    plausibility = json.loads(result.read_text())["plausibility"]
    assert plausibility["worse_than_nominal"] and not plausibility["plausible"]
    assert "worse than the nominal description" in capsys.readouterr().err


def test_the_diagnosis_names_the_truths_sign_law_and_delay(records):
    """The truth: viscous and Coulomb friction (the sign law) and a 6 ms delay. With the derivatives chosen on
    the validation record by the plain model (oed.workflows.diagnose.derivatives_on_validation), the viscous
    diagnosis names the sign law on each joint and the delay; on the training record's own choice (a 5-harmonic
    Fourier fit, which smooths the law's jump at each reversal) it named coulomb:tanh on every joint and a 3.2 ms
    delay, validating 1.7-3.4x worse per joint."""
    folder, (train, validate) = records
    report = folder / "sign_law.json"
    assert main(["diagnose", "--joints", "3", "--data", str(train), "--validate", str(validate),
                 "--friction", "viscous", "--out", str(report)]) == 0
    document = json.loads(report.read_text())
    assert document["preprocessing"]["selection"] == "validation"
    assert sorted((effect["spec"], tuple(effect["channels"])) for effect in document["effects"]) == \
        [("coulomb", ("tau1",)), ("coulomb", ("tau2",)), ("coulomb", ("tau3",)), ("delay", ("tau1", "tau2", "tau3"))]
    assert document["model_file"]["delay"]["value"] == pytest.approx(DELAY, abs=1e-3)
