"""Bad input named plainly: a CSV separated by another delimiter, a --frequency or --cutoff out of range;
a staged measurement file written once (no nested temporary file for a killed run to leave behind)."""

from __future__ import annotations

import numpy as np
import pytest

from dynamics.measurements import Measurements
from dynamics.runtime.output_files import OutputFiles
from oed.cli import main


@pytest.fixture
def record(tmp_path):
    t = np.arange(200) * 0.01
    q = np.column_stack([np.sin(t), np.cos(t), t])
    data = Measurements(t, q, np.zeros_like(q), np.zeros_like(q), tau=q.copy())
    path = tmp_path / "record.csv"
    data.write(path)
    return data, path


@pytest.mark.parametrize("delimiter, decimal", [(";", "."), (";", ","), ("\t", ".")])
def test_a_csv_separated_otherwise_is_read_or_names_its_delimiter(record, tmp_path, capsys, delimiter, decimal):
    _, path = record
    text = path.read_text()
    if decimal == ",":
        text = text.replace(",", delimiter).replace(".", ",")
    else:
        text = text.replace(",", delimiter)
    other = tmp_path / "other.csv"
    other.write_text(text)
    main(["identify", "--joints", "3", "--data", str(other), "--out", str(tmp_path / "r.json")])
    error = capsys.readouterr().err  # read so (h-unseen7), said: the header and the rows agree on the delimiter
    assert f"separated by {delimiter!r}" in error and "read so" in error and "missing column" not in error
    assert "cannot read" not in error
    lines = text.splitlines()
    lines[5] = lines[5].rsplit(delimiter, 1)[0]  # a row short of a field: nothing guessed, the delimiter named
    other.write_text("\n".join(lines) + "\n")
    assert main(["identify", "--joints", "3", "--data", str(other), "--out", str(tmp_path / "r.json")]) == 2
    error = capsys.readouterr().err
    assert f"separated by {delimiter!r}" in error and "read so" not in error and "missing column" not in error


@pytest.mark.parametrize("verb, option, value", [("identify", "--frequency", "-1"), ("identify", "--frequency", "0"),
                                                  ("identify", "--frequency", "nan"), ("identify", "--cutoff", "inf"),
                                                  ("diagnose", "--cutoff", "-2"), ("design", "--frequency", "0")])
def test_a_bad_frequency_names_the_option_typed(record, tmp_path, capsys, verb, option, value):
    _, path = record
    inputs = {"identify": ["--data", str(path)], "diagnose": ["--data", str(path), "--validate", str(tmp_path / "other.csv")],
              "design": ["--quiet"]}[verb]
    assert main([verb, "--joints", "3", *inputs, "--out", str(tmp_path / "r.json"), f"{option}={value}"]) == 2
    error = capsys.readouterr().err
    assert f"{option} must be a positive, finite number of hertz" in error and "_hz" not in error


def test_a_staged_measurement_file_is_written_once(record, tmp_path, monkeypatch):
    """While `oed simulate` writes its rows, the folder holds one temporary file (the run's stage), not a
    second one staged inside it that a SIGKILL would leave behind."""
    data, _ = record
    folder = tmp_path / "out"
    seen = []
    write_frame = Measurements._write_frame

    def spy(self, stream, suffix):
        seen.append(sorted(path.name for path in folder.iterdir()))
        write_frame(self, stream, suffix)

    monkeypatch.setattr(Measurements, "_write_frame", spy)
    with OutputFiles() as outputs:
        data.write(outputs.stage(folder / "s.csv"), staged=False)
    assert len(seen) == 1 and len(seen[0]) == 1, seen
    assert [path.name for path in folder.iterdir()] == ["s.csv"]


def test_an_npz_without_a_map_names_its_arrays_and_the_option(tmp_path, capsys):
    """The KUKA LWR4+ runs as a user first gives them (no --columns): the message named only the missing ``t``, not
    what the file holds nor the option that reads it (its 2-D arrays were no column, so not even listed)."""
    samples = 200
    generator = np.random.default_rng(0)
    path = tmp_path / "run.npz"
    np.savez(path, times=np.arange(samples) * 0.005, positions=generator.normal(size=(samples, 3)),
             torques=generator.normal(size=(samples, 3)))
    code = main(["identify", "--joints", "3", "--data", str(path), "--out", str(tmp_path / "result.json")])
    error = capsys.readouterr().err
    assert code == 2 and "missing column(s) t (the time)" in error
    assert "the file holds times, positions (200 x 3), torques (200 x 3)" in error and "--columns" in error
