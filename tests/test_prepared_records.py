"""``prepare_records``: the records of an identification read once, prepared by one plan chosen on the
training data, rows at rest dropped, the records as read kept for the noise floor."""

from __future__ import annotations

from collections import Counter
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

import dynamics.runtime.memory
import estimation.data.motor_side
from dynamics.models import build_model
from dynamics.robots import load_robot
from dynamics.runtime.memory import InsufficientMemoryError
from estimation.data.records import read_record
from estimation.preprocessing.plan import choose_preprocessing, prepare
from estimation.identification.prepared import (
    InMemoryBudget,
    PreparationSettings,
    prepare_records,
)
from oed.cli import main
from dynamics.simulation.synthetic import simulate, true_parameters
from oed.fourier import random_fourier

NOISE = {"tau1": 0.3, "tau2": 0.3, "tau3": 0.1}


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    """Positions and torques only (derivatives to derive) of three experiments: train, validation, test."""
    robot = load_robot("puma560", joints=3)
    model = build_model(robot, "internal", "viscous")
    theta = true_parameters(model, seed=2)
    folder = tmp_path_factory.mktemp("prepared")
    paths = []
    for name, seed in (("train", 3), ("validation", 4), ("test", 5)):
        record = simulate(model, theta, random_fourier(robot, seed), periods=2, noise=NOISE, seed=seed)
        path = folder / f"{name}.csv"
        replace(record, dq=None, ddq=None).write(path)
        paths.append(path)
    return model, paths


@pytest.fixture
def reads(monkeypatch):
    """How many times each file is read (every reader goes through ``read_record``)."""
    counts: Counter[str] = Counter()

    def counted(path, **options):
        counts[Path(path).name] += 1
        return read_record(path, **options)

    monkeypatch.setattr(estimation.data.motor_side, "read_record", counted)
    return counts


def test_each_record_is_read_once_and_prepared_by_the_plan_chosen_on_the_training_data(files, reads):
    model, (train, validation, test) = files
    records = prepare_records(model, [train], [validation], [test], PreparationSettings(frequency_hz=0.2))
    assert reads == {"train.csv": 1, "validation.csv": 1, "test.csv": 1}
    expected_plan = choose_preprocessing(read_record(train, model=model), frequency_hz=0.2)
    assert records.preprocessing == expected_plan and records.preprocessing.method == "fourier"
    for record, path in ((records.validation, validation), (records.test, test)):
        as_read = read_record(path, model=model, split=False)
        assert [file.path for file in record.files] == [path] and len(record.segments) == len(as_read) == 1
        np.testing.assert_array_equal(record.segments[0].q, as_read[0].q)
        assert record.segments[0].dq is None  # as read: nothing derived
        prepared = prepare(as_read, expected_plan, role="validation data")
        np.testing.assert_array_equal(record.measurements.dq, prepared.dq)
        np.testing.assert_array_equal(record.measurements.tau, prepared.tau)
        assert record.rest is None


def test_without_held_out_files_only_the_training_record_is_prepared(files):
    model, (train, _, _) = files
    records = prepare_records(model, [train], settings=PreparationSettings(cutoff_hz=4.0))
    assert records.validation is None and records.test is None
    assert records.preprocessing.method == "butterworth" and records.preprocessing.cutoff_hz == 4.0


def test_rows_at_rest_are_dropped_from_every_record_and_counted(files):
    model, (train, validation, _) = files
    kept = prepare_records(model, [train], [validation], settings=PreparationSettings(frequency_hz=0.2))
    speed = float(np.quantile(np.min(np.abs(kept.train.measurements.dq), axis=1), 0.2))
    dropped = prepare_records(model, [train], [validation],
                              settings=PreparationSettings(frequency_hz=0.2, min_speed=speed))
    for before, after in ((kept.train, dropped.train), (kept.validation, dropped.validation)):
        assert after.rest.total == before.measurements.n_samples
        assert after.rest.dropped == before.measurements.n_samples - after.measurements.n_samples > 0
        assert np.all(np.abs(after.measurements.dq) >= speed)
    smoothed = prepare_records(model, [train], settings=PreparationSettings(frequency_hz=0.2, min_speed=speed,
                                                                            rest="smooth"))
    assert smoothed.train.rest is None  # the smoothing changes the model, not the records
    assert smoothed.train.measurements.n_samples == kept.train.measurements.n_samples


def test_the_memory_budget_counts_the_prepared_samples_before_rows_at_rest_are_dropped(files, monkeypatch):
    model, (train, validation, _) = files
    records = prepare_records(model, [train], [validation], settings=PreparationSettings(frequency_hz=0.2))
    samples = records.train.measurements.n_samples + records.validation.measurements.n_samples  # periods averaged
    monkeypatch.setattr(dynamics.runtime.memory, "available_memory", lambda: 10**5)
    budget = InMemoryBudget(16, "identifying", "stream them")
    settings = PreparationSettings(frequency_hz=0.2, min_speed=1e3, memory=budget)  # would leave no row
    with pytest.raises(InsufficientMemoryError, match=rf"^identifying {samples} samples in memory \(stream them\) needs"):
        prepare_records(model, [train], [validation], settings=settings)


def test_a_file_given_twice_is_an_error_naming_it(files):
    model, (train, _, _) = files
    with pytest.raises(ValueError, match=f"{train} given twice"):
        prepare_records(model, [train, train])


@pytest.mark.parametrize(("options", "message"), [
    ({"max_gap": 0.0}, "--max-gap must be a positive number of seconds, got 0.0"),
    ({"max_gap": float("nan")}, "--max-gap must be a positive number of seconds, got nan"),
    ({"rest": "keep"}, "rest must be 'drop' or 'smooth', got 'keep'"),
])
def test_settings_refuse_a_gap_of_no_length_and_an_unknown_rest_handling(options, message):
    with pytest.raises(ValueError, match=message):
        PreparationSettings(**options)


def test_diagnose_reads_the_validation_file_once_for_the_fit_and_its_noise_floor(files, reads, tmp_path):
    _, (train, validation, _) = files
    code = main(["diagnose", "--joints", "3", "--data", str(train), "--validate", str(validation), "--frequency", "0.2",
                 "--max-effects", "1", "--out", str(tmp_path / "report.json")])
    assert code == 0
    assert reads == {"train.csv": 1, "validation.csv": 1}
