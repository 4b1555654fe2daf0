"""The measured-data loader: round trips, and each problem named in its error or warning."""

from __future__ import annotations

import warnings

import numpy as np
import pandas as pd
import pytest

from dynamics.models import build_model
from dynamics.robots import load_robot
from estimation.data.loading import (
    AngleUnitError,
    DuplicatedTimesWarning,
    JointCountError,
    MeasurementWarning,
    MissingColumnError,
    NonFiniteError,
    ReceiveTimesWarning,
    ResampledWarning,
    TimeBaseError,
    TooFewSamplesError,
)
from estimation.data.date_times import DateTimeStampsWarning
from estimation.data.records import read_measurements, read_record
from dynamics.measurements import Measurements


@pytest.fixture(scope="module")
def model():
    return build_model(load_robot("puma560", joints=3), "combined", "viscous")


def sample_data(n_samples: int = 200) -> Measurements:
    generator = np.random.default_rng(0)
    t = np.arange(n_samples) / 100.0
    q = np.column_stack([np.sin(t), 0.5 * np.cos(2 * t), 0.2 * t])
    return Measurements(t, q, np.gradient(q, t, axis=0), None, generator.normal(size=(n_samples, 3)),
                        generator.normal(size=(n_samples, 6)))


@pytest.mark.parametrize("suffix", [".csv", ".parquet"])
def test_written_measurements_read_back_unchanged(tmp_path, model, suffix):
    data = sample_data()
    path = tmp_path / f"data{suffix}"
    data.write(path)
    loaded = read_measurements(path, model=model)
    for name in ("t", "q", "dq", "tau", "wrench"):
        np.testing.assert_allclose(getattr(loaded, name), getattr(data, name), rtol=1e-9, atol=1e-12)
    assert loaded.ddq is None
    assert read_measurements(path).n_joints == 3


def write_frame(tmp_path, frame: pd.DataFrame):
    path = tmp_path / "data.csv"
    frame.to_csv(path, index=False)
    return path


def test_missing_columns_of_the_model_are_named(tmp_path, model):
    frame = sample_data().to_frame().drop(columns=["mz"])
    with pytest.raises(MissingColumnError, match=r"mz .*wrench"):
        read_measurements(write_frame(tmp_path, frame), model=model)
    frame = sample_data().to_frame().drop(columns=["tau2"])
    with pytest.raises(MissingColumnError, match="tau2"):
        read_measurements(write_frame(tmp_path, frame), model="internal", n_joints=3)
    # the internal model does not need the wrench
    frame = sample_data().to_frame().drop(columns=["fx", "fy", "fz", "mx", "my", "mz"])
    assert read_measurements(write_frame(tmp_path, frame), model="internal").wrench is None


def test_nan_is_reported_with_column_and_row(tmp_path, model):
    frame = sample_data().to_frame()
    frame.loc[17, "q2"] = np.nan
    with pytest.raises(NonFiniteError, match=r"column q2 .*row 17"):
        read_measurements(write_frame(tmp_path, frame), model=model)
    frame = sample_data().to_frame()
    frame.loc[3, "fz"] = np.inf
    with pytest.raises(NonFiniteError, match="fz"):
        read_measurements(write_frame(tmp_path, frame), model=model)


def test_duplicated_and_decreasing_times_are_errors(tmp_path, model):
    frame = sample_data().to_frame()
    frame["t"] = np.floor(frame["t"] * 10) / 10  # a coarse clock: most rows share a stamp
    with pytest.raises(TimeBaseError, match="duplicated"):
        read_measurements(write_frame(tmp_path, frame), model=model)
    frame = sample_data().to_frame()
    frame.loc[10, "t"] = 0.0
    with pytest.raises(TimeBaseError, match="decreases at row 10"):
        read_measurements(write_frame(tmp_path, frame), model=model)


def test_a_few_duplicated_time_stamps_with_new_values_are_dropped(tmp_path, model):
    """A logger's clock that did not tick now and then (issue 34: a Panda-like log with ten such rows exited):
    the later row of each pair dropped with a warning counting them, the record read as if it had not been
    logged; the rows kept are those recorded (their torques never interpolated)."""
    frame = sample_data(400).to_frame()
    rows = [40, 75, 130]
    frame.loc[rows, "t"] = frame.loc[[row - 1 for row in rows], "t"].to_numpy()
    with pytest.warns(MeasurementWarning) as caught:  # and a stall: the dropped rows' instants are missing
        (segment,) = read_record(write_frame(tmp_path, frame), model=model)
    said = [str(warning.message) for warning in caught if warning.category is DuplicatedTimesWarning]
    assert len(said) == 1 and "dropped 3 row(s) stamped with the previous row's time" in said[0], said
    assert segment.metadata["duplicated_times_dropped"] == 3
    recorded = segment.as_recorded
    kept = np.setdiff1d(np.arange(len(frame)), rows)
    np.testing.assert_array_equal(recorded.t, frame["t"].to_numpy()[kept])
    np.testing.assert_array_equal(recorded.tau[:, 0], frame["tau1"].to_numpy()[kept])


def test_time_in_other_units_and_gaps_are_errors_not_resampled(tmp_path, model):
    frame = sample_data().to_frame()
    frame["t"] = frame["t"] * 1e3  # milliseconds
    with pytest.raises(TimeBaseError, match="advances by 10 a sample: .* milliseconds or nanoseconds"):
        read_measurements(write_frame(tmp_path, frame), model=model)
    frame = sample_data().to_frame()
    seconds = frame["t"].to_numpy()
    frame["t"] = pd.Timestamp("2026-01-01") + pd.to_timedelta(frame["t"], unit="s")
    path = tmp_path / "dates.parquet"
    frame.to_parquet(path)
    with pytest.warns(DateTimeStampsWarning, match="column t holds date-times"):  # refused until h-unseen16
        read = read_measurements(path, model=model)
    np.testing.assert_allclose(read.t, seconds - seconds[0], rtol=0, atol=1e-9)
    frame = sample_data().to_frame()
    frame.loc[100:, "t"] += 10.0  # the logger stopped for 10 s
    with pytest.raises(TimeBaseError, match="jumps by 10.01 s between rows 99 and 100 .* split the record"):
        read_measurements(write_frame(tmp_path, frame), model=model)


def test_a_stalled_logger_that_catches_up_is_jitter_not_a_gap(tmp_path, model):
    frame = sample_data().to_frame()
    t = frame["t"].to_numpy().copy()
    t[50:56] = t[56] - 0.001 * np.arange(6, 0, -1) * 0.01  # six samples arrive late, in a burst
    frame["t"] = t
    with pytest.warns(MeasurementWarning) as caught:
        loaded = read_measurements(write_frame(tmp_path, frame), model=model)
    assert loaded.n_samples == 200
    messages = [str(warning.message) for warning in caught]
    assert any("stalls for 0.06994 s after row 49 and the following samples come in a burst" in m for m in messages)
    assert any(isinstance(warning.message, ResampledWarning) for warning in caught)
    frame["t"] = np.arange(200) * 0.01
    frame.loc[100:, "t"] += 0.045  # a hole of 5.5 steps: 4.5 samples missing, just over the line
    with pytest.raises(TimeBaseError, match="a gap in the record"):
        read_measurements(write_frame(tmp_path, frame), model=model)


def test_nan_cells_are_shown_as_plain_numbers(tmp_path, model):
    frame = sample_data().to_frame()
    frame.loc[5, "tau1"] = np.nan
    with pytest.raises(NonFiniteError, match=r"first at row 5 \(nan\)$"):
        read_measurements(write_frame(tmp_path, frame), model=model)


def test_irregular_sampling_is_resampled_with_a_warning(tmp_path, model):
    frame = sample_data().to_frame()
    jitter = np.random.default_rng(1).uniform(-0.003, 0.003, len(frame))
    jitter[[0, -1]] = 0
    frame["t"] = frame["t"] + jitter
    frame["q1"] = np.sin(frame["t"])
    # q2 and q3 stay those of the regular instants: the stamps look like receive times for them, and it is said
    with pytest.warns(ReceiveTimesWarning), pytest.warns(ResampledWarning, match="irregular sampling"):
        loaded = read_measurements(write_frame(tmp_path, frame), model=model)
    steps = np.diff(loaded.t)
    np.testing.assert_allclose(steps, steps[0], rtol=1e-9)
    # interpolation of a smooth column stays close to the truth
    np.testing.assert_allclose(loaded.q[:, 0], np.sin(loaded.t), atol=2e-3)
    with pytest.raises(TimeBaseError, match="irregular"):
        read_measurements(write_frame(tmp_path, frame), model=model, resample=False)


def test_regular_sampling_gives_no_warning(tmp_path, model):
    path = tmp_path / "data.csv"
    sample_data().write(path)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        read_measurements(path, model=model)


def test_angles_in_degrees_are_caught(tmp_path, model):
    frame = sample_data().to_frame()
    frame["q1"] = np.rad2deg(frame["q1"]) * 3
    with pytest.raises(AngleUnitError, match=r"q1 .*degrees"):
        read_measurements(write_frame(tmp_path, frame), model=model)


def test_too_few_samples_for_the_parameter_count(tmp_path, model):
    path = tmp_path / "short.csv"
    sample_data(model.n_base).write(path)
    with pytest.raises(TooFewSamplesError, match=f"{model.n_base} base parameters"):
        read_measurements(path, model=model)


def test_unknown_format_and_missing_file(tmp_path):
    with pytest.raises(ValueError, match="use .csv or .parquet"):  # a .txt table is read as CSV since h-logs5
        read_measurements(tmp_path / "data.xlsx")
    with pytest.raises(FileNotFoundError):
        read_measurements(tmp_path / "absent.csv")


def test_joint_columns_beyond_the_robot_are_an_error(tmp_path, model):
    """Data of a 4-joint robot read for the 3-joint PUMA: joint 4's motion would be silently ignored."""
    frame = sample_data().to_frame().drop(columns=["dq1", "dq2", "dq3"])
    frame["q4"], frame["tau4"] = 0.1, 0.0
    with pytest.raises(JointCountError, match=r"q4, tau4 beyond the robot's 3 joint"):
        read_measurements(write_frame(tmp_path, frame), model=model)
    with pytest.raises(JointCountError, match="q4"):
        read_measurements(write_frame(tmp_path, frame), n_joints=3)
    assert read_measurements(write_frame(tmp_path, frame)).n_joints == 4  # no robot given: the file says 4


def test_cli_identify_with_data_of_more_joints_fails_cleanly(tmp_path, capsys):
    from oed.cli import main

    frame = sample_data(400).to_frame()
    frame["q4"], frame["tau4"] = 0.1, 0.0
    out = tmp_path / "result.json"
    assert main(["identify", "--joints", "3", "--model", "internal", "--data", str(write_frame(tmp_path, frame)),
                 "--out", str(out)]) == 2
    assert "q4, tau4 beyond the robot's 3 joint" in capsys.readouterr().err
    assert not out.exists()


def test_cli_prints_the_resampling_warning_on_stderr(tmp_path, capsys):
    """stdout carries the result table; a repair of the data is a diagnostic, on stderr."""
    from oed.cli import main

    frame = sample_data(400).to_frame().drop(index=range(100, 200, 3))
    out = tmp_path / "result.json"
    assert main(["identify", "--joints", "3", "--model", "internal", "--data", str(write_frame(tmp_path, frame)),
                 "--out", str(out)]) == 0
    captured = capsys.readouterr()
    assert "oed identify: warning:" in captured.err and "resampled" in captured.err
    assert "warning" not in captured.out
