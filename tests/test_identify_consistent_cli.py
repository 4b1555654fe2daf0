"""``oed identify --consistent``: the promised keys, the prior, and bad input (exit 2, nothing written)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from dynamics.models import build_model
from dynamics.robots import load_robot
from oed.cli import main
from dynamics.simulation.synthetic import simulate
from oed.fourier import random_fourier
from tests.test_consistent import consistent_truth

NOISE = {"tau1": 0.5, "tau2": 0.5, "tau3": 0.2, "fx": 5.0, "fy": 5.0, "fz": 8.0, "mx": 3.0, "my": 3.0, "mz": 1.0}
BASE = ["identify", "--robot", "puma560", "--joints", "3", "--model", "combined", "--friction", "viscous"]


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    robot = load_robot("puma560", joints=3)
    model = build_model(robot, "combined", "viscous")
    theta = consistent_truth(model, seed=2)
    folder = tmp_path_factory.mktemp("consistent")
    simulate(model, theta, random_fourier(robot, 3), noise=NOISE, seed=11).write(folder / "train.csv")
    simulate(model, theta, random_fourier(robot, 4), noise=NOISE, seed=12).write(folder / "val.csv")
    return folder, model, theta


def run(folder, *extra):
    return main(BASE + ["--data", str(folder / "train.csv"), "--validate", str(folder / "val.csv"), *extra])


def test_consistent_adds_links_and_the_price_of_consistency(files, capsys):
    folder, model, theta = files
    out = folder / "result.json"
    assert run(folder, "--out", str(out), "--consistent") == 0
    document = json.loads(out.read_text())
    for key in ("parameters", "cond", "train", "validation", "warnings"):  # the existing keys stay
        assert key in document
    links = document["links"]
    assert [link["name"] for link in links] == model.robot.joint_names
    for link in links:
        assert set(link) >= {"name", "mass", "com", "inertia"}
        assert link["mass"] > 0 and np.asarray(link["inertia"]).shape == (3, 3)
        assert link["consistency_margin"] > 0
    consistent = document["consistent"]
    assert consistent["uncertainty_method"] == "reduced Hessian"
    assert [p["name"] for p in consistent["parameters"]] == list(model.base.names)
    assert set(consistent["price"]["validation"]) == set(model.channels)
    assert all(0.5 < ratio < 2.0 for ratio in consistent["price"]["validation"].values())
    assert all(value >= 0 for value in consistent["effects"].values())
    assert "consistent validation MSE" in capsys.readouterr().out


def test_prior_file_from_a_result_and_bounds(files):
    folder, model, _ = files
    out = folder / "prior_result.json"
    assert run(folder, "--out", str(out), "--consistent") == 0
    bounds = folder / "bounds.json"
    bounds.write_text(json.dumps({"links": {"2": {"mass": [1.0, 40.0]}}}))
    second = folder / "second.json"
    assert run(folder, "--out", str(second), "--consistent", "--prior", str(out), "--prior-weight", "10",
               "--link-bounds", str(bounds)) == 0
    document = json.loads(second.read_text())
    assert document["consistent"]["prior_weight"] == 10 and document["consistent"]["prior"] == str(out)
    assert all(link["std"] is not None for link in document["links"])
    assert 1.0 <= document["links"][1]["mass"] <= 40.0


@pytest.mark.parametrize("case", ["negative_mass", "box_excludes_prior", "other_robot", "no_consistent", "bad_weight"])
def test_bad_input_exits_2_and_writes_nothing(files, case, capsys):
    folder, model, _ = files
    out = folder / f"bad_{case}.json"
    extra = ["--consistent"]
    if case == "negative_mass":
        (folder / "neg.json").write_text(json.dumps({"links": {"1": {"mass": [-3.0, -1.0]}}}))
        extra += ["--link-bounds", str(folder / "neg.json")]
    elif case == "box_excludes_prior":
        (folder / "box.json").write_text(json.dumps({"links": {"2": {"com_lower": [3, 3, 3], "com_upper": [4, 4, 4]}}}))
        extra += ["--link-bounds", str(folder / "box.json"), "--prior-weight", "1"]
    elif case == "other_robot":
        (folder / "other.json").write_text(json.dumps({"robot": "kuka", "links": [
            {"name": f"lwr_{k}_joint", "mass": 1.0, "com": [0, 0, 0], "inertia": np.eye(3).tolist()} for k in range(7)]}))
        extra += ["--prior", str(folder / "other.json"), "--prior-weight", "1"]
    elif case == "no_consistent":
        extra = ["--prior-weight", "1"]
    else:
        extra += ["--prior-weight", "-1"]
    assert run(folder, "--out", str(out), *extra) == 2
    error = capsys.readouterr().err
    assert error.startswith("oed identify: error:"), error
    assert not out.exists()
