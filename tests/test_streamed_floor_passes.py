"""The streamed paths' noise floor is memory's in full (estimation.streaming.record_floor, the streamed diagnosis's
floor in estimation.streaming.diagnosis_passes.window_floor).

- a periodic segment longer than what is read whole (``capacity``): the period-to-period variance from each phase's
  sums, the same bits as memory's ``noise_floor`` at the frequency; the Fourier residual of a period that is no whole
  number of samples (the chirp sums of each chunk) and of jittered stamps (the design's blocks) within 1e-12; fewer
  than two periods: the differences, as memory; a record file streamed gives memory's pooled floor;
- the streamed diagnosis's floor by default of every row of each validation file, memory's
  (``PreparedRecord.noise_floor``), not of the first rows; ``--floor-window N`` still the first ``N`` rows;
- slow: ``oed diagnose --chunk-size`` on a validation file longer than the former window (100 000 rows) reports
  memory's floor.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from dynamics.measurements import Measurements
from estimation.streaming.record_floor import periodic_floor
from estimation.uncertainty.noise_floor import noise_floor

CHANNELS = ("tau1", "tau2")
#: the Fourier residual's sums taken chunk by chunk against memory's of the whole
SUMS = 1e-12


def _record(t, seed=4):
    rng = np.random.default_rng(seed)
    tau = np.column_stack([np.sin(2 * np.pi * 0.5 * t) + 0.3 * np.cos(2 * np.pi * 1.5 * t),
                           0.2 * np.sin(2 * np.pi * 2.0 * t + 0.4)])
    tau = tau + rng.normal(0.0, [0.01, 0.03], tau.shape)
    return Measurements(t, np.zeros((t.shape[0], 2)), tau=tau)


def _chunks(record, size):
    def chunks():
        for start in range(0, record.n_samples, size):
            rows = slice(start, start + size)
            yield Measurements(record.t[rows], record.q[rows], tau=record.tau[rows])
    return chunks


@pytest.mark.parametrize("size", [97, 500])
def test_a_long_periodic_segment_gets_memory_s_period_to_period_floor_bit_for_bit(size):
    record = _record(np.arange(2050) / 100.0)  # 0.5 Hz at 100 Hz: 200 samples a period, 10 periods and a tail
    memory = noise_floor(record, CHANNELS, frequency_hz=0.5)
    streamed = periodic_floor(_chunks(record, size), CHANNELS, 0.5, capacity=300)
    assert memory.method == streamed.method == "periods"
    assert np.array_equal(streamed.variance, memory.variance)
    assert (streamed.dof, streamed.n_samples, streamed.details) == (memory.dof, memory.n_samples, memory.details)


@pytest.mark.parametrize("jitter", [0.0, 0.2])
def test_a_long_periodic_segment_gets_memory_s_fourier_residual_floor(jitter):
    rng = np.random.default_rng(8)
    t = np.arange(6000) / 40.0 + jitter / 40.0 * rng.uniform(-0.5, 0.5, 6000)  # 0.3 Hz: 133.3 samples a period
    record = _record(t)
    memory = noise_floor(record, CHANNELS, frequency_hz=0.3)
    streamed = periodic_floor(_chunks(record, 1000), CHANNELS, 0.3, capacity=300)
    assert memory.method == streamed.method == "fourier"
    np.testing.assert_allclose(streamed.variance, memory.variance, rtol=SUMS, atol=0.0)
    if jitter:  # off a grid: the design's blocks as memory forms them, the same bits
        assert np.array_equal(streamed.variance, memory.variance)
    assert (streamed.dof, streamed.n_samples) == (memory.dof, memory.n_samples)
    assert streamed.details == pytest.approx(memory.details, rel=1e-12)


def test_a_periodic_segment_of_less_than_two_periods_takes_the_differences_as_memory():
    record = _record(np.arange(600) / 100.0)  # 3 s of a 0.2 Hz excitation
    memory = noise_floor(record, CHANNELS, frequency_hz=0.2)
    streamed = periodic_floor(_chunks(record, 128), CHANNELS, 0.2, capacity=100)
    assert memory.method == streamed.method == "differences"
    assert np.array_equal(streamed.variance, memory.variance) and streamed.dof == memory.dof


def _written(folder, *, rate_hz=100.0, periods=2, files=(1,)):
    from dynamics.models import build_model
    from dynamics.robots import load_robot
    from dynamics.simulation.synthetic import simulate
    from oed.fourier import random_fourier

    model = build_model(load_robot("puma560", joints=3), "internal", "viscous")
    theta = model.nominal_parameters()
    paths = []
    for seed in files:
        record = simulate(model, theta, random_fourier(model.robot, seed=seed, frequency_hz=0.5), rate_hz=rate_hz,
                          periods=periods, noise={f"tau{j}": 0.05 for j in (1, 2, 3)}, seed=30 + seed)
        path = folder / f"record{seed}.csv"
        record.write(path)
        paths.append(str(path))
    return model, paths


def _memory_floor(model, paths, frequency_hz):
    from estimation.data.records import read_record
    from estimation.uncertainty.noise_floor import pooled_floor

    floors = []
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for path in paths:
            for segment in read_record(path, model=model):
                floors.append(noise_floor(segment.as_recorded, model.channels, frequency_hz=frequency_hz))
    return pooled_floor(floors)


def test_a_record_streamed_in_chunks_gives_memory_s_periodic_and_difference_floors(tmp_path):
    from estimation.streaming.diagnosis_passes import window_floor
    from estimation.streaming.record_floor import record_floor

    model, paths = _written(tmp_path, periods=2)  # 400 rows, 2 periods
    periodic = _memory_floor(model, paths, 0.5)
    assert periodic.method == "periods"
    streamed = record_floor(paths, model, chunk_size=150, frequency_hz=0.5, capacity=150)
    assert streamed == dict(periodic.mse())  # the same bits
    # the streamed diagnosis's floor (every row by default) is memory's; --floor-window N: the first N rows
    memory = _memory_floor(model, paths, None)
    floor, note = window_floor(paths, model, chunk_size=150)
    assert np.array_equal(floor.variance, memory.variance) and floor.dof == memory.dof and "every row" in note
    floor, note = window_floor(paths, model, window=200, chunk_size=150)
    assert "first 200 rows" in note and not np.array_equal(floor.variance, memory.variance)


@pytest.mark.slow  # two files of 120 000 rows read in passes (about 60 s)
def test_the_streamed_diagnosis_s_floor_is_memory_s_over_every_row(tmp_path):
    from estimation.streaming.diagnosis_passes import window_floor

    model, paths = _written(tmp_path, rate_hz=1000.0, periods=60, files=(1, 2))  # 120 000 rows each
    memory = _memory_floor(model, paths, None)
    floor, note = window_floor(paths, model, chunk_size=20_000)  # the former default read 100 000 rows of each
    assert np.array_equal(floor.variance, memory.variance) and floor.dof == memory.dof
    assert floor.n_samples == memory.n_samples == 240_000 and "every row" in note
