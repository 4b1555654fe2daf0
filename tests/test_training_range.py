"""Extrapolation said, not silent (issue 34): each joint's training range stored in the model file, and ``oed predict``
and the verbs' held-out records checked against it (:mod:`estimation.identification.training_range`).

A simulated 3-joint PUMA with viscous friction: the training and validation records move along one Fourier
trajectory (the validation at half its amplitude, inside the range on every joint); the test record moves joints 1
and 3 as in training and joint 2 at 1.5 times its amplitude (outside its range in position and speed). The records
hold ``dq`` and ``ddq``: every sample is fitted, so the expected range and fractions are those of the samples."""

from __future__ import annotations

import dataclasses
import json
import warnings

import numpy as np
import pytest

import oed
from dynamics.models import build_model
from dynamics.robots import load_robot
from dynamics.simulation.synthetic import simulate, true_parameters
from estimation.identification.identified_model import IdentifiedModel
from estimation.identification.training_range import (
    UNKNOWN_RANGE,
    ExtrapolationWarning,
    TrainingRange,
)
from oed.cli import main
from oed.fourier import random_fourier

NOISE = {"tau1": 0.2, "tau2": 0.2, "tau3": 0.2}


@pytest.fixture(scope="module")
def records(tmp_path_factory):
    robot = load_robot("puma560", joints=3)
    truth = build_model(robot, "internal", ("viscous",))
    theta = true_parameters(truth, seed=0)
    trajectory = random_fourier(robot, seed=3, fill=0.6)
    scale = np.array([[1.0], [1.5], [1.0]])
    motions = {"train": trajectory,
               "val": dataclasses.replace(trajectory, a=0.5 * trajectory.a, b=0.5 * trajectory.b),
               "test": dataclasses.replace(trajectory, a=scale * trajectory.a, b=scale * trajectory.b)}
    folder = tmp_path_factory.mktemp("ranges")
    sampled = {}
    for seed, (name, motion) in enumerate(motions.items()):
        record = simulate(truth, theta, motion, noise=NOISE, seed=seed + 3, periods=2)
        record.write(folder / f"{name}.csv")
        sampled[name] = record
    return folder, sampled, robot


def expected_fraction(train, test, joint: int) -> float:
    """The share of ``test``'s samples beyond ``train``'s range of ``joint`` and its tolerances (2 % of the span,
    5 % of the largest speed)."""
    low, high = train.q[:, joint].min(), train.q[:, joint].max()
    fast = np.abs(train.dq[:, joint]).max()
    slack, quick = max(0.02 * (high - low), 1e-3), max(0.05 * fast, 1e-3)
    beyond = (test.q[:, joint] < low - slack) | (test.q[:, joint] > high + slack) | \
        (np.abs(test.dq[:, joint]) > fast + quick)
    assert 0.0 < beyond.mean() < 1.0
    return float(beyond.mean())


def test_the_range_is_the_samples_and_a_record_inside_is_not_warned_of():
    rng = np.random.default_rng(0)
    q, dq = rng.uniform(-1.0, 1.0, (500, 2)), rng.uniform(-2.0, 2.0, (500, 2))
    ranges = TrainingRange.of(q, dq, ("a", "b"))
    assert np.allclose(ranges.q_min, q.min(axis=0)) and np.allclose(ranges.dq_max, np.abs(dq).max(axis=0))
    assert TrainingRange.from_dict(json.loads(json.dumps(ranges.to_dict()))).to_dict() == ranges.to_dict()
    halves = TrainingRange.of(q[:200], dq[:200], ("a", "b")).merged(TrainingRange.of(q[200:], dq[200:], ("a", "b")))
    assert halves.to_dict() == ranges.to_dict()  # exact under any split: the streamed path's chunks
    inside = ranges.check(0.5 * q, 0.5 * dq)
    assert not inside.outside and inside.messages() == []
    moved = q.copy()
    moved[:, 1] += 0.5
    check = ranges.check(moved, dq)
    assert [joint.joint for joint in check.outside] == ["b"]
    slack = 0.02 * (q[:, 1].max() - q[:, 1].min())
    assert check.to_dict()["b"]["fraction"] == pytest.approx(float(np.mean(moved[:, 1] > q[:, 1].max() + slack)))
    assert check.to_dict()["a"]["fraction"] == 0.0 and "a:" not in check.messages()[0]
    assert check.to_dict()["b"]["position_above"] == pytest.approx(0.5)
    with pytest.raises(ValueError, match="q_max"):
        TrainingRange.from_dict({"joints": {"a": {"q_min": 1.0}}})


def test_the_result_file_holds_the_training_range_and_predict_names_the_joint_that_leaves_it(records, tmp_path,
                                                                                             capsys):
    folder, sampled, robot = records
    run = oed.identify(joints=3, data=folder / "train.csv", validate=folder / "val.csv", method="ols")
    document = run.to_dict()
    stored = document["model_file"]["training_range"]
    train = sampled["train"]
    assert stored["n_samples"] == train.n_samples
    for j, name in enumerate(robot.joint_names):
        assert stored["joints"][name]["q_min"] == pytest.approx(train.q[:, j].min(), abs=1e-9)
        assert stored["joints"][name]["q_max"] == pytest.approx(train.q[:, j].max(), abs=1e-9)
        assert stored["joints"][name]["dq_max"] == pytest.approx(np.abs(train.dq[:, j]).max(), abs=1e-9)
    # the validation record (half the training amplitude) stays inside: said so, no warning
    assert not any(entry["outside"] for entry in document["validation"]["outside_training_range"].values())
    assert not any("training range of" in line for line in run.warnings)
    assert any(line.startswith("training range: the validation record stays within") for line in run.summary())
    model = tmp_path / "result.json"
    run.write(model)
    with pytest.warns(ExtrapolationWarning) as caught:  # the library call behind oed predict: a typed warning
        warnings.simplefilter("always")
        IdentifiedModel.load(model).evaluate([folder / "test.csv"])
    said = [str(warning.message) for warning in caught if warning.category is ExtrapolationWarning]
    names = robot.joint_names
    assert len(said) == 1 and f"{names[1]}:" in said[0] and f"{names[0]}:" not in said[0] and f"{names[2]}:" not in said[0]
    prediction = oed.predict(model=model, data=folder / "test.csv")  # its warnings, as the command line says them
    assert said[0] in prediction.warnings
    metrics = prediction.to_dict()["outside_training_range"]
    assert [name for name, entry in metrics.items() if entry["outside"]] == [names[1]]
    assert metrics[names[1]]["fraction"] == pytest.approx(expected_fraction(train, sampled["test"], 1), abs=1e-9)
    assert metrics[names[1]]["position_above"] > 0 and metrics[names[1]]["speed_above"] > 0
    assert any(names[1] in line for line in prediction.warnings)
    assert any(line.startswith("training range: outside on") for line in prediction.summary())
    metrics_file = tmp_path / "metrics.json"  # the command line: the warning on stderr, the line, the metrics
    capsys.readouterr()
    assert main(["predict", "--model", str(model), "--data", str(folder / "test.csv"), "--metrics",
                 str(metrics_file)]) == 0
    printed = capsys.readouterr()
    assert "leaves the training range of 1 joint(s)" in printed.err and "training range: outside on" in printed.out
    assert json.loads(metrics_file.read_text())["outside_training_range"] == metrics
    with warnings.catch_warnings():  # a record inside the range: no warning
        warnings.simplefilter("error", ExtrapolationWarning)
        IdentifiedModel.load(model).evaluate([folder / "val.csv"])
    inside = oed.predict(model=model, data=folder / "val.csv")
    assert not any("training range" in line for line in inside.warnings)
    assert not any(entry["outside"] for entry in inside.to_dict()["outside_training_range"].values())


def test_an_old_result_file_without_ranges_still_predicts_and_says_it_cannot_tell(records, tmp_path):
    folder, _, _ = records
    run = oed.identify(joints=3, data=folder / "train.csv", validate=folder / "val.csv", method="ols")
    document = run.to_dict()
    del document["model_file"]["training_range"]
    del document["validation"]["outside_training_range"]
    model = tmp_path / "old.json"
    model.write_text(json.dumps(document))
    with warnings.catch_warnings():
        warnings.simplefilter("error", ExtrapolationWarning)
        IdentifiedModel.load(model).evaluate([folder / "test.csv"])
    prediction = oed.predict(model=model, data=folder / "test.csv")
    metrics = prediction.to_dict()
    assert metrics["outside_training_range"] is None and metrics["training_range_note"] == UNKNOWN_RANGE
    assert f"training range: {UNKNOWN_RANGE}" in prediction.summary()


def test_diagnose_checks_its_test_record_against_the_training_range(records):
    folder, sampled, robot = records
    run = oed.diagnose(joints=3, data=folder / "train.csv", validate=folder / "val.csv", test=[folder / "test.csv"])
    document = run.to_dict()
    assert "training_range" in document["model_file"]
    test = document["test"]["outside_training_range"]
    assert [name for name, entry in test.items() if entry["outside"]] == [robot.joint_names[1]]
    assert test[robot.joint_names[1]]["fraction"] == pytest.approx(
        expected_fraction(sampled["train"], sampled["test"], 1), abs=1e-9)
    assert any("the test record leaves the training range" in line for line in run.warnings)
    assert any("the test record leaves the training range" in line for line in document["warnings"]["after"])


def test_the_streamed_path_stores_the_same_ranges_as_in_memory(records):
    folder, _, _ = records
    options = dict(joints=3, data=folder / "train.csv", validate=folder / "val.csv", method="ols")
    memory = oed.identify(**options).to_dict()
    streamed = oed.identify(**options, chunk_size=300).to_dict()
    assert streamed["identification_path"] == "streamed"
    assert streamed["model_file"]["training_range"] == memory["model_file"]["training_range"]
    for name, entry in memory["validation"]["outside_training_range"].items():  # the streamed check: no fraction
        assert streamed["validation"]["outside_training_range"][name]["outside"] == entry["outside"]
    diagnosed = oed.diagnose(joints=3, data=folder / "train.csv", validate=folder / "val.csv", chunk_size=300)
    assert diagnosed.to_dict()["diagnosis_path"] == "streamed"
    assert diagnosed.to_dict()["model_file"]["training_range"] == memory["model_file"]["training_range"]


def test_on_the_filter_path_streamed_and_memory_agree_on_the_ranges(records, tmp_path):
    """Records without ``dq``, ``ddq``: the derivatives filtered whole in memory and chunk by chunk streamed."""
    import pandas as pd

    folder, _, _ = records
    for name in ("train", "val"):
        frame = pd.read_csv(folder / f"{name}.csv")
        frame[[c for c in frame.columns if not c.startswith(("dq", "ddq"))]].to_csv(tmp_path / f"{name}.csv", index=False)
    options = dict(joints=3, data=tmp_path / "train.csv", validate=tmp_path / "val.csv", method="ols", cutoff=10.0)
    memory = oed.identify(**options).to_dict()["model_file"]["training_range"]
    streamed = oed.identify(**options, chunk_size=300).to_dict()["model_file"]["training_range"]
    assert streamed["n_samples"] == memory["n_samples"]
    for name, entry in memory["joints"].items():
        for key, value in entry.items():
            assert streamed["joints"][name][key] == pytest.approx(value, rel=1e-9), (name, key)
