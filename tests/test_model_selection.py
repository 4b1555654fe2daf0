"""The default answer of `oed identify` (estimation.consistent.model_selection; issue 34): the candidates (OLS,
WLS, the consistent fit with the description's bodies as prior) scored on the same validation samples, the one
chosen, and one model per result file that `oed predict` and `oed export` use."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest

from dynamics.models import build_model
from dynamics.robots import load_robot
from dynamics.simulation.synthetic import simulate, true_parameters
from estimation.consistent.model_selection import select_model, selection_model_file
from estimation.data.records import read_record
from estimation.identification.model_file import RobotSource
from oed.cli import main
from oed.fourier import random_fourier

NOISE = {"tau1": 0.2, "tau2": 0.2, "tau3": 0.1}
EFFECTS = "viscous,coulomb,offset"


@pytest.fixture(scope="module")
def records(tmp_path_factory):
    """A 3-joint PUMA with viscous and Coulomb friction and offsets: two motions, and a repeat of the first
    (the same trajectory, other noise)."""
    folder = tmp_path_factory.mktemp("selection")
    robot = load_robot("puma560", joints=3)
    model = build_model(robot, "internal", EFFECTS)
    theta = true_parameters(model, seed=1, coulomb=[3.0, 2.0, 1.0], offset=[0.5, -0.3, 0.2])
    paths = {}
    for name, seed, noise_seed in (("train", 5, 5), ("other", 6, 6), ("repeat", 5, 9)):
        data = simulate(model, theta, random_fourier(robot, seed=seed), rate_hz=100.0, periods=1, noise=NOISE,
                        seed=noise_seed)
        paths[name] = folder / f"{name}.csv"
        data.write(paths[name])
    return folder, paths


def identify(folder, paths, name, *options, validate="other"):
    out = folder / f"{name}.json"
    arguments = ["identify", "--joints", "3", "--data", str(paths["train"]), "--friction", EFFECTS, "--out", str(out)]
    if validate is not None:
        arguments += ["--validate", str(paths[validate])]
    assert main(arguments + list(options)) == 0
    return out, json.loads(out.read_text())


def predict(folder, result, record, *options):
    metrics = folder / "metrics.json"
    assert main(["predict", "--model", str(result), "--data", str(record), "--metrics", str(metrics), *options]) == 0
    return json.loads(metrics.read_text())


def relative(measured: dict, reported: dict) -> float:
    return max(abs(measured[channel] / reported[channel] - 1) for channel in reported)


def test_every_candidate_is_scored_on_the_same_samples_and_the_smallest_error_is_chosen(records, capsys):
    folder, paths = records
    result, document = identify(folder, paths, "default")
    selection = document["model_selection"]
    assert selection["selection"] == "validation"
    candidates = {candidate["name"]: candidate for candidate in selection["candidates"]}
    assert set(candidates) == {"ols", "wls", "consistent"} and all(c["available"] for c in candidates.values())
    # the score: the mean over channels of each channel's error over the smallest any candidate reaches on it
    best_mse = {c: min(candidate["validation_mse"][c] for candidate in candidates.values()) for c in NOISE}
    for candidate in candidates.values():
        mse = candidate["validation_mse"]
        assert candidate["score"] == pytest.approx(np.mean([mse[c] / best_mse[c] for c in NOISE]), rel=1e-12)
        assert candidate["score"] >= 1.0
    assert selection["criterion"].startswith("mean over channels of each channel's validation MSE")
    best = min(candidates.values(), key=lambda candidate: candidate["score"])
    assert selection["chosen"] == best["name"] == document["model_file"]["chosen"]
    assert set(document["model_file"]["alternatives"]) == set(candidates) - {best["name"]}
    assert document["model_file"]["reported"]["validation_mse"] == best["validation_mse"]
    out = capsys.readouterr().out
    assert f"model: {best['name']}" in out and "validation MSE (vs recorded)" in out
    # the same validation samples: oed predict reproduces each candidate's reported error
    chosen = predict(folder, result, paths["other"])
    assert chosen["model"] == best["name"]
    assert relative(chosen["mse"], best["validation_mse"]) < 1e-6
    for name, candidate in candidates.items():
        measured = predict(folder, result, paths["other"], "--alternative", name)
        assert measured["model"] == name and relative(measured["mse"], candidate["validation_mse"]) < 1e-6
        assert measured["reported_validation_mse"] == candidate["validation_mse"]
    alias = predict(folder, result, paths["other"], "--consistent")
    assert alias["mse"] == predict(folder, result, paths["other"], "--alternative", "consistent")["mse"]


@pytest.mark.parametrize("validate, selection", [("repeat", "repeated-motion"), (None, "no-validation")])
def test_without_another_motion_the_fit_regularised_toward_the_description_is_chosen(records, capsys, validate,
                                                                                       selection):
    folder, paths = records
    result, document = identify(folder, paths, f"no_other_{validate}", validate=validate)
    chosen = document["model_selection"]
    assert chosen["selection"] == selection and chosen["chosen"] == "consistent"
    assert "nothing measured how the candidates extrapolate" in chosen["reason"]
    assert "nothing measured how the candidates extrapolate" in capsys.readouterr().out
    if validate is not None:
        measured = predict(folder, result, paths[validate])
        assert relative(measured["mse"], document["consistent"]["validation"]["mse"]) < 1e-6
    urdf = folder / f"{selection}.urdf"  # the chosen model is consistent: export writes it, no note
    assert main(["export", "--model", str(result), "--urdf", str(urdf)]) == 0
    assert urdf.is_file() and "instead" not in capsys.readouterr().err


def test_an_explicit_method_or_consistent_forces_the_choice(records, capsys):
    folder, paths = records
    result, document = identify(folder, paths, "ols", "--method", "ols")
    selection = document["model_selection"]
    assert selection["chosen"] == "ols" and selection["selection"] == "given"
    assert [candidate["name"] for candidate in selection["candidates"]] == ["ols"]
    assert document["method"] == "ols" and "consistent" not in document
    assert main(["export", "--model", str(result), "--urdf", str(folder / "ols.urdf")]) == 2
    assert "base parameters only" in capsys.readouterr().err
    _, forced = identify(folder, paths, "forced", "--consistent", "--method", "ols")
    assert forced["model_selection"]["chosen"] == "consistent" and forced["model_selection"]["base"] == "ols"
    assert forced["model_file"]["reported"]["validation_mse"] == forced["consistent"]["validation"]["mse"]


def test_export_of_an_unconstrained_choice_writes_the_consistent_alternative_and_says_so(records, capsys):
    folder, paths = records
    robot = load_robot("puma560", joints=3)
    model = build_model(robot, "internal", EFFECTS)
    train, other = (read_record(paths[name], model=model)[0] for name in ("train", "other"))
    selection = select_model(model, train, other)
    unconstrained = dataclasses.replace(selection, chosen="wls")
    document = selection_model_file(unconstrained, robot=RobotSource.from_description(robot, builtin="puma560",
                                                                                      urdf=None, joints=3),
                                    preprocessing=None)
    path = folder / "wls_chosen.json"
    path.write_text(json.dumps({"model_file": document}))
    urdf = folder / "alternative.urdf"
    assert main(["export", "--model", str(path), "--urdf", str(urdf)]) == 0
    error = capsys.readouterr().err
    assert "the chosen model (wls) holds base parameters only" in error and "'consistent' instead" in error
    assert main(["export", "--model", str(path), "--urdf", str(urdf), "--alternative", "ols"]) == 2
    assert "only the physically consistent one" in capsys.readouterr().err
    assert main(["predict", "--model", str(path), "--data", str(paths["other"]), "--alternative", "nope"]) == 2
    assert "holds no model 'nope'; it holds: wls, ols, consistent" in capsys.readouterr().err
