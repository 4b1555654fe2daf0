"""Wrong effects out: springs that are offsets or negative, candidates' rows at several states."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from dynamics.effects.linear import JointOffset, Spring, StribeckFriction
from dynamics.models import build_model
from dynamics.robots import load_robot
from estimation.diagnosis.search import diagnose, effect_channels
from dynamics.simulation.synthetic import simulate, true_parameters


from oed.fourier import random_fourier


@pytest.fixture(scope="module")
def robot():
    return load_robot("puma560", joints=3)


def _records(robot, extra):
    declared = build_model(robot, "internal", "viscous")
    theta = true_parameters(declared, seed=0)
    records = []
    for seed in (3, 4):
        data = simulate(declared, theta, random_fourier(robot, seed=seed), rate_hz=250.0, periods=2,
                        noise={f"tau{j}": 0.1 for j in (1, 2, 3)}, seed=seed)
        records.append(dataclasses.replace(data, tau=data.tau + extra(data)))
    return declared, records


def test_a_stribeck_candidate_with_a_small_velocity_keeps_its_rows(robot):
    model = build_model(robot, "internal", "viscous")
    assert effect_channels(StribeckFriction(joints=(1,), velocity=0.01), model) == ("tau2",)


def test_a_negative_stiffness_is_not_added_as_a_spring(robot):
    def anti_spring(data):
        extra = np.zeros_like(data.tau)
        extra[:, 2] = -8.0 * (data.q[:, 2] - data.q[:, 2].mean())
        return extra

    declared, (train, validate) = _records(robot, anti_spring)
    diagnosis = diagnose(declared, train, validate)
    assert all(effect.name != "spring" for effect in diagnosis.effects), [e.name for e in diagnosis.effects]
    reasons = {(r.name, r.channels): r.reason for r in diagnosis.rejected}
    assert "negative stiffness" in reasons[("spring", ("tau3",))]


def test_an_offset_is_not_taken_for_a_spring(robot):
    def offset(data):
        extra = np.zeros_like(data.tau)
        extra[:, 0] = 2.5
        return extra

    declared, (train, validate) = _records(robot, offset)
    diagnosis = diagnose(declared, train, validate,
                         candidates=[Spring(joints=(0,)), JointOffset(joints=(0,))])
    assert [(e.name, e.channels) for e in diagnosis.effects] == [("offset", ("tau1",))]
    diagnosis = diagnose(declared, train, validate, candidates=[Spring(joints=(0,))])
    assert diagnosis.effects == ()  # alone, the stiffness has no offset to beat: not a spring
