"""``oed diagnose --max-effects``: the cap is the user's, and the output says when it stopped the search."""

from __future__ import annotations

import json

import pytest

from dynamics.models import build_model
from dynamics.robots import load_robot
from oed.cli import main
from dynamics.simulation.synthetic import simulate, true_parameters


from oed.fourier import random_fourier


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    robot = load_robot("puma560", joints=3)
    truth = build_model(robot, "internal", "viscous,coulomb,offset")
    theta = true_parameters(truth, seed=2, coulomb=[4.0, 3.0, 2.0], offset=[1.0, -1.5, 0.8])
    folder = tmp_path_factory.mktemp("limits")
    noise = {"tau1": 0.3, "tau2": 0.3, "tau3": 0.1}
    for name, seed in (("train", 3), ("val", 4)):
        simulate(truth, theta, random_fourier(robot, seed), rate_hz=200.0, periods=2, noise=noise,
                 seed=seed).write(folder / f"{name}.csv")
    return folder


def diagnose(folder, *options):
    out = folder / "report.json"
    code = main(["diagnose", "--joints", "3", "--data", str(folder / "train.csv"), "--validate",
                 str(folder / "val.csv"), "--out", str(out), *options])
    return code, (json.loads(out.read_text()) if code == 0 else None)


def test_the_cap_on_effects_is_an_option_and_is_reported_when_reached(files, capsys):
    code, report = diagnose(files, "--max-effects", "1")
    output = capsys.readouterr().out
    assert code == 0
    assert len(report["effects"]) == 1 and report["max_effects"] == 1 and report["max_effects_reached"] is True
    assert "stopped at --max-effects 1:" in output and "candidate(s) not tested" in output
    assert report["preprocessing"]["method"] == "measured"
    code, report = diagnose(files)
    assert code == 0 and len(report["effects"]) >= 2 and report["max_effects_reached"] is False
    assert "stopped at --max-effects" not in capsys.readouterr().out


@pytest.mark.parametrize("value", ["0", "-2"])
def test_a_cap_below_one_is_refused(files, capsys, value):
    code, _ = diagnose(files, "--max-effects", value)
    assert code == 2 and "--max-effects must be a positive integer" in capsys.readouterr().err
