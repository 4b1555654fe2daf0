"""Streamed identification on the measured KUKA LWR4+ runs (jittered ~200 Hz, measured dq/ddq):
the same estimate as the in-memory path, from several files and in chunks."""

from __future__ import annotations

import dataclasses
import warnings

import numpy as np
import pytest

from dynamics.models import build_model
from dynamics.robots import load_robot
from estimation.estimators.identification_problem import IdentificationProblem
from estimation.datasets.kuka import load_kuka_run
from estimation.estimators.least_squares import WeightedLeastSquares, stack
from estimation.data.records import read_measurements
from estimation.streaming.identification import identify_files
from estimation.identification.validation import compare
from tests.conftest import shared_data

pytestmark = pytest.mark.realdata


def test_two_kuka_runs_streamed_in_chunks_equal_the_in_memory_estimate(tmp_path):
    folder = shared_data("kuka_lwr4")
    robot = load_robot(urdf=folder / "kuka_lwr4.urdf")
    model = build_model(robot, "internal", "viscous,coulomb,offset")
    paths = []
    for index in (1, 2, 3):
        path = tmp_path / f"run{index}.parquet"
        load_kuka_run(folder / f"kuka_lwr4_HW_measurements_{index}.npz").write(path)
        paths.append(path)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # resampled (jitter), implausible friction: checked elsewhere
        runs = [read_measurements(path, model=model) for path in paths]
        problems = [stack(model, run) for run in runs[:2]]
        joined = IdentificationProblem(np.concatenate([p.Y for p in problems]), np.concatenate([p.y for p in problems]),
                                       model.channels, model.base.names, model.base.expressions)
        reference = WeightedLeastSquares().fit(joined).estimate_
        result = identify_files(model, paths[:2], [paths[2]], chunk_size=1000)
    assert result.train.n_samples == joined.n_samples
    error = np.linalg.norm(result.estimate.values - reference.values) / np.linalg.norm(reference.values)
    assert error < 1e-10
    # the streamed path still takes a jittered file's errors on its resampled grid (in memory: at the recorded
    # stamps, tests/test_recorded_stamps.py); on the grid they agree
    expected = compare(model, reference.values, dataclasses.replace(runs[2], recorded=None)).mse
    for channel, value in (result.validation.mse or result.validation.mse_filtered).items():  # the sums' errors
        assert value == pytest.approx(expected[channel], rel=1e-9)
    assert [entry["resampled_from"] for entry in result.to_dict()["streaming"]["files"]] == [5027, 5027]
    # the batch-means standard deviations (a third pass) equal those computed in memory on the same residuals
    from tests.test_streamed_identification_covariance import classical_std_of, in_memory_batch_means

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        std = in_memory_batch_means(model, paths[:2], result)[0]
    assert result.to_dict()["cov_method"] == "batch_means"
    assert np.max(np.abs(result.estimate.std - std) / std) < 1e-8
    assert np.median(result.estimate.std / classical_std_of(result)) > 2.0  # the measured residuals are coloured
