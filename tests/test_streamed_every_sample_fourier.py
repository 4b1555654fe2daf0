"""The streamed Fourier path on records whose periods memory does not average (a jittered log's grid, whose rate is
not a multiple of the excitation frequency; fewer than two whole periods): the fit of every sample from normal
equations summed chunk by chunk (:class:`estimation.preprocessing.fourier_series.SummedFourierFit`,
:func:`estimation.streaming.periods.read_periodic`), against the in-memory
:class:`~estimation.preprocessing.differentiation.FourierDifferentiation` on the same samples. Before, the streamed
path averaged periods only and ``oed diagnose --chunk-size`` exited on such a log ("the sampling rate 249.575 Hz is
not a multiple of the excitation frequency 0.2 Hz")."""

from __future__ import annotations

import dataclasses
import json
import warnings

import numpy as np
import pytest

from dynamics.effects.linear import JointOffset
from dynamics.measurements import Measurements
from dynamics.models import build_model
from dynamics.robots import load_robot
from dynamics.simulation.synthetic import simulate, true_parameters
from estimation.data.records import read_measurements
from estimation.preprocessing.differentiation import (
    FourierDifferentiation,
    averages_periods,
    compensate_hold,
    periods_at_rate,
    whole_periods,
)
from estimation.preprocessing.fourier_series import SummedFourierFit, TriangularFourierFit, fit_series
from estimation.streaming.diagnosis_sums import concatenate
from estimation.streaming.periods import plan_chunks, read_periodic
from oed.fourier import random_fourier

FREQUENCY = 0.2  # Hz: random_fourier's fundamental
TRUE_DELAY = 0.007  # s: the torques lag the motion (the log of tests/test_streamed_delay.py)
NOISE = {"tau1": 0.1, "tau2": 0.1, "tau3": 0.05}


@pytest.mark.parametrize("jitter", [0.0, 0.3])
def test_the_summed_fit_is_the_whole_records_fit(jitter):
    generator = np.random.default_rng(4)
    t = (np.arange(1300) + generator.uniform(-jitter, jitter, 1300)) / 250.0 + 0.37
    q = np.column_stack([np.sin(2 * np.pi * FREQUENCY * t * k + k) for k in (1, 2, 3)]) \
        + 1e-3 * generator.standard_normal((t.shape[0], 3))
    whole, _ = fit_series(t, q, FREQUENCY, 7, solver="normal")
    summed = SummedFourierFit(FREQUENCY, 7, float(t[0]), 3)
    triangular = TriangularFourierFit(FREQUENCY, 7, float(t[0]), 3)
    for start in range(0, t.shape[0], 97):  # chunks across any bound
        summed.add(t[start:start + 97], q[start:start + 97])
        triangular.add(t[start:start + 97], q[start:start + 97])
    for fit in (summed.series(), triangular.series()):
        assert fit is not None
        for mine, theirs in zip(fit.evaluate(t), whole.evaluate(t)):
            np.testing.assert_allclose(mine, theirs, rtol=0, atol=1e-10 * np.max(np.abs(theirs)))
    with pytest.raises(ValueError, match="cannot determine"):
        SummedFourierFit(FREQUENCY, 7, 0.0, 3).series()


def test_memorys_rule_for_averaging_periods():
    assert periods_at_rate(250.0, 2500, FREQUENCY) == (2, 1250)
    assert periods_at_rate(249.575, 2496, FREQUENCY) is None
    assert averages_periods("auto", (2, 1250)) and not averages_periods("auto", (1, 1250))
    assert not averages_periods("auto", None) and not averages_periods("no", (3, 1250))
    assert averages_periods("yes", (1, 1250)) and averages_periods(True, (1, 1250))
    t = np.arange(1875) / 250.0  # one and a half periods: fitted at every sample
    measurements = Measurements(t, np.zeros((t.shape[0], 1)))
    assert whole_periods(measurements, FREQUENCY) == (1, 1250)
    assert not FourierDifferentiation(FREQUENCY).averages(measurements)


@pytest.fixture(scope="module")
def robot():
    return load_robot("puma560", joints=3)


@pytest.fixture(scope="module")
def records(robot, tmp_path_factory):
    """Positions-only logs of a 3-joint PUMA (250 Hz, two periods of 0.2 Hz, torques 7 ms behind the motion, an
    offset on joint 1): the training log's stamps jittered (resampled onto a 249.575 Hz grid), a validation and a
    test record of other motions; ``regular``: the training log's stamps as simulated (its periods averaged)."""
    from tests.test_streamed_reader_parity import with_defect

    folder = tmp_path_factory.mktemp("every_sample_fourier")
    truth = build_model(robot, "internal", ("viscous", JointOffset(joints=(0,))))
    theta = true_parameters(truth, seed=1, offset=[2.0])
    paths = {}
    for name, seed in (("train", 5), ("validate", 6), ("test", 7)):
        trajectory = random_fourier(robot, seed=seed)
        data = simulate(truth, theta, trajectory, rate_hz=250.0, periods=2, noise=NOISE, seed=seed)
        q, dq, ddq = trajectory.evaluate(data.t + TRUE_DELAY)  # the recorded motion runs ahead
        frame = dataclasses.replace(data, q=q, dq=dq, ddq=ddq).to_frame()
        frame = frame[[column for column in frame.columns if not column.startswith(("dq", "ddq"))]]
        if name == "train":
            paths["regular"] = folder / "regular.csv"
            frame.to_csv(paths["regular"], index=False, float_format="%.17g")
            frame = with_defect(frame, "jitter", 3)
        paths[name] = folder / f"{name}.csv"
        frame.to_csv(paths[name], index=False, float_format="%.17g")
    return paths


@pytest.mark.parametrize("held_torques", [False, True])
def test_the_streamed_chunks_are_memorys_fit_of_every_sample(robot, records, held_torques):
    """The jittered training log's grid (not a whole number of samples a period): every sample with the fit's motion,
    as the in-memory Fourier differentiation (and its hold compensation) gives them."""
    model = build_model(robot, "internal", "viscous")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the jitter and its stalls, said by the loader
        record = read_measurements(records["train"], model=model)
    assert record.metadata.get("resampled_from") is not None and whole_periods(record, FREQUENCY) is None
    memory = FourierDifferentiation(FREQUENCY, 10).apply(record)
    if held_torques:
        memory = compensate_hold(memory)
    said: dict = {}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        read = read_periodic(records["train"], model, FREQUENCY, 10, chunk_size=128)
        streamed = concatenate(list(plan_chunks(records["train"], model, frequency_hz=FREQUENCY, harmonics=10,
                                                chunk_size=128, held_torques=held_torques, record=said)))
    assert read.averaged is None and read.samples == record.n_samples
    assert said["metadata"]["periods_averaged"] == 0
    assert said["metadata"]["resampled_from"] == record.metadata["resampled_from"]
    np.testing.assert_allclose(streamed.t, memory.t, rtol=0, atol=1e-12)
    for name in ("q", "dq", "ddq", "tau"):
        expected = getattr(memory, name)
        np.testing.assert_allclose(getattr(streamed, name), expected, rtol=0, atol=1e-9 * np.max(np.abs(expected)))


@pytest.mark.slow  # two diagnoses (memory and streamed) and four predictions: about 40 s
def test_the_streamed_diagnosis_of_a_jittered_periodic_log_is_memorys(records, tmp_path, capsys):
    """``oed diagnose --chunk-size`` on the jittered log with its Fourier fit detected exited (exit 2) where memory
    fits every sample; now it gives memory's answer: the same effects and chosen model, the parameters, validation
    errors and ``oed predict``'s errors on the test record no choice saw to 1e-6 (measured 1e-10), its training
    errors those ``oed predict`` measures on the jittered log at its stamps, and the consistent fit's price against
    the same errors (it mixed the grid's and the stamps' before, 1.46 against 1.001)."""
    from oed.cli import main

    documents = {}
    for name, options in (("memory", ()), ("streamed", ("--chunk-size", "128"))):
        out = tmp_path / f"{name}.json"
        assert main(["diagnose", "--robot", "puma560", "--joints", "3", "--friction", "viscous", "--data",
                     str(records["train"]), "--validate", str(records["validate"]), "--out", str(out), "--quiet",
                     *options]) == 0
        documents[name] = json.loads(out.read_text())
    capsys.readouterr()
    memory, streamed = documents["memory"], documents["streamed"]
    assert streamed["diagnosis_path"] == "streamed" and streamed["preprocessing"]["method"] == "fourier"
    assert streamed["streaming"]["files"][0]["periods_averaged"] == 0
    assert [effect["spec"] for effect in streamed["effects"]] == [effect["spec"] for effect in memory["effects"]]
    assert streamed["model_selection"]["chosen"] == memory["model_selection"]["chosen"]
    np.testing.assert_allclose(streamed["model_file"]["theta"], memory["model_file"]["theta"], rtol=1e-6, atol=1e-9)
    for which in ("after", "chosen"):
        assert streamed["validation"][which]["mse"] == pytest.approx(memory["validation"][which]["mse"], rel=1e-6)
        assert streamed["train"][which]["mse"] == pytest.approx(memory["train"][which]["mse"], rel=1e-6)
    assert streamed["consistent"]["price"]["train"] == pytest.approx(memory["consistent"]["price"]["train"], rel=1e-6)
    metrics = tmp_path / "metrics.json"

    def predicted(name: str, data: str) -> dict:
        assert main(["predict", "--model", str(tmp_path / f"{name}.json"), "--data", str(records[data]),
                     "--metrics", str(metrics)]) == 0
        capsys.readouterr()
        return json.loads(metrics.read_text())["mse"]

    assert predicted("streamed", "test") == pytest.approx(predicted("memory", "test"), rel=1e-6)
    assert predicted("streamed", "train") == pytest.approx(streamed["train"]["chosen"]["mse"], rel=1e-6)
    assert predicted("streamed", "validate") == pytest.approx(streamed["validation"]["chosen"]["mse"], rel=1e-6)
