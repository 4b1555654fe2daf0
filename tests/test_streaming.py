"""Streamed identification (chunks, several files, executors, dask) against the in-memory path."""

from __future__ import annotations

import json
import re
from concurrent.futures import Future, ThreadPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from dataclasses import replace

import numpy as np
import pytest

from dynamics.models import build_model
from dynamics.robots import load_robot
from estimation.streaming.cluster import IncompleteSumError, WorkerLostError, check_parts, sum_files
from estimation.estimators.identification_problem import IdentificationProblem, ResidualBand
from estimation.estimators.least_squares import WeightedLeastSquares, stack
from estimation.data.loading import (MeasurementError, MissingColumnError, ReceiveTimesWarning, ResampledWarning, StallWarning,
                                     TimeBaseError)
from estimation.data.records import read_measurements
from dynamics.measurements import Measurements
from estimation.estimators.summed_least_squares import SummedLeastSquares
from estimation.preprocessing.differentiation import ButterworthDifferentiation, fill_derivatives
from estimation.streaming.identification import identify_files
from estimation.streaming.chunks import StreamingUnsupportedError, file_sums, filter_margin, segment_sources
from oed.cli import main
from dynamics.simulation.synthetic import simulate, true_parameters

from oed.fourier import random_fourier

NOISE = {"tau1": 0.5, "tau2": 0.5, "tau3": 0.2}
CUTOFF = 10.0



def weighted_values(document):
    """The weighted least-squares estimate of a ``result.json``: without a validation record the default answer is
    the consistent refit of it (as in memory), the weighted fit an alternative of the model file."""
    model_file = document["model_file"]
    entry = model_file if model_file["chosen"] == "wls" else model_file["alternatives"]["wls"]
    return np.array(entry["theta"])

def relative(a, b) -> float:
    return float(np.linalg.norm(np.asarray(a) - b) / np.linalg.norm(b))


@pytest.fixture(scope="module")
def model():
    return build_model(load_robot("puma560", joints=3), "internal", "viscous")


@pytest.fixture(scope="module")
def files(model, tmp_path_factory):
    """Three records (5 000, 4 000 and 3 000 samples at 500 Hz) as CSV with q, dq, ddq, tau, and as
    Parquet with q and tau only (positions noisy: the filter path)."""
    folder = tmp_path_factory.mktemp("streaming")
    theta = true_parameters(model, seed=2)
    rng = np.random.default_rng(0)
    paths = {"full": [], "raw": []}
    for index, samples in enumerate((5000, 4000, 3000)):
        data = simulate(model, theta, random_fourier(model.robot, 3 + index), noise=NOISE, seed=11 + index,
                        rate_hz=500.0, periods=2).select(slice(0, samples))
        full = folder / f"full{index}.csv"
        data.write(full)
        raw = folder / f"raw{index}.parquet"
        Measurements(data.t, data.q + 1e-4 * rng.standard_normal(data.q.shape), tau=data.tau).write(raw)
        paths["full"].append(full)
        paths["raw"].append(raw)
    return paths


def in_memory(model, paths, method=None, **options):
    """WLS on the stacked problems of each file preprocessed whole (each file a segment of the motion's band when the
    torques are fitted as recorded: the channel weights from the in-band residual, each file filtered on its own)."""
    problems = [stack(model, fill_derivatives(read_measurements(path, model=model), method, **options)) for path in paths]
    bands = [problem.band for problem in problems]
    band = None
    if all(entry is not None for entry in bands):
        stops = np.cumsum([problem.n_samples for problem in problems])
        bounds = tuple(zip((0, *stops[:-1].tolist()), stops.tolist()))
        rates = tuple(entry.rate_hz for entry in bands)
        band = ResidualBand(bands[0].cutoff_hz, bands[0].order, bands[0].rate_hz, bounds if len(bounds) > 1 else (),
                            rates if len(set(rates)) > 1 else ())
    joined = IdentificationProblem(np.concatenate([p.Y for p in problems]), np.concatenate([p.y for p in problems]),
                                   problems[0].channels, problems[0].names, problems[0].expressions, band=band)
    return WeightedLeastSquares().fit(joined).estimate_


@pytest.mark.parametrize("chunk_size", [1000, 4999, 20_000])
def test_chunks_of_a_file_with_derivatives_give_the_in_memory_estimate(model, files, chunk_size):
    path = files["full"][0]
    reference = in_memory(model, [path])
    part = file_sums(path, model, chunk_size=chunk_size)
    assert part.rows == part.sums.n_samples == 5000
    estimate = SummedLeastSquares().fit(part.sums).estimate_
    assert relative(estimate.values, reference.values) < 1e-10
    assert relative(estimate.std, reference.std) < 1e-10


@pytest.mark.parametrize("chunk_size, decimation, held", [(700, 1, False), (1000, 2, False), (333, 1, True)])
def test_filter_path_on_overlapping_windows_equals_whole_record_filtering(model, files, chunk_size, decimation, held):
    path = files["raw"][0]
    reference = in_memory(model, [path], ButterworthDifferentiation(CUTOFF), decimation=decimation, held_torques=held)
    part = file_sums(path, model, chunk_size=chunk_size, cutoff_hz=CUTOFF, decimation=decimation, held_torques=held)
    assert part.sums.n_samples == part.expected_samples == -(-5000 // decimation)
    assert part.metadata["margin"] == filter_margin(500.0, CUTOFF, 4, decimation) > chunk_size // 2
    estimate = SummedLeastSquares().fit(part.sums).estimate_
    assert relative(estimate.values, reference.values) < 1e-10
    assert np.max(np.abs(estimate.values - reference.values) / reference.std) < 1e-6


def test_several_files_one_estimate_serial_threads_and_validation(model, files):
    reference = in_memory(model, files["raw"], ButterworthDifferentiation(CUTOFF))
    serial = identify_files(model, files["raw"], [files["full"][1]], chunk_size=1500, cutoff_hz=CUTOFF)
    assert relative(serial.estimate.values, reference.values) < 1e-10
    assert serial.train.n_samples == 12_000
    with ThreadPoolExecutor(2) as executor:
        threaded = identify_files(model, files["raw"], [files["full"][1]], chunk_size=1500, cutoff_hz=CUTOFF,
                                  executor=executor)
    assert relative(threaded.estimate.values, serial.estimate.values) < 1e-12
    document = serial.to_dict()
    assert document["n_samples"] == 12_000
    assert [entry["rows"] for entry in document["streaming"]["files"]] == [5000, 4000, 3000]
    # the training files were low-pass filtered: their errors are not against the recording, and say so
    assert document["train"]["mse"] is None and set(document["train"]["mse_filtered"]) == set(model.channels)
    # the validation MSE on clean, exact-derivative data sits at the simulated noise floor
    for channel, value in document["validation"]["mse"].items():
        assert 0.85 < value / NOISE[channel] ** 2 < 1.2, (channel, value)


def test_dask_local_cluster_gives_the_serial_estimate(model, files, tmp_path):
    distributed = pytest.importorskip("dask.distributed", reason="dask is an optional extra: pip install 'robot-oed[cluster]'")
    serial = identify_files(model, files["raw"], chunk_size=2000, cutoff_hz=CUTOFF)
    changing = tmp_path / "changing.csv"
    data = read_measurements(files["full"][0], model=model)
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=False, dashboard_address=None) as cluster, \
            distributed.Client(cluster) as client:
        clustered = identify_files(model, files["raw"], chunk_size=2000, cutoff_hz=CUTOFF, executor=client.get_executor())
        # dask caches results by the task's arguments (pure=True by default): a rewritten file is summed anew
        executor = client.get_executor()
        data.select(slice(0, 3000)).write(changing)
        assert sum_files(model, [changing], executor=executor, chunk_size=2000)[0].n_samples == 3000
        data.select(slice(0, 2500)).write(changing)
        assert sum_files(model, [changing], executor=executor, chunk_size=2000)[0].n_samples == 2500
        out = tmp_path / "cluster.json"
        args = ["identify", "--joints", "3", "--model", "internal", "--cutoff", str(CUTOFF), "--chunk-size", "2000",
                "--scheduler", cluster.scheduler_address, "--out", str(out)]
        assert main(args + [arg for path in files["raw"] for arg in ("--data", str(path))]) == 0
    values = weighted_values(json.loads(out.read_text()))
    assert relative(values, serial.estimate.values) < 1e-10
    assert relative(clustered.estimate.values, serial.estimate.values) < 1e-10
    assert relative(clustered.estimate.cov, serial.estimate.cov) < 1e-10


@pytest.mark.slow
def test_dask_local_cluster_of_processes_and_process_pool(model, files):
    from concurrent.futures import ProcessPoolExecutor

    distributed = pytest.importorskip("dask.distributed", reason="dask is an optional extra: pip install 'robot-oed[cluster]'")
    serial = identify_files(model, files["raw"], chunk_size=2000, cutoff_hz=CUTOFF)
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as cluster, \
            distributed.Client(cluster) as client:
        clustered = identify_files(model, files["raw"], chunk_size=2000, cutoff_hz=CUTOFF, executor=client.get_executor())
    with ProcessPoolExecutor(2) as executor:
        pooled = identify_files(model, files["raw"], chunk_size=2000, cutoff_hz=CUTOFF, executor=executor)
    assert relative(clustered.estimate.values, serial.estimate.values) < 1e-10
    assert relative(pooled.estimate.values, serial.estimate.values) < 1e-10
    # the batch-means standard deviations (a third pass through the same executor)
    assert relative(clustered.estimate.std, serial.estimate.std) < 1e-10
    assert relative(pooled.estimate.std, serial.estimate.std) < 1e-10


class LostExecutor:
    """An executor whose second task's worker dies."""

    def __init__(self):
        self.calls = 0

    def submit(self, function, *args):
        self.calls += 1
        future = Future()
        if self.calls == 2:
            future.set_exception(BrokenProcessPool("A process in the process pool was terminated abruptly"))
        else:
            future.set_result(function(*args))
        return future


def test_a_lost_worker_fails_the_run_naming_the_file(model, files):
    with pytest.raises(WorkerLostError, match="full1.csv was lost"):
        sum_files(model, files["full"], executor=LostExecutor(), chunk_size=5000)


def test_a_partial_sum_is_refused(model, files):
    part = file_sums(files["full"][0], model, chunk_size=2500)
    short = replace(part, sums=file_sums(files["full"][2], model, chunk_size=2500).sums)
    with pytest.raises(IncompleteSumError, match="3000 samples summed of the 5000"):
        check_parts(model, [part.path], [short])
    with pytest.raises(IncompleteSumError, match="1 of 2 files"):
        check_parts(model, [part.path, "other.csv"], [part])


def test_bad_files_are_named(model, files, tmp_path):
    corrupt = tmp_path / "corrupt.parquet"
    corrupt.write_bytes(b"PAR1 not really parquet")
    with pytest.raises(MeasurementError, match="corrupt.parquet"):
        sum_files(model, [files["raw"][0], corrupt], chunk_size=2000, cutoff_hz=CUTOFF)
    frame = read_measurements(files["full"][1], model=model).to_frame().drop(columns=["tau3"])
    other = tmp_path / "other.csv"
    frame.to_csv(other, index=False)
    with pytest.raises(MissingColumnError, match="other.csv.*tau3"):
        sum_files(model, [files["full"][0], other], chunk_size=2000)
    with pytest.raises(MeasurementError, match="same columns"):
        sum_files(model, [files["full"][0], files["raw"][1]], chunk_size=2000, cutoff_hz=CUTOFF)
    with pytest.raises(StreamingUnsupportedError, match="cut-off"):
        file_sums(files["raw"][0], model, chunk_size=2000)


def test_a_time_jump_between_chunks_is_refused(model, files, tmp_path):
    data = read_measurements(files["full"][0], model=model)
    shifted = replace(data, t=np.where(np.arange(data.n_samples) >= 2000, data.t + 0.5, data.t))
    path = tmp_path / "jump.csv"
    shifted.write(path)
    # the scan of the file finds the hole as the loader does: one file is one segment here (HoleError, the
    # loader's message); the verbs read its two segments (segment_sources), as the in-memory path splits it
    with pytest.raises(TimeBaseError, match="jump.csv: column t jumps by 0.502 s between rows 1999 and 2000"):
        file_sums(path, model, chunk_size=1000)
    assert [str(source) for source in segment_sources([path], model)] == [f"{path} (segment 1)", f"{path} (segment 2)"]


def test_cli_several_files_with_chunks(model, files, tmp_path):
    out = tmp_path / "result.json"
    args = ["identify", "--joints", "3", "--model", "internal", "--cutoff", str(CUTOFF), "--out", str(out)]
    for path in files["raw"]:
        args += ["--data", str(path)]
    assert main(args + ["--chunk-size", "1500"]) == 0
    document = json.loads(out.read_text())
    reference = in_memory(model, files["raw"], ButterworthDifferentiation(CUTOFF))
    values = weighted_values(document)
    assert relative(values, reference.values) < 1e-10
    assert document["streaming"]["chunk_size"] == 1500 and document["n_samples"] == 12_000
    single = tmp_path / "single.json"  # the unconstrained fit both ways (the streamed path has no consistent one)
    assert main(["identify", "--joints", "3", "--model", "internal", "--data", str(files["full"][0]), "--method", "wls",
                 "--out", str(single)]) == 0
    streamed = tmp_path / "streamed.json"
    assert main(["identify", "--joints", "3", "--model", "internal", "--data", str(files["full"][0]), "--chunk-size", "999",
                 "--method", "wls", "--out", str(streamed)]) == 0
    a, b = json.loads(single.read_text()), json.loads(streamed.read_text())
    assert set(b) == set(a)  # one document: in memory, streaming null and not_computed empty
    assert a["streaming"] is None and b["streaming"] is not None and a["not_computed"] == {}
    assert (a["identification_path"], b["identification_path"]) == ("in-memory", "streamed")
    for key in ("train",):
        for channel, value in a[key]["mse"].items():
            assert b[key]["mse"][channel] == pytest.approx(value, rel=1e-10)


def test_cli_bad_file_of_a_set_exit_2_nothing_written(files, tmp_path, capsys, monkeypatch):
    import estimation.streaming.cluster

    monkeypatch.setattr(estimation.streaming.cluster, "CONNECT_TIMEOUT", 2.0)
    corrupt = tmp_path / "corrupt.csv"
    corrupt.write_text("t,q1,q2\n0,1\nnot,a,csv,at,all\n")
    out = tmp_path / "result.json"
    code = main(["identify", "--joints", "3", "--model", "internal", "--data", str(files["full"][0]), "--data",
                 str(corrupt), "--out", str(out)])
    assert code == 2
    assert "corrupt.csv" in capsys.readouterr().err
    assert not out.exists()
    # a rate that is not a multiple of the frequency: every sample fitted, as in memory (it exited before)
    fitted = tmp_path / "every_sample.json"
    code = main(["identify", "--joints", "3", "--model", "internal", "--data", str(files["raw"][0]), "--frequency", "0.3",
                 "--chunk-size", "1000", "--out", str(fitted), "--quiet"])
    assert code == 0 and json.loads(fitted.read_text())["streaming"]["files"][0]["periods_averaged"] == 0
    capsys.readouterr()
    code = main(["identify", "--joints", "3", "--model", "internal", "--data", str(files["full"][0]), "--chunk-size",
                 "1000", "--scheduler", "tcp://127.0.0.1:1", "--out", str(out)])
    assert code == 2 and "127.0.0.1:1" in capsys.readouterr().err
    assert not out.exists()


def test_design_starts_on_a_dask_scheduler(tmp_path, monkeypatch):
    distributed = pytest.importorskip("dask.distributed", reason="dask is an optional extra: pip install 'robot-oed[cluster]'")
    out, serial = tmp_path / "cluster.json", tmp_path / "serial.json"
    args = ["design", "--joints", "3", "--model", "internal", "--starts", "2", "--max-iter", "200", "--samples", "60",
            "--constraint-points", "20", "--quiet"]
    assert main(args + ["--out", str(serial)]) == 0
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=False, dashboard_address=None) as cluster:
        monkeypatch.setenv("ROBOT_OED_SCHEDULER", cluster.scheduler_address)
        assert main(args + ["--out", str(out)]) == 0

    def timeless(value):
        if isinstance(value, dict):
            return {key: timeless(item) for key, item in value.items() if "time" not in key}
        return [timeless(item) for item in value] if isinstance(value, list) else value

    assert timeless(json.loads(serial.read_text())) == timeless(json.loads(out.read_text()))  # same trajectory, cost


def test_diagnose_max_effects_is_an_option_and_says_when_reached(model, files, tmp_path, capsys):
    out = tmp_path / "diagnosis.json"
    base = ["diagnose", "--joints", "3", "--model", "internal", "--data", str(files["full"][0]), "--validate",
            str(files["full"][1]), "--out", str(out)]
    assert main(base + ["--max-effects", "0"]) == 2
    assert "--max-effects must be a positive integer" in capsys.readouterr().err
    assert main(base + ["--max-effects", "1", "--alpha", "0.5"]) == 0
    printed = capsys.readouterr().out
    document = json.loads(out.read_text())
    assert len(document["effects"]) <= 1
    assert ("stopped at --max-effects 1" in printed) == (len(document["effects"]) == 1)


def test_a_chunk_too_short_for_the_checks_is_refused(model, files):
    with pytest.raises(ValueError, match="a chunk of 10 samples is shorter"):
        file_sums(files["full"][0], model, chunk_size=10)


@pytest.mark.parametrize("chunk_size, held", [(700, False), (2600, True)])
def test_fourier_path_averages_periods_chunk_by_chunk(model, files, tmp_path, chunk_size, held):
    """Two periods of 0.2 Hz at 500 Hz and a 700-sample tail, positions and torques only."""
    from estimation.preprocessing.differentiation import FourierDifferentiation

    theta = true_parameters(model, seed=2)
    data = simulate(model, theta, random_fourier(model.robot, 3), noise=NOISE, seed=5, rate_hz=500.0, periods=3)
    rng = np.random.default_rng(1)
    record = data.select(slice(0, 5700))
    path = tmp_path / "periodic.csv"
    Measurements(record.t, record.q + 1e-4 * rng.standard_normal(record.q.shape), tau=record.tau).write(path)
    second = tmp_path / "periodic2.csv"
    Measurements(data.t, data.q + 1e-4 * rng.standard_normal(data.q.shape), tau=data.tau).write(second)
    method = FourierDifferentiation(0.2, 15)
    alone = identify_files(model, [path], chunk_size=chunk_size, frequency_hz=0.2, harmonics=15, held_torques=held)
    assert relative(alone.estimate.values, in_memory(model, [path], method, held_torques=held).values) < 1e-10
    assert alone.train.n_samples == 2500
    both = identify_files(model, [path, second], chunk_size=chunk_size, frequency_hz=0.2, harmonics=15,
                          held_torques=held)
    assert relative(both.estimate.values, in_memory(model, [path, second], method, held_torques=held).values) < 1e-10
    document = both.to_dict()["streaming"]
    assert document["frequency_hz"] == 0.2 and document["cutoff_hz"] is None
    assert [(entry["rows"], entry["periods_averaged"]) for entry in document["files"]] == [(5700, 2), (7500, 3)]


@pytest.mark.slow
def test_a_worker_killed_on_a_dask_cluster_fails_the_run(model, files):
    import os

    distributed = pytest.importorskip("dask.distributed", reason="dask is an optional extra: pip install 'robot-oed[cluster]'")
    import dask

    class KillingExecutor:
        """Submits the second file's task as a worker's death."""

        def __init__(self, inner):
            self.inner, self.calls = inner, 0

        def submit(self, function, *args):
            self.calls += 1
            return self.inner.submit(os._exit, 1) if self.calls == 2 else self.inner.submit(function, *args)

    with dask.config.set({"distributed.scheduler.allowed-failures": 0}), \
            distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as cluster, \
            distributed.Client(cluster) as client:
        with pytest.raises(WorkerLostError, match="full1.csv was lost"):
            sum_files(model, files["full"], executor=KillingExecutor(client.get_executor()), chunk_size=5000)


@pytest.mark.parametrize("chunk_size, cutoff", [(700, None), (1200, CUTOFF)])
def test_jittered_time_is_resampled_onto_the_whole_files_grid(model, files, tmp_path, chunk_size, cutoff):
    """Stamps jittered by ±30 % of the 2 ms step (the KUKA logs jitter so): the in-memory loader resamples;
    steps beyond 1.5 times the median (up to 3.2 ms) are bridged as one-sample stalls, file by file and chunk
    by chunk."""
    data = read_measurements(files["full"][0], model=model)
    rng = np.random.default_rng(3)
    t = data.t + rng.uniform(-0.3, 0.3, data.n_samples) * (data.t[1] - data.t[0])
    jittered = replace(data, t=t) if cutoff is None else Measurements(t, data.q, tau=data.tau)
    path = tmp_path / "jittered.csv"
    jittered.write(path)
    # the samples where they were, the stamps moved: the reader says they look like receive times
    with pytest.warns(StallWarning, match="jittered.csv: the logger stalled 24 time"), pytest.warns(ResampledWarning), \
            pytest.warns(ReceiveTimesWarning):
        reference = in_memory(model, [path], None if cutoff is None else ButterworthDifferentiation(cutoff))
    with pytest.warns(StallWarning, match="jittered.csv: the logger stalled 24 time") as stalls, \
            pytest.warns(ResampledWarning, match="jittered.csv: irregular sampling"), \
            pytest.warns(ReceiveTimesWarning, match="jittered.csv: the positions are"):  # as in memory
        result = identify_files(model, [path], chunk_size=chunk_size, cutoff_hz=cutoff)
    assert not [warning for warning in stalls if "(rows" in str(warning.message)]  # said for the file, not by block
    assert relative(result.estimate.values, reference.values) < 1e-10
    entry = result.to_dict()["streaming"]["files"][0]
    assert entry["resampled_from"] == 5000 and entry["rows"] == entry["samples"] == result.train.n_samples


def test_warnings_of_a_worker_reach_the_caller(model, files, tmp_path):
    data = read_measurements(files["full"][0], model=model)
    t = data.t + np.random.default_rng(3).uniform(-0.3, 0.3, data.n_samples) * (data.t[1] - data.t[0])
    path = tmp_path / "jittered.csv"
    replace(data, t=t).write(path)
    with ThreadPoolExecutor(1) as executor, \
            pytest.warns(StallWarning, match="jittered.csv: the logger stalled 24 time") as stalls, \
            pytest.warns(ResampledWarning, match="jittered.csv: irregular sampling"), \
            pytest.warns(ReceiveTimesWarning, match="jittered.csv: the positions are"):
        sum_files(model, [path], executor=executor, chunk_size=2000)
    assert not [warning for warning in stalls if re.search(r"\(rows [\d-]+\)", str(warning.message))]  # the file's


def test_cli_process_pool_and_option_conflicts(model, files, tmp_path, capsys):
    out = tmp_path / "pool.json"
    base = ["identify", "--joints", "3", "--model", "internal", "--data", str(files["full"][0]), "--data",
            str(files["full"][2]), "--out", str(out)]
    assert main(base + ["--workers", "2"]) == 0
    reference = in_memory(model, [files["full"][0], files["full"][2]])
    values = weighted_values(json.loads(out.read_text()))
    assert relative(values, reference.values) < 1e-10
    out.unlink()
    assert main(base + ["--workers", "2", "--scheduler", "tcp://127.0.0.1:1"]) == 2
    assert "not both" in capsys.readouterr().err
    assert main(base + ["--chunk-size", "1500", "--plot", str(tmp_path / "figure.png")]) == 2
    assert "--plot draws every sample" in capsys.readouterr().err
    assert main(base[:-2] + ["--data", str(files["full"][0]), "--out", str(out)]) == 2
    assert "given twice" in capsys.readouterr().err
    assert not out.exists()


def test_combined_model_with_the_base_wrench_streamed(tmp_path):
    """Joint torques and the base wrench (9 channels), positions only: the filter path on both."""
    robot = load_robot("puma560", joints=3)
    combined = build_model(robot, "combined", "viscous")
    noise = {**NOISE, "fx": 5.0, "fy": 5.0, "fz": 8.0, "mx": 3.0, "my": 3.0, "mz": 1.0}
    data = simulate(combined, true_parameters(combined, seed=2), random_fourier(robot, 3), noise=noise, seed=4,
                    rate_hz=500.0, periods=1)
    path = tmp_path / "combined.parquet"
    Measurements(data.t, data.q, tau=data.tau, wrench=data.wrench).write(path)
    reference = in_memory(combined, [path], ButterworthDifferentiation(CUTOFF))
    estimate = identify_files(combined, [path], chunk_size=800, cutoff_hz=CUTOFF).estimate
    assert relative(estimate.values, reference.values) < 1e-10
    assert estimate.channels == combined.channels and len(estimate.channels) == 9
