"""``oed predict`` on a record read in chunks (estimation.streaming.prediction): memory's errors, yardsticks and
training range, on a record no choice saw.

The models are a 3-joint PUMA's, identified in memory and streamed on simulated records (tests/test_time_base_choice):
their stamps a logger's receive times (the model reads a record on the regular clock) or the samples taken at
jittered stamps (the record resampled by them, its errors at the recorded stamps). Each streamed prediction is
compared with the in-memory one of the same model on the same file, the record's noise floor and the record-change
check too; only the per-sample predictions are said in ``not_computed``.
"""

from __future__ import annotations

import json
import warnings

import numpy as np
import pytest

from estimation.identification.training_range import TrainingRange
from estimation.streaming.prediction import pooled_range
from oed.cli import main
from tests.test_time_base_choice import simulated

#: the streamed errors against memory's (the filter's chunks equal the whole record's to 1e-13; measured 7e-12)
SAME = 1e-9
CHUNK = "500"


def _identified(folder, paths: dict[str, str], *options: str) -> str:
    out = folder / "result.json"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        assert main(["identify", "--joints", "3", "--friction", "viscous", "--data", paths["train"],
                     "--validate", paths["validate"], "--out", str(out), "--quiet", *options]) == 0
    return str(out)


def _predicted(model: str, record: str, metrics, *options: str) -> dict:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        assert main(["predict", "--model", model, "--data", record, "--metrics", str(metrics), *options]) == 0
    return json.loads(metrics.read_text())


def _assert_alike(streamed: dict, memory: dict) -> None:
    assert streamed["prediction_path"] == "streamed"
    for key in ("mse", "zero_mse", "nominal_mse"):
        for channel, value in memory[key].items():
            assert streamed[key][channel] == pytest.approx(value, rel=SAME), (key, channel)
    assert streamed["n_samples"] == memory["n_samples"]
    assert streamed["reported_validation_mse"] == memory["reported_validation_mse"]
    assert streamed["model"] == memory["model"]
    for joint, excursion in memory["outside_training_range"].items():
        other = streamed["outside_training_range"][joint]
        assert other["outside"] == excursion["outside"] and other["fraction"] == excursion["fraction"], joint
        for key in ("position_below", "position_above", "speed_above"):
            assert other[key] == pytest.approx(excursion[key], rel=SAME, abs=1e-12), (joint, key)
    # the record's noise floor and the record-change check: memory's (only the per-sample outputs not kept)
    assert set(streamed["not_computed"]) == {"predictions"}
    assert memory["noise_floor_mse"] is not None and memory["changed"] is not None
    for channel, value in memory["noise_floor_mse"].items():
        assert streamed["noise_floor_mse"][channel] == pytest.approx(value, rel=SAME), channel
    assert streamed["changed"]["summary"] == memory["changed"]["summary"]
    for name, family in memory["changed"]["tested"].items():
        # a p-value moves with the fits more than the errors (measured 2e-10 apart, the errors 7e-12)
        assert streamed["changed"]["tested"][name]["p_value"] == pytest.approx(family["p_value"], rel=1e-6), name


def test_the_training_range_checked_chunk_by_chunk_is_the_whole_record_s():
    """The pooled check of a record's chunks: each joint's largest excursions and its share of samples outside, as
    :meth:`TrainingRange.check` of the whole record gives them."""
    rng = np.random.default_rng(7)
    ranges = TrainingRange(("joint1", "joint2"), np.array([-1.0, -0.5]), np.array([1.0, 0.5]), np.array([2.0, 1.0]),
                           1000)
    q, dq = rng.normal(0.0, 0.6, (1000, 2)), rng.normal(0.0, 0.8, (1000, 2))
    whole = ranges.check(q, dq)
    pooled = pooled_range([ranges.check(q[start:start + 170], dq[start:start + 170]) for start in range(0, 1000, 170)])
    assert pooled is not None and pooled.n_samples == whole.n_samples
    for left, right in zip(pooled.joints, whole.joints):
        assert left.outside == right.outside and left.below == right.below and left.above == right.above
        assert left.speed_above == right.speed_above and left.fraction == pytest.approx(right.fraction, rel=1e-12)
    assert any(joint.outside for joint in whole.joints)  # the check has something to pool


@pytest.mark.slow  # two identify runs and six predictions on a 3-joint arm (about 40 s)
@pytest.mark.parametrize("at_stamps", [False, True], ids=["receive-times", "jittered"])
def test_predict_streamed_gives_memory_s_errors_on_a_record_no_choice_saw(at_stamps, tmp_path, capsys):
    paths = simulated(tmp_path, at_stamps=at_stamps)
    for name, options in (("memory", ()), ("streamed", ("--chunk-size", CHUNK))):
        (tmp_path / name).mkdir()
        model = _identified(tmp_path / name, paths, *options)
        document = json.loads((tmp_path / name / "result.json").read_text())
        assert document["preprocessing"].get("time_base", "stamps") == ("stamps" if at_stamps else "regular")
        memory = _predicted(model, paths["test"], tmp_path / f"{name}-memory.json")
        streamed = _predicted(model, paths["test"], tmp_path / f"{name}-streamed.json", "--chunk-size", CHUNK)
        _assert_alike(streamed, memory)
        # the validation record: the verb's reported error reproduced (1e-6), as in memory
        validation = _predicted(model, paths["validate"], tmp_path / f"{name}-validation.json", "--chunk-size", CHUNK)
        for channel, value in validation["reported_validation_mse"].items():
            assert validation["mse"][channel] == pytest.approx(value, rel=1e-6), channel
    capsys.readouterr()


@pytest.mark.slow  # one identify run and three predictions (about 20 s)
def test_predict_past_the_memory_budget_streams_and_refuses_per_sample_outputs(tmp_path, capsys):
    paths = simulated(tmp_path, at_stamps=False)
    model = _identified(tmp_path, paths)
    memory = _predicted(model, paths["test"], tmp_path / "memory.json")
    capsys.readouterr()
    streamed = _predicted(model, paths["test"], tmp_path / "budget.json", "--memory-budget", "10KB")
    said = capsys.readouterr().err
    assert "over the budget" in said and "streaming" in said
    _assert_alike(streamed, memory)
    # per-sample outputs asked for: read in memory whatever the budget
    again = _predicted(model, paths["test"], tmp_path / "with-out.json", "--memory-budget", "10KB", "--out",
                       str(tmp_path / "predictions.csv"))
    assert "prediction_path" not in again and (tmp_path / "predictions.csv").is_file()
    # and refused with --chunk-size, a clear error
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        code = main(["predict", "--model", model, "--data", paths["test"], "--chunk-size", CHUNK, "--out",
                     str(tmp_path / "refused.csv")])
    assert code != 0
    assert "--out and --plot write every sample" in capsys.readouterr().err
    assert not (tmp_path / "refused.csv").exists()


def test_a_streamed_run_refuses_every_samples_outputs_naming_the_in_memory_route_in_python_too():
    """A notebook's ``predict(...)`` past the memory budget returns a streamed run: its ``columns()``, ``plot()`` and
    ``write(out=...)`` are refused with a message naming the route that keeps every sample, for the command line and
    for Python (``per_sample=True``), and nothing is written."""
    from oed.workflows.predict import StreamedPredictRun

    run = StreamedPredictRun(evaluation=None, lines=("robot: model",), warnings=())
    for call in (run.columns, run.plot, lambda: run.write(out="never.csv")):
        with pytest.raises(ValueError, match=r"columns\(\) and plot\(\).*per_sample=True"):
            call()
