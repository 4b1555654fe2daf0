"""Output files of the verbs: all or none on failure, readable permissions, clear messages."""

from __future__ import annotations

import os
import re
import stat

import numpy as np
import pytest

from dynamics.models import build_model
from dynamics.robots import load_robot
from oed.cli import main
from dynamics.runtime.output_files import OutputFiles, atomic_output
from oed.fourier import FourierTrajectory
from dynamics.simulation.synthetic import simulate, true_parameters


from oed.fourier import random_fourier


@pytest.fixture
def blocker(tmp_path):
    """A plain file: any output path under it cannot be created."""
    path = tmp_path / "a_file"
    path.write_text("not a folder")
    return path


def _listing(folder):
    return sorted(path.name for path in folder.iterdir())


@pytest.fixture(scope="module")
def internal_data(tmp_path_factory):
    robot = load_robot("puma560", joints=3)
    model = build_model(robot, "internal", "viscous")
    theta = true_parameters(model, seed=2)
    folder = tmp_path_factory.mktemp("outputs")
    noise = {"tau1": 0.5, "tau2": 0.5, "tau3": 0.2}
    simulate(model, theta, random_fourier(robot, 3), noise=noise, seed=11).write(folder / "train.csv")
    simulate(model, theta, random_fourier(robot, 4), noise=noise, seed=12).write(folder / "val.csv")
    return folder


def test_output_files_get_the_umask_permissions_not_0600(tmp_path):
    old = os.umask(0o022)
    try:
        with atomic_output(tmp_path / "a.json") as stream:
            stream.write("{}")
    finally:
        os.umask(old)
    assert stat.S_IMODE((tmp_path / "a.json").stat().st_mode) == 0o644


def test_output_files_all_or_none(tmp_path, blocker):
    with pytest.raises(OSError, match="a_file"):
        with OutputFiles() as outputs:
            with outputs.open(tmp_path / "first.json") as stream:
                stream.write("{}")
            outputs.stage(blocker / "second.csv")
    assert _listing(tmp_path) == ["a_file"]


def test_output_into_a_folder_path_is_named(tmp_path):
    with pytest.raises(IsADirectoryError, match="is a folder"):
        with atomic_output(tmp_path) as stream:
            stream.write("x")


def test_design_with_an_unwritable_csv_leaves_no_json(tmp_path, blocker, capsys):
    out = tmp_path / "traj.json"
    code = main(["design", "--joints", "3", "--model", "internal", "--starts", "1", "--quiet",
                 "--out", str(out), "--csv", str(blocker / "traj.csv")])
    assert code == 2
    assert "a_file" in capsys.readouterr().err
    assert _listing(tmp_path) == ["a_file"]


def test_design_rejects_an_unknown_figure_format_before_solving(tmp_path, capsys):
    code = main(["design", "--joints", "3", "--model", "internal", "--quiet",
                 "--out", str(tmp_path / "traj.json"), "--plot", str(tmp_path / "traj.xyz")])
    assert code == 2
    assert "unknown format 'xyz'" in capsys.readouterr().err
    assert _listing(tmp_path) == []


def test_identify_with_an_unwritable_figure_leaves_no_json(internal_data, tmp_path, blocker, capsys):
    out = tmp_path / "result.json"
    code = main(["identify", "--joints", "3", "--model", "internal", "--data", str(internal_data / "train.csv"),
                 "--out", str(out), "--plot", str(blocker / "fig.png")])
    assert code == 2
    assert "a_file" in capsys.readouterr().err
    assert _listing(tmp_path) == ["a_file"]


def test_diagnose_with_an_unwritable_report_leaves_no_json(internal_data, tmp_path, blocker, capsys):
    code = main(["diagnose", "--joints", "3", "--model", "internal", "--data", str(internal_data / "train.csv"),
                 "--validate", str(internal_data / "val.csv"), "--out", str(tmp_path / "report.json"),
                 "--report", str(blocker / "report.md")])
    assert code == 2
    assert "a_file" in capsys.readouterr().err
    assert _listing(tmp_path) == ["a_file"]


def test_simulate_with_an_unwritable_truth_file_leaves_no_data(tmp_path, blocker, capsys):
    trajectory = tmp_path / "traj.json"
    FourierTrajectory(1.0, np.zeros(3), np.full((3, 2), 0.05), np.zeros((3, 2))).save(trajectory)
    code = main(["simulate", "--joints", "3", "--trajectory", str(trajectory), "--out", str(tmp_path / "data.csv"),
                 "--truth", str(blocker / "truth.json")])
    assert code == 2
    assert "a_file" in capsys.readouterr().err
    assert _listing(tmp_path) == ["a_file", "traj.json"]


def test_aprbs_with_an_unwritable_figure_leaves_no_csv(tmp_path, blocker, capsys):
    code = main(["aprbs", "--joints", "2", "--duration", "4", "--candidates", "2", "--out", str(tmp_path / "u.csv"),
                 "--figure", str(blocker / "u.png")])
    assert code == 2
    assert "a_file" in capsys.readouterr().err
    assert _listing(tmp_path) == ["a_file"]


@pytest.mark.parametrize(
    "arguments,message",
    [
        (["model", "--urdf", "{folder}"], "URDF file {folder} is a folder"),
        (["identify", "--joints", "3", "--data", "{folder}.csv", "--out", "{folder}/r.json"], "data file {folder}.csv is a folder"),
        (["servo-fit", "--data", "{folder}", "--out", "{folder}/f.json"], "input file '{folder}' is a folder"),
    ],
)
def test_an_input_path_that_is_a_folder_is_called_one(tmp_path, capsys, arguments, message):
    """It was reported as 'not found'."""
    folder = tmp_path / "inputs"
    folder.mkdir()
    (tmp_path / "inputs.csv").mkdir()
    assert main([argument.format(folder=folder) for argument in arguments]) == 2
    assert message.format(folder=folder) in capsys.readouterr().err


def test_json_documents_are_strict_json_with_null_for_non_finite_numbers():
    import json

    from dynamics.runtime.output_files import json_text

    text = json_text({"a": float("nan"), "b": [1.0, float("inf"), {"c": -float("inf")}], "d": (2, "x")})
    assert "NaN" not in text and "Infinity" not in text
    assert json.loads(text) == {"a": None, "b": [1.0, None, {"c": None}], "d": [2, "x"]}


def test_a_figure_path_without_suffix_is_written_as_png(tmp_path):
    figure, data = tmp_path / "aprbs_figure", tmp_path / "u.csv"
    assert main(["aprbs", "--joints", "2", "--duration", "4", "--candidates", "2", "--out", str(data),
                 "--figure", str(figure)]) == 0
    assert figure.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert _listing(tmp_path) == ["aprbs_figure", "u.csv"]


def test_a_failed_run_removes_the_folders_it_made_and_names_the_target(tmp_path, blocker):
    with pytest.raises(OSError, match="a_file"):
        with OutputFiles() as outputs:
            with outputs.open(tmp_path / "new" / "deeper" / "first.json") as stream:
                stream.write("{}")
            outputs.stage(blocker / "second.csv")
    assert _listing(tmp_path) == ["a_file"]
    (tmp_path / "taken").mkdir()
    (tmp_path / "taken" / "inside").write_text("x")
    with pytest.raises(OSError, match=r"cannot write .*taken"):
        with OutputFiles() as outputs:
            staged = outputs.stage(tmp_path / "taken.json")
            staged.write_text("{}")
            outputs._staged[-1] = (staged, tmp_path / "taken")  # the target became a non-empty folder meanwhile
    assert _listing(tmp_path) == ["a_file", "taken"]
    with pytest.raises(ValueError, match="written twice in one run"):
        with OutputFiles() as outputs:
            outputs.stage(tmp_path / "one.json")
            outputs.stage(tmp_path / "." / "one.json")
    assert _listing(tmp_path) == ["a_file", "taken"]


@pytest.mark.parametrize(
    "arguments,message",
    [
        (["identify", "--joints", "3", "--data", "{d}/train.csv", "--out", "{d}/train.csv"],
         "--out .*train.csv is the input file of --data"),
        (["identify", "--joints", "3", "--data", "{d}/train.csv", "--out", "{d}/r.png", "--plot", "{d}/r.png"],
         "--out and --plot are the same file"),
        (["diagnose", "--joints", "3", "--data", "{d}/train.csv", "--validate", "{d}/val.csv", "--out", "{d}/val.csv"],
         "--out .*val.csv is the input file of --validate"),
        (["diagnose", "--joints", "3", "--data", "{d}/train.csv", "--validate", "{d}/val.csv",
          "--out", "{d}/r.residuals.png", "--report", "{d}/r.md"], "--out and the report's residual figure"),
        (["diagnose", "--joints", "3", "--data", "{d}/train.csv", "--validate", "{d}/train.csv", "--out", "{d}/x.json"],
         "--validate is --data"),
        (["aprbs", "--duration", "5", "--out", "{d}/a.png", "--figure", "{d}/a.png"], "--out and --figure"),
        (["demo", "--out", ""], "--out is empty"),
        (["design", "--joints", "3", "--starts", "1", "--out", ""], r"--out \. is a folder"),  # Path("") is "."
        (["simulate", "--joints", "3", "--trajectory", "{d}/traj.json", "--effect-values", "{d}/values.json",
          "--truth", "{d}/values.json", "--out", "{d}/s.csv"], "--truth .*values.json is the input file of --effect-values"),
    ],
)
def test_an_output_never_replaces_an_input_or_another_output(internal_data, capsys, arguments, message):
    (internal_data / "values.json").write_text('{"viscous": 1.0}')
    before = {path.name: path.read_bytes() for path in internal_data.iterdir()}
    code = main([argument.format(d=internal_data) for argument in arguments])
    assert code == 2
    assert re.search(message, capsys.readouterr().err)
    assert {path.name: path.read_bytes() for path in internal_data.iterdir()} == before  # nothing written or lost


def test_long_json_text_is_not_taken_for_a_file_name(tmp_path):
    import argparse

    from oed.cli.shared.paths import check_paths

    text = "{" + " " * 300 + '"viscous": 1.0}'  # longer than a file name may be
    check_paths(argparse.Namespace(effect_values=text, truth=tmp_path / "truth.json", out=tmp_path / "s.csv"))


def test_design_csv_named_like_another_format_is_refused_before_the_work(tmp_path, capsys):
    code = main(["design", "--joints", "3", "--out", str(tmp_path / "t.json"), "--csv", str(tmp_path / "t.png")])
    assert code == 2 and "--csv" in capsys.readouterr().err and _listing(tmp_path) == []
