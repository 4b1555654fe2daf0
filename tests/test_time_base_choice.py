"""The two time bases as candidates (estimation.identification.time_base_choice): the samples at their stamps, or
on the regular clock the stamps jitter around, chosen on the validation record where the positions say the stamps
may be a logger's receive times. The truth is known by construction: a simulated robot's samples taken on a regular
clock and stamped late or early (receive times), against the same samples taken at their jittered stamps."""

from __future__ import annotations

import json
import warnings

import numpy as np
import pandas as pd
import pytest

from dynamics.measurements import Measurements
from dynamics.robots import load_robot
from dynamics.simulation.simulator import Simulator
from estimation.data.sampling_clock import CLOCK_TOLERANCE, on_regular_clock, regular_clock
from estimation.identification.identified_model import IdentifiedModel
from oed.cli import main
from oed.fourier import random_fourier

RATE = 500.0


def moved(count: int, fraction: float, seed: int) -> np.ndarray:
    """Each sample's stamp moved by a uniform error of at most ``fraction`` of a step, s."""
    return np.random.default_rng(seed).uniform(-fraction, fraction, count) / RATE


def test_the_regular_clock_is_found_from_stamps_that_jitter_around_it():
    truth = 0.25 + np.arange(3000) / RATE
    stamps = truth + moved(truth.shape[0], 0.4, seed=1)
    clock = regular_clock(stamps)
    assert clock is not None
    assert np.max(np.abs(clock - truth)) < 0.02 / RATE  # within 2 % of a step of the true instants
    assert np.max(np.abs(stamps - truth)) > 0.3 / RATE  # where the stamps were up to 40 % off


def test_no_regular_clock_where_a_row_was_dropped_inside_the_segment():
    truth = np.arange(3000) / RATE
    kept = np.ones(truth.shape[0], dtype=bool)
    kept[1500:1502] = False  # two rows lost: the index is no longer the sample's instant
    assert regular_clock(truth[kept] + moved(int(kept.sum()), 0.2, seed=2)) is None
    assert CLOCK_TOLERANCE == 0.5


def test_on_the_regular_clock_every_recorded_row_keeps_its_values():
    truth = np.arange(400) / RATE
    stamps = truth + moved(truth.shape[0], 0.4, seed=3)
    q = np.column_stack([np.sin(truth), np.cos(truth)])
    grid = np.linspace(stamps[0], stamps[-1], stamps.shape[0])
    recorded = Measurements(stamps, q, tau=2 * q, metadata={"recorded_stamps": True})
    segment = Measurements(grid, np.column_stack([np.interp(grid, stamps, column) for column in q.T]),
                           tau=np.column_stack([np.interp(grid, stamps, column) for column in (2 * q).T]),
                           metadata={"source": "x", "resampled_from": 400}, recorded=recorded,
                           recorded_rows=np.arange(400))
    clocked = on_regular_clock(segment)
    assert clocked is not None and clocked.recorded is None and clocked.metadata["time_base"] == "regular"
    np.testing.assert_array_equal(clocked.q, q)
    np.testing.assert_array_equal(clocked.tau, 2 * q)  # the recorded torques, never interpolated
    plain = Measurements(truth, q)
    assert on_regular_clock(plain) is plain  # regular stamps: nothing to place


def simulated(folder, at_stamps: bool) -> dict[str, str]:
    """A 3-joint PUMA's training, validation and test records at 500 Hz, positions and torques only, the stamps
    moved by up to 40 % of a step: the samples taken on the regular clock (``at_stamps`` False: receive times), or
    at the moved stamps."""
    robot = load_robot("puma560", joints=3)
    simulator = Simulator(robot, rate_hz=RATE)
    paths = {}
    for name, seed in (("train", 11), ("validate", 12), ("test", 13)):
        trajectory = random_fourier(robot, seed, frequency_hz=0.2)
        measurements = simulator.run(trajectory, duration=6.0, warmup_periods=1, seed=seed).measurements
        stamps = measurements.t + moved(measurements.t.shape[0], 0.4, seed + 100)
        frame = measurements.to_frame()
        frame = frame[[column for column in frame.columns if not column.startswith(("dq", "ddq"))]]
        if at_stamps:  # the samples taken at the moved stamps: the motion evaluated there
            for column in frame.columns:
                if column != "t":
                    frame[column] = np.interp(stamps, measurements.t, frame[column].to_numpy())
        frame["t"] = stamps
        paths[name] = str(folder / f"{name}.csv")
        frame.to_csv(paths[name], index=False, float_format="%.12g")
    return paths


def _identified(tmp_path, paths):
    """The default ``oed identify`` (viscous friction) on the simulated training and validation records: the result
    file's path and its document."""
    result = tmp_path / "result.json"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        assert main(["identify", "--joints", "3", "--friction", "viscous", "--data", paths["train"],
                     "--validate", paths["validate"], "--out", str(result), "--quiet"]) == 0
    return result, json.loads(result.read_text())


@pytest.mark.slow
def test_receive_time_stamps_choose_the_regular_clock_and_predict_follows_it(tmp_path):
    paths = simulated(tmp_path, at_stamps=False)
    result, document = _identified(tmp_path, paths)
    preprocessing = document["preprocessing"]
    assert preprocessing["time_base"] == "regular"
    scores = preprocessing["time_base_scores"]
    assert scores["regular"] < scores["stamps"]
    assert preprocessing["receive_times_ratio"] > 2
    # oed predict reads a record on the same clock, reproduces the verb's error, keeps the recorded t
    predicted, metrics = tmp_path / "predicted.csv", tmp_path / "metrics.json"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        assert main(["predict", "--model", str(result), "--data", paths["validate"], "--out", str(predicted),
                     "--metrics", str(metrics)]) == 0
    reported = document["model_file"]["reported"]["validation_mse"]
    measured = json.loads(metrics.read_text())["mse"]
    for channel, value in reported.items():
        assert measured[channel] == pytest.approx(value, rel=1e-6)
    table = pd.read_csv(predicted)
    recorded = pd.read_csv(paths["validate"])
    np.testing.assert_allclose(table.t.to_numpy(), recorded.t.to_numpy(), rtol=0, atol=1e-12)
    assert "t_clock" in table.columns and np.ptp(np.diff(table.t_clock.to_numpy())) < 1e-9
    np.testing.assert_allclose(table.tau1_measured.to_numpy(), recorded.tau1.to_numpy(), rtol=0, atol=1e-9)
    # and the model file read alike: the same clock, the stamps as recorded beside it
    model = IdentifiedModel.load(result)
    assert model.preprocessing.time_base == "regular"


@pytest.mark.slow
def test_samples_taken_at_their_stamps_keep_the_stamps_and_score_nothing_twice(tmp_path):
    paths = simulated(tmp_path, at_stamps=True)
    _, document = _identified(tmp_path, paths)
    preprocessing = document["preprocessing"]
    assert "time_base" not in preprocessing and "time_base_scores" not in preprocessing
