"""What the data did not determine of the bodies (estimation.consistent.determination), and the prior's weight
``oed identify --consistent`` takes when none is given (auto with --validate, 1 without)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from dynamics.models import build_model
from dynamics.robots import load_robot
from dynamics.simulation.synthetic import simulate, true_parameters
from estimation.consistent.determination import RELATIVE_STD_THRESHOLD, determination
from estimation.identification.fit import identify
from oed.cli import main
from oed.fourier import random_fourier

NOISE = {"tau1": 0.2, "tau2": 0.2, "tau3": 0.1}


@pytest.fixture(scope="module")
def fitted(tmp_path_factory):
    robot = load_robot("puma560", joints=3)
    model = build_model(robot, "internal", "viscous,coulomb")
    theta = true_parameters(model, seed=1, coulomb=[3.0, 2.0, 1.0])
    folder = tmp_path_factory.mktemp("determination")
    records = []
    for seed in (5, 6):
        data = simulate(model, theta, random_fourier(robot, seed=seed), rate_hz=100.0, periods=1, noise=NOISE, seed=seed)
        records.append(data)
        data.write(folder / f"record{seed}.csv")
    return model, identify(model, records[0]), folder


def test_structural_directions_are_those_no_base_parameter_holds(fitted):
    model, result, _ = fitted
    found = determination(model, result.estimate.cov, model.robot.standard_parameters)
    n_links = 10 * model.robot.n_joints
    K = np.asarray(model.base.K)
    assert found.n_directions == n_links
    # the links' standard parameters reach the base parameters through K's link columns: what they do not reach
    # (the rank deficit of those columns, with the effects' columns eliminated) no record determines
    assert found.n_structural == n_links - (np.linalg.matrix_rank(K) - np.linalg.matrix_rank(K[:, n_links:]))
    # link 1 of the PUMA only turns about the vertical: its mass and centre of mass are not determined
    assert {"m1", "mx1", "my1", "mz1"} <= set(found.links["joint1"])
    for direction in found.directions:
        assert direction.structural or direction.relative_std > RELATIVE_STD_THRESHOLD
        assert sum(loading for _, loading in direction.loadings) <= 1.0 + 1e-9


def test_directions_follow_the_noise(fitted):
    """The same excitation with a million times the noise's standard deviation determines nothing; with
    a millionth of it, every direction a base parameter holds."""
    model, result, _ = fitted
    prior = model.robot.standard_parameters
    quiet = determination(model, 1e-12 * result.estimate.cov, prior)
    loud = determination(model, 1e12 * result.estimate.cov, prior)
    assert len(quiet.directions) == quiet.n_structural
    assert len(loud.directions) == loud.n_directions
    assert set(loud.links) == set(model.robot.joint_names)


def test_the_prior_weight_is_chosen_on_the_validation_record_unless_given(fitted, capsys):
    _, _, folder = fitted
    base = ["identify", "--joints", "3", "--friction", "viscous,coulomb", "--data", str(folder / "record5.csv"),
            "--consistent"]
    validated = [*base, "--validate", str(folder / "record6.csv")]
    assert main([*validated, "--out", str(folder / "auto.json")]) == 0
    consistent = json.loads((folder / "auto.json").read_text())["consistent"]
    assert consistent["prior_weight_choice"] == "held-out" and len(consistent["prior_weight_search"]) == 5
    undetermined = consistent["undetermined"]
    assert undetermined["n_structural"] > 0 and "joint1" in undetermined["links"]
    output = capsys.readouterr().out
    assert "chosen by the validation error" in output and "not determined by the data" in output
    assert main([*base, "--out", str(folder / "default.json")]) == 0
    consistent = json.loads((folder / "default.json").read_text())["consistent"]
    assert consistent["prior_weight"] == 1.0 and consistent["prior_weight_choice"] == "default"
    assert "prior_weight_search" not in consistent and consistent["prior"] == "robot description"
    assert "the default without --validate" in capsys.readouterr().out
    assert main([*validated, "--prior-weight", "0", "--out", str(folder / "none.json")]) == 0
    consistent = json.loads((folder / "none.json").read_text())["consistent"]
    assert consistent["prior_weight"] == 0 and consistent["prior_weight_choice"] == "given" and consistent["prior"] is None
