"""Live and early: the warnings about the input files are said as the files are read, one line per finding across
files (naming how many), and every step of ``oed identify`` and ``oed diagnose`` that takes seconds says so on
stderr as it ends."""

from __future__ import annotations

import warnings

import pandas as pd
import pytest

from dynamics.effects.linear import CoulombFriction
from dynamics.models import build_model
from dynamics.robots import load_robot
from dynamics.runtime import progress
from dynamics.simulation.synthetic import simulate, true_parameters
from estimation.data.input_findings import group_findings
from oed.cli import main
from oed.fourier import random_fourier


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    """Four short records whose logger re-sent two packets each (the same defect, other rows)."""
    folder = tmp_path_factory.mktemp("live")
    robot = load_robot("puma560", joints=3)
    truth = build_model(robot, "internal", ("viscous", CoulombFriction(joints=(1,))))
    theta = true_parameters(truth, seed=0, coulomb=[8.0])
    paths = []
    for k in range(4):
        frame = simulate(truth, theta, random_fourier(robot, seed=3 + k), noise={c: 0.2 for c in truth.channels},
                         seed=1 + k, periods=2).to_frame()
        rows = [100 + 37 * k, 900 + 11 * k]
        frame = pd.concat([frame, frame.iloc[rows].assign(t=frame.t.iloc[rows] + 1e-4)]).sort_values("t")
        frame.to_csv(folder / f"part{k}.csv", index=False)
        paths.append(str(folder / f"part{k}.csv"))
    return folder, paths


def test_one_line_per_finding_across_files_said_before_the_work_goes_on(files, capsys, monkeypatch):
    folder, paths = files
    monkeypatch.setattr(progress, "SECONDS", 0.0)  # every step says so
    code = main(["diagnose", "--joints", "3", "--data", paths[0], "--data", paths[1], "--data", paths[2],
                 "--validate", paths[3], "--out", str(folder / "report.json")])
    assert code == 0
    error = capsys.readouterr().err.splitlines()
    found = [line for line in error if "dropped 2 row(s) that repeat the previous row" in line]
    assert len(found) == 1, error
    assert found[0].startswith("oed diagnose: warning: 4 files (part0.csv, part1.csv, part2.csv and 1 more): ")
    assert "(figures of part0.csv; the others' differ)" in found[0]  # first at another row in each file
    steps = [line.split(": ")[1] for line in error if line.startswith("oed diagnose: ") and "warning" not in line]
    assert steps[0] == "read 4 file(s)" and "preprocessing chosen" in steps
    assert any(text.startswith("round 1 of the search") for text in steps) and "forward selection" in steps
    # said at reading: before the preprocessing is chosen, not at the end
    assert error.index(found[0]) < next(i for i, line in enumerate(error) if "preprocessing chosen" in line)


def test_identify_says_the_finding_once_and_quiet_says_it_at_the_end(files, capsys, monkeypatch):
    folder, paths = files
    monkeypatch.setattr(progress, "SECONDS", 0.0)
    arguments = ["identify", "--joints", "3", "--data", paths[0], "--data", paths[1], "--out",
                 str(folder / "result.json")]
    assert main(arguments) == 0
    error = capsys.readouterr().err.splitlines()
    assert sum("dropped 2 row(s)" in line for line in error) == 1
    assert any(line.startswith("oed identify: read 2 file(s): ") for line in error)
    assert main([*arguments, "--quiet"]) == 0
    error = capsys.readouterr().err.splitlines()
    assert [line.split(":")[0] for line in error] == ["oed identify"] and "2 files (part0.csv, part1.csv)" in error[0]


def test_findings_are_grouped_by_their_words_figures_aside():
    def caught(*messages):
        with warnings.catch_warnings(record=True) as record:
            warnings.simplefilter("always")
            for message, category in messages:
                warnings.warn(message, category, stacklevel=2)
        return record

    record = caught(("/d/a.csv: column t advances by 0.05 s a sample", UserWarning),
                    ("/d/b.csv: column t advances by 0.05 s a sample", UserWarning),
                    ("/d/b.csv: 3 holes", RuntimeWarning),
                    ("something about no file", UserWarning))
    findings = group_findings(record, ["/d/a.csv", "/d/b.csv"])
    assert [finding.message() if finding.sources else finding.text for finding in findings] == [
        "2 files (a.csv, b.csv): column t advances by 0.05 s a sample", "/d/b.csv: 3 holes",
        "something about no file"]
    assert [finding.category for finding in findings] == [UserWarning, RuntimeWarning, UserWarning]


def test_the_streamed_path_says_a_finding_once_for_every_file_and_pass(files, capsys):
    folder, paths = files
    assert main(["identify", "--joints", "3", "--data", paths[0], "--data", paths[1], "--validate", paths[3],
                 "--chunk-size", "1000", "--out", str(folder / "streamed.json")]) == 0
    error = capsys.readouterr().err.splitlines()
    found = [line for line in error if "dropped 2 row(s)" in line]
    assert len(found) == 1 and "3 files (" in found[0], error  # named in the order they were read (the validation
    assert all(name in found[0].split("):")[0] for name in ("part0.csv", "part1.csv", "part3.csv"))  # file: first)


def test_findings_of_several_passes_are_said_as_each_pass_ends_each_once(capsys):
    """The streamed path reads its files two or three times: a pass says the findings new to the run, naming the
    files that gave them in that pass; the same finding of the same file is not said again."""
    from estimation.data.input_findings import FindingsSaid

    findings = FindingsSaid(["/d/a.csv", "/d/b.csv", "/d/c.csv"])
    with progress.show_progress("oed test"):
        with pytest.warns(UserWarning) as issued:
            with findings.reading():
                warnings.warn("/d/a.csv (rows 1-500): dropped 2 row(s)", UserWarning, stacklevel=1)
                warnings.warn("/d/b.csv (rows 1-500): dropped 3 row(s)", UserWarning, stacklevel=1)
                warnings.warn("no file named", UserWarning, stacklevel=1)
            said_first = capsys.readouterr().err.splitlines()
            with findings.reading():
                for name in ("a", "b", "c"):
                    warnings.warn(f"/d/{name}.csv: dropped 2 row(s)", UserWarning, stacklevel=1)
                warnings.warn("no file named", UserWarning, stacklevel=1)
    assert said_first == ["oed test: warning: 2 files (a.csv, b.csv): dropped 2 row(s) (figures of a.csv; the "
                          "others' differ)", "oed test: warning: no file named"]
    assert capsys.readouterr().err.splitlines() == ["oed test: warning: /d/c.csv: dropped 2 row(s)"]
    assert [str(warning.message) for warning in issued] == [line.split("warning: ", 1)[1] for line in said_first] + [
        "/d/c.csv: dropped 2 row(s)"]
    assert findings.lines == [str(warning.message) for warning in issued]


def test_the_streamed_diagnosis_says_a_finding_once_as_its_files_are_read(files, capsys, monkeypatch):
    folder, paths = files
    monkeypatch.setattr(progress, "SECONDS", 0.0)  # every step says so
    assert main(["diagnose", "--joints", "3", "--data", paths[0], "--data", paths[1], "--data", paths[2],
                 "--validate", paths[3], "--chunk-size", "1000", "--out", str(folder / "streamed_report.json")]) == 0
    error = capsys.readouterr().err.splitlines()
    found = [line for line in error if "dropped 2 row(s)" in line]
    assert len(found) == 1 and found[0].startswith("oed diagnose: warning: 4 files ("), error
    # said as the files are read: before the first pass over them ends, not with the run's end
    assert error.index(found[0]) < next(i for i, line in enumerate(error) if "first pass" in line)
