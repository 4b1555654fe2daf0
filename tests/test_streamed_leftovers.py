"""The streamed path (``--chunk-size``, or records past ``--memory-budget``) gives the in-memory path's answers
(issue 34: "the result must not depend on ... the free memory of the machine"): the leftovers of h-streamdiag.

Simulated 3-joint PUMA records at 100 Hz, each read in memory and in blocks of 250 rows:

* the validation record's samples as recorded are counted (the floor's F test, the summary), not the uniform grid's
  a jittered log is resampled onto;
* whether a validation record of another sampling rate repeats the training motion is tested at common instants, as
  in memory (:func:`estimation.streaming.model_selection.streamed_repeated_motion`).
"""

from __future__ import annotations

import json
import warnings

import numpy as np
import pandas as pd
import pytest

from dynamics.models import build_model
from dynamics.robots import load_robot
from dynamics.simulation.synthetic import simulate, true_parameters
from estimation.data.records import read_measurements
from estimation.identification.repeated_motion import repeated_motion
from estimation.streaming.model_selection import streamed_repeated_motion
from oed import diagnose
from oed.fourier import random_fourier

NOISE = {"tau1": 0.2, "tau2": 0.2, "tau3": 0.1}
OFFSETS = [0.0, -np.pi / 2, 0.3]  # the joint positions where the encoders read zero (tests/test_joint_offsets.py)


def jittered(source, target, seed):
    """``source`` with every stamp moved by up to ±30 % of a step (the readings those of the true instant)."""
    frame = pd.read_csv(source)
    step = float(np.median(np.diff(frame.t)))
    frame["t"] = frame.t + np.random.default_rng(seed).uniform(-0.3, 0.3, len(frame)) * step
    frame.to_csv(target, index=False, float_format="%.10g")
    return target


@pytest.fixture(scope="module")
def records(tmp_path_factory):
    folder = tmp_path_factory.mktemp("streamed_leftovers")
    robot = load_robot("puma560", joints=3)
    truth = build_model(robot, "internal", "viscous,coulomb,offset")
    theta = true_parameters(truth, seed=1, coulomb=[3.0, 2.0, 1.0], offset=[0.5, -0.3, 0.2])
    paths = {}
    for name, seed, noise_seed in (("train", 5, 5), ("repeat", 5, 9), ("other", 7, 7)):
        data = simulate(truth, theta, random_fourier(robot, seed=seed), rate_hz=100.0, periods=1, noise=NOISE,
                        seed=noise_seed)
        paths[name] = folder / f"{name}.csv"
        data.write(paths[name])
    paths["jittered_repeat"] = jittered(paths["repeat"], folder / "jittered_repeat.csv", 2)
    paths["jittered_other"] = jittered(paths["other"], folder / "jittered_other.csv", 3)
    return truth, paths


@pytest.mark.parametrize("validation", ["jittered_repeat", "jittered_other", "repeat"])
def test_repeated_motion_of_records_at_other_rates_as_in_memory(records, validation):
    """A jittered validation log is resampled onto a grid of another step than the training record's: both paths
    compare the positions at common instants (at the training record's times from its start), so the repeat of the
    training motion is found streamed too (before: compared sample by sample, the grids drifting apart)."""
    model, paths = records
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the loader's findings on the jittered log
        train = read_measurements(paths["train"], model=model)
        other = read_measurements(paths[validation], model=model)
        memory = repeated_motion(train, other)
        streamed = streamed_repeated_motion(model, [paths["train"]], [paths[validation]], chunk_size=250)
    if validation.startswith("jittered"):
        assert other.q.shape[0] != train.q.shape[0]  # another grid
    assert streamed == pytest.approx(memory, rel=1e-9)
    assert (streamed < 0.05) == validation.endswith("repeat")


@pytest.mark.parametrize("validation", ["jittered_other", "jittered_repeat"])
def test_the_streamed_diagnosis_counts_the_recorded_validation_samples(records, validation):
    """The validation errors of a jittered log are measured at its recorded samples on both paths; the streamed
    diagnosis now counts those samples too (the floor's F test and the summary), not the 495 of the grid."""
    _, paths = records
    runs = {name: diagnose(joints=3, friction="viscous", data=paths["train"], validate=paths[validation],
                           max_effects=2, **options)
            for name, options in (("memory", {}), ("streamed", {"chunk_size": 250}))}
    memory, streamed = (runs[name].to_dict() for name in ("memory", "streamed"))
    assert streamed["diagnosis_path"] == "streamed"
    rows = len(pd.read_csv(paths[validation]))
    grid = streamed["streaming"]["validation_files"][0]["samples"]
    assert grid != rows  # resampled onto another count of samples
    line = next(line for line in runs["streamed"].summary() if "streamed diagnosis of" in line)
    assert f", {rows} validation samples" in line, line
    for which in ("before", "after"):
        for channel, entry in memory["floor_comparison"][which].items():
            other = streamed["floor_comparison"][which][channel]
            assert other["p_value"] == pytest.approx(entry["p_value"], rel=1e-6, abs=1e-300), (which, channel)
            assert other["ratio"] == pytest.approx(entry["ratio"], rel=1e-9), (which, channel)
    assert streamed["floor_statements"] == {channel: text.split(";")[0]
                                            for channel, text in memory["floor_statements"].items()}
    assert json.dumps(streamed["model_selection"]["selection"]) == json.dumps(memory["model_selection"]["selection"])


@pytest.fixture(scope="module")
def zeroed(tmp_path_factory):
    """A 3-joint PUMA's records as logged by encoders zeroed away from the description's (joint 2 a quarter turn
    off, joint 3 by 0.3 rad: ``tests/test_joint_offsets.py``'s), and the offsets file that puts them right."""
    robot = load_robot("puma560", joints=3)
    model = build_model(robot, "internal", "viscous")
    theta = true_parameters(model, seed=4)
    folder = tmp_path_factory.mktemp("zeroed")
    for name, seed in (("train", 5), ("val", 6)):
        record = simulate(model, theta, random_fourier(robot, seed), noise=NOISE, seed=seed + 10)
        record.write(folder / f"{name}.csv")
        frame = pd.read_csv(folder / f"{name}.csv")
        for j, offset in enumerate(OFFSETS):
            frame[f"q{j + 1}"] -= offset
        frame.to_csv(folder / f"{name}_zeroed.csv", index=False)
    (folder / "offsets.json").write_text(json.dumps({"offsets": {"joint2": OFFSETS[1], "3": OFFSETS[2]}}))
    return folder


def _zero_warnings(run):
    return [text for text in run.warnings if "offset from the robot description's zeros" in text]


@pytest.mark.parametrize("validate", [True, False], ids=["validation-record", "halves"])
def test_the_streamed_identify_checks_the_joint_zeros_as_in_memory(zeroed, validate):
    """The joint-zero check on a log read in blocks keeps the samples the in-memory check keeps: the same warning,
    the same offsets; nothing on the correctly zeroed log."""
    from oed import identify

    held = {"validate": zeroed / "val_zeroed.csv"} if validate else {}
    runs = {name: identify(joints=3, friction="viscous", data=zeroed / "train_zeroed.csv", cutoff=20, **held,
                           **options)
            for name, options in (("memory", {}), ("streamed", {"chunk_size": 250}))}
    assert runs["streamed"].to_dict()["streaming"] is not None
    memory, streamed = _zero_warnings(runs["memory"]), _zero_warnings(runs["streamed"])
    assert len(memory) == 1 and "joint 2" in memory[0]
    assert streamed == memory
    clean = identify(joints=3, friction="viscous", data=zeroed / "train.csv", cutoff=20, chunk_size=250,
                     **({"validate": zeroed / "val.csv"} if validate else {}))
    assert _zero_warnings(clean) == []


def test_the_streamed_diagnosis_checks_the_joint_zeros_as_in_memory(zeroed):
    """``oed diagnose`` streamed says the joint-zero warning of the in-memory run (in its warnings and in
    ``warnings.after``), and the notes it says beside it: the channels the diagnosis made worse."""
    runs = {name: diagnose(joints=3, friction="viscous", data=zeroed / "train_zeroed.csv",
                           validate=zeroed / "val_zeroed.csv", cutoff=20, **options)
            for name, options in (("memory", {}), ("streamed", {"chunk_size": 250}))}
    memory, streamed = _zero_warnings(runs["memory"]), _zero_warnings(runs["streamed"])
    assert len(memory) == 1 and "joint 2" in memory[0]
    assert streamed == memory
    documents = {name: run.to_dict() for name, run in runs.items()}
    assert documents["streamed"]["diagnosis_path"] == "streamed"
    assert documents["streamed"]["warnings"]["after"] == documents["memory"]["warnings"]["after"]


def test_the_streamed_identify_says_a_repeat_as_in_memory(records):
    """A validation record that repeats the training motion is said on both paths, with the same words."""
    from oed import identify

    _, paths = records
    runs = {name: identify(joints=3, friction="viscous", data=paths["train"], validate=paths["repeat"], **options)
            for name, options in (("memory", {}), ("streamed", {"chunk_size": 250}))}
    said = {name: [text for text in run.warnings if "repeats the training motion" in text] for name, run in runs.items()}
    assert len(said["memory"]) == 1 and said["streamed"] == said["memory"]


#: the two streamed routes: blocks asked for, and the record past the memory budget
ROUTES = {"chunk": ["--chunk-size", "250"], "budget": ["--memory-budget", "1KB"]}


#: ``identify`` runs in ``make test-slow``: ``make test`` streams ``oed identify`` with ``--transmission`` and
#: ``--joint-offsets`` on both routes (``--chunk-size`` and past ``--memory-budget``) against the in-memory estimate in
#: tests/test_streamed_motor_side.py (``test_identify_streamed_with_transmission_and_joint_offsets``), and keeps
#: ``diagnose`` here (the streamed diagnosis's joint-side copies with ``--joint-offsets``, tested nowhere else) on the
#: ``--chunk-size`` route; past ``--memory-budget`` it runs in ``make test-slow`` (the same streamed diagnosis once
#: the route is decided: the budget route itself stays in ``make test`` in tests/test_one_answer_audit.py's
#: ``jittered-diagnose-budget`` and tests/test_memory_path.py's budget cases)
@pytest.mark.parametrize(("verb", "route"), [pytest.param("identify", "chunk", marks=pytest.mark.slow),
                                             pytest.param("identify", "budget", marks=pytest.mark.slow),
                                             ("diagnose", "chunk"),
                                             pytest.param("diagnose", "budget", marks=pytest.mark.slow)])
def test_joint_offsets_and_transmission_streamed(zeroed, verb, route):
    """``--joint-offsets`` and ``--transmission`` on the streamed path (``--chunk-size``, or past ``--memory-budget``):
    read through joint-side copies (:mod:`oed.workflows.joint_side`; was: exit 2 with ``--chunk-size``, in memory past
    the budget). The records logged in other zeros with ``--joint-offsets`` give what the same path gives on the
    correctly zeroed records (``oed identify``: also the in-memory estimate; the streamed diagnosis's own search
    differs from the in-memory one, benchmarks/README.md), the zeros in the model file."""
    from oed.cli import main

    (zeroed / "transmission.json").write_text(json.dumps({"ratios": [1.0, 1.0, 1.0]}))
    common = [verb, "--joints", "3", "--friction", "viscous", "--cutoff", "20", "--quiet"]
    given = ["--data", str(zeroed / "train_zeroed.csv"), "--validate", str(zeroed / "val_zeroed.csv")]
    right = ["--data", str(zeroed / "train.csv"), "--validate", str(zeroed / "val.csv")]

    def run(name, *options):
        out = zeroed / f"{verb}_{name}.json"
        assert main([*common, *options, "--out", str(out)]) == 0
        return json.loads(out.read_text())

    extra = ROUTES[route]
    reference = run(f"reference_{route}", *right, *extra)
    shifted = run(f"offsets_{route}", *given, "--joint-offsets", str(zeroed / "offsets.json"), *extra)
    geared = run(f"transmission_{route}", *right, "--transmission", str(zeroed / "transmission.json"), *extra)
    for document in (reference, shifted, geared):
        assert document.get("identification_path", document.get("diagnosis_path")) == "streamed"
    assert shifted["model_file"]["joint_offsets"] == pytest.approx(OFFSETS)
    for document in (shifted, geared):
        np.testing.assert_allclose(document["model_file"]["theta"], reference["model_file"]["theta"], rtol=1e-6,
                                   atol=1e-8)
    assert geared["model_file"]["transmission"]["matrix"] == np.eye(3).tolist()
    if verb == "identify":
        memory = run("offsets_memory", *given, "--joint-offsets", str(zeroed / "offsets.json"))
        np.testing.assert_allclose(shifted["model_file"]["theta"], memory["model_file"]["theta"], rtol=1e-6, atol=1e-8)
