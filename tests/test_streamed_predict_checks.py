"""The streamed ``oed predict`` gives memory's noise floor and record-change check (estimation.streaming.record_floor,
estimation.identification.record_changes.sampled_record_changes).

- the exact selection over passes (estimation.streaming.record_floor.order_statistics) against ``numpy.partition``
  and ``numpy.median``, on values with many ties (a quantised sensor's differences), every rank found by histograms
  narrowed pass by pass (a capacity far below the values);
- the difference floor of a segment read in blocks against memory's ``noise_floor`` of the whole: bit for bit, the
  refusal of a filtered channel and a passive joint's zero channel alike;
- slow: a 6-joint PUMA's model predicting a record of two segments (16 000 samples, more than the check's 6000 rows)
  made with a 2 kg payload on its last link: memory's ``predict`` and the streamed one (``chunk_size=500``) give the
  same floor, the same change said with the same estimate, p-values and errors with the change (relative 1e-9;
  measured 1e-14 with the logged derivatives), nothing left in ``not_computed`` but the per-sample predictions.
"""

from __future__ import annotations

import json
import warnings

import numpy as np
import pytest
import scipy.signal

from dynamics.measurements import Measurements
from estimation.streaming.record_floor import difference_floor, order_statistics
from estimation.uncertainty.noise_floor import NoiseFloorError, noise_floor

#: streamed against memory: the same samples, sums in another order
SAME = 1e-9


def _blocks(values, size):
    return lambda: (values[start:start + size] for start in range(0, values.shape[0], size))


def test_order_statistics_by_passes_are_numpy_s_on_values_with_ties():
    rng = np.random.default_rng(3)
    values = np.column_stack([np.round(rng.normal(0.0, 1.0, 5001), 1),  # a quantised channel: many ties
                              rng.standard_t(2.0, 5001) * 1e-3, np.full(5001, 0.25)])
    ranks = [0, 17, 2500, 2501, 5000]
    expected = np.array([np.partition(values, rank, axis=0)[rank] for rank in ranks])
    for capacity in (10, 100, 10**6):  # narrowed by histograms, gathered after a pass, gathered at once
        found = order_statistics(_blocks(values, 333), ranks, capacity=capacity, bins=16)
        assert np.array_equal(found, expected), capacity


def test_the_difference_floor_read_in_blocks_is_memory_s_bit_for_bit():
    rng = np.random.default_rng(5)
    t = np.arange(4000) / 500.0
    smooth = np.column_stack([np.sin(2 * np.pi * 0.3 * t), np.cos(2 * np.pi * 0.7 * t)])
    tau = np.column_stack([smooth[:, 0] + rng.normal(0.0, 0.01, t.shape[0]),
                           np.round(smooth[:, 1] + rng.normal(0.0, 0.02, t.shape[0]), 2), np.zeros(t.shape[0])])
    record = Measurements(t, np.zeros((t.shape[0], 3)), tau=tau)
    channels = ("tau1", "tau2", "tau3")
    memory = noise_floor(record, channels)
    for size, capacity in ((500, 10**6), (333, 64)):
        streamed = difference_floor(_blocks(tau, size), channels, capacity=capacity)
        assert np.array_equal(streamed.variance, memory.variance) and streamed.dof == memory.dof
        assert streamed.n_samples == memory.n_samples and streamed.method == memory.method
    # a channel filtered before it was recorded: refused alike
    filtered = tau.copy()
    filtered[:, 0] = scipy.signal.sosfiltfilt(scipy.signal.butter(4, 0.2, output="sos"), filtered[:, 0])
    with pytest.raises(NoiseFloorError) as in_memory:
        noise_floor(Measurements(t, np.zeros((t.shape[0], 3)), tau=filtered), channels)
    with pytest.raises(NoiseFloorError) as streamed_error:
        difference_floor(_blocks(filtered, 400), channels, capacity=64)
    assert str(streamed_error.value) == str(in_memory.value)


@pytest.fixture(scope="module")
def payload_record(tmp_path_factory):
    """A 6-joint PUMA's model identified without a payload (logged derivatives) and a record of two segments made
    with a 2 kg payload on link 6, each 8000 samples at 200 Hz."""
    from dynamics.simulation.synthetic import simulate
    from estimation.identification.fit import identify
    from estimation.identification.model_file import RobotSource, model_file_document
    from oed.fourier import random_fourier
    from tests.test_payload import FREQUENCY_HZ, puma_with_payload

    folder = tmp_path_factory.mktemp("payload")
    model, theta, loaded, noise = puma_with_payload()
    train = simulate(model, theta, random_fourier(model.robot, seed=1, frequency_hz=FREQUENCY_HZ), rate_hz=200.0,
                     periods=2, noise=noise, seed=3)
    document = model_file_document(identify(model, train, covariance="classical"),
                                   robot=RobotSource("puma560", "puma560", None), preprocessing=None)
    (folder / "model.json").write_text(json.dumps(document))
    paths = []
    for index, seed in enumerate((21, 22)):
        record = simulate(model, loaded, random_fourier(model.robot, seed=seed, frequency_hz=FREQUENCY_HZ),
                          rate_hz=200.0, periods=4, noise=noise, seed=100 + seed)
        path = folder / f"segment{index}.csv"
        record.write(path)
        paths.append(str(path))
    return folder / "model.json", paths


@pytest.mark.slow  # a 6-joint model predicting 16 000 samples in memory and streamed (about 40 s)
def test_predict_streamed_gives_memory_s_floor_and_record_change_check(payload_record):
    from oed.workflows.predict import predict

    model, paths = payload_record
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        memory = predict(model=model, data=paths).to_dict()
        streamed = predict(model=model, data=paths, chunk_size=500).to_dict()
    assert streamed["prediction_path"] == "streamed" and set(streamed["not_computed"]) == {"predictions"}
    assert streamed["n_samples"] == memory["n_samples"] == 16000
    for key in ("mse", "noise_floor_mse", "mse_over_floor"):
        for channel, value in memory[key].items():
            assert streamed[key][channel] == pytest.approx(value, rel=SAME), (key, channel)
    changed, said = memory["changed"], streamed["changed"]
    assert [family["change"] for family in said["said"]] == [family["change"] for family in changed["said"]] \
        == ["payload"]
    assert said["summary"] == changed["summary"] and said["floor_source"] == changed["floor_source"]
    assert "2 ± 0.0017 kg more on link 6" in said["summary"]
    for name, family in changed["tested"].items():
        other = said["tested"][name]
        assert other["said"] == family["said"], name
        for key in ("p_value", "wald_statistic"):
            assert other[key] == pytest.approx(family[key], rel=SAME), (name, key)
        for key in ("model_mse", "cross_fitted_mse", "mse_with_change", "noise_floor_mse"):
            for channel, value in family[key].items():
                assert other[key][channel] == pytest.approx(value, rel=SAME), (name, key, channel)
