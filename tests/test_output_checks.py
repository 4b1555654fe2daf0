"""Every output path is checked before any work: its suffix (the format the verb writes) and a folder that can be
written."""

from __future__ import annotations

import os

import pytest

from oed.cli import main


@pytest.mark.parametrize(("arguments", "option"), [
    (["identify", "--data", "{d}/missing.csv", "--out", "{d}/result.csv"], "--out"),
    (["diagnose", "--data", "{d}/missing.csv", "--validate", "{d}/other.csv", "--out", "{d}/report.csv"], "--out"),
    (["diagnose", "--data", "{d}/missing.csv", "--validate", "{d}/other.csv", "--out", "{d}/report.json",
      "--report", "{d}/report.pdf"], "--report"),
    (["servo-fit", "--data", "{d}/missing.csv", "--out", "{d}/fit.csv"], "--out"),
])
def test_an_output_named_like_another_format_is_refused_before_the_inputs_are_read(tmp_path, capsys, arguments,
                                                                                 option):
    code = main([argument.format(d=tmp_path) for argument in arguments])
    error = capsys.readouterr().err
    assert code == 2
    assert f"{option} " in error and "missing.csv" not in error  # refused before the (missing) record was read
    assert list(tmp_path.iterdir()) == []


def test_an_output_in_a_folder_that_cannot_exist_is_refused_before_any_work(tmp_path, capsys):
    blocker = tmp_path / "a_file.txt"
    blocker.write_text("not a folder")
    code = main(["identify", "--data", str(tmp_path / "missing.csv"), "--out", str(blocker / "result.json")])
    error = capsys.readouterr().err
    assert code == 2 and "--out" in error and "not a folder" in error and "missing.csv" not in error


@pytest.mark.skipif(os.name != "posix" or os.geteuid() == 0, reason="root writes in read-only folders")
def test_an_output_in_a_read_only_folder_is_refused_before_any_work(tmp_path, capsys):
    locked = tmp_path / "locked"
    locked.mkdir()
    locked.chmod(0o500)
    try:
        code = main(["diagnose", "--data", str(tmp_path / "missing.csv"), "--validate", str(tmp_path / "v.csv"),
                     "--out", str(tmp_path / "report.json"), "--report", str(locked / "report.md")])
    finally:
        locked.chmod(0o700)
    error = capsys.readouterr().err
    assert code == 2 and "--report" in error and "cannot write" in error and "missing.csv" not in error
