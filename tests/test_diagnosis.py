"""Residual diagnosis: undeclared effects are found on the right channels; clean data gets nothing."""

from __future__ import annotations

import pytest

from dynamics.effects.linear import CoulombFriction
from dynamics.models import build_model
from dynamics.robots import load_robot
from estimation.diagnosis.search import diagnose, provisional_stopping_rule
from estimation.diagnosis.statistics import floor_for_validation
from estimation.diagnosis.rules.stopping_rules import floor_stopping_rule
from dynamics.simulation.synthetic import simulate, true_parameters

from oed.fourier import random_fourier

NOISE_TAU = 0.2
NOISE_WRENCH = {"fx": 2.0, "fy": 2.0, "fz": 2.0, "mx": 0.5, "my": 0.5, "mz": 0.5}


@pytest.fixture(scope="module")
def robot():
    return load_robot("puma560", joints=3)


def _experiments(truth, theta, *, bias=None):
    noise = {channel: NOISE_TAU for channel in truth.channels if channel.startswith("tau")}
    noise.update({channel: value for channel, value in NOISE_WRENCH.items() if channel in truth.channels})
    train = simulate(truth, theta, random_fourier(truth.robot, seed=3), noise=noise, seed=1, bias=bias)
    validate = simulate(truth, theta, random_fourier(truth.robot, seed=4), noise=noise, seed=2, bias=bias)
    return train, validate


def test_undeclared_coulomb_friction_is_named_on_its_joint(robot):
    truth = build_model(robot, "internal", ("viscous", CoulombFriction(joints=(1,))))
    theta = true_parameters(truth, seed=0, coulomb=[8.0])
    train, validate = _experiments(truth, theta)
    declared = build_model(robot, "internal", "viscous")
    diagnosis = diagnose(declared, train, validate)
    assert [(effect.name, effect.channels) for effect in diagnosis.effects] == [("coulomb", ("tau2",))]
    found = diagnosis.effects[0]
    assert abs(found.values[0] - 8.0) < 3 * found.std[0] + 0.05
    before, after = diagnosis.before.validation.mse, diagnosis.after.validation.mse
    assert before["tau2"] > 10 * NOISE_TAU**2
    for channel, value in after.items():
        assert value < 1.3 * NOISE_TAU**2, (channel, value)  # back at the noise floor
    document = diagnosis.to_dict()
    assert document["effects"][0]["name"] == "coulomb" and set(document["validation"]) == {"before", "after"}


def test_constant_plate_moment_is_found_on_its_channel(robot):
    truth = build_model(robot, "combined", "viscous")
    theta = true_parameters(truth, seed=0)
    train, validate = _experiments(truth, theta, bias={"mz": 4.0})
    declared = build_model(robot, "combined", "viscous")
    diagnosis = diagnose(declared, train, validate)
    names = [(effect.name, effect.channels) for effect in diagnosis.effects]
    assert ("wrench_offset", ("mz",)) in names
    assert all(effect.name == "wrench_offset" for effect in diagnosis.effects)
    mz = next(effect for effect in diagnosis.effects if effect.channels == ("mz",))
    assert abs(mz.values[0] - 4.0) < 3 * mz.std[0] + 0.05
    assert diagnosis.after.validation.mse["mz"] < 1.3 * NOISE_WRENCH["mz"] ** 2 < diagnosis.before.validation.mse["mz"]


def test_clean_data_gets_nothing_added(robot):
    truth = build_model(robot, "internal", "viscous")
    theta = true_parameters(truth, seed=5)
    train, validate = _experiments(truth, theta)
    diagnosis = diagnose(truth, train, validate)
    assert diagnosis.effects == ()
    assert diagnosis.to_dict()["effects"] == []


def test_clean_data_at_the_floor_are_not_searched_under_the_floor_rule(robot):
    # the search runs until no move is confirmed; the floor rule, when asked for, ends it at the floor
    truth = build_model(robot, "internal", "viscous")
    train, validate = _experiments(truth, true_parameters(truth, seed=6))
    floor, _ = floor_for_validation(validate, truth.channels)
    diagnosis = diagnose(truth, train, validate, stopping_rule=floor_stopping_rule(floor))
    assert diagnosis.statistics.floor is not None
    assert diagnosis.effects == ()
    assert all("noise floor" in rejected.reason for rejected in diagnosis.rejected if rejected.reason.startswith("not tested"))
    assert any(rejected.reason.startswith("not tested") for rejected in diagnosis.rejected)


def test_absorbed_candidates_are_reported_not_added(robot):
    declared = build_model(robot, "internal", "viscous")
    truth = build_model(robot, "internal", "viscous")
    train, validate = _experiments(truth, true_parameters(truth, seed=6))
    # clean data sit at their noise floor, where the floor rule would end the search before any candidate
    # is fitted (test_clean_data_at_the_floor_are_not_searched_under_the_floor_rule); without it every one is tried
    diagnosis = diagnose(declared, train, validate, stopping_rule=provisional_stopping_rule)
    reasons = {(r.name, r.channels): r.reason for r in diagnosis.rejected}
    # joint 1's axis is vertical and joint 2's armature merges with Izz2R: the base parameters absorb them
    assert "absorb" in reasons[("armature", ("tau1",))] and "absorb" in reasons[("armature", ("tau2",))]


def test_bad_alpha_is_named(robot):
    model = build_model(robot, "internal", "viscous")
    train, validate = _experiments(model, true_parameters(model))
    with pytest.raises(ValueError, match="alpha"):
        diagnose(model, train, validate, alpha=2.0)
    with pytest.raises(TypeError, match="validate must be Measurements .* got NoneType"):
        diagnose(model, train, None)


def test_diagnose_cli_writes_the_promised_json_and_report(tmp_path, robot, capsys):
    import json

    from oed.cli import main

    truth = build_model(robot, "internal", ("viscous", CoulombFriction(joints=(2,))))
    train, validate = _experiments(truth, true_parameters(truth, seed=0, coulomb=[6.0]))
    train.write(tmp_path / "train.csv")
    validate.write(tmp_path / "val.csv")
    code = main([
        "diagnose", "--robot", "puma560", "--joints", "3", "--model", "internal", "--data", str(tmp_path / "train.csv"),
        "--validate", str(tmp_path / "val.csv"), "--out", str(tmp_path / "report.json"), "--report", str(tmp_path / "report.md"),
    ])
    assert code == 0, capsys.readouterr().err
    document = json.loads((tmp_path / "report.json").read_text())
    effect = document["effects"][0]
    assert set(effect) >= {"name", "channels", "values", "std", "p_value"}
    assert (effect["name"], effect["channels"]) == ("coulomb", ["tau3"])
    assert set(document["validation"]["before"]["mse"]) == {"tau1", "tau2", "tau3"}
    assert "coulomb" in (tmp_path / "report.md").read_text()
    assert (tmp_path / "report.residuals.png").exists()


def test_diagnose_cli_bad_file_is_a_message(tmp_path, capsys):
    from oed.cli import main

    code = main(["diagnose", "--robot", "puma560", "--joints", "3", "--data", str(tmp_path / "absent.csv"),
                 "--validate", str(tmp_path / "absent.csv"), "--out", str(tmp_path / "r.json")])
    assert code == 2 and "absent.csv" in capsys.readouterr().err
    assert not (tmp_path / "r.json").exists()
