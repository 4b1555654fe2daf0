"""Which clock the samples follow (estimation.data.sampling_clock): the stamps, or a regular clock they only
approximate. The truth is known by construction (a smooth motion evaluated at the instants the samples were
taken, the stamps written apart from it), and on the real logs by their facts (the KUKA LWR4+'s stamps jitter
around 5 ms, the Panda's are its samples' instants: ``benchmarks/README.md``, h-jitter)."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from estimation.data import MeasurementWarning, ReceiveTimesWarning, ResampledWarning, clock_roughness
from estimation.data.records import read_measurements
from estimation.data.sampling_clock import RECEIVE_TIMES_RATIO, ClockSums
from tests.conftest import shared_data

RATE = 500.0


def motion(t: np.ndarray) -> np.ndarray:
    """Two joints of a smooth motion (a few harmonics, rad) at the instants ``t``."""
    return np.column_stack([0.8 * np.sin(2 * np.pi * 0.3 * t) + 0.2 * np.sin(2 * np.pi * 1.7 * t),
                            0.5 * np.cos(2 * np.pi * 0.45 * t) - 0.1 * np.sin(2 * np.pi * 2.3 * t)])


def moved(t: np.ndarray, fraction: float, seed: int = 0) -> np.ndarray:
    """``t`` each moved by a uniform error of at most ``fraction`` of a step (order kept)."""
    return t + np.random.default_rng(seed).uniform(-fraction, fraction, t.shape[0]) / RATE


def test_stamps_moved_off_a_regular_clock_are_told_from_samples_taken_at_their_stamps():
    regular = np.arange(4000) / RATE
    stamps = moved(regular, 0.4)
    # the samples taken on the regular clock, stamped late or early: far smoother on the regular clock
    assert clock_roughness(stamps, motion(regular)) > 10 * RECEIVE_TIMES_RATIO
    # the samples taken at their (irregular) stamps: smoother at the stamps
    assert clock_roughness(stamps, motion(stamps)) < 1.0
    # regular stamps: the two clocks are one
    assert clock_roughness(regular, motion(regular)) == pytest.approx(1.0)


def test_dropped_rows_and_stalls_do_not_count_against_the_regular_clock():
    regular = np.arange(4000) / RATE
    kept = np.ones(regular.shape[0], dtype=bool)
    kept[np.random.default_rng(3).choice(np.arange(5, 3995), 60, replace=False)] = False  # rows dropped
    kept[1000:1010] = False  # a stall of ten samples
    t = regular[kept]
    assert clock_roughness(t, motion(t)) == pytest.approx(1.0, abs=1e-6)


def test_still_or_short_records_give_no_evidence():
    t = np.arange(4000) / RATE
    assert clock_roughness(t, np.zeros((4000, 2))) is None
    assert clock_roughness(t[:50], motion(t[:50])) is None


def test_the_reader_says_the_stamps_look_like_receive_times_and_changes_nothing(tmp_path):
    regular = np.arange(3000) / RATE
    q = motion(regular)
    stamps = moved(regular, 0.4, seed=1)
    frame = pd.DataFrame({"t": stamps, "q1": q[:, 0], "q2": q[:, 1], "tau1": q[:, 0], "tau2": q[:, 1]})
    path = tmp_path / "received.csv"
    frame.to_csv(path, index=False)
    with pytest.warns(MeasurementWarning) as caught:
        loaded = read_measurements(path)
    said = [str(warning.message) for warning in caught if isinstance(warning.message, ReceiveTimesWarning)]
    assert any(isinstance(warning.message, ResampledWarning) for warning in caught)
    assert len(said) == 1 and "received.csv: the positions are" in said[0]
    assert "times smoother on a regular clock (a sample every " in said[0]
    # nothing changed: resampled by the stamps as before
    np.testing.assert_allclose(loaded.q[:, 0], np.interp(loaded.t, stamps, q[:, 0]))
    frame["q1"], frame["q2"] = motion(stamps).T  # taken at the stamps: resampled, nothing more said
    frame.to_csv(path, index=False)
    with pytest.warns(MeasurementWarning) as caught:
        read_measurements(path)
    assert any(isinstance(warning.message, ResampledWarning) for warning in caught)
    assert not any(isinstance(warning.message, ReceiveTimesWarning) for warning in caught)


@pytest.mark.realdata
def test_the_real_logs_clocks():
    """The KUKA LWR4+'s positions are smoother on a regular clock than at its jittered stamps (its logged velocity
    agrees with both within 1 %); the Panda's stamps are its samples' instants."""
    kuka = np.load(shared_data("kuka_lwr4", "kuka_lwr4_HW_measurements_1.npz"))
    ratio = clock_roughness(np.asarray(kuka["times"], float).ravel(), np.asarray(kuka["positions"], float))
    assert ratio is not None and ratio > RECEIVE_TIMES_RATIO
    log = shared_data("panda", "Trajectory_1", "rbt_log")
    t = np.loadtxt(log / "exciting_traj_time.txt").ravel()
    q = np.loadtxt(log / "exciting_traj_positions.txt").reshape(-1, 7)
    fresh = np.r_[True, np.any(np.diff(q, axis=0) != 0, axis=1)]  # re-sent rows dropped, as the reader does
    ratio = clock_roughness(t[fresh], q[fresh])
    assert ratio is not None and ratio < 1.2


def test_the_sums_of_blocks_carrying_two_rows_give_the_whole_records_ratio():
    """The streamed reader's way (estimation.streaming.chunks): blocks of rows, the last two of each carried."""
    regular = np.arange(5000) / RATE
    stamps, q = moved(regular, 0.3, seed=2), motion(regular)
    whole = ClockSums.of(stamps, q, 1 / RATE)
    total, carry = None, None
    for start in range(0, 5000, 700):
        t, values = stamps[start:start + 700], q[start:start + 700]
        if carry is not None:
            t, values = np.r_[carry[0], t], np.vstack([carry[1], values])
        carry = (t[-2:], values[-2:])
        total = ClockSums.of(t, values, 1 / RATE) if total is None else total + ClockSums.of(t, values, 1 / RATE)
    assert total.compared == whole.compared
    assert total.ratio == pytest.approx(whole.ratio, rel=1e-12)
    assert whole.ratio == pytest.approx(clock_roughness(stamps, q, 1 / RATE))
