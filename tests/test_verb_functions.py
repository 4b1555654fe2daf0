"""The verbs as library calls (``oed.identify(...)``, ``oed.diagnose(...)``…) give what the command line writes and
prints: the same parameters, effects and errors (relative 1e-9), the same files, the same lines."""

from __future__ import annotations

import json
import math
import subprocess
import sys

import pytest

import oed
from dynamics.effects.linear import CoulombFriction
from dynamics.models import build_model
from dynamics.robots import load_robot
from dynamics.simulation.synthetic import simulate, true_parameters
from oed.cli import main
from oed.fourier import random_fourier

NOISE = {"tau1": 0.2, "tau2": 0.2, "tau3": 0.2}
RELATIVE = 1e-9


@pytest.fixture(scope="module")
def records(tmp_path_factory):
    """Training, validation and test records of a 3-joint PUMA with Coulomb friction on joint 2 (undeclared)."""
    robot = load_robot("puma560", joints=3)
    truth = build_model(robot, "internal", ("viscous", CoulombFriction(joints=(2,))))
    theta = true_parameters(truth, seed=0, coulomb=[6.0])
    folder = tmp_path_factory.mktemp("verbs")
    for seed, name in ((3, "train"), (4, "val"), (5, "test")):
        simulate(truth, theta, random_fourier(robot, seed=seed), noise=NOISE, seed=seed).write(folder / f"{name}.csv")
    return folder


def close(first, second, path="") -> None:
    """``first`` equals ``second``: numbers within :data:`RELATIVE`, every other value exactly; timings (keys
    ``seconds``, ``time_s``) skipped."""
    if isinstance(first, dict):
        assert isinstance(second, dict) and set(first) == set(second), path
        for key in first:
            if key not in ("seconds", "time_s"):
                close(first[key], second[key], f"{path}.{key}")
    elif isinstance(first, list):
        assert isinstance(second, list) and len(first) == len(second), path
        for index, (a, b) in enumerate(zip(first, second)):
            close(a, b, f"{path}[{index}]")
    elif isinstance(first, float) and isinstance(second, float):
        assert (math.isnan(first) and math.isnan(second)) or math.isclose(first, second, rel_tol=RELATIVE,
                                                                          abs_tol=1e-300), (path, first, second)
    else:
        assert first == second, (path, first, second)


def test_identify_from_python_gives_the_command_lines_parameters_and_errors(records, capsys):
    out = records / "cli_result.json"
    assert main(["identify", "--joints", "3", "--friction", "viscous,coulomb", "--data", str(records / "train.csv"),
                 "--validate", str(records / "val.csv"), "--out", str(out)]) == 0
    printed = capsys.readouterr().out.splitlines()
    run = oed.identify(joints=3, friction="viscous,coulomb", data=records / "train.csv",
                       validate=[str(records / "val.csv")])
    written = json.loads(out.read_text())
    document = run.to_dict()
    close(document, written)
    assert [p["name"] for p in document["parameters"]] == [p["name"] for p in written["parameters"]]
    assert printed[:-1] == run.summary() and printed[-1] == f"wrote {out}"
    run.write(records / "python_result.json")
    close(json.loads((records / "python_result.json").read_text()), written)


def test_diagnose_from_python_gives_the_command_lines_effects_and_errors(records, capsys):
    out, report = records / "cli_report.json", records / "cli_report.md"
    assert main(["diagnose", "--joints", "3", "--data", str(records / "train.csv"), "--validate",
                 str(records / "val.csv"), "--test", str(records / "test.csv"), "--out", str(out),
                 "--report", str(report)]) == 0
    printed = capsys.readouterr().out.splitlines()
    run = oed.diagnose(joints=3, data=records / "train.csv", validate=records / "val.csv",
                       test=[records / "test.csv"], report=True)
    written = json.loads(out.read_text())
    document = run.to_dict()
    close(document, written)
    assert [effect["name"] for effect in document["effects"]] == ["coulomb"]
    assert printed[:-1] == run.summary()
    run.write(records / "python_report.json", report=records / "python_report.md")
    assert (records / "python_report.md").read_text() == report.read_text().replace("cli_report", "python_report")
    assert (records / "python_report.residuals.png").exists() and (records / "python_report.validation.tau1.png").exists()


def test_predict_from_python_gives_the_command_lines_metrics(records, capsys):
    model = records / "model.json"
    oed.identify(joints=3, data=records / "train.csv", validate=records / "val.csv").write(model)
    metrics = records / "metrics.json"
    assert main(["predict", "--model", str(model), "--data", str(records / "test.csv"), "--metrics", str(metrics)]) == 0
    printed = capsys.readouterr().out.splitlines()
    run = oed.predict(model=model, data=records / "test.csv")
    close(run.to_dict(), json.loads(metrics.read_text()))
    assert printed[:-1] == run.summary()


def test_options_are_keywords_of_the_verbs_names_and_an_unknown_one_is_refused(records):
    with pytest.raises(TypeError, match="frobnicate"):
        oed.identify(data=records / "train.csv", frobnicate=True)
    with pytest.raises(ValueError, match="--rest"):
        oed.identify(data=records / "train.csv", rest="sometimes")
    with pytest.raises(ValueError, match="--validate"):
        oed.diagnose(data=records / "train.csv")


def test_the_streamed_run_has_no_figure_and_says_so(records):
    run = oed.identify(joints=3, data=records / "train.csv", validate=records / "val.csv", chunk_size=500)
    assert run.streamed and run.to_dict()["validation"] is not None
    with pytest.raises(ValueError, match="--plot"):
        run.write(records / "streamed.json", plot=records / "streamed.png")
    assert not (records / "streamed.json").exists()


def test_import_oed_imports_no_verb():
    code = "import sys, oed; print(sorted(name for name in sys.modules if name.startswith('oed.')))"
    shown = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert shown.strip() == "[]"
    assert callable(oed.design) and callable(oed.servo_fit)
