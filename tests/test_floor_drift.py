"""A periodic record's noise floor when something drifts between its periods (h-plants19): the period-to-period
variance counts every change from one period to the next as noise; a change slow along the phase (a friction
warming, a sensor's bias drifting) is taken out (:func:`estimation.uncertainty.noise_floor.without_drift`), white
noise alone is left as it was."""

from __future__ import annotations

import numpy as np

from dynamics.measurements import Measurements
from estimation.uncertainty.noise_floor import noise_floor

RATE, FREQUENCY, PERIODS = 250.0, 0.2, 2


def record(drift: float, seed: int = 0, sigma: float = 0.1) -> Measurements:
    """Two periods of a periodic torque (harmonics of 0.2 Hz and a Coulomb-like step) with white noise of ``sigma``
    on both channels; on the second, a level ``drift`` decaying over 3 s from the record's start (a joint warming)."""
    t = np.arange(0.0, PERIODS / FREQUENCY, 1.0 / RATE)
    phase = 2 * np.pi * FREQUENCY * t
    q = np.column_stack([0.4 * np.sin(phase), 0.3 * np.sin(2 * phase + 1.0)])
    periodic = np.column_stack([3 * np.sin(phase) + np.cos(5 * phase), 2 * np.tanh(np.cos(2 * phase + 1.0) / 0.02)])
    tau = periodic + np.random.default_rng(seed).normal(0.0, sigma, periodic.shape)
    tau[:, 1] += drift * np.exp(-t / 3.0) * np.tanh(np.cos(2 * phase + 1.0) / 0.02)
    return Measurements(t, q, None, None, tau, None, {"frequency_hz": FREQUENCY})


def test_a_drift_between_the_periods_is_no_noise():
    """A level warming by 2.4 N m on one channel (the corpus's warming case): the period variance is 0.53 there,
    the floor 0.01 within 15 % (the noise's), said in the details; the steady channel's floor as before."""
    floor = noise_floor(record(drift=2.4), ("tau1", "tau2"))
    assert floor.method == "periods"
    assert np.allclose(floor.variance, 0.01, rtol=0.15), floor.variance
    assert set(floor.details["drift"]) == {"tau2"}, floor.details
    assert floor.details["drift"]["tau2"]["periods"] > 10 * floor.variance[1]


def test_white_noise_alone_keeps_the_period_variance():
    """No drift, ten noise draws: the period-to-period variance stands on every channel (no false drift)."""
    for seed in range(10):
        floor = noise_floor(record(drift=0.0, seed=seed), ("tau1", "tau2"))
        assert "drift" not in floor.details, (seed, floor.details)
        assert floor.dof == (RATE / FREQUENCY) * (PERIODS - 1)


def test_read_in_blocks_the_drift_is_taken_out_alike():
    """The drifting record read in blocks past the whole-record capacity (the floor by passes,
    :func:`estimation.streaming.record_floor.periodic_floor`): memory's floor, its drift said alike."""
    from estimation.streaming.record_floor import periodic_floor

    whole = record(drift=2.4)

    def chunks():
        for start in range(0, whole.n_samples, 300):
            rows = slice(start, start + 300)
            yield Measurements(whole.t[rows], whole.q[rows], None, None, whole.tau[rows], None, {})

    memory = noise_floor(whole, ("tau1", "tau2"))
    streamed = periodic_floor(chunks, ("tau1", "tau2"), FREQUENCY, capacity=1000)
    assert streamed.method == memory.method == "periods"
    np.testing.assert_allclose(streamed.variance, memory.variance, rtol=1e-12)
    assert streamed.dof == memory.dof and set(streamed.details["drift"]) == {"tau2"}, streamed.details
