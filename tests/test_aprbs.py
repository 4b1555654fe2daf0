"""APRBS designer: ranges, hold times, amplitude coverage, seeding, and the best-of-candidates criterion."""

from __future__ import annotations

import numpy as np
import pytest

from dynamics.robots.servo_arm import SERVO_ARM_RANGES
from oed.aprbs_signal import (
    AmplitudeCoverage, APRBSDesign, SpectralContent, WeightedSum, design_aprbs, hold_min_from_time_constant, random_aprbs,
)


def _runs(column: np.ndarray) -> np.ndarray:
    change = np.flatnonzero(np.diff(column) != 0) + 1
    edges = np.concatenate(([0], change, [column.size]))
    return np.diff(edges)


def test_aprbs_respects_ranges_hold_min_and_covers_levels():
    design = APRBSDesign(ranges=SERVO_ARM_RANGES, duration=60.0, dt=0.01, hold_min=0.2)
    result = design_aprbs(design, candidates=8, seed=1)
    assert result.u.shape == (6000, 4) and np.allclose(np.diff(result.t), 0.01)
    for j, (low, high) in enumerate(SERVO_ARM_RANGES):
        column = result.u[:, j]
        assert column.min() >= low and column.max() <= high
        runs = _runs(column)
        assert runs.min() >= 20  # 0.2 s at 10 ms, including the last (truncated) hold
        levels = np.unique(column)
        assert levels.size >= 20  # many amplitudes, not two
        counts, _ = np.histogram(column, bins=6, range=(low, high))
        assert np.all(counts > 0)  # every sixth of the range visited
        assert (levels.max() - levels.min()) > 0.8 * (high - low)


def test_same_seed_same_signal_other_seed_other_signal():
    design = APRBSDesign(duration=10.0)
    a, b, c = (design_aprbs(design, candidates=4, seed=s).u for s in (7, 7, 8))
    assert np.array_equal(a, b) and not np.array_equal(a, c)


def test_best_candidate_beats_random_candidates_under_the_criterion():
    design = APRBSDesign(duration=30.0)
    criterion = WeightedSum()
    result = design_aprbs(design, criterion=criterion, candidates=32, seed=2)
    random_scores = [criterion.score(random_aprbs(design, np.random.default_rng(100 + i))) for i in range(16)]
    assert result.score >= max(result.candidate_scores) and result.score > np.median(random_scores)
    assert result.score == pytest.approx(criterion.score(random_aprbs(design, np.random.default_rng(np.random.SeedSequence(2).spawn(32)[result.best_index]))))


def test_criteria_rank_sensible_signals():
    design = APRBSDesign(ranges=((0.0, 1.0),), duration=20.0, dt=0.01, hold_min=0.2)
    t = np.arange(2000) * 0.01
    two_level = np.where((t // 1.0) % 2 == 0, 0.02, 0.98)[:, None]
    prbs = random_aprbs(design, np.random.default_rng(0)).__class__(t=t, u=two_level, design=design, holds=())
    aprbs = random_aprbs(design, np.random.default_rng(0))
    assert AmplitudeCoverage().score(aprbs) > AmplitudeCoverage().score(prbs) + 0.3
    slow = prbs.__class__(t=t, u=np.where(t < 10, 0.2, 0.8)[:, None], design=design, holds=())
    assert SpectralContent(band=(0.2, 2.5)).score(aprbs) > SpectralContent(band=(0.2, 2.5)).score(slow)


def test_hold_min_tied_to_time_constant():
    tau = 2 * 0.239 / 2.4919  # 2m/b for the paper's joint 2 (underdamped)
    assert hold_min_from_time_constant(tau, dt=0.01) == pytest.approx(0.20)
    assert hold_min_from_time_constant(1e-4, dt=0.01) == pytest.approx(0.01)


@pytest.mark.parametrize(
    "kwargs,message",
    [
        (dict(hold_min=0.005, dt=0.01), "hold_min = 0.005 s is shorter than the sample time"),
        (dict(ranges=((1.0, 0.5),)), "joint 1: range"),
        (dict(n_levels=2), "n_levels"),
        (dict(hold_min=0.2, hold_max=0.1), "hold_max"),
        (dict(duration=float("inf")), "duration must be a finite time"),
        (dict(hold_max=float("nan")), "hold_max must be a finite time"),
        (dict(hold_min=float("inf")), "hold_min must be a finite time"),
        # numpy scalars (e.g. taken from a robot's limits) are printed as plain numbers
        (dict(ranges=((np.float64("nan"), np.float64(1.0)),)), r"got \[nan, 1\.0\]$"),
        (dict(dt=np.float64("nan")), "dt must be positive, got nan$"),
    ],
)
def test_bad_designs_raise_named_errors(kwargs, message):
    with pytest.raises(ValueError, match=message):
        APRBSDesign(**kwargs)


def test_figure_of_signal_histogram_and_spectrum_is_written(tmp_path):
    from oed.aprbs_figures import plot_aprbs

    result = design_aprbs(APRBSDesign(duration=10.0), candidates=2, seed=0)
    path = tmp_path / "aprbs.png"
    plot_aprbs(result, path)
    assert path.stat().st_size > 10_000


def test_cli_infinite_duration_is_a_clear_error_not_a_traceback(tmp_path, capsys):
    from oed.cli import main

    assert main(["aprbs", "--duration", "inf", "--out", str(tmp_path / "u.csv")]) == 2
    error = capsys.readouterr().err
    assert "duration must be a finite time" in error and "Traceback" not in error
    assert list(tmp_path.iterdir()) == []
