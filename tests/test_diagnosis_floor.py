"""diagnose reports each channel against its noise floor, traces what remains and checks whiteness."""

from __future__ import annotations

import numpy as np
import pytest

from dynamics.effects.linear import CoulombFriction, JointOffset
from dynamics.models import build_model
from dynamics.robots import load_robot
from estimation.diagnosis.search import diagnose
from estimation.diagnosis.report import markdown_report
from estimation.uncertainty.noise_floor import noise_floor
from estimation.preprocessing.differentiation import average_periods
from dynamics.simulation.synthetic import simulate, true_parameters

from oed.fourier import random_fourier

NOISE_TAU = 0.2


@pytest.fixture(scope="module")
def setting():
    robot = load_robot("puma560", joints=3)
    truth = build_model(robot, "internal", ("viscous", CoulombFriction(joints=(1,))))
    theta = true_parameters(truth, seed=0, coulomb=[8.0])
    noise = {channel: NOISE_TAU for channel in truth.channels}
    train = simulate(truth, theta, random_fourier(robot, seed=3), noise=noise, seed=1, periods=2)
    validate = simulate(truth, theta, random_fourier(robot, seed=4), noise=noise, seed=2, periods=2)
    return robot, train, validate


def test_found_effect_brings_every_channel_to_its_floor(setting):
    robot, train, validate = setting
    diagnosis = diagnose(build_model(robot, "internal", "viscous"), train, validate)
    document = diagnosis.to_dict()
    assert document["noise_floor"]["method"] == "periods"
    for value in document["noise_floor"]["mse"].values():
        assert abs(value / NOISE_TAU**2 - 1) < 0.15
    after = document["floor_comparison"]["after"]
    assert all(not entry["above"] for entry in after.values()), after
    assert document["floor_comparison"]["before"]["tau2"]["above"]
    assert document["validation"]["before"]["mse_over_floor"]["tau2"] > 5
    assert all(ratio < 1.2 for ratio in document["validation"]["after"]["mse_over_floor"].values())
    assert all("at its floor" in document["floor_statements"][channel] for channel in ("tau1", "tau2", "tau3"))
    assert document["cov_method"] == "hac"
    top = [row for row in document["tracing"]["before"]["rows"] if row["channel"] == "tau2"][0]
    assert top["variable"] in ("sign_dq2", "dq2") and top["validation_share"] > 0.3
    whiteness = document["whiteness"]
    assert not whiteness["before"]["channels"]["tau2"]["whiteness"]["passed"]
    assert all(whiteness["after"]["channels"][c]["whiteness"]["passed"] for c in ("tau1", "tau2", "tau3"))
    text = markdown_report(diagnosis)
    assert "## Noise floor" in text and "## What the residual follows" in text and "at its floor" in text


def test_a_missing_effect_outside_the_library_is_named_by_its_variable(setting):
    robot, train, validate = setting
    declared = build_model(robot, "internal", "viscous")
    floor = noise_floor(validate, declared.channels)
    diagnosis = diagnose(declared, train, validate, candidates=[JointOffset(joints=(0,))], noise_floor=floor)
    document = diagnosis.to_dict()
    assert document["noise_floor"]["note"].startswith("given")
    statement = document["floor_statements"]["tau2"]
    assert "above its floor" in statement and ("sign_dq2" in statement or "dq2" in statement)


def test_averaged_validation_is_compared_with_the_averaged_floor(setting):
    robot, train, validate = setting
    declared = build_model(robot, "internal", ("viscous", CoulombFriction(joints=(1,))))
    floor = noise_floor(validate, declared.channels)
    averaged = average_periods(validate, 0.2)
    document = diagnose(declared, train, averaged, candidates=[], noise_floor=floor).to_dict()
    np.testing.assert_allclose(list(document["noise_floor"]["mse"].values()), floor.variance / 2)
    assert all(not entry["above"] for entry in document["floor_comparison"]["after"].values())
    estimated = diagnose(declared, train, averaged, candidates=[]).to_dict()  # from the averaged data
    assert estimated["noise_floor"]["method"] == "differences"
    np.testing.assert_allclose(list(estimated["noise_floor"]["mse"].values()), NOISE_TAU**2 / 2, rtol=0.2)


def test_cli_prints_how_far_above_the_floor_each_channel_stays(setting, tmp_path, capsys):
    from oed.cli import main

    _, train, validate = setting
    train.write(tmp_path / "train.csv")
    validate.write(tmp_path / "validate.csv")
    code = main(["diagnose", "--joints", "3", "--data", str(tmp_path / "train.csv"), "--validate",
                 str(tmp_path / "validate.csv"), "--frequency", "0.2", "--out", str(tmp_path / "report.json"),
                 "--report", str(tmp_path / "report.md")])
    out = capsys.readouterr().out
    assert code == 0
    assert "noise floor" in out and "(periods;" in out and "after / floor" in out
    assert out.count("at its floor") == 3
    text = (tmp_path / "report.md").read_text()
    assert "## Noise floor" in text
    # every channel at its floor: no traced variable explains anything after, so no tracing figure of "0 %" panels
    assert not (tmp_path / "report.trace.png").exists() and "no tracing figure" in text


def test_short_records_still_get_a_report(setting):
    robot, _, _ = setting
    model = build_model(robot, "internal", "viscous")
    theta = true_parameters(model, seed=0)
    noise = {channel: NOISE_TAU for channel in model.channels}
    train = simulate(model, theta, random_fourier(robot, seed=3), rate_hz=12.0, noise=noise, seed=1)  # 60 samples
    validate = simulate(model, theta, random_fourier(robot, seed=4), rate_hz=12.0, noise=noise, seed=2)
    document = diagnose(model, train, validate, candidates=[]).to_dict()
    assert document["tracing"]["after"]["bins"] == 12 and "whiteness" in document
    assert document["noise_floor"]["mse"] is None or document["noise_floor"]["method"] == "differences"
