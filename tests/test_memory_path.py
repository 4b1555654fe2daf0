"""In memory or streamed, decided by memory: the estimate before reading, and the same choices either way."""

from __future__ import annotations

import json
import warnings

import numpy as np
import pytest

from dynamics.effects.linear import CoulombFriction, JointOffset
from dynamics.measurements import Measurements
from dynamics.models import build_model
from dynamics.robots import load_robot
from dynamics.runtime import progress
from dynamics.simulation.synthetic import simulate, true_parameters
from estimation.identification import preprocessing_choice
from estimation.identification.prepared import read_files
from estimation.identification.preprocessing_choice import ChoiceWindow, choose_by_evidence
from estimation.streaming import cutoff_choice
from estimation.streaming.cutoff_choice import choose_streamed_preprocessing, streamed_window
from estimation.data.memory_budget import (
    MemorySizeError,
    count_rows,
    estimate_in_memory,
    format_size,
    parse_memory_size,
)
from oed.cli import main
from oed.fourier import random_fourier

NOISE = 0.2


@pytest.mark.parametrize(("text", "expected"), [
    ("2GB", 2 * 10**9), ("500MB", 500 * 10**6), ("1.5GiB", int(1.5 * 2**30)), ("2G", 2 * 2**30),
    ("123456", 123456), (" 64 kb ", 64_000), (4096, 4096)])
def test_memory_sizes_are_read_in_decimal_and_binary_units(text, expected):
    assert parse_memory_size(text) == expected


@pytest.mark.parametrize("text", ["", "GB", "2 parsecs", "-1GB", "0", "nan", True])
def test_unreadable_memory_sizes_are_refused_with_the_value(text):
    with pytest.raises(MemorySizeError, match="memory size"):
        parse_memory_size(text)


def test_rows_are_counted_without_parsing(tmp_path):
    """CSV with and without a line break after the last row, Parquet from its footer: as many rows as pandas reads."""
    data = Measurements(np.arange(1234) / 100.0, np.zeros((1234, 2)), tau=np.ones((1234, 2)))
    data.write(tmp_path / "a.csv")
    data.write(tmp_path / "a.parquet")
    text = (tmp_path / "a.csv").read_text()
    (tmp_path / "b.csv").write_text(text.rstrip("\n"))
    assert [count_rows(tmp_path / name, block=1000) for name in ("a.csv", "b.csv", "a.parquet")] == [1234] * 3
    with pytest.raises(ValueError, match="unknown data format"):
        count_rows(tmp_path / "a.xlsx")  # a .txt table is counted as CSV since h-logs5
    with pytest.raises(FileNotFoundError):
        count_rows(tmp_path / "missing.csv")


def test_the_estimate_grows_with_rows_and_shrinks_with_period_averaging():
    model = build_model(load_robot("puma560", joints=3), "internal", "viscous")
    small = estimate_in_memory([1000], model, bytes_per_value=64, budget=10**9)
    large = estimate_in_memory([10**7], model, bytes_per_value=64, budget=10**9)
    averaged = estimate_in_memory([10**7], model, bytes_per_value=64, budget=10**9, reduced_rows=[1000])
    assert not small.stream and large.stream and averaged.n_bytes < large.n_bytes / 5
    assert large.n_bytes > 64 * 10**7 * model.n_channels * model.n_base
    assert "over the budget of 1 GB: streaming" in large.describe("diagnosing")
    assert format_size(2.5e9) == "2.5 GB"
    with pytest.raises(ValueError, match="reduced_rows"):
        estimate_in_memory([1, 2], model, bytes_per_value=64, budget=1, reduced_rows=[1])


@pytest.fixture(scope="module")
def model():
    return build_model(load_robot("puma560", joints=3), "internal", "viscous")


@pytest.fixture(scope="module")
def records(model, tmp_path_factory):
    """Training and validation records of a 3-joint PUMA, positions and torques only, three periods each at
    200 Hz; Coulomb friction on joint 2 and an offset on joint 1 the declared model lacks."""
    folder = tmp_path_factory.mktemp("memory_path")
    truth = build_model(model.robot, "internal", ("viscous", CoulombFriction(joints=(1,)), JointOffset(joints=(0,))))
    theta = true_parameters(truth, seed=0, coulomb=[8.0], offset=[3.0])
    rng = np.random.default_rng(5)
    paths = []
    for seed, trajectory in ((1, 3), (2, 4)):
        data = simulate(truth, theta, random_fourier(model.robot, seed=trajectory), noise={c: NOISE for c in truth.channels},
                        seed=seed, rate_hz=200.0, periods=3)
        path = folder / f"raw{seed}.parquet"
        Measurements(data.t, data.q + 1e-4 * rng.standard_normal(data.q.shape), tau=data.tau).write(path)
        paths.append(path)
    return paths


@pytest.mark.parametrize("scored", [None, 1000])
def test_the_streamed_window_is_the_in_memory_one(model, records, monkeypatch, scored):
    """Whole records, and a record longer than the scored window: the same samples, the same choice and scores."""
    if scored is not None:
        monkeypatch.setattr(preprocessing_choice, "SCORED_SAMPLES", scored)
        monkeypatch.setattr(cutoff_choice, "SCORED_SAMPLES", scored)
    segments = [segment for file in read_files(records[:1], model, split=True) for segment in file.segments]
    memory, streamed = ChoiceWindow.of(segments), streamed_window(records[:1], model)
    assert [s.n_samples for s in streamed.segments] == [s.n_samples for s in memory.segments]
    for a, b in zip(streamed.segments, memory.segments):
        np.testing.assert_array_equal(a.q, b.q)
        np.testing.assert_array_equal(a.tau, b.tau)
    assert streamed.shortest_s == pytest.approx(memory.shortest_s, rel=1e-9)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)  # the fundamental found, said by both
        in_memory = choose_by_evidence(model, segments, held_torques=None).chosen
        from_files = choose_streamed_preprocessing(records[:1], model, held_torques=None).chosen
    assert from_files == in_memory
    assert [(c.preprocessing, c.score) for c in from_files.evidence.candidates] == \
        [(c.preprocessing, c.score) for c in in_memory.evidence.candidates]


def _diagnose(tmp_path, records, name, *options):
    out = tmp_path / f"{name}.json"
    code = main(["diagnose", "--joints", "3", "--model", "internal", "--friction", "viscous", "--data", str(records[0]),
                 "--validate", str(records[1]), "--out", str(out), *options])
    assert code == 0
    return json.loads(out.read_text())


def _effects(document):
    return [(effect["spec"], tuple(effect["channels"])) for effect in document["effects"]]


@pytest.mark.parametrize("derivatives", [(), ("--cutoff", "6")])
def test_in_memory_and_streamed_make_the_same_choices(tmp_path, records, capsys, derivatives):
    """No derivative option (a periodic record: the choice may be a Fourier fit of averaged periods) and a
    given filter: the in-memory and the streamed diagnosis (forced by --chunk-size, and chosen by a tiny
    --memory-budget) choose the same derivatives and effects, and agree on the estimates."""
    memory = _diagnose(tmp_path, records, "memory", *derivatives)
    forced = _diagnose(tmp_path, records, "forced", "--chunk-size", "250", *derivatives)
    capsys.readouterr()
    budget = _diagnose(tmp_path, records, "budget", "--memory-budget", "1000", *derivatives)
    error = capsys.readouterr().err
    assert "over the budget of 1 kB: streaming" in error
    assert memory["diagnosis_path"] == "in-memory" and forced["diagnosis_path"] == budget["diagnosis_path"] == "streamed"
    assert memory["preprocessing"]["method"] == ("butterworth" if derivatives else "fourier")  # both paths exercised
    plan = {key: value for key, value in memory["preprocessing"].items()
            if key not in ("candidates", "trimmed_s", "validation_candidates")}

    def untimed(document):  # the validation's scores (chosen again there, by the plain model), without their seconds
        return [{key: value for key, value in candidate.items() if key != "seconds"}
                for candidate in document["preprocessing"].get("validation_candidates", [])]

    for streamed in (forced, budget):
        assert {key: streamed["preprocessing"][key] for key in plan} == plan
        assert untimed(streamed) == untimed(memory)
        assert [c["score"] for c in streamed["preprocessing"]["candidates"]] == \
            [c["score"] for c in memory["preprocessing"]["candidates"]]
        assert _effects(streamed) == _effects(memory)
        assert ("offset", ("tau1",)) in _effects(memory)
        for s, m in zip(streamed["effects"], memory["effects"]):
            np.testing.assert_allclose(s["values"], m["values"], rtol=0.05, atol=0.05 * np.max(np.abs(m["values"])))
        for which in ("before", "after"):
            np.testing.assert_allclose(list(streamed["validation"][which]["mse"].values()),
                                       list(memory["validation"][which]["mse"].values()), rtol=0.05)
        # one document: the streamed one has every key of the in-memory one, and says why each it lacks is None
        assert set(memory) <= set(streamed) and set(memory["validation"]) <= set(streamed["validation"])
        missing = {key for key, value in streamed.items() if value is None and memory.get(key) is not None}
        assert missing and missing <= set(streamed["not_computed"])
        assert all(streamed["not_computed"].values()) and memory["not_computed"] == {}
        if memory["preprocessing"]["method"] == "fourier":  # the training sums hold the averaged period: the
            # errors measured against the recording as in memory, the averaged period's kept as mse_filtered
            for which in ("before", "after", "chosen"):
                assert set(streamed["train"][which]["mse_filtered"]) == set(memory["train"][which]["mse"])
                np.testing.assert_allclose(list(streamed["train"][which]["mse"].values()),
                                           list(memory["train"][which]["mse"].values()), rtol=0.05)
            np.testing.assert_allclose(list(streamed["train"]["before"]["mse"].values()),
                                       list(memory["train"]["before"]["mse"].values()), rtol=1e-6)  # the same fit
            assert all(c["train_mse"] and c["train_mse_filtered"] for c in streamed["model_selection"]["candidates"])
            assert "averaged period" in streamed["train"]["against"]
        else:
            assert all(streamed["train"][which]["mse"] for which in ("before", "after", "chosen"))
        # the paired difference of the best candidate and the consistent one, reported on both paths (streamed: from
        # the validation sums of each block, h-streamdiag; measured: 2e-9 apart on both derivative paths)
        paired = [document["model_selection"]["paired_difference"] for document in (memory, streamed)]
        assert (paired[1] is None) == (paired[0] is None)
        if paired[0] is not None:
            assert paired[1]["best"] == paired[0]["best"] and paired[1]["blocks"] == paired[0]["blocks"]
            for key in ("difference", "standard_error"):
                assert paired[1][key] == pytest.approx(paired[0][key], rel=1e-6), key


def test_one_result_type_whichever_the_path(records, tmp_path):
    """``oed.diagnose`` in memory and streamed (a tiny budget): one result type, the same fields filled (the
    errors before and after, the floor against them), the summary in the same form."""
    import oed
    from estimation.diagnosis.results import Diagnosis

    options = dict(joints=3, model="internal", friction="viscous", data=records[0], validate=records[1], cutoff=6.0)
    memory, streamed = oed.diagnose(**options), oed.diagnose(**options, memory_budget="1000")
    assert (memory.diagnosis.path, streamed.diagnosis.path) == ("in-memory", "streamed")
    for run in (memory, streamed):
        diagnosis = run.diagnosis
        assert type(diagnosis) is Diagnosis
        document, own = run.to_dict(), diagnosis.to_dict()
        assert set(own) <= set(document)
        assert set(document["train"].pop("chosen")) == {"name", "mse"}  # the chosen model's, beside the diagnosis's
        for key in ("effects", "rejected", "train", "cov_method", "noise_floor", "floor_comparison", "diagnosis_path",
                    "tracing", "whiteness", "residuals"):
            assert document[key] == own[key], key
        # what the diagnosis did not compute, less what the verb computed beside it (the streamed run's masked
        # cells, counted by oed diagnose: estimation.streaming.masked_counts)
        counted = ("saturated_samples", "channel_samples")
        assert document["not_computed"] == {key: why for key, why in (own["not_computed"] or {}).items()
                                            if key not in counted} or None, document["not_computed"]
        for which in ("before", "after"):
            fit = getattr(diagnosis, which)
            assert set(fit.validation.mse) == set(fit.train.mse) == {"tau1", "tau2", "tau3"}
            assert diagnosis.statistics.ratios(which)
        assert any(line.startswith("  after / floor") for line in run.summary())
        assert "validation MSE vs recorded" in run.summary()
    assert streamed.diagnosis.residuals is None and "residuals" in streamed.diagnosis.not_computed
    assert streamed.diagnosis.statistics.tracing is None and memory.diagnosis.statistics.tracing is not None
    assert [e.spec for e in streamed.diagnosis.effects] == [e.spec for e in memory.diagnosis.effects]
    # one report builder: the streamed run's report has the same sections but the figures, and says what it lacks
    streamed.write(tmp_path / "r.json", report=tmp_path / "r.md")
    text = (tmp_path / "r.md").read_text()
    assert "## Parameters of the diagnosed model" in text and "## Not computed on this path" in text
    assert "- tracing: residual tracing needs the residuals sample by sample" in text
    assert sorted(path.name for path in tmp_path.iterdir()) == ["r.json", "r.md"]
    assert "<img" not in streamed.html() and "<img" in memory.html()
    with pytest.raises(ValueError, match="need the samples"):
        streamed.plot_residuals(tmp_path / "r.png")


def test_a_long_step_says_so_while_it_runs(capsys):
    """A step past the limit says so while it runs (its watcher's wait timed out), then how long it took (a fake
    clock); a short one says nothing; nothing is watched unless a program shows the lines."""
    import io

    def timed_out(done, seconds):
        assert not done.is_set() and seconds == 2.0  # asked while the step runs, for the limit
        return False

    stream = io.StringIO()
    with progress.show_progress("oed test", stream=stream):
        ticks = iter([10.0, 15.5])
        with progress.step("a pass", clock=lambda: next(ticks), wait=timed_out):
            pass
        ticks = iter([20.0, 20.5])
        with progress.step("a short pass", clock=lambda: next(ticks), wait=lambda done, seconds: done.wait()):
            pass
    assert stream.getvalue().splitlines() == ["oed test: a pass: running (over 2 s)", "oed test: a pass: 5.5 s"]
    ticks = iter([0.0, 0.0])
    with progress.step("unseen", clock=lambda: next(ticks), wait=timed_out):
        pass
    assert capsys.readouterr().err == ""


def test_a_long_step_is_said_by_its_watcher_before_it_ends():
    """With the real wait: a step that outlasts a short limit is said while still running."""
    import io
    import threading

    stream, said = io.StringIO(), threading.Event()

    class Written(io.StringIO):
        def write(self, text):
            stream.write(text)
            said.set()
            return len(text)

    with progress.show_progress("oed test", stream=Written()):
        with progress.step("a long pass", seconds=0.01):
            assert said.wait(30.0)  # the line comes while the step runs
            assert stream.getvalue() == "oed test: a long pass: running (over 0.01 s)\n"
    assert stream.getvalue().splitlines()[-1].startswith("oed test: a long pass: ")


def test_progress_lines_go_to_stderr_unless_quiet(capsys):
    with progress.show_progress("oed test"):
        with progress.step("a pass", seconds=0.0):
            pass
    assert capsys.readouterr().err.startswith("oed test: a pass: ")
    with progress.show_progress("oed test", quiet=True):
        with progress.step("a pass", seconds=0.0):
            pass
    assert capsys.readouterr().err == ""


def test_a_bad_memory_budget_is_refused_by_name(tmp_path, records, capsys):
    code = main(["diagnose", "--joints", "3", "--data", str(records[0]), "--validate", str(records[1]),
                 "--out", str(tmp_path / "r.json"), "--memory-budget", "lots"])
    assert code == 2 and "cannot read the memory size 'lots'" in capsys.readouterr().err


def test_identify_chooses_alike_in_memory_and_streamed(identify_runs, capsys):
    """The same derivatives, channel weighting, answer and estimate, in memory and streamed (a Fourier fit of averaged
    periods: the streamed path chose no answer there before, and kept the weighting, WLS, where memory chose the
    consistent fit)."""
    documents = {name: identify_runs(options, capsys)[0]
                 for name, options in (("memory", ()), ("streamed", ("--chunk-size", "250")))}
    memory, streamed = documents["memory"], documents["streamed"]
    plan = {key: value for key, value in memory["preprocessing"].items()
            if key not in ("candidates", "validation_candidates")}
    assert {key: streamed["preprocessing"][key] for key in plan} == plan

    def untimed(document):  # the validation's scores, without the seconds they took
        return [{key: value for key, value in candidate.items() if key != "seconds"}
                for candidate in document["preprocessing"].get("validation_candidates", [])]

    assert untimed(streamed) == untimed(memory)
    assert streamed["method_selection"]["chosen"] == memory["method_selection"]["chosen"]
    assert streamed["method_selection"]["candidates"] == memory["method_selection"]["candidates"]
    values = {name: np.array([record["value"] for record in document["parameters"]])
              for name, document in documents.items()}
    # the answer chosen among OLS, WLS and the consistent fit on the validation record (model_selection), on the
    # Fourier path too (streamed: every sample of the validation record's whole periods scored, as in memory)
    assert streamed["model_selection"]["chosen"] == memory["model_selection"]["chosen"] == streamed["chosen"]
    assert [c["name"] for c in streamed["model_selection"]["candidates"]] == \
        [c["name"] for c in memory["model_selection"]["candidates"]]
    assert values["memory"].size > 18 and memory["preprocessing"]["method"] == "fourier"
    np.testing.assert_allclose(values["streamed"], values["memory"], rtol=1e-6, atol=1e-9 * np.max(np.abs(values["memory"])))


@pytest.mark.parametrize("available", [10**5, 4 * 10**9, 24 * 10**9, 10**13])
def test_the_path_is_decided_by_the_record_whatever_the_free_memory(model, records, monkeypatch, available):
    """The default budget is fixed (1 GB): the small record stays in memory, a million-row record of the same
    files would stream, however much memory the machine has free; ``memory_budget`` still overrides."""
    import dynamics.runtime.memory
    from oed.workflows import memory_path
    from oed.workflows.options import RecordOptions

    monkeypatch.setattr(dynamics.runtime.memory, "available_memory", lambda: available)
    assert memory_path.default_budget() == memory_path.budget_of(RecordOptions(joints=3, data=records[:1])) == 10**9
    said = []
    options = RecordOptions(joints=3, data=records[:1], validate=records[1:])
    small = memory_path.decide_path(options, model, task="diagnosing", bytes_per_value=64,
                                    in_memory_only=lambda: None, say=said.append)
    assert not small.stream and not small.need.stream and small.need.budget == 10**9 and said == []
    monkeypatch.setattr(memory_path, "count_rows", lambda path: 10**6)
    large = memory_path.decide_path(options, model, task="diagnosing", bytes_per_value=64,
                                    in_memory_only=lambda: "an option the streamed path lacks", say=said.append)
    assert large.need.stream and large.need.rows == 2 * 10**6 and large.need.budget == 10**9
    assert said == [large.need.describe("diagnosing") + ", but an option the streamed path lacks: in memory"]
    generous = memory_path.decide_path(options.replace(memory_budget="1TB"), model, task="diagnosing",
                                       bytes_per_value=64, in_memory_only=lambda: None, say=said.append)
    assert not generous.stream and generous.need.budget == 10**12


@pytest.fixture(scope="module")
def identify_runs(records, tmp_path_factory):
    """``oed identify`` on the records with some options, each run once a module (the tests that compare the paths
    on the same options share it; the runs are deterministic, their results read only): the document, and what the
    run printed on standard output and standard error."""
    folder, runs = tmp_path_factory.mktemp("identify_runs"), {}

    def run(options: tuple[str, ...], capsys) -> tuple[dict, str, str]:
        if options not in runs:
            out = folder / f"identify_{len(runs)}.json"
            capsys.readouterr()
            code = main(["identify", "--joints", "3", "--model", "internal", "--friction", "viscous,coulomb,offset",
                         "--data", str(records[0]), "--validate", str(records[1]), "--out", str(out), *options])
            printed = capsys.readouterr()
            assert code == 0, printed.err
            runs[options] = json.loads(out.read_text()), printed.out, printed.err
        return runs[options]

    return run


@pytest.mark.parametrize("derivatives", [(), ("--cutoff", "6")])
def test_identify_one_document_whichever_the_path(identify_runs, capsys, derivatives):
    """``oed identify`` in memory and streamed (forced by --chunk-size, chosen by a tiny --memory-budget): the
    streamed document has every key of the in-memory one (the validation's too), the same derivatives and estimate
    and errors; what it lacks is null with its reason in not_computed; the summary in the same form."""
    memory, printed_memory, _ = identify_runs((*derivatives,), capsys)
    forced, printed, _ = identify_runs(("--chunk-size", "250", *derivatives), capsys)
    budget, _, error = identify_runs(("--memory-budget", "1000", *derivatives), capsys)
    assert "over the budget of 1 kB: streaming" in error
    assert memory["identification_path"] == "in-memory" and memory["streaming"] is None
    assert memory["not_computed"] == {}
    for streamed in (forced, budget):
        assert streamed["identification_path"] == "streamed" and streamed["streaming"]["files"]
        assert set(memory) <= set(streamed) and set(memory["validation"]) <= set(streamed["validation"])
        assert set(memory["model_parameters"]) <= set(streamed["model_parameters"])
        missing = {key for key, value in streamed.items() if value is None and memory.get(key) is not None}
        missing |= {f"validation.{key}" for key, value in streamed["validation"].items()
                    if value is None and memory["validation"].get(key) is not None}
        assert missing <= set(streamed["not_computed"]), missing
        # the filter path computes every key but the HAC lags (the streamed covariance is batch means, by design),
        # which the in-memory document holds when its chosen model is an unconstrained fit (the per-joint torque
        # gains are a candidate there too, estimation.streaming.torque_gains, on the Fourier path as well: h-streamclock);
        # the friction drift is checked on both paths, on the same samples (h-streamchecks), averaged periods too
        # (h-streamchecks2)
        assert "friction_drift" not in missing and "friction_drift" not in streamed["not_computed"]
        assert streamed["friction_drift"]["joints"].keys() == memory["friction_drift"]["joints"].keys()
        for name, joint in memory["friction_drift"]["joints"].items():
            assert streamed["friction_drift"]["joints"][name]["scale"] == pytest.approx(joint["scale"], rel=1e-6)
        assert not missing - {"hac_lags"}, missing
        assert "torque_gains" not in streamed["not_computed"]
        assert (streamed["torque_gains"] is None) == (memory["torque_gains"] is None)
        assert ("hac_lags" in missing) == (memory["hac_lags"] is not None)
        assert all(streamed["not_computed"].values())
        assert streamed["preprocessing"]["method"] == memory["preprocessing"]["method"]
        assert streamed["transmission"] == memory["transmission"] and streamed["rest"] is None is memory["rest"]
        assert streamed["model_parameters"]["names"] == memory["model_parameters"]["names"]
        assert streamed["model_parameters"]["values"] == [p["value"] for p in streamed["parameters"]]
        assert streamed["model_parameters"]["chosen"] == streamed["chosen"] == streamed["model_file"]["chosen"]
        assert set(streamed["noise_floor"]["mse"]) == set(memory["noise_floor"]["mse"])
        # against the recording on both paths (averaged periods: a pass over every sample of the whole periods)
        assert streamed["chosen"] == memory["chosen"]  # the same answer, chosen alike
        assert "model_selection" not in streamed["not_computed"]
        for key, rtol in (("zero_mse", 1e-3), ("nominal_mse", 1e-3), ("mse", 1e-6)):
            np.testing.assert_allclose(list(streamed["validation"][key].values()),
                                       list(memory["validation"][key].values()), rtol=rtol)
        assert streamed["validation"]["mse_over_floor"] == pytest.approx(
            {c: v / streamed["noise_floor"]["mse"][c] for c, v in streamed["validation"]["mse"].items()},
            rel=1e-12)
    assert printed.splitlines()[0] == printed_memory.splitlines()[0]  # the same derivatives, said alike
    assert "validation MSE (vs" in printed and "validation MSE (vs" in printed_memory


def test_identify_one_result_type_whichever_the_path(records, tmp_path):
    """``oed.identify`` in memory and streamed: one result type (IdentificationResult), the same fields filled, one
    report builder."""
    import oed
    from estimation.identification.fit import IdentificationResult

    options = dict(joints=3, model="internal", friction="viscous,coulomb,offset", data=records[0],
                   validate=records[1], cutoff=6.0)
    memory, streamed = oed.identify(**options), oed.identify(**options, chunk_size=250)
    assert (memory.result.path, streamed.result.path) == ("in-memory", "streamed")
    assert not memory.streamed and streamed.streamed
    for run in (memory, streamed):
        result = run.result
        assert type(result) is IdentificationResult
        assert set(result.validation.mse) == set(result.train.mse_filtered) == {"tau1", "tau2", "tau3"}
        own = result.to_dict()
        assert set(own) <= set(run.to_dict())
        assert run.to_dict()["not_computed"] == {**own["not_computed"], **run.to_dict()["not_computed"]}
    assert streamed.result.not_computed and memory.result.not_computed == {}
    np.testing.assert_allclose(streamed.result.estimate.values, memory.result.estimate.values, rtol=0.1, atol=0.05)
    # one report builder: the streamed run's report has the same sections but the figures, and says what it lacks
    folder = tmp_path
    streamed.write(folder / "r.json", report=folder / "r.md")
    text = (folder / "r.md").read_text()
    assert "## Parameters" in text and "## Error per channel" in text and "## Not computed on this path" in text
    assert "- hac_lags: the standard deviations are not HAC ones" in text
    assert "model_selection" not in text  # the answer chosen from sums, as in memory
    assert sorted(path.name for path in folder.iterdir()) == ["r.json", "r.md"]
    assert "<img" not in streamed.report().html() and "<img" in memory.report().html()
    assert "Not computed on this path" not in memory.report().html()
    with pytest.raises(ValueError, match="--plot"):
        streamed.plot(folder / "r.png")


@pytest.fixture(scope="module")
def measured_records(model, tmp_path_factory):
    """The records of :func:`records` with their velocities and accelerations logged (no derivative to choose)."""
    folder = tmp_path_factory.mktemp("memory_path_measured")
    truth = build_model(model.robot, "internal", ("viscous", CoulombFriction(joints=(1,)), JointOffset(joints=(0,))))
    theta = true_parameters(truth, seed=0, coulomb=[8.0], offset=[3.0])
    paths = []
    for seed, trajectory in ((1, 3), (2, 4)):
        data = simulate(truth, theta, random_fourier(model.robot, seed=trajectory), noise={c: NOISE for c in truth.channels},
                        seed=seed, rate_hz=200.0, periods=3)
        path = folder / f"measured{seed}.parquet"
        Measurements(data.t, data.q, dq=data.dq, ddq=data.ddq, tau=data.tau).write(path)
        paths.append(path)
    return paths


def _candidates(document):
    return {candidate["name"]: candidate for candidate in document["model_selection"]["candidates"]}


@pytest.mark.parametrize(("kind", "validated"), [("filtered", True), ("measured", True), ("filtered", False)])
def test_identify_chooses_the_same_model_in_memory_and_streamed(tmp_path, records, measured_records, kind,
                                                                validated):
    """Issue 34 on the streamed path: a record over the memory budget gets the in-memory default answer, chosen among
    OLS, WLS and the consistent fit (its prior weight chosen on the validation record) from sums: the same choice,
    base, prior weight, parameters and every candidate's validation error (against the recording, on the same
    samples) to 1e-6; the model file holds the same models, and the filter path's validation errors come from one
    more pass over the validation blocks. Without a validation record both choose the consistent fit at the
    default prior weight."""
    paths = records if kind == "filtered" else measured_records
    derivatives = ("--cutoff", "6") if kind == "filtered" else ()
    documents = {}
    for name, options in (("memory", ()), ("streamed", ("--memory-budget", "1KB"))):
        out = tmp_path / f"{name}.json"
        validate = ("--validate", str(paths[1])) if validated else ()
        assert main(["identify", "--joints", "3", "--model", "internal", "--friction", "viscous,coulomb,offset",
                     "--data", str(paths[0]), *validate, "--out", str(out), "--quiet", *derivatives, *options]) == 0
        documents[name] = json.loads(out.read_text())
    memory, streamed = documents["memory"], documents["streamed"]
    assert (memory["identification_path"], streamed["identification_path"]) == ("in-memory", "streamed")
    assert streamed["chosen"] == memory["chosen"] == streamed["model_file"]["chosen"] == memory["model_file"]["chosen"]
    if kind == "filtered" and validated:
        # fitted as recorded, the torques keep the Coulomb step the 6 Hz filter smeared (the filtered target, before
        # h-flip, made the consistent fit win here): the unconstrained fit wins; the consistent candidate and its
        # prior weight search are still compared path to path below
        assert memory["chosen"] == "ols" and "consistent" in _candidates(memory)
    for key in ("selection", "base"):
        assert streamed["model_selection"][key] == memory["model_selection"][key]
    assert "model_selection" not in streamed["not_computed"] and "consistent" not in streamed["not_computed"]
    values = {name: np.array([p["value"] for p in document["parameters"]]) for name, document in documents.items()}
    np.testing.assert_allclose(values["streamed"], values["memory"], rtol=1e-6, atol=1e-6 * np.abs(values["memory"]).max())
    assert streamed["consistent"]["prior_weight"] == memory["consistent"]["prior_weight"]
    assert streamed["consistent"]["prior_weight_choice"] == memory["consistent"]["prior_weight_choice"]
    alternatives = {name: document["model_file"]["alternatives"] for name, document in documents.items()}
    assert set(alternatives["streamed"]) == set(alternatives["memory"])
    for name, entry in alternatives["memory"].items():
        np.testing.assert_allclose(alternatives["streamed"][name]["theta"], entry["theta"], rtol=1e-6,
                                   atol=1e-6 * np.abs(entry["theta"]).max())
    if not validated:
        assert memory["model_selection"]["selection"] == "no-validation" and memory["chosen"] == "consistent"
        return
    assert streamed["model_selection"]["repeat_ratio"] == pytest.approx(memory["model_selection"]["repeat_ratio"],
                                                                        rel=1e-4)
    for name, candidate in _candidates(memory).items():
        other = _candidates(streamed)[name]
        assert other["validation_mse"] == pytest.approx(candidate["validation_mse"], rel=1e-6)
        assert other["score"] == pytest.approx(candidate["score"], rel=1e-6)
    assert streamed["validation"]["mse"] == pytest.approx(memory["validation"]["mse"], rel=1e-6)
    # the paired difference of the best candidate and the consistent one: from each validation block's sums streamed
    # (the blocks memory cuts its samples into), the same figures (measured: 1e-11 relative on both records)
    paired = {name: document["model_selection"]["paired_difference"] for name, document in documents.items()}
    assert (paired["streamed"] is None) == (paired["memory"] is None)
    if paired["memory"] is not None:
        for key in ("best", "regularised", "blocks", "within_noise"):
            assert paired["streamed"][key] == paired["memory"][key]
        for key in ("difference", "standard_error"):
            assert paired["streamed"][key] == pytest.approx(paired["memory"][key], rel=1e-8), key
    search = {name: {entry["prior_weight"]: entry["weighted_validation_error"]
                     for entry in document["consistent"]["prior_weight_search"]} for name, document in documents.items()}
    assert set(search["streamed"]) == set(search["memory"])
    for weight, error in search["memory"].items():
        # weight 0: the optimum on the cone's boundary, not unique (choose_prior_weight): the spline derivatives
        # of a streamed window and of the whole record differ by 5e-11 of ddq, which moved its error by 1.5e-5
        assert search["streamed"][weight] == pytest.approx(error, rel=1e-6 if weight > 0 else 1e-4), weight
