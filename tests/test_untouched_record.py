"""Three roles for data: training fits, validation decides, and a ``--test`` record no choice used gives the error
to quote (``test{before,after}{mse, mse_over_floor}``); a test record that is another record, or cut from one, is
refused."""

from __future__ import annotations

import json

import pytest

from dynamics.effects.linear import CoulombFriction
from dynamics.models import build_model
from dynamics.robots import load_robot
from estimation.diagnosis.search import diagnose
from estimation.diagnosis.untouched import recorded_mse, untouched_errors
from estimation.uncertainty.noise_floor import noise_floor
from oed.cli import main
from dynamics.simulation.synthetic import simulate, true_parameters
from oed.fourier import random_fourier

NOISE_TAU = 0.2


@pytest.fixture(scope="module")
def records():
    robot = load_robot("puma560", joints=3)
    truth = build_model(robot, "internal", ("viscous", CoulombFriction(joints=(1,))))
    theta = true_parameters(truth, seed=0, coulomb=[8.0])
    noise = {channel: NOISE_TAU for channel in truth.channels}
    return robot, [simulate(truth, theta, random_fourier(robot, seed=3 + k), noise=noise, seed=1 + k, periods=2)
                   for k in range(3)]


def test_the_test_error_is_the_validation_error_computed_on_another_record(records):
    robot, (train, validate, test) = records
    diagnosis = diagnose(build_model(robot, "internal", "viscous"), train, validate)
    # the same computation on the validation record gives back the diagnosis's own validation MSE
    for result in (diagnosis.before, diagnosis.after):
        again = recorded_mse(result, validate)
        for channel, value in result.validation.mse.items():
            assert again[channel] == pytest.approx(value, rel=1e-9)
    errors = untouched_errors(diagnosis, test, noise_floor(test, diagnosis.after.model.channels, frequency_hz=0.2))
    assert set(errors.after) == {"tau1", "tau2", "tau3"}
    assert errors.after["tau2"] < 0.1 * errors.before["tau2"]  # the Coulomb friction found holds on the third record
    assert all(ratio < 1.3 for ratio in errors.over_floor("after").values())
    document = errors.to_dict()
    assert set(document) == {"before", "after", "noise_floor", "n_samples"}
    assert document["n_samples"] == test.n_samples


def write(records, folder):
    names = []
    for name, record in zip(("train", "validate", "test"), records):
        record.write(folder / f"{name}.csv")
        names.append(str(folder / f"{name}.csv"))
    return names


def test_cli_reports_the_test_record_and_says_when_there_is_none(records, tmp_path, capsys):
    train, validate, test = write(records[1], tmp_path)
    out = tmp_path / "report.json"
    code = main(["diagnose", "--joints", "3", "--data", train, "--validate", validate, "--test", test,
                 "--frequency", "0.2", "--out", str(out), "--report", str(tmp_path / "report.md")])
    printed = capsys.readouterr().out
    assert code == 0
    document = json.loads(out.read_text())
    assert document["test"]["after"]["mse"]["tau2"] < 0.1 * document["test"]["before"]["mse"]["tau2"]
    assert set(document["test"]["after"]["mse_over_floor"]) == {"tau1", "tau2", "tau3"}
    assert "test MSE vs recorded (a record no choice used)" in printed
    assert "## Test record (no choice used it)" in (tmp_path / "report.md").read_text()
    code = main(["diagnose", "--joints", "3", "--data", train, "--validate", validate, "--frequency", "0.2",
                 "--out", str(out)])
    assert code == 0
    assert json.loads(out.read_text())["test"] is None
    assert "give --test FILE" in capsys.readouterr().out


@pytest.mark.parametrize("case", ["validate", "train", "cut", "streamed"])
def test_a_test_record_that_is_not_a_third_experiment_is_refused(records, tmp_path, capsys, case):
    train, validate, test = write(records[1], tmp_path)
    extra = []
    if case == "cut":
        import pandas as pd

        pd.read_csv(train).iloc[500:1500].to_csv(tmp_path / "cut.csv", index=False)
        test = str(tmp_path / "cut.csv")
    elif case == "streamed":
        extra = ["--chunk-size", "1000"]
    else:
        test = {"validate": validate, "train": train}[case]
    out = tmp_path / "report.json"
    code = main(["diagnose", "--joints", "3", "--data", train, "--validate", validate, "--test", test,
                 "--frequency", "0.2", "--out", str(out), *extra])
    error = capsys.readouterr().err
    assert code == 2
    assert {"validate": "is also a --validate file", "train": "is also a --data file",
            "cut": "shares samples with training file", "streamed": "--test is read in memory"}[case] in error
    assert not out.exists()
