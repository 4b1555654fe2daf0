"""One answer per result (issue 34), audited verb by verb: after every verb that writes a model (``oed identify`` by
default, with ``--method ols`` and with ``--consistent``; ``oed diagnose``, by default, with ``--consistent`` and with
``--test``), on both paths (in memory, streamed by ``--chunk-size 250``, streamed by ``--memory-budget 1KB``) and on
a regular log (derivatives logged), a periodic one (a Fourier fit of averaged periods) and a jittered one:

* ``oed predict`` on the validation record reproduces the validation error the verb reported for its chosen model
  (relative 1e-6), and ``oed predict --alternative NAME`` the error reported for each alternative the file names
  (``model_file.alternatives``, ``model_selection.candidates``; ``unconstrained`` too); the runner-up's model file
  of ``oed diagnose`` the runner-up's reported error; ``--test``: the chosen model's test error;
* on the jittered log those errors are taken at the recorded samples: every row ``oed predict`` scores is a row of
  the file (its time stamp and its torques as written), and the reported error is the mean square of those rows'
  residuals;
* the top level of ``result.json`` describes the chosen model (its parameters are the model file's);
* ``oed export`` writes the chosen model, or names the consistent alternative it writes instead, or refuses a file
  without bodies (exit 2, nothing written);
* the printed summary and the report (``--report``, on the streamed path too: no figures, what the path did not
  compute) give the chosen model's validation error; the errors over the noise floor are those errors', and the
  standard deviations of identify's parameters its covariance's (the checks of ``tests/test_one_model.py``, whose
  runs on the same records are these cases': that file runs in ``make test-slow``).

Beside: ``--held-torques``, ``--decimate`` and two validation records; and, on a record whose third joint's viscous
coefficient is negative, that ``identify --consistent`` says the consistent model's warning and deviations, the
unconstrained fit's staying under its alternative entry.

Small simulated 3-joint PUMA records (a few seconds each case)."""

from __future__ import annotations

import json
import re
import xml.etree.ElementTree as ElementTree

import numpy as np
import pandas as pd
import pytest

from dynamics.models import build_model
from dynamics.robots import load_robot
from dynamics.simulation.simulator import Simulator
from dynamics.simulation.synthetic import simulate, true_parameters
from oed.cli import main
from oed.fourier import random_fourier
from tests.test_recorded_stamps import logger_faults

NOISE = {"tau1": 0.2, "tau2": 0.2, "tau3": 0.1}
EFFECTS = "viscous,coulomb,offset"
RELATIVE = 1e-6

#: the verbs, each with the paths it takes (the streamed ones refuse identify --consistent and --test)
VERBS = {
    "identify": ["identify", "--friction", EFFECTS],
    "identify --method ols": ["identify", "--friction", EFFECTS, "--method", "ols"],
    "identify --consistent": ["identify", "--friction", EFFECTS, "--consistent"],
    "diagnose": ["diagnose", "--friction", "viscous"],
    "diagnose --consistent": ["diagnose", "--friction", "viscous", "--consistent"],
    "diagnose --test": ["diagnose", "--friction", "viscous"],
}
PATHS = {"in-memory": [], "chunks": ["--chunk-size", "250"], "budget": ["--memory-budget", "1KB"]}
IN_MEMORY_ONLY = ("identify --consistent", "diagnose --test")
#: the options a record needs: the period of the periodic one
RECORD_OPTIONS = {"periodic": ["--frequency", "0.2"]}
#: ``--memory-budget`` is the defaults' own route to the streamed path, the reading and the result as with
#: ``--chunk-size``: ``make test`` takes that route on the jittered record (with the defaults); on the arm and the
#: periodic records, whose streamed path the chunks cases take, it runs in ``make test-slow``
SLOW_BUDGET_RECORDS = ("arm", "periodic")
#: on the jittered record too, the budget route with an option beside the defaults (``--method ols``,
#: ``--consistent``) runs in ``make test-slow``: ``make test`` streams each option there with ``--chunk-size``, and takes
#: the budget route with the default ``identify`` and ``diagnose``
SLOW_BUDGET_VERBS = ("identify --method ols", "diagnose --consistent")


def slow_case(verb: str, path: str, record: str) -> bool:
    """The cases ``make test-slow`` runs: the budget route on the arm and periodic records, and with an option
    (:data:`SLOW_BUDGET_VERBS`) on the jittered one; the in-memory ``diagnose`` without ``--test`` (``diagnose
    --test`` makes the same diagnosis, every check of this case on it, and scores the test record beside)."""
    return (path == "budget" and (record in SLOW_BUDGET_RECORDS or verb in SLOW_BUDGET_VERBS)) or \
        (verb == "diagnose" and path == "in-memory")


CASES = [pytest.param(verb, path, record, id=f"{record}-{verb}-{path}",
                      marks=[pytest.mark.slow] if slow_case(verb, path, record) else [])
         for record in ("arm", "periodic", "jittered") for verb in VERBS for path in PATHS
         if path == "in-memory" or verb not in IN_MEMORY_ONLY]


@pytest.fixture(scope="module")
def records(tmp_path_factory):
    """``arm``: training, validation and test motions of a 3-joint PUMA with Coulomb friction and offsets, logged
    with q, dq, ddq at 100 Hz; ``periodic``: the same with positions only, two periods of 5 s (derivatives by a
    Fourier fit, ``--frequency 0.2``); ``jittered``: the same robot's positions and torques at 200 Hz over 8 s (derivatives
    by a filter), the validation and test logs jittered (stamps moved, rows re-sent, a stall)."""
    folder = tmp_path_factory.mktemp("one_answer")
    robot = load_robot("puma560", joints=3)
    truth = build_model(robot, "internal", EFFECTS)
    theta = true_parameters(truth, seed=1, coulomb=[3.0, 2.0, 1.0], offset=[0.5, -0.3, 0.2])
    paths = {}
    for name, seed in (("train", 5), ("validate", 6), ("test", 7)):
        paths["arm", name] = folder / f"arm_{name}.csv"
        simulate(truth, theta, random_fourier(robot, seed=seed), rate_hz=100.0, periods=1, noise=NOISE,
                 seed=seed).write(paths["arm", name])
    for name, seed in (("train", 5), ("validate", 6), ("test", 7)):  # two periods, positions only
        paths["periodic", name] = folder / f"periodic_{name}.csv"
        simulate(truth, theta, random_fourier(robot, seed=seed, frequency_hz=0.2), rate_hz=100.0, periods=2,
                 noise=NOISE, seed=seed).write(paths["periodic", name])
        frame = pd.read_csv(paths["periodic", name])
        frame[[column for column in frame.columns if not column.startswith(("dq", "ddq"))]].to_csv(
            paths["periodic", name], index=False, float_format="%.10g")
    simulator = Simulator(robot, rate_hz=200.0)
    for name, seed in (("train", 1), ("validate", 2), ("test", 3)):
        frame = simulator.run(random_fourier(robot, seed, frequency_hz=0.1), duration=8.0, warmup_periods=1,
                              seed=seed).measurements.to_frame()
        frame = frame[[column for column in frame.columns if not column.startswith(("dq", "ddq"))]]
        if name != "train":
            frame = logger_faults(frame, seed)
        paths["jittered", name] = folder / f"jittered_{name}.csv"
        frame.to_csv(paths["jittered", name], index=False, float_format="%.10g")
    return folder, paths


def relative(measured: dict[str, float], reported: dict[str, float]) -> float:
    assert set(measured) == set(reported), (measured, reported)
    return max(abs(measured[channel] / reported[channel] - 1) for channel in reported)


def predicted(folder, model, data, *options: str) -> tuple[dict, pd.DataFrame]:
    """``oed predict`` of ``model`` on ``data``: its metrics and its predictions CSV."""
    metrics, out = folder / "metrics.json", folder / "predictions.csv"
    assert main(["predict", "--model", str(model), "--data", str(data), "--metrics", str(metrics), "--out", str(out),
                 *options]) == 0
    return json.loads(metrics.read_text()), pd.read_csv(out)


def check_recorded_rows(predictions: pd.DataFrame, path, metrics: dict) -> None:
    """Every row scored is a row of the file as written (its stamp, its torques), and the error is those rows'."""
    raw = pd.read_csv(path)
    channels = list(metrics["mse"])
    rows = raw.set_index("t")
    assert predictions.t.isin(rows.index).all(), "a scored time stamp is not one of the file's"
    written = rows.loc[predictions.t, channels].to_numpy()
    measured = predictions[[f"{channel}_measured" for channel in channels]].to_numpy()
    assert np.array_equal(written, measured), "a scored torque is not the file's"
    mse = np.mean(predictions[[f"{channel}_residual" for channel in channels]].to_numpy() ** 2, axis=0)
    assert dict(zip(channels, mse)) == pytest.approx(metrics["mse"], rel=1e-9)


def reported_models(document: dict) -> tuple[str, dict[str, float], dict[str, dict[str, float]]]:
    """The chosen model's name and reported validation error, and each alternative's reported validation error by
    name (from the model file's alternatives and the comparison of candidates, which must agree)."""
    if "chosen" in document["validation"]:  # report.json
        chosen, reported = document["validation"]["chosen"]["name"], document["validation"]["chosen"]["mse"]
    else:
        chosen, reported = document["chosen"], document["validation"]["mse"]
    model_file = document["model_file"]
    alternatives = {name: entry["validation_mse"] for name, entry in model_file["alternatives"].items()}
    selection = document.get("model_selection")
    if selection is not None:
        assert selection["chosen"] == chosen
        for candidate in selection["candidates"]:
            if not candidate["available"]:
                continue
            expected = reported if candidate["name"] == chosen else alternatives[candidate["name"]]
            assert candidate["validation_mse"] == expected, candidate["name"]
    return chosen, reported, alternatives


def check_errors_over_floor(document: dict, diagnosis: bool) -> None:
    """The validation errors over the noise floor a result reports are those errors' (on a jittered log too)."""
    floor = (document.get("noise_floor") or {}).get("mse")
    for errors in ([document["validation"]["after"], document["validation"]["chosen"]] if diagnosis
                   else [document["validation"]]):
        if floor and errors.get("mse_over_floor"):
            assert errors["mse_over_floor"] == pytest.approx({c: v / floor[c] for c, v in errors["mse"].items()},
                                                             rel=1e-12)


@pytest.mark.parametrize(("verb", "path", "record"), CASES)
def test_every_model_a_verb_reports_is_the_one_predict_measures(records, verb, path, record, capsys):
    folder, paths = records
    out = folder / f"{record}_{verb.replace(' ', '_').replace('-', '')}_{path}.json"
    test = ["--test", str(paths[record, "test"])] if verb.endswith("--test") else []
    streamed = path != "in-memory"
    report = out.with_suffix(".html")  # streamed (no figures: cheap), and the diagnosis with its test record
    report_option = ["--report", str(report)] if streamed or verb.endswith("--test") else []
    assert main([*VERBS[verb], *PATHS[path], *RECORD_OPTIONS.get(record, []), "--joints", "3", "--data", str(paths[record, "train"]), "--validate",
                 str(paths[record, "validate"]), *test, "--out", str(out), *report_option]) == 0
    printed = capsys.readouterr().out
    document = json.loads(out.read_text())
    assert (document.get("diagnosis_path") or document.get("identification_path")) == \
        ("streamed" if streamed else "in-memory")
    chosen, reported, alternatives = reported_models(document)
    model_file = document["model_file"]
    assert model_file["chosen"] == chosen and model_file["reported"]["validation_mse"] == reported
    if verb.endswith("--consistent"):
        assert chosen == "consistent"
    elif verb.endswith("ols"):
        assert chosen == "ols"
    # the summary and the report give the chosen model's validation error (the diagnosis's line naming its model)
    assert "  ".join(f"{channel} {value:.4g}" for channel, value in reported.items()) in printed, printed
    assert re.search(rf"validation MSE.*\({chosen}\)" if verb.startswith("diagnose") else "validation MSE",
                     printed), printed
    check_errors_over_floor(document, verb.startswith("diagnose"))
    if report_option:
        text = report.read_text()
        assert ("<img" not in text and "Not computed on this path" in text) if streamed else "<img" in text
        if verb.startswith("diagnose"):
            assert f"Model: {chosen}" in text
            assert all(f">{value:.5g}</td>" in text for value in reported.values()), reported
            if test:
                assert all(f">{value:.5g}</td>" in text for value in document["test"]["chosen"]["mse"].values())
        else:
            assert all(f">{value:.4g}</td>" in text for value in reported.values()), reported

    # the chosen model: predict on the validation record reproduces its reported error, at the recorded samples
    metrics, predictions = predicted(folder, out, paths[record, "validate"])
    assert metrics["model"] == chosen and metrics["reported_validation_mse"] == reported
    assert relative(metrics["mse"], reported) < RELATIVE, (metrics["mse"], reported)
    if record == "jittered":
        check_recorded_rows(predictions, paths[record, "validate"], metrics)

    # every alternative the file names, and the unconstrained fit behind the choice
    for name, expected in alternatives.items():
        measured, _ = predicted(folder, out, paths[record, "validate"], "--alternative", name)
        assert measured["model"] == name
        assert relative(measured["mse"], expected) < RELATIVE, (name, measured["mse"], expected)
    if "consistent" in alternatives:  # --consistent is --alternative consistent
        measured, _ = predicted(folder, out, paths[record, "validate"], "--consistent")
        assert relative(measured["mse"], alternatives["consistent"]) < RELATIVE
    unconstrained = chosen if chosen != "consistent" else model_file["method"]
    measured, _ = predicted(folder, out, paths[record, "validate"], "--alternative", "unconstrained")
    expected = reported if unconstrained == chosen else alternatives[unconstrained]
    assert relative(measured["mse"], expected) < RELATIVE, ("unconstrained", measured["mse"], expected)

    if verb.startswith("identify"):  # the top level is the chosen model's: its parameters are the model file's
        names = model_file["base"]["names"]
        values = dict(zip(names, model_file["theta"]))
        assert {p["name"]: p["value"] for p in document["parameters"]} == pytest.approx(values, rel=1e-12)
        assert document["model_parameters"]["values"] == pytest.approx(
            [values[name] for name in document["model_parameters"]["names"]], rel=1e-12)
        assert document["validation"]["model"] == document["train"]["model"] == chosen
        assert document.get("shape_std", {}) == (model_file.get("shape_std") or {})
        if not streamed:  # the standard deviations are the chosen model's covariance's
            assert [p["std"] for p in document["parameters"]] == pytest.approx(np.sqrt(np.diag(model_file["cov"])),
                                                                               rel=1e-12)
    else:
        # the runner-up's model file: its reported validation error is what predict measures with it
        runner_up = document.get("runner_up")
        if runner_up is not None and runner_up["validation"]["mse"] is not None:
            rival = folder / "runner_up.json"
            rival.write_text(json.dumps({"model_file": runner_up["model_file"]}))
            measured, predictions = predicted(folder, rival, paths[record, "validate"])
            assert relative(measured["mse"], runner_up["validation"]["mse"]) < RELATIVE, \
                (measured["mse"], runner_up["validation"]["mse"])
            if record == "jittered":
                check_recorded_rows(predictions, paths[record, "validate"], measured)
        if test:  # the chosen model's error on the test record, which no choice saw
            measured, predictions = predicted(folder, out, paths[record, "test"])
            assert document["test"]["chosen"]["name"] == chosen
            assert relative(measured["mse"], document["test"]["chosen"]["mse"]) < RELATIVE
            if record == "jittered":
                check_recorded_rows(predictions, paths[record, "test"], measured)

    # oed export: the chosen model when it has bodies, else the consistent alternative named, else a refusal
    urdf = folder / "exported.urdf"
    urdf.unlink(missing_ok=True)
    for name in alternatives:  # an unconstrained alternative has no bodies to write
        if name != "consistent":
            assert main(["export", "--model", str(out), "--urdf", str(urdf), "--alternative", name]) == 2
            assert "base parameters only" in capsys.readouterr().err and not urdf.exists()
    code = main(["export", "--model", str(out), "--urdf", str(urdf)])
    error = capsys.readouterr().err
    if chosen == "consistent":
        assert code == 0 and "instead" not in error
    elif "consistent" in alternatives:
        assert code == 0 and f"the chosen model ({chosen})" in error and "'consistent' instead" in error
    else:
        assert code == 2 and "base parameters only" in error and not urdf.exists()
        return
    masses = [float(element.get("value")) for element in ElementTree.parse(urdf).findall("./link/inertial/mass")]
    assert masses[-3:] == pytest.approx([link["mass"] for link in document["links"]], rel=1e-9)


@pytest.fixture(scope="module")
def negative_friction(tmp_path_factory):
    """A 3-joint PUMA whose third joint's viscous coefficient is negative (a sign a consistent fit cannot give:
    the unconstrained fit warns of it) and whose Coulomb law is smoothed by tanh (a shaped law: its smoothing
    velocities estimated by the unconstrained fit, held by the consistent one)."""
    from dynamics.effects.linear import CoulombFriction

    folder = tmp_path_factory.mktemp("negative_friction")
    robot = load_robot("puma560", joints=3)
    truth = build_model(robot, "internal", ("viscous", CoulombFriction(smoothing=0.04), "offset"))
    theta = true_parameters(truth, seed=1, viscous=[5.0, 3.0, -1.5], coulomb=[3.0, 2.0, 1.0],
                            offset=[0.5, -0.3, 0.2])
    paths = {}
    for name, seed in (("train", 5), ("validate", 6)):
        paths[name] = folder / f"{name}.csv"
        simulate(truth, theta, random_fourier(robot, seed=seed), rate_hz=100.0, periods=1, noise=NOISE,
                 seed=seed).write(paths[name])
    return folder, paths


def test_the_top_level_warnings_and_shape_deviations_are_the_chosen_model_s(negative_friction, capsys):
    """``identify --consistent``: the unconstrained fit's warning (a negative viscous coefficient) and its shapes'
    standard deviations stay under its alternative entry; result.json's top level, the printed summary, the
    warnings said and the report describe the consistent model (the coefficient held at zero, which says the model
    lacks something; its shapes held, not estimated)."""
    folder, paths = negative_friction
    out, report = folder / "result.json", folder / "report.html"
    assert main(["identify", "--joints", "3", "--friction", "viscous,coulomb:tanh,offset", "--consistent", "--data",
                 str(paths["train"]), "--validate", str(paths["validate"]), "--out", str(out), "--report",
                 str(report)]) == 0
    captured = capsys.readouterr()
    document = json.loads(out.read_text())
    model_file = document["model_file"]
    assert document["chosen"] == model_file["chosen"] == "consistent"
    base = model_file["method"]
    unconstrained = [text for text in model_file["alternatives"][base]["warnings"] if text.startswith("fv3 = -1.")]
    assert len(unconstrained) == 1  # the unconstrained fit's own, under its name
    assert model_file["alternatives"][base]["shape_std"]["vc3"] > 0
    # the top level: the consistent model's
    held = [text for text in document["warnings"] if text.startswith("fv3 = ")]
    assert len(held) == 1 and "held >= 0 by the physically consistent fit" in held[0], document["warnings"]
    assert f"unconstrained {base} fit puts it at -1." in held[0] and unconstrained[0] not in document["warnings"]
    assert document["shape"] == model_file["shape"] and set(document["shape_std"]) == {"vc1", "vc2", "vc3"}
    assert all(value is None for value in document["shape_std"].values()) and model_file["shape_std"] == {}
    assert document["model_parameters"]["shape_std"] == document["shape_std"]
    values = {p["name"]: p["value"] for p in document["parameters"]}
    assert values["fv3"] > -1e-6
    assert values == pytest.approx(dict(zip(model_file["base"]["names"], model_file["theta"])), rel=1e-12)
    # said, printed and reported: the consistent model's warning, its shapes without a deviation
    assert held[0] in captured.err and unconstrained[0] not in captured.err
    shape_lines = [line for line in captured.out.splitlines() if "(shape of coulomb:tanh" in line]
    assert len(shape_lines) == 3 and not any("±" in line for line in shape_lines), shape_lines
    text = report.read_text()
    section = text[text.index("<h2>Warnings</h2>"):text.index("<h2>Choices made</h2>")]
    assert "held &gt;= 0 by the physically consistent fit" in section and "is negative" not in section
    assert text.count("n/a (held)") == 3
    # and predict measures the error reported
    metrics = folder / "metrics.json"
    assert main(["predict", "--model", str(out), "--data", str(paths["validate"]), "--metrics", str(metrics)]) == 0
    assert relative(json.loads(metrics.read_text())["mse"], document["validation"]["mse"]) < RELATIVE


def test_an_unconstrained_answer_keeps_its_own_warning(negative_friction, capsys):
    """The same records with ``--method wls``: the warning is the chosen model's, at the top level and said."""
    folder, paths = negative_friction
    out = folder / "wls.json"
    assert main(["identify", "--joints", "3", "--friction", "viscous,coulomb,offset", "--method", "wls", "--data",
                 str(paths["train"]), "--validate", str(paths["validate"]), "--out", str(out)]) == 0
    captured = capsys.readouterr()
    document = json.loads(out.read_text())
    assert document["chosen"] == "wls"
    assert any(text.startswith("fv3 = -") for text in document["warnings"]) and "fv3 = -" in captured.err


#: derivative options and several validation files, each on the path it changes
OPTION_CASES = {
    "periodic identify streamed --held-torques": ("periodic", ["identify", "--friction", EFFECTS, "--chunk-size", "250",
                                                               "--held-torques"]),
    "periodic diagnose streamed --held-torques": ("periodic", ["diagnose", "--friction", "viscous", "--chunk-size", "250",
                                                               "--held-torques"]),
    "arm identify streamed --decimate 2": ("arm", ["identify", "--friction", EFFECTS, "--chunk-size", "250",
                                                   "--decimate", "2"]),
    "jittered identify --held-torques": ("jittered", ["identify", "--friction", EFFECTS, "--held-torques"]),
    "jittered identify streamed --held-torques": ("jittered", ["identify", "--friction", EFFECTS, "--chunk-size",
                                                               "250", "--held-torques"]),
    "jittered diagnose streamed --held-torques": ("jittered", ["diagnose", "--friction", "viscous", "--chunk-size",
                                                               "250", "--held-torques"]),
}


#: the costliest option cases (a jittered log read in blocks with --held-torques: 13-16 s each, quiet), run by
#: ``make test-slow``; the default suite keeps the same options streamed on the periodic record, the jittered record
#: in memory with --held-torques, and the jittered record streamed without it (``test_every_model_a_verb_reports...``)
SLOW_OPTION_CASES = ("jittered identify streamed --held-torques", "jittered diagnose streamed --held-torques")


@pytest.mark.parametrize("case", [pytest.param(case, marks=pytest.mark.slow) if case in SLOW_OPTION_CASES else case
                                  for case in OPTION_CASES])
def test_derivative_options_and_two_validation_records_keep_one_answer(records, case, capsys):
    """With ``--held-torques`` or ``--decimate`` and two validation records (``--validate`` twice), the validation
    error reported for the chosen model is what ``oed predict`` measures on both records (given as segments)."""
    folder, paths = records
    record, options = OPTION_CASES[case]
    out = folder / f"options_{case.replace(' ', '_').replace('-', '')}.json"
    validation = [paths[record, "validate"], paths[record, "test"]]
    assert main([*options, *RECORD_OPTIONS.get(record, []), "--joints", "3", "--data", str(paths[record, "train"]),
                 *(argument for path in validation for argument in ("--validate", str(path))), "--out", str(out)]) == 0
    capsys.readouterr()
    document = json.loads(out.read_text())
    chosen, reported, _ = reported_models(document)
    assert reported is not None and document["model_file"]["reported"]["validation_mse"] == reported
    metrics, _ = predicted(folder, out, validation[0], "--data", str(validation[1]))
    assert metrics["model"] == chosen and relative(metrics["mse"], reported) < RELATIVE, (metrics["mse"], reported)
