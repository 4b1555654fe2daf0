"""The reference motion of ``benchmarks/bench_reach.py`` (h-reach): the training positions shifted over the
description's joint limits, each copy within them, the copies spread over the room the limits leave."""

from __future__ import annotations

import numpy as np

from benchmarks.bench_reach import shifts


def test_the_shifted_copies_stay_within_the_limits_and_spread_over_them():
    generator = np.random.default_rng(3)
    q = np.column_stack([generator.uniform(-1.2, -0.2, 500), generator.uniform(0.1, 0.4, 500)])
    lower, upper = np.array([-2.9, -1.8]), np.array([2.9, 1.8])
    moved = shifts(lower, upper, q, 6)
    assert moved.shape == (6, 2)
    for shift in moved:
        assert np.all(q.min(axis=0) + shift >= lower) and np.all(q.max(axis=0) + shift <= upper)
    room = (upper - q.max(axis=0)) - (lower - q.min(axis=0))
    strata = np.sort((moved - (lower - q.min(axis=0))) / room, axis=0)  # a Latin hypercube: one copy a sixth
    assert np.allclose(strata, ((np.arange(6) + 0.5) / 6)[:, None])
    assert np.array_equal(moved, shifts(lower, upper, q, 6))  # seeded


def test_a_joint_without_limits_or_room_is_not_shifted():
    q = np.column_stack([np.linspace(-1.0, 1.0, 50), np.linspace(-1.0, 1.0, 50)])
    moved = shifts(np.array([-np.inf, -0.5]), np.array([np.inf, 0.5]), q, 4)
    assert np.all(moved == 0.0)
