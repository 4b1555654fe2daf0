"""The default answer of `oed diagnose` when the validation record repeats the training motion (issue 34): nothing
measured on another motion what the search left out, so the answer completes the diagnosed model with the plain law
(Coulomb friction and an offset on each joint that the diagnosis left without one; the model class of a plain
least-squares fit) and chooses its physically consistent refit (`estimation.diagnosis.plain_laws.plain_completion`).
The completed laws are not named as findings.

Simulated 3-joint PUMA, the model declared viscous only, the validation record the training motion with other
noise, the test record another motion. The search is capped (``--max-effects``), as a search that refuses a law
(the KUKA LWR4+'s joint 1 from positions only: Coulomb friction refused by the Wald test at the Bonferroni
threshold, its test error 2x the plain fit's) leaves it out."""

from __future__ import annotations

import json

import numpy as np
import pytest

from dynamics.models import build_model
from dynamics.robots import load_robot
from dynamics.simulation.synthetic import simulate, true_parameters
from estimation.diagnosis.plain_laws import plain_completion
from estimation.identification.fit import identify
from oed.cli import main
from oed.fourier import random_fourier

NOISE = {"tau1": 0.2, "tau2": 0.2, "tau3": 0.1}


def write_records(folder, truth, theta, robot):
    paths = {}
    for name, seed, noise_seed in (("train", 5, 5), ("repeat", 5, 9), ("test", 7, 7)):
        data = simulate(truth, theta, random_fourier(robot, seed=seed), rate_hz=100.0, periods=1, noise=NOISE,
                        seed=noise_seed)
        paths[name] = folder / f"{name}.csv"
        data.write(paths[name])
    return paths


@pytest.fixture(scope="module")
def friction(tmp_path_factory):
    """Coulomb friction and an offset on every joint (the truth), the records and the true model's test error."""
    folder = tmp_path_factory.mktemp("repeat_plain_law")
    robot = load_robot("puma560", joints=3)
    truth = build_model(robot, "internal", "viscous,coulomb,offset")
    theta = true_parameters(truth, seed=1, coulomb=[3.0, 2.0, 1.0], offset=[0.5, -0.3, 0.2])
    return folder, write_records(folder, truth, theta, robot)


def diagnose(folder, paths, name, *options):
    out = folder / f"{name}.json"
    assert main(["diagnose", "--joints", "3", "--friction", "viscous", "--data", str(paths["train"]), "--validate",
                 str(paths["repeat"]), "--test", str(paths["test"]), "--out", str(out), "--quiet", *options]) == 0
    return out, json.loads(out.read_text())


def predict(folder, report, record, *options):
    metrics = folder / "metrics.json"
    assert main(["predict", "--model", str(report), "--data", str(record), "--metrics", str(metrics), *options]) == 0
    return json.loads(metrics.read_text())["mse"]


def test_a_capped_search_on_a_repeat_answers_with_the_plain_law_completed(friction):
    folder, paths = friction
    report, document = diagnose(folder, paths, "capped", "--max-effects", "2")
    named = [(effect["spec"], tuple(effect["channels"])) for effect in document["effects"]]
    assert len(named) <= 2, named  # the search stopped at its cap: four of the six true laws are not named
    selection = document["model_selection"]
    assert selection["selection"] == "repeated-motion" and selection["chosen"] == "consistent"
    description = next(c["description"] for c in selection["candidates"] if c["name"] == "consistent")
    assert "the plain law where the diagnosis named none" in description and "not findings" in description
    # the answer holds a Coulomb law and an offset on every joint (named or completed); the findings are unchanged
    assert {"fc1", "fc2", "fc3", "off1", "off2", "off3"} <= set(document["model_file"]["base"]["names"])
    assert {"fc1", "off1", "off2", "off3"}.isdisjoint(p for e in document["effects"] for p in e["parameters"])
    # on another motion the chosen model predicts each joint near its noise (without the completion the missing
    # Coulomb laws of 1-3 N·m leave errors of several N²m²), and `oed predict` reproduces the reported error
    chosen = document["test"]["chosen"]
    assert chosen["name"] == "consistent"
    for channel, sigma in NOISE.items():
        assert chosen["mse"][channel] < 2.0 * sigma**2, (channel, chosen["mse"])
    measured = predict(folder, report, paths["test"])
    assert max(abs(measured[c] / chosen["mse"][c] - 1) for c in NOISE) < 1e-6


def test_the_completion_on_a_clean_truth_names_nothing_and_costs_nothing(tmp_path):
    """No friction in the truth: nothing named, the completed laws fitted near zero, the test error at the noise."""
    robot = load_robot("puma560", joints=3)
    truth = build_model(robot, "internal", "viscous")
    paths = write_records(tmp_path, truth, true_parameters(truth, seed=1), robot)
    report, document = diagnose(tmp_path, paths, "clean")
    assert document["effects"] == []
    assert document["model_selection"]["chosen"] == "consistent"
    for channel, sigma in NOISE.items():
        assert document["test"]["chosen"]["mse"][channel] < 1.3 * sigma**2, document["test"]["chosen"]["mse"]


def test_plain_completion_adds_only_what_the_model_lacks():
    """Coulomb friction where no friction law acts on a joint, an offset where none does; nothing on a model that
    already holds both on every joint."""
    robot = load_robot("puma560", joints=3)
    truth = build_model(robot, "internal", "viscous,coulomb,offset")
    theta = true_parameters(truth, seed=1, coulomb=[3.0, 2.0, 1.0], offset=[0.5, -0.3, 0.2])
    train = simulate(truth, theta, random_fourier(robot, seed=5), rate_hz=100.0, periods=1, noise=NOISE, seed=5)
    full = identify(truth, train)
    assert plain_completion(full, train, None) is None
    partial = identify(build_model(robot, "internal", "viscous,coulomb@1,offset@2"), train)
    completed, added = plain_completion(partial, train, None)
    assert sorted((effect.name, effect.joints) for effect in added) == [
        ("coulomb", (1,)), ("coulomb", (2,)), ("offset", (0,)), ("offset", (2,))]
    assert completed.estimate.method == partial.estimate.method
    # the linear Stribeck law is the static-friction bump alone: its joint still takes Coulomb friction
    bump = identify(build_model(robot, "internal", "viscous,stribeck@1,offset"), train)
    _, added = plain_completion(bump, train, None)
    assert [(effect.name, effect.joints) for effect in added] == [("coulomb", (0,)), ("coulomb", (1,)),
                                                                   ("coulomb", (2,))]
    residual = np.mean(completed.train.mse["tau1"])
    assert residual < partial.train.mse["tau1"]


@pytest.fixture(scope="module")
def capped_in_memory(friction):
    """The capped diagnosis of the repeat in memory, without ``--test`` (the streamed path reads none)."""
    folder, paths = friction
    out = folder / "capped_memory.json"
    assert main(["diagnose", "--joints", "3", "--friction", "viscous", "--data", str(paths["train"]), "--validate",
                 str(paths["repeat"]), "--out", str(out), "--quiet", "--max-effects", "2"]) == 0
    return json.loads(out.read_text())


#: past ``--memory-budget`` the run streams as with ``--chunk-size`` (that route's own findings and answers are checked in
#: ``make test`` by tests/test_streamed_reader_parity.py and tests/test_one_answer_audit.py's jittered budget cases):
#: the budget case runs in ``make test-slow``; so does the clean validation log with ``--chunk-size``: the jittered case,
#: which stays, streams the same training file with the same options and makes every check of it (effects, the plain
#: law completed and taken, the model file, the errors, ``oed predict``) against memory's run on its own validation log
@pytest.mark.parametrize("options", [pytest.param(("--chunk-size", "250"), marks=pytest.mark.slow),
                                     pytest.param(("--memory-budget", "1KB"), marks=pytest.mark.slow), ("jittered",)],
                         ids=["chunk-size", "memory-budget", "jittered-validation"])
def test_the_streamed_diagnosis_completes_the_plain_law_as_in_memory(friction, request, tmp_path, options):
    """A log streamed (``--chunk-size``, or past ``--memory-budget``) answers the repeat as in memory: the same
    effects, the plain law completed and taken with the same scores, the same model file's parameters, the same
    validation errors of the chosen model; ``oed predict`` reproduces them. On a jittered validation log (resampled by
    the loader, streamed with ``--chunk-size``) every candidate is scored at the recorded samples on both paths."""
    import pandas as pd

    folder, paths = friction
    validate = paths["repeat"]
    if options != ("jittered",):  # the jittered case runs memory on its own validation log, not this one
        memory = request.getfixturevalue("capped_in_memory")
    else:  # every stamp moved by up to ±30 % of a step, the readings those of the true instant
        validate = tmp_path / "jittered_repeat.csv"
        frame = pd.read_csv(paths["repeat"])
        step = float(np.median(np.diff(frame.t)))
        frame["t"] = frame.t + np.random.default_rng(2).uniform(-0.3, 0.3, len(frame)) * step
        frame.to_csv(validate, index=False, float_format="%.10g")
        options = ("--chunk-size", "250")
        out = tmp_path / "jittered_memory.json"
        assert main(["diagnose", "--joints", "3", "--friction", "viscous", "--data", str(paths["train"]),
                     "--validate", str(validate), "--out", str(out), "--quiet", "--max-effects", "2"]) == 0
        memory = json.loads(out.read_text())
    out = tmp_path / "streamed.json"
    assert main(["diagnose", "--joints", "3", "--friction", "viscous", "--data", str(paths["train"]), "--validate",
                 str(validate), "--out", str(out), "--quiet", "--max-effects", "2", *options]) == 0
    streamed = json.loads(out.read_text())
    assert streamed["diagnosis_path"] == "streamed" and memory["diagnosis_path"] == "in-memory"
    assert [(e["spec"], e["channels"]) for e in streamed["effects"]] == \
        [(e["spec"], e["channels"]) for e in memory["effects"]]
    for document in (memory, streamed):
        selection = document["model_selection"]
        assert selection["selection"] == "repeated-motion" and selection["chosen"] == "consistent"
        assert "the plain law completed" in selection["reason"] and selection["reason"].endswith("taken")
        assert not selection["reason"].endswith("not taken")
    assert streamed["model_selection"]["reason"] == memory["model_selection"]["reason"]
    assert streamed["model_file"]["base"]["names"] == memory["model_file"]["base"]["names"]
    assert {"fc1", "off1", "off2", "off3"} <= set(streamed["model_file"]["base"]["names"])
    assert streamed["consistent"]["prior_weight"] == memory["consistent"]["prior_weight"]
    chosen = streamed["validation"]["chosen"]["mse"]
    assert chosen == pytest.approx(memory["validation"]["chosen"]["mse"], rel=1e-8)
    values = {name: np.array([p["value"] for p in document["consistent"]["parameters"]])
              for name, document in (("memory", memory), ("streamed", streamed))}
    np.testing.assert_allclose(values["streamed"], values["memory"], rtol=1e-6,
                               atol=1e-6 * np.abs(values["memory"]).max())
    measured = predict(tmp_path, out, validate)
    assert measured == pytest.approx(chosen, rel=1e-6)
