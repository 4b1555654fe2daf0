"""The streamed diagnosis (bounded memory) against the in-memory one, through executors, bad input."""

from __future__ import annotations

import json

import numpy as np
import pytest

from dynamics.effects.linear import CoulombFriction, JointOffset
from dynamics.models import build_model
from dynamics.robots import load_robot
from estimation.diagnosis.search import diagnose
from estimation.streaming.diagnosis_sums import EvenSubsample
from estimation.data.loading import MeasurementError
from estimation.data.records import read_measurements
from dynamics.measurements import Measurements
from estimation.uncertainty.noise_floor import noise_floor
from estimation.preprocessing.differentiation import ButterworthDifferentiation
from estimation.streaming.diagnosis import diagnose_files
from oed.cli import main
from dynamics.simulation.synthetic import simulate, true_parameters

from oed.fourier import random_fourier

NOISE = 0.2
CUTOFF = 8.0


def relative(a, b) -> float:
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    return float(np.max(np.abs(a - b) / np.maximum(np.abs(b), 1e-300)))


@pytest.fixture(scope="module")
def model():
    return build_model(load_robot("puma560", joints=3), "internal", "viscous")


@pytest.fixture(scope="module")
def files(model, tmp_path_factory):
    """A training and a validation record of a 3-joint PUMA with Coulomb friction on joint 2 and a
    torque offset on joint 1 the declared model lacks: CSV with q, dq, ddq (``full``) and Parquet with
    noisy q and tau only (``raw``, the filter path); the training record also split in two files."""
    folder = tmp_path_factory.mktemp("streamed_diagnosis")
    truth = build_model(model.robot, "internal", ("viscous", CoulombFriction(joints=(1,)), JointOffset(joints=(0,))))
    theta = true_parameters(truth, seed=0, coulomb=[8.0], offset=[3.0])
    rng = np.random.default_rng(5)
    paths: dict[str, list] = {"full": [], "raw": [], "halves": []}
    for seed, trajectory in ((1, 3), (2, 4)):
        data = simulate(truth, theta, random_fourier(model.robot, seed=trajectory), noise={c: NOISE for c in truth.channels},
                        seed=seed, rate_hz=200.0, periods=1)
        full = folder / f"full{seed}.csv"
        data.write(full)
        raw = folder / f"raw{seed}.parquet"
        Measurements(data.t, data.q + 1e-5 * rng.standard_normal(data.q.shape), tau=data.tau).write(raw)
        paths["full"].append(full)
        paths["raw"].append(raw)
        if seed == 1:
            for index, rows in enumerate((slice(0, 600), slice(600, None))):
                half = folder / f"half{index}.csv"
                data.select(rows).write(half)
                paths["halves"].append(half)
    return paths


def _compare(streamed, memory, tolerance=1e-8):
    assert [(e.spec, e.channels) for e in streamed.effects] == [(e.spec, e.channels) for e in memory.effects]
    assert {"tau1", "tau2"} <= {channel for e in streamed.effects for channel in e.channels}
    for s, m in zip(streamed.effects, memory.effects):
        assert relative(s.values, m.values) < tolerance
    assert relative(streamed.after.estimate.values, memory.after.estimate.values) < tolerance
    assert relative(list(streamed.before.validation.mse.values()), list(memory.before.validation.mse.values())) < 1e-8
    assert relative(list(streamed.before.train.mse.values()), list(memory.before.train.mse.values())) < 1e-8
    assert relative(list(streamed.after.validation.mse.values()), list(memory.after.validation.mse.values())) < tolerance
    assert relative(list(streamed.after.train.mse.values()), list(memory.after.train.mse.values())) < tolerance


def test_streamed_diagnosis_equals_the_in_memory_one(model, files):
    """Measured dq, ddq; chunks of 300 of 1 000 samples; the whole record is the subsample, so the
    shapes are searched as in memory: same effects, rejections and reasons, estimates and MSEs to 1e-8."""
    train, validate = (read_measurements(path, model=model) for path in files["full"])
    floor = noise_floor(validate, model.channels)
    memory = diagnose(model, train, validate, noise_floor=floor)
    streamed = diagnose_files(model, files["full"][:1], files["full"][1:], chunk_size=300, noise_floor=floor)
    _compare(streamed, memory)
    assert [(e.spec, e.channels) for e in streamed.effects] == [("coulomb", ("tau2",)), ("offset", ("tau1",))]
    for s, m in zip(streamed.effects, memory.effects):
        assert s.p_value == pytest.approx(m.p_value, rel=1e-6, abs=1e-300)
    # the delay between torques and motion a candidate as in memory (tests/test_streamed_delay.py): not adopted here
    assert {r.spec + str(r.channels): r.reason for r in streamed.rejected} == \
        {r.spec + str(r.channels): r.reason for r in memory.rejected}
    document = streamed.to_dict()
    assert document["diagnosis_path"] == "streamed" and document["streaming"]["subsample"]["samples"] == 1000
    assert {"effects", "rejected", "validation", "train", "noise_floor", "floor_comparison"} <= set(document)
    assert set(document["effects"][0]) >= {"name", "channels", "values", "std", "p_value"}


def test_filter_path_errors_against_the_recording_as_in_memory(model, files):
    """No dq, ddq in the files: Butterworth derivatives on overlapping windows, the record's ends covered,
    errors against the torques as recorded; the in-memory diagnosis of the whole records filtered at once finds the same
    effects, the sign law of the truth (the tanh law's shape is not supported on either path), with the same estimates
    and errors to 1e-8: the streamed sums hold the in-band problem the channel weights come from."""
    method = ButterworthDifferentiation(CUTOFF)  # the CLI's: the filter covers the record's ends
    train, validate = (read_measurements(path, model=model) for path in files["raw"])
    floor = noise_floor(validate, model.channels)
    train, validate = method.apply(train), method.apply(validate)
    memory = diagnose(model, train, validate, noise_floor=floor)
    streamed = diagnose_files(model, files["raw"][:1], files["raw"][1:], chunk_size=400, cutoff_hz=CUTOFF,
                              noise_floor=floor)
    # the torques fitted as recorded (the default), the channel weights from the residual in the motion's band (the
    # streamed sums hold it): both paths name the sign law of the truth and agree
    assert [(e.spec, e.channels) for e in streamed.effects] == [("coulomb", ("tau2",)), ("offset", ("tau1",))]
    assert [(e.spec, e.channels) for e in memory.effects] == [("coulomb", ("tau2",)), ("offset", ("tau1",))]
    assert relative(list(streamed.before.validation.mse.values()), list(memory.before.validation.mse.values())) < 1e-8
    assert relative(list(streamed.before.train.mse.values()), list(memory.before.train.mse.values())) < 1e-8
    assert relative(list(streamed.after.validation.mse.values()), list(memory.after.validation.mse.values())) < 1e-8
    assert relative(streamed.after.estimate.values, memory.after.estimate.values) < 1e-8


def test_process_pool_gives_the_serial_diagnosis(model, files):
    from concurrent.futures import ProcessPoolExecutor

    serial = diagnose_files(model, files["halves"], files["full"][1:], chunk_size=300)
    with ProcessPoolExecutor(2) as executor:
        pooled = diagnose_files(model, files["halves"], files["full"][1:], chunk_size=300, executor=executor)
    assert [(e.spec, e.channels) for e in pooled.effects] == [(e.spec, e.channels) for e in serial.effects]
    # two files, one set of sums: the effects of the whole record (test above)
    assert [(e.spec, e.channels) for e in serial.effects] == [("coulomb", ("tau2",)), ("offset", ("tau1",))]
    assert relative(pooled.after.estimate.values, serial.after.estimate.values) < 1e-10
    for which in ("before", "after"):
        assert getattr(pooled, which).validation.mse == pytest.approx(getattr(serial, which).validation.mse, rel=1e-10)


def test_even_subsample_is_bounded_and_spread():
    subsample = EvenSubsample(100)
    t = np.arange(10_007) * 0.01
    for start in range(0, t.size, 333):
        rows = slice(start, start + 333)
        subsample.add(Measurements(t[rows], np.zeros((t[rows].size, 1))))
    kept = subsample.measurements()
    assert 100 <= kept.n_samples <= 200 and subsample.seen == t.size
    steps = np.diff(kept.t)
    assert np.allclose(steps, steps[0]) and kept.t[0] == 0.0 and kept.t[-1] > 0.95 * t[-1]


def test_bad_files_are_named_and_nothing_is_written(model, files, tmp_path, capsys):
    other = tmp_path / "other.csv"
    Measurements(np.arange(500) * 0.005, np.zeros((500, 3)), tau=np.zeros((500, 3))).write(other)  # no dq, ddq
    with pytest.raises(MeasurementError, match="other.csv"):
        diagnose_files(model, [files["halves"][0], other], files["full"][1:], chunk_size=300, cutoff_hz=CUTOFF)
    corrupt = tmp_path / "corrupt.csv"
    corrupt.write_text("t,q1,q2\n0,1\nnot,a,csv,at,all\n")
    out = tmp_path / "report.json"
    base = ["diagnose", "--joints", "3", "--model", "internal", "--validate", str(files["full"][1]), "--out", str(out),
            "--chunk-size", "300"]
    for data in ([files["halves"][0], corrupt], [files["halves"][0], other]):
        arguments = base + [argument for path in data for argument in ("--data", str(path))]
        assert main(arguments) == 2
        assert data[1].name in capsys.readouterr().err
        assert not out.exists()


def test_cli_streamed_diagnosis_writes_the_diagnose_keys(files, tmp_path, capsys):
    out = tmp_path / "report.json"
    report = tmp_path / "report.md"
    code = main(["diagnose", "--joints", "3", "--model", "internal", "--data", str(files["full"][0]), "--validate",
                 str(files["full"][1]), "--out", str(out), "--chunk-size", "400", "--report", str(report)])
    assert code == 0
    document = json.loads(out.read_text())
    assert document["diagnosis_path"] == "streamed" and document["cov_method"] == "batch_means"
    # the report on the streamed path: no figures (no samples held), and what the path did not compute
    text = report.read_text()
    assert "Not computed on this path" in text and "![" not in text
    assert sorted(path.name for path in tmp_path.iterdir()) == ["report.json", "report.md"]
    assert [(e["name"], e["channels"]) for e in document["effects"]] == [("coulomb", ["tau2"]), ("offset", ["tau1"])]
    assert set(document["validation"]["after"]) >= {"mse", "mse_over_floor"}
    assert "found coulomb on tau2" in capsys.readouterr().out


@pytest.mark.slow  # 26 s on the shared 2-core machine (the process pool above runs in the fast suite)
def test_dask_local_cluster_gives_the_serial_diagnosis(model, files):
    distributed = pytest.importorskip("dask.distributed", reason="dask is an optional extra: pip install 'robot-oed[cluster]'")
    serial = diagnose_files(model, files["halves"], files["full"][1:], chunk_size=300)
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=False, dashboard_address=None) as cluster, \
            distributed.Client(cluster) as client:
        clustered = diagnose_files(model, files["halves"], files["full"][1:], chunk_size=300,
                                   executor=client.get_executor(pure=False))
    assert [(e.spec, e.channels) for e in clustered.effects] == [(e.spec, e.channels) for e in serial.effects]
    assert relative(clustered.after.estimate.values, serial.after.estimate.values) < 1e-10


def test_a_lost_worker_fails_the_diagnosis_naming_the_file(model, files):
    from concurrent.futures import Future
    from concurrent.futures.process import BrokenProcessPool

    from estimation.streaming.cluster import WorkerLostError

    class Lost:
        calls = 0

        def submit(self, function, *args):
            Lost.calls += 1
            future = Future()
            if Lost.calls == 2:
                future.set_exception(BrokenProcessPool("A process in the process pool was terminated abruptly"))
            else:
                future.set_result(function(*args))
            return future

    with pytest.raises(WorkerLostError, match="half1.csv"):
        diagnose_files(model, files["halves"], files["full"][1:], chunk_size=300, executor=Lost())


def test_an_in_memory_diagnosis_larger_than_the_machine_is_refused(model, files, monkeypatch, tmp_path, capsys):
    import dynamics.runtime.memory

    monkeypatch.setattr(dynamics.runtime.memory, "available_memory", lambda: 1_000_000)  # 1 MB
    out = tmp_path / "report.json"
    code = main(["diagnose", "--joints", "3", "--model", "internal", "--data", str(files["full"][0]), "--validate",
                 str(files["full"][1]), "--out", str(out)])
    assert code == 2 and "--chunk-size" in capsys.readouterr().err and not out.exists()


def test_batch_scores_by_chunks_equal_the_batch_means_of_the_whole_record():
    from estimation.uncertainty.batch_means import batch_means
    from estimation.streaming.covariance import BATCH_LENGTHS, BatchScores, lag_one_correlation

    rng = np.random.default_rng(3)
    scores = rng.standard_normal((1000, 3))
    residual = np.cumsum(rng.standard_normal((2, 1000)), axis=1)  # correlated
    accumulator = BatchScores.empty(3, 2)
    for start, stop in ((0, 137), (137, 400), (400, 401), (401, 1000)):
        accumulator.add(scores[start:stop], residual[:, start:stop])
    closed = accumulator.closed()
    for k, length in enumerate(BATCH_LENGTHS[:10]):
        assert np.allclose(closed.meat[k], batch_means(scores, length), rtol=1e-12, atol=1e-12)
    weights = np.array([1.0, 2.0])
    centred = residual - residual.mean(axis=1, keepdims=True)
    variance = np.sum(centred**2, axis=1)
    lagged = np.sum(centred[:, 1:] * centred[:, :-1], axis=1)
    assert lag_one_correlation([closed], weights)[0] == pytest.approx(np.sum(weights * lagged) / np.sum(weights * variance), rel=1e-10)


def test_trivial_predictors_from_the_sums_equal_the_in_memory_ones(model, files):
    from estimation.identification.trivial_predictors import trivial_mse

    validate = read_measurements(files["full"][1], model=model)
    streamed = diagnose_files(model, files["full"][:1], files["full"][1:], chunk_size=300, candidates=())
    expected = trivial_mse(model, validate)
    document = streamed.to_dict()
    for key in ("zero_mse", "nominal_mse"):
        assert relative(list(document["validation"][key].values()), list(expected[key].values())) < 1e-10


@pytest.fixture(scope="module")
def noisy_files(model, tmp_path_factory):
    """The truth of ``files`` (Coulomb friction on joint 2, an offset on joint 1, both plain laws) logged with q, dq,
    ddq at 100 Hz under a noise of 1 N·m: a record where the consistent refit of the adopted model predicts the
    validation motion better than the adopted model as fitted (the in-memory default answer is the refit)."""
    folder = tmp_path_factory.mktemp("streamed_answer")
    truth = build_model(model.robot, "internal", ("viscous", CoulombFriction(joints=(1,)), JointOffset(joints=(0,))))
    theta = true_parameters(truth, seed=0, coulomb=[8.0], offset=[3.0])
    paths = []
    for seed, trajectory in ((1, 3), (2, 4)):
        path = folder / f"noisy{seed}.csv"
        simulate(truth, theta, random_fourier(model.robot, seed=trajectory), noise={c: 1.0 for c in truth.channels},
                 seed=seed, rate_hz=100.0, periods=1).write(path)
        paths.append(path)
    return paths


def _candidates(document):
    return {candidate["name"]: candidate for candidate in document["model_selection"]["candidates"]}


@pytest.mark.parametrize("given", [False, True])
def test_streamed_diagnosis_chooses_the_default_answer_as_in_memory(noisy_files, tmp_path, given):
    """Issue 34 on the streamed path of ``oed diagnose``: a record over the memory budget gets the in-memory default
    answer, the adopted model as fitted or its consistent refit (its prior weight chosen on the validation record)
    from the diagnosis's sums: the same effects, choice, prior weight and search, parameters and every candidate's
    validation error against the recording to 1e-6; the same keys in report.json (``chosen`` through
    ``model_selection``, ``consistent``, ``links`` and the model file's alternatives); ``--consistent`` refits there
    too. ``oed predict`` measures the streamed run's reported errors of the chosen model and of the alternative."""
    import oed

    options = dict(joints=3, model="internal", friction="viscous", data=noisy_files[0], validate=noisy_files[1],
                   consistent=given)
    runs = {"memory": oed.diagnose(**options), "streamed": oed.diagnose(**options, memory_budget="1KB")}
    memory, streamed = (runs[name].to_dict() for name in ("memory", "streamed"))
    assert (memory["diagnosis_path"], streamed["diagnosis_path"]) == ("in-memory", "streamed")
    assert [(e["spec"], e["channels"]) for e in streamed["effects"]] == \
        [(e["spec"], e["channels"]) for e in memory["effects"]] == [("coulomb", ["tau2"]), ("offset", ["tau1"])]
    assert memory["model_selection"]["chosen"] == "consistent"  # the refit wins: the streamed path must see it
    for key in ("chosen", "selection", "base"):
        assert streamed["model_selection"][key] == memory["model_selection"][key], key
    assert streamed["model_file"]["chosen"] == memory["model_file"]["chosen"] == "consistent"
    assert {"consistent", "links", "model_selection"}.isdisjoint(streamed["not_computed"])
    assert set(memory) <= set(streamed)
    assert streamed["model_selection"]["repeat_ratio"] == pytest.approx(memory["model_selection"]["repeat_ratio"],
                                                                        rel=1e-6)
    for name, candidate in _candidates(memory).items():
        other = _candidates(streamed)[name]
        assert other["validation_mse"] == pytest.approx(candidate["validation_mse"], rel=1e-6), name
        assert other["train_mse"] == pytest.approx(candidate["train_mse"], rel=1e-6), name
        if not given:
            assert other["score"] == pytest.approx(candidate["score"], rel=1e-6), name
    for key in ("prior_weight", "prior_weight_choice"):
        assert streamed["consistent"][key] == memory["consistent"][key], key
    search = {name: [entry["weighted_validation_error"] for entry in document["consistent"].get("prior_weight_search",
                                                                                                    [])]
              for name, document in (("memory", memory), ("streamed", streamed))}
    assert search["streamed"] == pytest.approx(search["memory"], rel=1e-6)
    assert len(search["memory"]) == 5
    values = {name: np.array([p["value"] for p in document["consistent"]["parameters"]])
              for name, document in (("memory", memory), ("streamed", streamed))}
    np.testing.assert_allclose(values["streamed"], values["memory"], rtol=1e-6,
                               atol=1e-6 * np.abs(values["memory"]).max())
    assert [link["name"] for link in streamed["links"]] == [link["name"] for link in memory["links"]]
    for which in ("train", "validation"):
        assert streamed[which]["chosen"]["name"] == memory[which]["chosen"]["name"] == "consistent"
        assert streamed[which]["chosen"]["mse"] == pytest.approx(memory[which]["chosen"]["mse"], rel=1e-6)
    assert set(streamed["model_file"]["alternatives"]) == set(memory["model_file"]["alternatives"]) == {"wls"}
    for name, entry in memory["model_file"]["alternatives"].items():
        np.testing.assert_allclose(streamed["model_file"]["alternatives"][name]["theta"], entry["theta"], rtol=1e-6,
                                   atol=1e-6 * np.abs(entry["theta"]).max())
    summary = runs["streamed"].summary()
    assert any(line.startswith("model: consistent") for line in summary)
    # oed predict measures what the streamed run reported, for the chosen model and its alternative
    out = tmp_path / "streamed.json"
    runs["streamed"].write(out)
    for alternative, reported in ((None, streamed["validation"]["chosen"]["mse"]),
                                  ("wls", _candidates(streamed)["wls"]["validation_mse"])):
        metrics = tmp_path / "metrics.json"
        assert main(["predict", "--model", str(out), "--data", str(noisy_files[1]), "--metrics", str(metrics),
                     *(("--alternative", alternative) if alternative else ())]) == 0
        measured = json.loads(metrics.read_text())["mse"]
        assert measured == pytest.approx(reported, rel=1e-6)


@pytest.fixture(scope="module")
def tanh_files(model, tmp_path_factory):
    """As ``files["raw"]`` (noisy q and tau, Parquet), the Coulomb law of joint 2 smooth: ``8 tanh(q̇₂ / 0.1)``."""
    folder = tmp_path_factory.mktemp("streamed_tanh")
    truth = build_model(model.robot, "internal", ("viscous", JointOffset(joints=(0,))))
    theta = true_parameters(truth, seed=0, offset=[3.0])
    rng = np.random.default_rng(5)
    paths = []
    for seed, trajectory in ((1, 3), (2, 4)):
        data = simulate(truth, theta, random_fourier(model.robot, seed=trajectory), noise={c: NOISE for c in truth.channels},
                        seed=seed, rate_hz=200.0, periods=1)
        tau = data.tau.copy()
        tau[:, 1] += 8.0 * np.tanh(data.dq[:, 1] / 0.1)
        raw = folder / f"tanh{seed}.parquet"
        Measurements(data.t, data.q + 1e-5 * rng.standard_normal(data.q.shape), tau=tau).write(raw)
        paths.append(raw)
    return paths


@pytest.mark.parametrize("jittered", [False, True])
def test_a_shaped_law_enters_the_streamed_consistent_refit_at_its_fixed_shape(model, tanh_files, tmp_path, jittered):
    """The filter path finds the smooth Coulomb law of joint 2, ``coulomb:tanh``, streamed (its shape fixed at the
    subsample's optimum): its
    consistent refit holds that shape (the sums' columns at it, in the model's base order), and ``oed predict`` of
    each model of the file (the consistent refit and the adopted model) measures the errors the run reported; on a
    jittered validation log (stamps moved, rows re-sent, a stall: resampled by the loader) every candidate and
    prior weight is scored at the recorded samples, as predict scores them."""
    import oed
    import pandas as pd

    from tests.test_recorded_stamps import logger_faults

    validate = tanh_files[1]
    if jittered:
        validate = tmp_path / "jittered_validate.csv"
        logger_faults(pd.read_parquet(tanh_files[1]), 2).to_csv(validate, index=False, float_format="%.10g")
    run = oed.diagnose(joints=3, model="internal", friction="viscous", data=tanh_files[0], validate=validate,
                       cutoff=CUTOFF, memory_budget="1KB")
    if jittered:
        assert any(entry["resampled_from"] for entry in run.to_dict()["streaming"]["validation_files"])
    document = run.to_dict()
    assert document["diagnosis_path"] == "streamed"
    assert ("coulomb:tanh", ["tau2"]) in [(e["spec"], e["channels"]) for e in document["effects"]]
    candidates = _candidates(document)
    assert candidates["consistent"]["available"], candidates["consistent"]["reason"]
    assert set(document["consistent"]["shape"]) == set(document["model_file"]["shape"]) != set()
    assert document["consistent"]["shape"] == pytest.approx(document["model_file"]["shape"], rel=1e-12)
    out = tmp_path / "shaped.json"
    run.write(out)
    for name, candidate in candidates.items():
        metrics = tmp_path / f"{name}.json"
        assert main(["predict", "--model", str(out), "--data", str(validate), "--metrics", str(metrics),
                     "--alternative", name]) == 0
        assert json.loads(metrics.read_text())["mse"] == pytest.approx(candidate["validation_mse"], rel=1e-6), name
