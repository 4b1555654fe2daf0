"""Residual tracing finds the variable a residual follows, confirmed on another record."""

from __future__ import annotations

import numpy as np
import pytest

from dynamics.effects.linear import Armature, CoulombFriction, JointOffset, Spring
from dynamics.robots import load_robot
from dynamics.measurements import Measurements
from estimation.uncertainty.residual_tracing import plot_residual_trace, rank_candidates, residual_statements, trace_residuals
from oed.fourier import random_fourier


@pytest.fixture(scope="module")
def records():
    robot = load_robot("puma560", joints=3)
    out = []
    for seed in (3, 4):
        t, q, dq, ddq = random_fourier(robot, seed=seed).sample(200.0, 2)
        generator = np.random.default_rng(seed)
        residual = generator.normal(0.0, 0.2, q.shape)
        residual[:, 0] += 0.5 * np.tanh(dq[:, 0] / 0.02)  # Coulomb-like on joint 1
        residual[:, 1] += 0.5 * (q[:, 1] - q[:, 1].mean()) / q[:, 1].std()  # a spring on joint 2
        out.append((Measurements(t, q, dq, ddq), residual))
    return out


def test_tracing_names_the_variable_each_residual_follows(records):
    (train, r_train), (validate, r_validate) = records
    trace = trace_residuals(r_train, train, r_validate, validate, ("tau1", "tau2", "tau3"))
    assert trace.strongest("tau1", 1)[0].variable in ("sign_dq1", "dq1")
    assert trace.share("tau1", "sign_dq1") > 0.5
    assert trace.strongest("tau2", 1)[0].variable == "q2" and trace.share("tau2", "q2") > 0.5
    assert max(row.validation_share for row in trace.rows if row.channel == "tau3") < 0.03  # white: nothing
    assert all(row.train_share < 0.05 for row in trace.rows if row.channel == "tau3")
    statements = residual_statements(trace)
    assert "follows q2" in statements["tau2"] and "none of the traced variables" in statements["tau3"]
    document = trace.to_dict()
    assert document["bins"] == 20 and len(document["rows"]) == 3 * (5 * 3 + 1)


def test_dependence_not_confirmed_on_validation_is_not_named(records):
    (train, r_train), (validate, _) = records
    white = np.random.default_rng(9).normal(size=(validate.n_samples, 3))
    trace = trace_residuals(r_train, train, white, validate, ("tau1", "tau2", "tau3"))
    assert trace.share("tau2", "q2") < 0.03 < [r for r in trace.rows if r.channel == "tau2" and r.variable == "q2"][0].train_share


def test_candidates_ranked_by_the_variables_they_follow(records):
    (train, r_train), (validate, r_validate) = records
    trace = trace_residuals(r_train, train, r_validate, validate, ("tau1", "tau2", "tau3"))
    candidates = [Armature(joints=(0,)), JointOffset(joints=(2,)), Spring(joints=(1,)), CoulombFriction(joints=(0,)),
                  Spring(joints=(2,))]
    ranked = rank_candidates(trace, candidates, 3)
    assert {type(ranked[0][0]), type(ranked[1][0])} == {Spring, CoulombFriction}
    assert ranked[0][0].joints in ((0,), (1,)) and ranked[0][1] > 0.5
    assert ranked[-1][1] < 0.05


def test_figure_of_the_strongest_variables(records, tmp_path):
    (train, r_train), (validate, r_validate) = records
    trace = trace_residuals(r_train, train, r_validate, validate, ("tau1", "tau2", "tau3"))
    figure = plot_residual_trace(trace, r_validate, validate, ("tau1", "tau2", "tau3"), tmp_path / "trace.png")
    assert (tmp_path / "trace.png").stat().st_size > 1000 and len(figure.axes) == 9
    with pytest.raises(ValueError, match="channel names"):
        trace_residuals(r_train, train, r_validate, validate, ("tau1",))
