"""``oed identify`` end to end on synthetic data written with Measurements.write."""

from __future__ import annotations

import json
import re
from dataclasses import replace

import numpy as np
import pandas as pd
import pytest

from dynamics.models import build_model
from dynamics.robots import load_robot
from oed.cli import main
from dynamics.simulation.synthetic import simulate, true_parameters

from oed.fourier import random_fourier

NOISE = {"tau1": 0.5, "tau2": 0.5, "tau3": 0.2, "fx": 5.0, "fy": 5.0, "fz": 8.0, "mx": 3.0, "my": 3.0, "mz": 1.0}


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    robot = load_robot("puma560", joints=3)
    model = build_model(robot, "combined", "viscous")
    theta = true_parameters(model, seed=2)
    folder = tmp_path_factory.mktemp("identify")
    train = simulate(model, theta, random_fourier(robot, 3), noise=NOISE, seed=11)
    validate = simulate(model, theta, random_fourier(robot, 4), noise=NOISE, seed=12)
    train.write(folder / "train.csv")
    validate.write(folder / "val.parquet")
    replace(train, dq=None, ddq=None).write(folder / "train_positions_only.csv")
    return folder, model, theta


def test_identify_writes_the_promised_json_and_figure(files, capsys):
    folder, model, theta = files
    out, figure = folder / "result.json", folder / "fig.png"
    code = main(["identify", "--robot", "puma560", "--joints", "3", "--model", "combined", "--friction", "viscous",
                 "--data", str(folder / "train.csv"), "--validate", str(folder / "val.parquet"),
                 "--out", str(out), "--plot", str(figure)])
    assert code == 0
    document = json.loads(out.read_text())
    assert [p["name"] for p in document["parameters"]] == list(model.base.names)
    assert set(document["parameters"][0]) == {"name", "expression", "value", "std", "relative_std"}
    assert document["cond"] > 1
    assert list(document["train"]["mse"]) == list(model.channels) == list(document["validation"]["mse"])
    values = np.array([p["value"] for p in document["parameters"]])
    std = np.array([p["std"] for p in document["parameters"]])
    assert np.all(np.abs(values - model.base.to_base(theta)) < 3 * std)
    for channel, mse in document["validation"]["mse"].items():
        assert mse < 1.2 * NOISE[channel] ** 2
    assert figure.stat().st_size > 10_000
    assert document["warnings"] == []
    assert "validation MSE" in capsys.readouterr().out


def test_negative_friction_is_flagged_in_the_result_and_on_stderr(tmp_path, capsys):
    robot = load_robot("puma560", joints=3)
    model = build_model(robot, "internal", "viscous")
    theta = true_parameters(model, seed=2, viscous=[5.0, -3.0, 4.0])  # joint 2 "pushes": not friction
    simulate(model, theta, random_fourier(robot, 3), noise={"tau1": 0.5, "tau2": 0.5, "tau3": 0.2},
             seed=11).write(tmp_path / "train.csv")
    out = tmp_path / "result.json"
    code = main(["identify", "--robot", "puma560", "--joints", "3", "--model", "internal", "--data",
                 str(tmp_path / "train.csv"), "--out", str(out)])
    assert code == 0
    document = json.loads(out.read_text())
    warnings = document["warnings"]  # the chosen model's: the unconstrained fit's value, or it held at zero
    assert len(warnings) == 1 and warnings[0].startswith("fv2 = ") and "viscous friction" in warnings[0]
    assert re.match(r"fv2 = -3\.\d+ ± .* is negative", warnings[0]) if document["chosen"] != "consistent" else \
        re.search(r"held >= 0 by the physically consistent fit, where the unconstrained \w+ fit puts it at -3\.",
                  warnings[0]), warnings
    assert f"oed identify: warning: {warnings[0]}" in capsys.readouterr().err


def test_identify_derives_velocities_from_positions_by_fourier_fit(files):
    folder, model, theta = files
    out = folder / "internal.json"
    code = main(["identify", "--joints", "3", "--model", "internal", "--data", str(folder / "train_positions_only.csv"),
                 "--frequency", "0.2", "--validate", str(folder / "val.parquet"), "--out", str(out)])
    assert code == 0
    document = json.loads(out.read_text())
    assert document["validation"]["mse"]["tau2"] < 1.2 * NOISE["tau2"] ** 2


def test_identify_reports_bad_data_with_exit_code_2(files, tmp_path, capsys):
    folder, _, _ = files
    data = pd.read_csv(folder / "train.csv").drop(columns=["tau3"])
    data.to_csv(tmp_path / "bad.csv", index=False)
    out = tmp_path / "result.json"
    code = main(["identify", "--joints", "3", "--model", "combined", "--data", str(tmp_path / "bad.csv"), "--out", str(out)])
    assert code == 2
    assert "tau3" in capsys.readouterr().err
    assert not out.exists()


@pytest.mark.parametrize(
    "options,message",
    [
        (["--frequency", "0.2", "--cutoff", "5"], "give --frequency .* or --cutoff .*, not both"),
        (["--cutoff", "1e-6"], "cutoff 1e-06 Hz is below 1/.record length."),
    ],
)
def test_derivative_options_that_contradict_or_cannot_work_are_named(files, capsys, options, message):
    folder, _, _ = files
    code = main(["identify", "--joints", "3", "--model", "combined", "--data", str(folder / "train_positions_only.csv"),
                 "--out", str(folder / "unused.json"), *options])
    assert code == 2 and re.search(message, capsys.readouterr().err)
    assert not (folder / "unused.json").exists()
