"""A validation record at rest (issue 34's sweep: a Stäubli TX40 record where the robot holds its pose chose a 3.5 Hz
filter, the weighting and the default answer on no dynamics, 1.37x the plain fit on the test). Such a record makes
no choice: the derivatives, the weighting and the default answer are chosen as without a validation record, and its
errors are still reported."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pandas as pd
import pytest

from dynamics.models import build_model
from dynamics.robots import load_robot
from dynamics.simulation.synthetic import simulate, true_parameters
from estimation.diagnosis.search import diagnose
from estimation.identification.repeated_motion import still_motion
from oed.cli import main
from oed.fourier import random_fourier
from tests.corpus.cases import ALONE
from tests.corpus.records import declared_model, matches, named_pairs
from tests.corpus.records import records as corpus_records

NOISE = {"tau1": 0.2, "tau2": 0.2, "tau3": 0.1}
EFFECTS = "viscous,coulomb,offset"


@pytest.fixture(scope="module")
def records(tmp_path_factory):
    """A 3-joint PUMA: a training motion, another motion, and a record of the robot holding the other motion's
    first pose (its torques that pose's, with noise); all as positions only, the derivatives chosen."""
    folder = tmp_path_factory.mktemp("still")
    robot = load_robot("puma560", joints=3)
    model = build_model(robot, "internal", EFFECTS)
    theta = true_parameters(model, seed=1, coulomb=[3.0, 2.0, 1.0], offset=[0.5, -0.3, 0.2])
    paths, data = {}, {}
    for name, seed in (("train", 5), ("other", 6)):
        data[name] = simulate(model, theta, random_fourier(robot, seed=seed), rate_hz=100.0, periods=1, noise=NOISE,
                              seed=seed)
        paths[name] = folder / f"{name}.csv"
        data[name].write(paths[name])
    generator = np.random.default_rng(0)
    for name in ("train", "other"):
        frame = pd.read_csv(paths[name])
        frame.drop(columns=[c for c in frame.columns if c.startswith(("dq", "ddq"))]).to_csv(paths[name], index=False)
    frame = pd.read_csv(paths["other"])
    for joint in (1, 2, 3):
        frame[f"q{joint}"] = frame[f"q{joint}"].iloc[0] + 1e-5 * generator.normal(size=len(frame))
        frame[f"tau{joint}"] = frame[f"tau{joint}"].iloc[:5].mean() + 0.2 * generator.normal(size=len(frame))
    paths["still"] = folder / "still.csv"
    frame.to_csv(paths["still"], index=False)
    return folder, paths, data


def identify(folder, paths, validate, *options):
    out = folder / f"{validate}{''.join(options)}.json"
    assert main(["identify", "--joints", "3", "--data", str(paths["train"]), "--validate", str(paths[validate]),
                 "--friction", EFFECTS, "--out", str(out), *options]) == 0
    return json.loads(out.read_text())


def test_a_record_at_rest_is_told_from_a_moving_one(records):
    _, _, data = records
    train, other = data["train"], data["other"]
    assert not still_motion(train, other)
    held = other.select(slice(0, 40))
    assert not still_motion(train, held)  # 0.4 s of a motion still moves
    assert still_motion(train, held.select(slice(0, 1)))
    assert not still_motion(train, train.select(slice(0, 0)))


def test_a_validation_record_at_rest_makes_no_choice_and_says_so(records, capsys):
    """On a record of another motion the derivatives and the default answer are chosen on it; at rest, as without
    a validation record (the derivatives by the training record's held-out evidence, the consistent fit preferred),
    and the validation errors are reported all the same."""
    folder, paths, _ = records
    moving = identify(folder, paths, "other")
    capsys.readouterr()
    still = identify(folder, paths, "still")
    error = capsys.readouterr().err
    assert "hardly moves" in error and "as without a validation record" in error, error
    assert moving["model_selection"]["selection"] == "validation"
    assert still["model_selection"]["selection"] == "still-validation"
    assert still["model_selection"]["chosen"] == "consistent"
    assert "hardly moves" in still["model_selection"]["reason"]
    assert still["validation"]["mse"] and all(np.isfinite(v) for v in still["validation"]["mse"].values())
    assert moving["preprocessing"]["selection"] == "validation"  # the derivatives chosen on the other motion
    assert still["preprocessing"]["selection"] == "held-out"  # not on the record at rest


#: past ``--memory-budget`` the run streams as with ``--chunk-size`` (that route's own findings and answers are checked in
#: ``make test`` by tests/test_streamed_reader_parity.py and tests/test_one_answer_audit.py's jittered budget cases):
#: the budget case runs in ``make test-slow``
@pytest.mark.parametrize("options", [("--chunk-size", "250"), pytest.param(("--memory-budget", "1KB"), marks=pytest.mark.slow)])
def test_a_validation_record_at_rest_streamed_makes_no_choice_as_in_memory(records, capsys, options):
    """Streamed (in blocks, the still test from each joint's running minimum and maximum), a record at rest gives
    the in-memory answer: the same selection, the same chosen model, the derivatives not chosen on it; said."""
    folder, paths, _ = records
    in_memory = identify(folder, paths, "still")
    capsys.readouterr()
    streamed = identify(folder, paths, "still", *options)
    error = capsys.readouterr().err
    assert "hardly moves" in error and "as without a validation record" in error, error
    assert in_memory["identification_path"] == "in-memory" and streamed["identification_path"] == "streamed"
    assert streamed["model_selection"]["selection"] == in_memory["model_selection"]["selection"] == "still-validation"
    assert streamed["model_selection"]["chosen"] == in_memory["model_selection"]["chosen"]
    assert streamed["preprocessing"]["selection"] == in_memory["preprocessing"]["selection"] == "held-out"
    assert streamed["validation"]["mse"] and all(np.isfinite(v) for v in streamed["validation"]["mse"].values())


def _laws(document):
    """The joints with a Coulomb law (sign or smoothed) and those with an offset, by the effects named."""
    laws = {"coulomb": set(), "offset": set()}
    for entry in document["effects"]:
        kind = "coulomb" if entry["spec"].startswith("coulomb") else entry["spec"]
        if kind in laws:
            laws[kind].update(entry["channels"])
    return laws


def test_a_streamed_diagnosis_with_a_validation_record_at_rest_chooses_its_answer_as_in_memory(records, capsys):
    """``oed diagnose``'s default answer (the adopted model or its consistent refit) with a record at rest: streamed,
    as in memory, no choice on it (``still-validation``), said. The streamed effect search compares its candidates on
    the stretches of the training record their fits did not see, as in memory (h-streamparity; it compared them on
    the record at rest and named Coulomb friction on joints 1 and 3 alone, an offset on joint 1 alone)."""
    folder, paths, _ = records
    documents = {}
    for name, options in (("memory", ()), ("streamed", ("--chunk-size", "250")), ("budget", ("--memory-budget", "1KB"))):
        out = folder / f"diagnose-{name}.json"
        assert main(["diagnose", "--joints", "3", "--model", "internal", "--data", str(paths["train"]), "--validate",
                     str(paths["still"]), "--out", str(out), *options]) == 0
        error = capsys.readouterr().err
        assert "hardly moves" in error, error
        assert "compared its candidate effects on that validation record at rest" not in error, error
        documents[name] = json.loads(out.read_text())
    assert documents["memory"]["diagnosis_path"] == "in-memory"
    memory = documents["memory"]["model_selection"]
    for name in ("streamed", "budget"):
        document = documents[name]
        assert document["diagnosis_path"] == "streamed"
        streamed = document["model_selection"]
        assert streamed["selection"] == memory["selection"] == "still-validation"
        assert streamed["chosen"] == memory["chosen"]
        assert "training record its fit did not see" in document["streaming"]["still_search"]
        assert "effect_search_on_still_validation" not in document["streaming"]
        # the same laws on the same joints (the in-memory search also refines a smoothed Coulomb law's shape and
        # tries a delay, which the streamed path does not)
        assert _laws(document) == _laws(documents["memory"]), (name, document["effects"])
        assert _laws(document) == {"coulomb": {"tau1", "tau2", "tau3"}, "offset": {"tau1", "tau3"}}


def at_rest(record, samples=500, seed=0):
    """``samples`` of ``record``'s first pose held: positions within 1e-5 rad, no velocity, its torques with noise."""
    generator = np.random.default_rng(seed)
    held = record.select(slice(0, samples))
    q = np.repeat(record.q[:1], samples, axis=0) + 1e-5 * generator.normal(size=(samples, record.q.shape[1]))
    tau = np.repeat(record.tau[:1], samples, axis=0) + 0.1 * generator.normal(size=(samples, record.tau.shape[1]))
    return dataclasses.replace(held, q=q, dq=np.zeros_like(q), ddq=np.zeros_like(q), tau=tau)


@pytest.mark.parametrize("name", ["coulomb sign", "clean"])
def test_a_diagnosis_with_a_validation_record_at_rest_confirms_on_unseen_stretches_of_training(name, monkeypatch):
    """A record at rest cannot confirm a friction law (nothing moves there): each candidate is judged on the stretches
    of the training record its fit did not see instead (every comparison made there); the truth's law is named, and
    nothing on a clean truth."""
    import estimation.diagnosis.record_fits as record_fits

    judged_on = []
    blocked = record_fits.blocked_comparison

    def spy(*args, **kwargs):
        comparison = blocked(*args, **kwargs)
        judged_on.append(comparison.held_out)
        return comparison

    monkeypatch.setattr(record_fits, "blocked_comparison", spy)
    case = next(case for case in ALONE if case.name == name)
    train, validate = corpus_records(case)
    still = at_rest(validate)
    assert still_motion(train, still)
    diagnosis = diagnose(declared_model(), train, still)
    assert matches(case.named, named_pairs(diagnosis)), named_pairs(diagnosis)
    if case.named:
        assert judged_on and all("training record" in where for where in judged_on), judged_on
    judged_on.clear()
    diagnose(declared_model(), train, validate)  # a record of another motion confirms on itself
    assert judged_on == []
