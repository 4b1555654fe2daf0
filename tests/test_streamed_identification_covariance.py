"""The batch-means standard deviations of the streamed identification (a third pass over the files)
against the batch means computed in memory on the same residuals and scores."""

from __future__ import annotations

import json
from concurrent.futures import ProcessPoolExecutor

import numpy as np
import pytest

from dynamics.models import build_model
from dynamics.robots import load_robot
from estimation.uncertainty.batch_means import batch_length, batch_means
from estimation.streaming.cluster import IncompleteSumError, WorkerLostError
from estimation.data.records import read_measurements
from dynamics.measurements import Measurements
from estimation.preprocessing.differentiation import ButterworthDifferentiation, FourierDifferentiation, fill_derivatives
from estimation.streaming.identification import identify_files
from oed.cli import main
from dynamics.simulation.synthetic import simulate, true_parameters

from oed.fourier import random_fourier

NOISE = 0.3


@pytest.fixture(scope="module")
def model():
    return build_model(load_robot("puma560", joints=3), "internal", "viscous")


def _ar1(rng, n_samples: int, n_channels: int, rho: float, std: float) -> np.ndarray:
    """``(N, m)`` AR(1) noise of stationary standard deviation ``std``."""
    shocks = rng.standard_normal((n_samples, n_channels)) * std * np.sqrt(1 - rho**2)
    values = np.empty_like(shocks)
    values[0] = rng.standard_normal(n_channels) * std
    for t in range(1, n_samples):
        values[t] = rho * values[t - 1] + shocks[t]
    return values


@pytest.fixture(scope="module")
def files(model, tmp_path_factory):
    """A 3-joint PUMA record (q, dq, ddq, tau; 2 000 samples at 200 Hz), its torques with white noise
    (``white``) or with slow AR(1) noise the model does not describe (``coloured``), each split in two files."""
    folder = tmp_path_factory.mktemp("streamed_hac")
    theta = true_parameters(model, seed=4)
    data = simulate(model, theta, random_fourier(model.robot, seed=6), noise={c: NOISE for c in model.channels},
                    seed=3, rate_hz=200.0, periods=2)
    rng = np.random.default_rng(8)
    coloured = data.tau - (data.tau - model.predict(theta, data.q, data.dq, data.ddq)) \
        + _ar1(rng, data.n_samples, model.n_channels, 0.97, NOISE)
    paths: dict[str, list] = {"white": [], "coloured": []}
    for name, tau in (("white", data.tau), ("coloured", coloured)):
        record = data.__class__(data.t, data.q, data.dq, data.ddq, tau)
        for index, rows in enumerate((slice(0, 1100), slice(1100, None))):
            path = folder / f"{name}{index}.csv"
            record.select(rows).write(path)
            paths[name].append(path)
    return paths


def batch_length_of(result):
    return result.streaming["covariance"]["batch_length"]


def classical_std_of(result):
    """The white-noise standard deviations the streamed result reports beside its batch-means ones."""
    return np.array([result.streaming["covariance"]["classical_std"][name] for name in result.estimate.names])


def in_memory_batch_means(model, paths, result, method=None):
    """The batch-means covariance on the stacked records' residuals and scores at the streamed estimate
    (each file read and prepared whole by ``method``; batches restarting at each file), with the
    streamed batch length, floored at the classical std."""
    records = [fill_derivatives(read_measurements(path, model=model), method) for path in paths]
    theta, weights = result.estimate.values, result.estimate.weights
    scores, residuals, H = [], [], 0.0
    for record in records:
        Y = model.evaluate_base(record.q, record.dq, record.ddq)  # (N, m, p)
        residual = record.channels(model.channels) - np.einsum("ncp,p->nc", Y, theta)
        scores.append(np.einsum("c,nc,ncp->np", weights, residual, Y))
        residuals.append(residual.T)
        H = H + np.einsum("c,ncp,ncq->pq", weights, Y, Y)
    bounds = np.cumsum([0] + [record.n_samples for record in records])
    segments = list(zip(bounds[:-1], bounds[1:]))
    score, residual = np.concatenate(scores), np.concatenate(residuals, axis=1)
    n_samples, p = score.shape
    inverse = np.linalg.inv(H)
    cov = inverse @ batch_means(score, batch_length_of(result), segments) @ inverse * n_samples / (n_samples - p)
    std = np.sqrt(np.maximum(np.diag(cov), classical_std_of(result)**2))
    return std, batch_length(residual, weights, segments)


@pytest.mark.parametrize("name", ["white", "coloured"])
def test_streamed_batch_means_std_equal_the_in_memory_batch_means(model, files, name):
    result = identify_files(model, files[name], chunk_size=300)
    assert result.estimate.cov_method == "batch_means" and result.to_dict()["cov_method"] == "batch_means"
    std, andrews = in_memory_batch_means(model, files[name], result)
    assert np.max(np.abs(result.estimate.std - std) / std) < 1e-8
    # the power of two nearest to Andrews' length of the whole record, at least twenty batches
    allowed = [2**k for k in range(17) if 2**k <= result.train.n_samples // 20]
    assert batch_length_of(result) == min(allowed, key=lambda length: abs(np.log(length / andrews)))
    classical = identify_files(model, files[name], chunk_size=300, covariance="classical")
    assert classical.estimate.cov_method == "classical" and batch_length_of(classical) is None
    assert np.allclose(classical.estimate.std, classical_std_of(result), rtol=1e-12)
    assert np.allclose(classical.estimate.values, result.estimate.values, rtol=1e-12)
    ratio = result.estimate.std / classical_std_of(result)
    if name == "white":
        assert np.all(ratio >= 1.0) and np.median(ratio) < 1.3, ratio
    else:  # slow AR(1) noise: the white-noise std are far too small
        assert np.median(ratio) > 2.0, ratio


def test_filter_and_fourier_paths_score_the_samples_they_summed(model, files, tmp_path):
    """Positions and torques only: the third pass prepares the files again exactly as the sums did
    (Butterworth on overlapping windows; on the Fourier path the averaged period)."""
    rng = np.random.default_rng(2)
    raw = []
    for index, path in enumerate(files["coloured"]):
        record = read_measurements(path, model=model)
        raw.append(tmp_path / f"raw{index}.parquet")
        Measurements(record.t, record.q + 1e-5 * rng.standard_normal(record.q.shape), tau=record.tau).write(raw[-1])
    filtered = identify_files(model, raw, chunk_size=250, cutoff_hz=8.0)
    std = in_memory_batch_means(model, raw, filtered, ButterworthDifferentiation(8.0))[0]
    assert np.max(np.abs(filtered.estimate.std - std) / std) < 1e-8
    assert np.median(filtered.estimate.std / classical_std_of(filtered)) > 2.0
    whole = tmp_path / "periodic.csv"  # the two periods of 0.2 Hz at 200 Hz in one file
    record = read_measurements(files["coloured"][0], model=model)
    second = read_measurements(files["coloured"][1], model=model)
    Measurements(np.r_[record.t, second.t], np.r_[record.q, second.q], tau=np.r_[record.tau, second.tau]).write(whole)
    periodic = identify_files(model, [whole], chunk_size=300, frequency_hz=0.2, harmonics=10)
    assert periodic.train.n_samples == 1000 and periodic.estimate.cov_method == "batch_means"
    std = in_memory_batch_means(model, [whole], periodic, FourierDifferentiation(0.2, 10))[0]
    assert np.max(np.abs(periodic.estimate.std - std) / std) < 1e-8


def test_a_file_changed_between_the_passes_is_refused(model, files, monkeypatch):
    import estimation.streaming.identification as passes

    original = passes.plan_chunks  # what the covariance pass reads the files with

    def shorter(*args, **kwargs):
        chunks = list(original(*args, **kwargs))
        yield from chunks[:-1]

    monkeypatch.setattr(passes, "plan_chunks", shorter)
    with pytest.raises(IncompleteSumError, match="white0.csv.*scored"):
        identify_files(model, files["white"], chunk_size=300)


def test_process_pool_gives_the_serial_std(model, files):
    serial = identify_files(model, files["coloured"], chunk_size=500)
    with ProcessPoolExecutor(2) as executor:
        pooled = identify_files(model, files["coloured"], chunk_size=500, executor=executor)
    assert batch_length_of(pooled) == batch_length_of(serial)
    assert np.max(np.abs(pooled.estimate.std - serial.estimate.std) / serial.estimate.std) < 1e-10


def test_a_worker_lost_in_the_covariance_pass_fails_the_run(model, files):
    from tests.test_streaming import LostExecutor  # its worker dies on its second task

    executor = LostExecutor()
    executor.calls = -1  # two files summed, then the covariance pass's first task is the one lost
    with pytest.raises(WorkerLostError, match="white0.csv"):
        identify_files(model, files["white"], chunk_size=300, executor=executor)


def test_cli_streamed_identify_reports_batch_means(model, files, tmp_path):
    out = tmp_path / "identify.json"
    # the weighted fit asked for: without a validation record the default answer is the consistent fit, whose
    # standard deviations are the reduced Hessian's (as in memory)
    arguments = ["identify", "--joints", "3", "--model", "internal", "--friction", "viscous", "--chunk-size", "400",
                 "--method", "wls", "--out", str(out)]
    assert main(arguments + [arg for path in files["coloured"] for arg in ("--data", str(path))]) == 0
    document = json.loads(out.read_text())
    assert document["cov_method"] == "batch_means"
    covariance = document["streaming"]["covariance"]
    assert covariance["method"] == "batch_means" and covariance["batch_length"] >= 1
    assert set(covariance["classical_std"]) == {entry["name"] for entry in document["parameters"]}
    assert {"sums_pass", "covariance_pass"} <= set(document["streaming"]["seconds"])
    assert all(entry["std"] >= covariance["classical_std"][entry["name"]] for entry in document["parameters"])


def test_covariance_choice_is_checked(model, files):
    with pytest.raises(ValueError, match="covariance"):
        identify_files(model, files["white"], chunk_size=300, covariance="newey-west")
