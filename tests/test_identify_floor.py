"""oed identify holds its validation error to the noise floor estimated without the model: ``mse_over_floor`` per
channel in result.json, and a warning naming a channel that stays above it, what its residual follows, and
``oed diagnose``."""

from __future__ import annotations

import json

import pytest

from dynamics.effects.linear import CoulombFriction
from dynamics.models import build_model
from dynamics.robots import load_robot
from oed.cli import main
from dynamics.simulation.synthetic import simulate, true_parameters
from oed.fourier import random_fourier


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    folder = tmp_path_factory.mktemp("floor")
    robot = load_robot("puma560", joints=3)
    truth = build_model(robot, "internal", ("viscous", CoulombFriction(joints=(1,))))
    theta = true_parameters(truth, seed=0, coulomb=[8.0])
    noise = {channel: 0.2 for channel in truth.channels}
    for k, name in enumerate(("train", "validate")):
        simulate(truth, theta, random_fourier(robot, seed=3 + k), noise=noise, seed=1 + k, periods=2).write(
            folder / f"{name}.csv")
    return folder


@pytest.mark.parametrize("friction", ["viscous", "viscous,coulomb@2"])
def test_identify_says_which_channel_stays_above_its_floor(files, tmp_path, capsys, friction):
    out = tmp_path / "result.json"
    code = main(["identify", "--joints", "3", "--friction", friction, "--data", str(files / "train.csv"),
                 "--validate", str(files / "validate.csv"), "--frequency", "0.2", "--out", str(out)])
    error = capsys.readouterr().err
    assert code == 0, error
    document = json.loads(out.read_text())
    ratios = document["validation"]["mse_over_floor"]
    assert set(ratios) == {"tau1", "tau2", "tau3"}
    assert document["noise_floor"]["method"] == "periods"
    if friction == "viscous":  # the Coulomb friction of joint 2 is missing: its channel stays far above
        assert ratios["tau2"] > 5
        assert "tau2:" in error and "above its floor" in error and "oed diagnose" in error
        assert "follows" in error and "dq2" in error
    else:
        assert all(ratio < 1.3 for ratio in ratios.values()), ratios
        assert "above its floor" not in error
