"""The streamed reader does what the in-memory reader does with every logger defect the latter accepts (issue 34: no
verb exits on its defaults when a user's explicit option would have worked): holes in --data and --validate files,
stamps duplicated with new values, re-sent rows, jitter, stalls, epoch time, reordered and extra columns. Each defect
sits on both records of a small simulated log, read in memory and in blocks of 250 rows, so that the defects straddle
block boundaries (rows 250, 500, 750…): both exit 0 with the same estimate, validation errors (relative 1e-6) and
warnings, and ``oed predict`` on the validation file reproduces the streamed run's error. Where the in-memory reader
exits (too many duplicated stamps), the streamed one exits with the same message."""

from __future__ import annotations

import json
import re

import numpy as np
import pandas as pd
import pytest

from dynamics.robots import load_robot
from dynamics.simulation.simulator import Simulator
from oed.cli import main
from oed.fourier import random_fourier

EFFECTS = "viscous,coulomb,offset"
CHUNK = "250"
#: rows on block boundaries of CHUNK rows
BOUNDARIES = [250, 500, 750, 1000, 1250]


def with_defect(frame: pd.DataFrame, kind: str, seed: int) -> pd.DataFrame:
    """``frame`` as a logger with the defect ``kind`` writes it."""
    frame = frame.copy()
    generator = np.random.default_rng(seed)
    step = float(np.median(np.diff(frame.t)))
    data = [column for column in frame.columns if column != "t"]
    if kind == "hole":  # 1 s without samples across the boundary at row 750
        return frame.drop(index=range(700, 900)).reset_index(drop=True)
    if kind in ("duplicated", "many_duplicated"):  # the clock did not tick: the previous row's stamp, new values
        rows = np.array(BOUNDARIES + [251, 777]) if kind == "duplicated" else np.arange(10, len(frame) - 10, 40)
        frame.loc[rows, "t"] = frame.t[rows - 1].to_numpy()
        return frame
    if kind == "resent":  # the previous row again, its stamp advanced (some on block boundaries)
        rows = np.unique(np.r_[generator.choice(np.arange(100, len(frame) - 100), 30, replace=False), BOUNDARIES])
        frame.loc[rows, data] = frame.loc[rows - 1, data].to_numpy()
        return frame
    if kind == "resent_same_stamp":  # the previous row again, time stamp too: the rest of the record regular
        rows = np.array(BOUNDARIES + [333, 1666])
        frame = pd.concat([frame, frame.loc[rows - 1]]).sort_index(kind="stable").reset_index(drop=True)
        return frame
    if kind == "jitter":  # the samples taken at their irregular stamps (receive times: the regular clock, scored
        # in memory only, test_time_base_choice.py)
        return at_stamps(frame, frame.t + generator.uniform(-0.3, 0.3, len(frame)) * step)
    if kind == "stall":  # 30 and 20 ms without samples, the first across the boundary at row 500
        return frame.drop(index=[*range(497, 503), *range(1200, 1204)]).reset_index(drop=True)
    if kind == "epoch":  # Unix time stamps
        frame["t"] = frame.t + 1.7e9
        return frame
    if kind == "columns":  # reordered, with a column the toolkit does not read
        frame["temperature"] = 35.0
        return frame[list(reversed(frame.columns))]
    if kind == "received":  # receive times: the samples where they were, the stamps moved
        frame["t"] = frame.t + generator.uniform(-0.3, 0.3, len(frame)) * step
        return frame
    if kind == "hole_and_jitter":  # each segment resampled onto its own grid
        frame = at_stamps(frame, frame.t + generator.uniform(-0.3, 0.3, len(frame)) * step)
        return frame.drop(index=range(1240, 1300)).reset_index(drop=True)
    raise ValueError(kind)


def at_stamps(frame: pd.DataFrame, stamps: pd.Series) -> pd.DataFrame:
    """``frame`` with its positions taken at the irregular ``stamps`` (the smooth motion interpolated there; the
    torques as simulated, whose noise an interpolation would smooth): a logger whose stamps are its samples'
    instants, which both readers resample by them."""
    moved = frame.copy()
    for column in frame.columns:
        if column.startswith("q"):
            moved[column] = np.interp(stamps.to_numpy(), frame.t.to_numpy(), frame[column].to_numpy())
    moved["t"] = stamps
    return moved


KINDS = ["hole", "duplicated", "resent", "resent_same_stamp", "jitter", "stall", "epoch", "columns", "hole_and_jitter"]


@pytest.fixture(scope="module")
def logs(tmp_path_factory):
    """Positions and torques of a 3-joint PUMA at 200 Hz, 10 s: a training and a validation record of another
    motion, each as written with every defect."""
    folder = tmp_path_factory.mktemp("parity")
    robot = load_robot("puma560", joints=3)
    simulator = Simulator(robot, rate_hz=200.0)
    clean = {}
    for name, seed in (("train", 1), ("val", 2)):
        frame = simulator.run(random_fourier(robot, seed, frequency_hz=0.1), duration=10.0, warmup_periods=1,
                              seed=seed).measurements.to_frame()
        clean[name] = frame[[column for column in frame.columns if not column.startswith(("dq", "ddq"))]]
    for kind in [*KINDS, "many_duplicated", "received"]:
        for name, seed in (("train", 5), ("val", 6)):
            frame = clean[name] if kind == "many_duplicated" and name == "train" else with_defect(clean[name], kind, seed)
            frame.to_csv(folder / f"{name}_{kind}.csv", index=False, float_format="%.17g")
    return folder


def _run(verb: str, folder, kind: str, out, capsys, *options: str) -> tuple[int, list[str], str]:
    """Exit code, warnings (the files of a grouped one in sorted order) and error of ``oed verb`` on the logs."""
    extra = ("--friction", EFFECTS) if verb == "identify" else ()
    code = main([verb, "--joints", "3", *extra, "--data", str(folder / f"train_{kind}.csv"), "--validate",
                 str(folder / f"val_{kind}.csv"), "--out", str(out), *options])
    error = capsys.readouterr().err
    warnings = sorted(re.sub(r"\d+ files \(([^)]*)\)", lambda match: ", ".join(sorted(match[1].split(", "))), line)
                      for line in error.splitlines() if ": warning: " in line)
    return code, warnings, error


def _close(memory: dict[str, float], streamed: dict[str, float], what: str, tolerance: float = 1e-6) -> None:
    assert set(memory) == set(streamed), what
    for channel, value in memory.items():
        assert streamed[channel] == pytest.approx(value, rel=tolerance), f"{what}: {channel}"


@pytest.fixture(scope="module")
def in_memory(logs, tmp_path_factory):
    """``oed identify`` in memory on a defective log, run once a module (the identify and the memory-budget tests
    compare their streamed runs with the same one; the runs are deterministic, their results read only): the
    document, the warnings said and the error output, by defect."""
    folder, runs = tmp_path_factory.mktemp("parity_in_memory"), {}

    def run(kind: str, capsys) -> tuple[dict, list[str]]:
        if kind not in runs:
            out = folder / f"{kind}.json"
            code, said, error = _run("identify", logs, kind, out, capsys)
            assert code == 0, error
            runs[kind] = json.loads(out.read_text()), said
        return runs[kind]

    return run


@pytest.mark.parametrize("kind", KINDS)
def test_identify_streamed_reads_a_defective_log_as_in_memory(logs, in_memory, kind, tmp_path, capsys):
    documents, said = {}, {}
    documents["memory"], said["memory"] = in_memory(kind, capsys)
    out = tmp_path / "streamed.json"
    code, said["streamed"], error = _run("identify", logs, kind, out, capsys, "--chunk-size", CHUNK)
    assert code == 0, error
    documents["streamed"] = json.loads(out.read_text())
    memory, streamed = documents["memory"], documents["streamed"]
    assert streamed["identification_path"] == "streamed" and memory["identification_path"] != "streamed"
    assert said["streamed"] == said["memory"]
    assert streamed["chosen"] == memory["chosen"]
    assert streamed["preprocessing"]["cutoff_hz"] == pytest.approx(memory["preprocessing"]["cutoff_hz"], rel=1e-9)
    values = {mode: np.array([entry["value"] for entry in document["parameters"]])
              for mode, document in documents.items()}
    # epoch stamps are quantised (2.4e-7 s at 1.7e9 s): each block's median step differs from the record's by up to
    # 5e-5 (the filter is designed for the record's rate, ButterworthDifferentiation.rate_hz), and differences of
    # epoch times round to 5e-5 of a step (the derivatives take the time from the record's start)
    tolerance = 1e-6
    assert np.max(np.abs(values["streamed"] - values["memory"])) <= tolerance * np.max(np.abs(values["memory"]))
    _close(memory["validation"]["mse"], streamed["validation"]["mse"], "validation", tolerance)
    candidates = {mode: {entry["name"]: entry["validation_mse"] for entry in document["model_selection"]["candidates"]}
                  for mode, document in documents.items()}
    assert set(candidates["streamed"]) == set(candidates["memory"])
    for name, mse in candidates["memory"].items():
        _close(mse, candidates["streamed"][name], name, tolerance)
    metrics = tmp_path / "metrics.json"
    assert main(["predict", "--model", str(tmp_path / "streamed.json"), "--data", str(logs / f"val_{kind}.csv"),
                 "--metrics", str(metrics)]) == 0
    _close(streamed["validation"]["mse"], json.loads(metrics.read_text())["mse"], "predict", tolerance)
    if kind in ("jitter", "stall"):  # tests/test_streamed_training_errors.py's logs and runs: its checks, here
        from tests.test_streamed_training_errors import assert_training_errors_alike

        assert_training_errors_alike(memory, streamed, kind)


@pytest.mark.slow
def test_receive_time_stamps_the_regular_clock_on_both_paths_and_said(logs, tmp_path, capsys):
    """Where the stamps are receive times, the in-memory path scores the regular clock on the validation record and
    takes it (tests/test_time_base_choice.py); the streamed path reads its sources on that clock and takes it too
    (tests/test_streamed_time_base.py holds the answers alike): nothing left in ``not_computed.time_base``. Both
    say the same findings, the receive-times warning among them."""
    documents, said = {}, {}
    for mode, options in (("memory", ()), ("streamed", ("--chunk-size", CHUNK))):
        out = tmp_path / f"{mode}.json"
        code, said[mode], error = _run("identify", logs, "received", out, capsys, *options)
        assert code == 0, error
        documents[mode] = json.loads(out.read_text())
    assert said["streamed"] == said["memory"] and any("look like a logger's receive times" in line
                                                      for line in said["memory"])
    for document in documents.values():
        assert document["preprocessing"]["time_base"] == "regular"
        assert document["model_file"]["preprocessing"]["time_base"] == "regular"
    assert "time_base" not in documents["streamed"]["not_computed"]


@pytest.mark.parametrize("kind", ["hole", "duplicated", "jitter"])
def test_past_the_memory_budget_the_defaults_read_as_in_memory(logs, in_memory, kind, tmp_path, capsys):
    """The defaults' own route to the streamed path (the record past ``--memory-budget``): the same answer, and each
    finding said once (when the path is decided), as in memory."""
    documents, said = {}, {}
    documents["memory"], said["memory"] = in_memory(kind, capsys)
    out = tmp_path / "streamed.json"
    code, said["streamed"], error = _run("identify", logs, kind, out, capsys, "--memory-budget", "1KB")
    assert code == 0, error
    documents["streamed"] = json.loads(out.read_text())
    assert documents["streamed"]["identification_path"] == "streamed"
    assert said["streamed"] == said["memory"]
    _close(documents["memory"]["validation"]["mse"], documents["streamed"]["validation"]["mse"], "validation")


@pytest.mark.slow  # about 40 s: the diagnosis passes, in memory and in blocks (hole_and_jitter: the runner-up's
# validation error read from the files, not from the streamed segments' names)
@pytest.mark.parametrize("kind", ["hole", "duplicated", "jitter", "hole_and_jitter"])
def test_diagnose_streamed_reads_a_defective_log_as_in_memory(logs, kind, tmp_path, capsys):
    documents, said = {}, {}
    for mode, options in (("memory", ()), ("streamed", ("--chunk-size", CHUNK))):
        out = tmp_path / f"{mode}.json"
        code, said[mode], error = _run("diagnose", logs, kind, out, capsys, *options)
        assert code == 0, error
        documents[mode] = json.loads(out.read_text())
    memory, streamed = documents["memory"], documents["streamed"]
    assert said["streamed"] == said["memory"]
    assert [effect["name"] if isinstance(effect, dict) else effect for effect in streamed["effects"]] == \
        [effect["name"] if isinstance(effect, dict) else effect for effect in memory["effects"]]
    _close(memory["validation"]["before"]["mse"], streamed["validation"]["before"]["mse"], "before")


def test_too_many_duplicated_stamps_exit_alike(logs, tmp_path, capsys):
    """More than 1 % of the rows stamped with the previous row's time: both paths refuse the file, by one message."""
    errors = {}
    for mode, options in (("memory", ()), ("streamed", ("--chunk-size", CHUNK))):
        code, _, error = _run("identify", logs, "many_duplicated", tmp_path / f"{mode}.json", capsys, *options)
        assert code == 2, error
        errors[mode] = [line for line in error.splitlines() if ": error: " in line]
    assert errors["streamed"] == errors["memory"] and "duplicated time(s)" in errors["memory"][0]
