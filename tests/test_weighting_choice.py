"""The channel weighting chosen by held-out error: the weighted fit (the paper's) unless ordinary least squares
predicts held-out blocks of the training record clearly better."""

from __future__ import annotations

import json

import numpy as np
import pytest

from dynamics.effects.linear import CoulombFriction
from dynamics.models import build_model
from dynamics.robots import load_robot
from estimation.identification import weighting_choice
from estimation.identification.weighting_choice import choose_weighting
from oed.cli import main
from dynamics.simulation.synthetic import simulate, true_parameters
from oed.fourier import random_fourier


@pytest.fixture(scope="module")
def setting():
    robot = load_robot("puma560", joints=3)
    truth = build_model(robot, "internal", ("viscous", CoulombFriction(joints=(1,))))
    theta = true_parameters(truth, seed=0, coulomb=[8.0])
    noise = {channel: 0.2 for channel in truth.channels}
    records = [simulate(truth, theta, random_fourier(robot, seed=3 + k), noise=noise, seed=1 + k, periods=2)
               for k in range(2)]
    return robot, records


def test_both_weightings_are_scored_on_held_out_blocks(setting):
    robot, (train, _) = setting
    choice = choose_weighting(build_model(robot, "internal", "viscous"), train)
    assert set(choice.scores) == {"wls", "ols"}
    for name, errors in choice.held_out_mse.items():
        assert set(errors) == {"tau1", "tau2", "tau3"}
        geometric = np.exp(np.mean(np.log(list(errors.values()))))
        assert choice.scores[name] == pytest.approx(geometric)
    # the missing Coulomb friction of joint 2 dominates tau2's held-out error whatever the weighting
    assert choice.held_out_mse["wls"]["tau2"] > 5 * 0.2**2
    assert choice.to_dict()["chosen"] == choice.method


@pytest.mark.parametrize("ols_error, chosen", [(0.5, "ols"), (0.9, "wls")])
def test_ordinary_least_squares_only_when_clearly_better(setting, monkeypatch, ols_error, chosen):
    robot, (train, _) = setting

    def fixed(problem, estimator, folds):
        return np.full(problem.n_channels, ols_error if estimator.__name__ == "LeastSquares" else 1.0)

    monkeypatch.setattr(weighting_choice, "held_out_mse", fixed)
    assert choose_weighting(build_model(robot, "internal", "viscous"), train).method == chosen


def test_cli_records_the_choice_unless_the_method_is_given(setting, tmp_path):
    _, records = setting
    for name, record in zip(("train", "validate"), records):
        record.write(tmp_path / f"{name}.csv")
    out = tmp_path / "result.json"
    common = ["identify", "--joints", "3", "--data", str(tmp_path / "train.csv"), "--validate",
              str(tmp_path / "validate.csv"), "--frequency", "0.2", "--out", str(out)]
    assert main(common) == 0
    document = json.loads(out.read_text())
    assert document["method_selection"]["chosen"] == document["method"].lower()
    assert main([*common, "--method", "ols"]) == 0
    document = json.loads(out.read_text())
    assert document["method"].lower() == "ols" and "method_selection" not in document
