"""The streamed ``oed identify`` reports its training errors as the in-memory one does (issue 34, "errors against the
samples as recorded"): ``n_samples`` counts the recorded samples (a jittered or stalled log is resampled onto a grid of
another length), the training ``mse`` is measured against the recording, block by block, where the sums hold filtered
or period-averaged channels (those errors kept as ``mse_filtered``), on the filter path and on the Fourier path; and the
extra pass over the training files holds a few blocks, not the record. A stalled log on the Fourier path (the
streamed run exited on it) is measured as in memory too."""

from __future__ import annotations

import json
import tracemalloc

import numpy as np
import pandas as pd
import pytest

from dynamics.models import build_model
from dynamics.robots import load_robot
from dynamics.simulation.simulator import Simulator
from estimation.streaming.chunks import read_chunks
from estimation.streaming.recorded_errors import counted_recorded_errors
from oed.cli import main
from oed.fourier import random_fourier
from tests.test_streamed_reader_parity import with_defect

EFFECTS = "viscous,coulomb,offset"
CHUNK = "250"


@pytest.fixture(scope="module")
def logs(tmp_path_factory):
    """A 3-joint PUMA at 200 Hz: 10 s records of a 0.1 Hz motion (clean, jittered, stalled) and 12 s records of a
    0.25 Hz motion (three periods) for the Fourier path; a training and a validation record of another motion each."""
    folder = tmp_path_factory.mktemp("training_errors")
    robot = load_robot("puma560", joints=3)
    simulator = Simulator(robot, rate_hz=200.0)
    for name, seed in (("train", 1), ("val", 2)):
        for prefix, frequency, duration in (("", 0.1, 10.0), ("periodic_", 0.25, 12.0)):
            frame = simulator.run(random_fourier(robot, seed, frequency_hz=frequency), duration=duration,
                                  warmup_periods=1, seed=seed).measurements.to_frame()
            frame = frame[[column for column in frame.columns if not column.startswith(("dq", "ddq"))]]
            frame.to_csv(folder / f"{name}_{prefix}clean.csv", index=False, float_format="%.17g")
            for kind in ("stall",) if prefix else ("jitter", "stall"):
                with_defect(frame, kind, 5 + (name == "val")).to_csv(folder / f"{name}_{prefix}{kind}.csv", index=False,
                                                                 float_format="%.17g")
    return folder


def _identify(folder, kind: str, out, *options: str) -> dict:
    code = main(["identify", "--joints", "3", "--friction", EFFECTS, "--data", str(folder / f"train_{kind}.csv"),
                 "--validate", str(folder / f"val_{kind}.csv"), "--out", str(out), *options])
    assert code == 0
    return json.loads(out.read_text())


def _close(memory: dict[str, float], streamed: dict[str, float], what: str) -> None:
    assert set(memory) == set(streamed), what
    for channel, value in memory.items():
        assert streamed[channel] == pytest.approx(value, rel=1e-6), f"{what}: {channel}"


def assert_training_errors_alike(memory: dict, streamed: dict, kind: str) -> None:
    """The streamed identification's sample count and training errors are the in-memory one's (``kind``: the log's
    defect, a grid of another length for a jittered or stalled log)."""
    assert streamed["identification_path"] == "streamed" and memory["identification_path"] != "streamed"
    assert streamed["chosen"] == memory["chosen"]
    assert streamed["n_samples"] == memory["n_samples"]  # the recorded samples, not the grid's
    files = streamed["streaming"]["files"]
    if kind.endswith(("jitter", "stall")):  # the grid has another length than the recording
        assert files[0]["samples"] != memory["n_samples"]
    if kind.startswith("periodic"):  # the sums hold one averaged period, the error every sample of the periods
        assert files[0]["samples"] < memory["n_samples"]
    assert streamed["train"]["mse"] is not None
    _close(memory["train"]["mse"], streamed["train"]["mse"], "train mse (vs recorded)")
    _close(memory["train"]["mse_filtered"], streamed["train"]["mse_filtered"], "train mse_filtered")
    _close(memory["validation"]["mse"], streamed["validation"]["mse"], "validation")
    # the model file's prediction band: the training error against the recording, as in memory
    _close(memory["model_file"]["recorded_variance"], streamed["model_file"]["recorded_variance"], "recorded_variance")


#: the jittered and the stalled log with the default options are tests/test_streamed_reader_parity.py's ``jitter`` and
#: ``stall`` logs and runs (the same simulations, defects and seeds), which check them with
#: :func:`assert_training_errors_alike` in ``make test``; here they run in ``make test-slow``
@pytest.mark.parametrize(("kind", "options"), [
    pytest.param("jitter", (), marks=pytest.mark.slow), pytest.param("stall", (), marks=pytest.mark.slow),
    ("jitter", ("--decimate", "2")), ("clean", ()),
    ("periodic_clean", ("--frequency", "0.25", "--method", "wls")),
    ("periodic_stall", ("--frequency", "0.25", "--method", "wls")),
    # the default answer on the Fourier path: chosen among OLS, WLS and the consistent fit as in memory, the
    # candidates scored on every sample of the validation file's whole periods (at its recorded stamps when stalled)
    pytest.param("periodic_clean", ("--frequency", "0.25"), marks=pytest.mark.slow),
    pytest.param("periodic_stall", ("--frequency", "0.25"), marks=pytest.mark.slow)])
def test_streamed_training_errors_and_sample_count_are_the_in_memory_ones(logs, tmp_path, capsys, kind, options):
    memory = _identify(logs, kind, tmp_path / "memory.json", *options)
    streamed = _identify(logs, kind, tmp_path / "streamed.json", "--chunk-size", CHUNK, *options)
    capsys.readouterr()
    assert_training_errors_alike(memory, streamed, kind)
    if "--method" not in options:  # the default answer: memory's, every candidate's validation error memory's
        assert streamed["model_selection"]["chosen"] == memory["model_selection"]["chosen"]
        assert "model_selection" not in streamed["not_computed"]
        mine = {entry["name"]: entry for entry in streamed["model_selection"]["candidates"]}
        for entry in memory["model_selection"]["candidates"]:
            if entry.get("validation_mse"):
                _close(entry["validation_mse"], mine[entry["name"]]["validation_mse"], f"candidate {entry['name']}")
    if kind.startswith("periodic"):  # a stalled validation log on this path: measured as predict measures it
        metrics = tmp_path / "metrics.json"
        assert main(["predict", "--model", str(tmp_path / "streamed.json"), "--data", str(logs / f"val_{kind}.csv"),
                     "--metrics", str(metrics)]) == 0
        _close(json.loads(metrics.read_text())["mse"], streamed["validation"]["mse"], "validation (predict)")


def _peak(run) -> int:
    tracemalloc.start()
    try:
        run()
        return tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()


def test_the_training_pass_holds_a_few_blocks_not_the_record(tmp_path):
    """Peak memory of the extra pass over a 60 000-row record of 13 columns read in blocks of 500 rows: what reading
    the blocks alone takes (the reader's scan of the time column, about 50 bytes a row whatever the columns) and a
    few blocks more, not the record (60 000 x 13 x 8 bytes = 6.2 MB)."""
    robot = load_robot("puma560", joints=3)
    # one period of the 0.1 Hz motion simulated (10 s, 2 000 rows), logged 30 times over on a continued clock: what
    # the pass holds depends on the rows and columns, not on their values (simulating the 300 s is not checked here)
    period = Simulator(robot, rate_hz=200.0).run(random_fourier(robot, 3, frequency_hz=0.1), duration=10.0,
                                                 warmup_periods=1, seed=3).measurements.to_frame()
    period = period[[column for column in period.columns if not column.startswith(("dq", "ddq"))]]
    frame = pd.concat([period] * 30, ignore_index=True)
    frame["t"] = np.arange(len(frame)) / 200.0
    path, short = tmp_path / "long.csv", tmp_path / "period.csv"
    frame.to_csv(path, index=False)
    frame.iloc[:len(period)].to_csv(short, index=False)
    model = build_model(robot, "internal", EFFECTS)
    theta = {"nominal": model.base.K @ model.nominal_parameters()}
    found = {}

    def measure(record=path) -> None:
        found["errors"], found["count"] = counted_recorded_errors(model, theta, [record], chunk_size=500, cutoff_hz=5.0)

    def read() -> None:
        for _ in read_chunks(path, model, chunk_size=500):
            pass

    measure(short)  # the compiled functions warmed (the same blocks of 500 rows, on one period: not a third pass)
    peak, reading = _peak(measure), _peak(read)
    assert found["count"] == len(frame) and np.all(np.isfinite(list(found["errors"]["nominal"].values())))
    record = len(frame) * frame.shape[1] * 8
    assert peak < reading + 0.1 * record, (peak, reading, record)
    assert peak < 0.75 * record, (peak, record)


def _diagnose(folder, kind: str, out, *options: str) -> dict:
    code = main(["diagnose", "--joints", "3", "--data", str(folder / f"train_{kind}.csv"), "--validate",
                 str(folder / f"val_{kind}.csv"), "--out", str(out), *options])
    assert code == 0
    return json.loads(out.read_text())


@pytest.mark.slow  # about 40 s: two diagnoses in memory and streamed
@pytest.mark.parametrize(("kind", "options"), [("stall", ()), ("periodic_clean", ("--frequency", "0.25"))])
def test_streamed_diagnosis_training_errors_are_against_the_recording(logs, tmp_path, capsys, kind, options):
    """The streamed diagnosis's training errors: on a stalled log at its recorded samples (not the grid's interpolated
    torques), on the Fourier path on every sample of the whole periods (the averaged period's error kept as
    ``mse_filtered``); the declared model's as in memory, and the chosen model's what ``oed predict`` measures on
    the training file."""
    memory = _diagnose(logs, kind, tmp_path / "memory.json", *options)
    streamed = _diagnose(logs, kind, tmp_path / "streamed.json", "--chunk-size", CHUNK, *options)
    capsys.readouterr()
    assert streamed["diagnosis_path"] == "streamed"
    _close(memory["train"]["before"]["mse"], streamed["train"]["before"]["mse"], "before")
    metrics = tmp_path / "metrics.json"
    assert main(["predict", "--model", str(tmp_path / "streamed.json"), "--data", str(logs / f"train_{kind}.csv"),
                 "--metrics", str(metrics)]) == 0
    _close(json.loads(metrics.read_text())["mse"], streamed["train"]["chosen"]["mse"], "chosen (predict)")
    names = {candidate["name"]: candidate for candidate in streamed["model_selection"]["candidates"]}
    _close(streamed["train"]["chosen"]["mse"], names[streamed["model_selection"]["chosen"]]["train_mse"], "candidate")
    if kind.startswith("periodic"):
        assert streamed["train"]["before"]["mse_filtered"] and streamed["train"]["chosen"]["mse_filtered"]
        assert all(candidate["train_mse_filtered"] for candidate in names.values())
    else:  # the same effects: the adopted model's and the chosen one's errors as in memory
        assert [e["name"] for e in streamed["effects"]] == [e["name"] for e in memory["effects"]]
        _close(memory["train"]["after"]["mse"], streamed["train"]["after"]["mse"], "after")
        _close(memory["train"]["chosen"]["mse"], streamed["train"]["chosen"]["mse"], "chosen")
