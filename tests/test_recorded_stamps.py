"""Errors against the samples as recorded (issue 34): a log with jittered time stamps, re-sent rows and a stall is
resampled onto a uniform grid to derive the motion, but the reported errors are those of the predictions at the
recorded time stamps against the recorded torques, never interpolated ones. Checked by recomputing them from the
file itself: the prepared motion interpolated at the file's time stamps, the file's torques."""

from __future__ import annotations

import json
import warnings
from dataclasses import replace
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from dynamics.models import build_model
from dynamics.robots import load_robot
from dynamics.simulation.simulator import Simulator
from estimation.data.records import read_record
from estimation.identification.identified_model import IdentifiedModel
from oed.cli import main
from oed.fourier import random_fourier

SHARED = Path(__file__).resolve().parents[1] / ".." / "shared" / "data" / "panda"


def logger_faults(frame: pd.DataFrame, seed: int) -> pd.DataFrame:
    """The frame as a jittery logger writes it: every row's stamp moved by up to ±30 % of a step (the readings
    are those of the true instant, the stamp is not), 40 rows re-sent (the previous row again, its stamp advanced),
    and a stall of 8 ms (rows missing)."""
    generator = np.random.default_rng(seed)
    frame = frame.copy()
    step = float(np.median(np.diff(frame.t)))
    frame["t"] = frame.t + generator.uniform(-0.3, 0.3, len(frame)) * step
    frame = frame.drop(index=range(900, 908)).reset_index(drop=True)  # the stall
    resent = np.sort(generator.choice(np.arange(100, len(frame) - 100), 40, replace=False))
    data = [column for column in frame.columns if column != "t"]
    frame.loc[resent, data] = frame.loc[resent - 1, data].to_numpy()
    return frame


@pytest.fixture(scope="module")
def records(tmp_path_factory):
    robot = load_robot("puma560", joints=3)
    simulator = Simulator(robot, rate_hz=500.0)
    folder = tmp_path_factory.mktemp("stamps")
    paths = {}
    for name, seed in (("train", 1), ("validate", 2)):
        trajectory = random_fourier(robot, seed, frequency_hz=0.2)
        frame = simulator.run(trajectory, duration=8.0, warmup_periods=1, seed=seed).measurements.to_frame()
        frame = frame[[column for column in frame.columns if not column.startswith(("dq", "ddq"))]]
        if name == "validate":
            frame = logger_faults(frame, seed)
        paths[name] = folder / f"{name}.csv"
        frame.to_csv(paths[name], index=False, float_format="%.10g")
    return folder, paths


def recomputed(result: Path, path: Path) -> dict[str, float]:
    """The model's error on the file's own samples: the motion the model's preprocessing derives (on its uniform
    grid) interpolated at each recorded time stamp, against the torque in that row. Rows that repeat the row before
    on every channel are the logger re-sending a packet, not samples of their instant: left out."""
    model = IdentifiedModel.load(result)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        segments = model.read([path])
    grid = model.prepare(segments)
    frame = pd.read_csv(path)
    data = frame.drop(columns="t").to_numpy()
    fresh = np.concatenate([[True], np.any(data[1:] != data[:-1], axis=1)])
    frame = frame[fresh]
    t = frame.t.to_numpy()
    inside = (t >= grid.t[0] - 1e-9) & (t <= grid.t[-1] + 1e-9)
    t = t[inside]
    motion = [np.column_stack([np.interp(t, grid.t, column) for column in values.T])
              for values in (grid.q, grid.dq, grid.ddq)]
    tau = frame[list(model.channels)].to_numpy()[inside]
    assert inside.mean() > 0.999  # the filter covers the record: every sample but rounding at the ends
    residual = tau - model.predict(*motion)
    return dict(zip(model.channels, np.mean(residual**2, axis=0)))


def test_reported_errors_on_a_jittered_log_are_those_of_the_recorded_samples(records):
    folder, paths = records
    result = folder / "result.json"
    code = main(["identify", "--joints", "3", "--friction", "viscous", "--data", str(paths["train"]),
                 "--validate", str(paths["validate"]), "--out", str(result), "--quiet"])
    assert code == 0
    reported = json.loads(result.read_text())["model_file"]["reported"]["validation_mse"]  # the chosen model's
    expected = recomputed(result, paths["validate"])
    for channel, value in expected.items():
        assert reported[channel] == pytest.approx(value, rel=1e-6)
    # and oed predict measures the same, at the recorded stamps (its CSV has them)
    predicted = folder / "predicted.csv"
    assert main(["predict", "--model", str(result), "--data", str(paths["validate"]), "--out", str(predicted),
                 "--metrics", str(folder / "metrics.json")]) == 0
    metrics = json.loads((folder / "metrics.json").read_text())["mse"]
    for channel, value in expected.items():
        assert metrics[channel] == pytest.approx(value, rel=1e-6)
    stamps = pd.read_csv(predicted).t.to_numpy()
    assert np.isin(stamps, pd.read_csv(paths["validate"]).t.to_numpy()).all()


def test_interpolated_torques_would_have_reported_another_error(records):
    """The test above can fail: the same predictions scored on the grid, against torques interpolated onto it (what
    the errors were before), differ from those on the recorded samples."""
    folder, paths = records
    result = folder / "result.json"
    if not result.is_file():
        assert main(["identify", "--joints", "3", "--friction", "viscous", "--data", str(paths["train"]),
                     "--validate", str(paths["validate"]), "--out", str(result), "--quiet"]) == 0
    model = IdentifiedModel.load(result)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        segment = model.read([paths["validate"]])[0]
    assert segment.recorded is not None and segment.recorded.n_samples < segment.n_samples
    recorded_t = pd.read_csv(paths["validate"]).t.to_numpy()
    assert np.isin(segment.recorded.t, recorded_t).all()
    assert not np.isin(segment.t[1:-1], recorded_t).all()  # the grid is not the recorded stamps
    grid = model.prepare([replace(segment, recorded=None)])
    interpolated = np.mean((segment.tau - model.predict(grid.q, grid.dq, grid.ddq)) ** 2, axis=0)
    reported = json.loads(result.read_text())["validation"]["mse"]
    assert max(abs(value / reported[channel] - 1) for channel, value in zip(model.channels, interpolated)) > 1e-3


def test_selecting_samples_keeps_the_recorded_ones_beside_them(records):
    _, paths = records
    model = build_model(load_robot("puma560", joints=3), "internal", "viscous")
    with pytest.warns(UserWarning):
        segment = read_record(paths["validate"], model=model, split=False)[0]
    half = segment.select(slice(0, segment.n_samples // 2))
    assert half.recorded.t.max() <= half.t[-1] + 0.5 * np.median(np.diff(segment.t)) + 1e-12
    assert half.recorded.n_samples + segment.select(slice(segment.n_samples // 2, None)).recorded.n_samples \
        == segment.recorded.n_samples
    every_other = segment.select(np.arange(0, segment.n_samples, 2))
    assert np.all(every_other.recorded_rows < every_other.n_samples)
    np.testing.assert_array_equal(segment.recorded.t[segment.recorded_rows % 2 == 0], every_other.recorded.t)


@pytest.mark.skipif(not SHARED.is_dir(), reason="the Panda log (../shared/data/panda) is absent")
def test_panda_log_errors_are_those_of_its_recorded_samples(tmp_path):
    """The real Franka Panda log (jittered stamps, ~1 100 repeated rows, four 8.5 ms stalls): the reported
    validation error is that of its own samples."""
    log = SHARED / "Trajectory_1" / "rbt_log"
    read = lambda name: np.loadtxt(log / f"exciting_traj_{name}.txt").reshape(-1)  # noqa: E731
    t = read("time")
    t = t - t[0]
    q, tau = read("positions").reshape(-1, 7), read("torques").reshape(-1, 7)
    frame = pd.DataFrame({"t": t, **{f"q{j + 1}": q[:, j] for j in range(7)},
                          **{f"tau{j + 1}": tau[:, j] for j in range(7)}})
    train, validate = tmp_path / "train.csv", tmp_path / "validate.csv"
    frame[frame.t < 13.84].to_csv(train, index=False, float_format="%.10g")
    frame[frame.t >= 13.84].to_csv(validate, index=False, float_format="%.10g")
    result = tmp_path / "result.json"
    assert main(["identify", "--urdf", str(SHARED / "panda_gaz.urdf"), "--friction", "viscous,coulomb,offset",
                 "--data", str(train), "--validate", str(validate), "--out", str(result), "--quiet"]) == 0
    reported = json.loads(result.read_text())["validation"]["mse"]
    expected = recomputed(result, validate)
    for channel, value in expected.items():
        assert reported[channel] == pytest.approx(value, rel=1e-6)


def test_the_noise_floor_of_a_jittered_log_is_that_of_its_recorded_samples(records):
    """Interpolated onto the grid, the torques' noise is smoothed: the floor comes from the samples as recorded
    (0.2 N·m simulated: variance 0.04)."""
    folder, paths = records
    result = folder / "result.json"
    if not result.is_file():
        assert main(["identify", "--joints", "3", "--friction", "viscous", "--data", str(paths["train"]),
                     "--validate", str(paths["validate"]), "--out", str(result), "--quiet"]) == 0
    model = IdentifiedModel.load(result)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        segments = model.read([paths["validate"]])
        floor = model.floor(segments)
    assert all(0.8 < value / 0.04 < 1.25 for value in floor.values()), floor
