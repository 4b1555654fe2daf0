"""The streamed reader's clock as memory's (estimation.identification.time_base_choice on the streamed path).

Where a log's stamps are a logger's receive times (the samples taken on a regular clock, each stamped late or early
by up to 40 % of a step), memory scores the regular clock the stamps jitter around as a candidate of the
preprocessing choice and takes it; the streamed verbs read each source on that clock
(``estimation.streaming.time_base.RegularClock``: the kept rows, their instants on the least-squares line of their
stamps, nothing resampled) and make the same choice. Checked against memory's run on the same files: the time
base, both clocks' scores and the receive-times ratio, the chosen model and effects, the parameters, the validation
errors, and ``oed predict`` on a third record no choice saw. Before, the streamed path kept the stamps
(``not_computed.time_base``) and predicted the test record 1.115x, 1.085x, 1.000x memory's error.
"""

from __future__ import annotations

import json
import warnings

import numpy as np
import pandas as pd
import pytest

from dynamics.models import build_model
from dynamics.robots import load_robot
from estimation.data.records import read_record
from estimation.data.sampling_clock import on_regular_clock
from estimation.streaming.chunks import clock_source, read_chunks, source_file
from estimation.streaming.time_base import RegularClock
from oed.cli import main
from tests.test_time_base_choice import RATE, moved, simulated

#: the streamed answer against memory's (sums of another order; measured: parameters 2e-9 of the largest,
#: validation and test errors 1e-11)
SAME_ANSWER = 1e-8
CHUNK = "500"


def _run(verb: str, folder, paths: dict[str, str], name: str, *options: str) -> dict:
    out = folder / f"{name}.json"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        assert main([verb, "--joints", "3", *(("--friction", "viscous") if verb == "identify" else ()),
                     "--data", paths["train"], "--validate", paths["validate"], "--out", str(out), "--quiet",
                     *options]) == 0
    return json.loads(out.read_text())


def _predicted(document: dict, record: str, folder, name: str) -> dict[str, float]:
    """``oed predict``'s MSE per channel of the model file in ``document`` on ``record``."""
    model, metrics = folder / f"{name}-model.json", folder / f"{name}-metrics.json"
    model.write_text(json.dumps(document))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        assert main(["predict", "--model", str(model), "--data", record, "--metrics", str(metrics)]) == 0
    return json.loads(metrics.read_text())["mse"]


def _answer(document: dict) -> dict[str, float]:
    validation = document["validation"]
    return validation["chosen"]["mse"] if "chosen" in validation else validation["mse"]


def _close(measured: dict[str, float], expected: dict[str, float]) -> float:
    return max(abs(measured[channel] / expected[channel] - 1.0) for channel in expected)


def _jittered_file(folder, rows: int = 1200) -> str:
    """A 3-joint record whose stamps jitter by up to 40 % of a step around a regular clock (receive times)."""
    truth = np.arange(rows) / RATE
    stamps = truth + moved(rows, 0.4, seed=5)
    frame = {"t": stamps}
    for joint in range(1, 4):
        frame[f"q{joint}"] = np.sin((joint + 1) * truth)
        frame[f"tau{joint}"] = np.cos(joint * truth) + 0.01 * joint
    path = folder / "jittered.csv"
    pd.DataFrame(frame).to_csv(path, index=False, float_format="%.17g")
    return str(path)


def test_a_source_on_its_regular_clock_reads_memory_s_samples_on_that_clock(tmp_path):
    """``run.csv (regular clock)`` read in chunks gives the rows memory's ``on_regular_clock`` places (instants to
    the bit, values as recorded, nothing interpolated)."""
    path = _jittered_file(tmp_path)
    model = build_model(load_robot("puma560", joints=3), "internal", ())
    assert source_file(clock_source(path)) == (source_file(path)[0], RegularClock(None))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        memory = on_regular_clock(read_record(path, model=model)[0])
        chunks = list(read_chunks(clock_source(path), model, chunk_size=250))
    assert memory is not None and all("resampled_from" not in chunk.metadata for chunk in chunks)
    t = np.concatenate([chunk.t for chunk in chunks])
    np.testing.assert_array_equal(t, memory.t)
    np.testing.assert_array_equal(np.vstack([chunk.q for chunk in chunks]), memory.q)
    np.testing.assert_array_equal(np.vstack([chunk.tau for chunk in chunks]), memory.tau)


@pytest.mark.slow  # each verb twice, in memory and streamed, on a 3-joint arm (about 20 s a verb)
@pytest.mark.parametrize("verb", ["identify", "diagnose"])
def test_the_streamed_verbs_read_receive_times_on_the_regular_clock_as_memory_does(verb, tmp_path):
    paths = simulated(tmp_path, at_stamps=False)
    memory = _run(verb, tmp_path, paths, "memory")
    streamed = _run(verb, tmp_path, paths, "streamed", "--chunk-size", CHUNK)
    path = "identification_path" if verb == "identify" else "diagnosis_path"
    assert memory[path] == "in-memory" and streamed[path] == "streamed"
    # the same clock chosen on the same evidence: both scores and the ratio of the positions' roughness
    for document in (memory, streamed):
        assert document["preprocessing"]["time_base"] == "regular"
        assert document["model_file"]["preprocessing"]["time_base"] == "regular"  # what oed predict reads on
    assert "time_base" not in streamed["not_computed"]
    for key in ("stamps", "regular"):
        assert streamed["preprocessing"]["time_base_scores"][key] \
            == pytest.approx(memory["preprocessing"]["time_base_scores"][key], rel=SAME_ANSWER)
    assert streamed["preprocessing"]["receive_times_ratio"] \
        == pytest.approx(memory["preprocessing"]["receive_times_ratio"], rel=SAME_ANSWER)
    assert streamed["preprocessing"]["cutoff_hz"] == memory["preprocessing"]["cutoff_hz"]
    # the same answer
    assert streamed["model_file"]["chosen"] == memory["model_file"]["chosen"]
    if verb == "diagnose":
        assert [(effect["name"], effect["channels"]) for effect in streamed["effects"]] \
            == [(effect["name"], effect["channels"]) for effect in memory["effects"]]
    theta = {name: np.asarray(document["model_file"]["theta"], dtype=float)
             for name, document in (("memory", memory), ("streamed", streamed))}
    np.testing.assert_allclose(theta["streamed"], theta["memory"], rtol=SAME_ANSWER,
                               atol=SAME_ANSWER * np.abs(theta["memory"]).max())
    assert _close(_answer(streamed), _answer(memory)) < SAME_ANSWER
    # oed predict reads the validation record on the clock the model file names and reproduces the verb's error
    reported = streamed["model_file"]["reported"]["validation_mse"]
    assert _close(_predicted(streamed, paths["validate"], tmp_path, "streamed-validation"), reported) < 1e-6
    # the test record no choice saw: memory's errors
    errors = {name: _predicted(document, paths["test"], tmp_path, f"{name}-test")
              for name, document in (("memory", memory), ("streamed", streamed))}
    assert _close(errors["streamed"], errors["memory"]) < SAME_ANSWER, errors
