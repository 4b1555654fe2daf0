"""A shape grid's columns kept while a trial lasts (Block.keeping_shapes, trials._grid_columns_kept): the kept columns
are the evaluation's bit for bit, the same array asked again, released on exit; a trial with them kept equals the
trial evaluated afresh (fits, costs, shapes bit for bit), with fewer evaluations when the law's physical screen runs."""

from __future__ import annotations

import contextlib

import numpy as np
import pytest

from dynamics.effects.linear import parse_effects
from dynamics.models import ModelKind
from estimation.diagnosis.candidates import trials
from estimation.estimators.effect_blocks import Block, States
from tests.shaped_problem import counting_evaluations, shaped_problem


@pytest.fixture(scope="module")
def problem():
    shaped = shaped_problem(kept=True)
    return shaped.robot, shaped.model, shaped.fixed, shaped.states, shaped.record


def test_kept_columns_are_the_evaluation_and_released(problem):
    robot, model, fixed, states, record = problem
    block = Block(ModelKind.INTERNAL, robot, parse_effects("coulomb:tanh")[0].__class__(joints=(1,)), len(model.channels))
    shapes = [np.array([0.01]), np.array([0.05])]
    with block.keeping_shapes(states):
        first = [block.evaluate(states, shape) for shape in shapes]
        again = [block.evaluate(states, shape) for shape in shapes]  # the first shape is no longer the latest
        assert all(a is b for a, b in zip(first, again))
        columns, derivative = block.evaluate(states, shapes[0], jacobian=True)  # the derivatives: evaluated
        assert derivative is not None and np.array_equal(columns, first[0])
    fresh = Block(ModelKind.INTERNAL, robot, block.effect, len(model.channels))
    other = States(record.q, record.dq, record.ddq, kept=True)
    for shape, kept in zip(shapes, first):
        evaluated = fresh.evaluate(other, shape)
        assert np.array_equal(kept, evaluated) and kept.strides == evaluated.strides and not kept.flags.writeable
    assert block._shapes is None
    assert block.evaluate(states, shapes[0]) is not first[0]  # released: evaluated again
    loose = States(record.q, record.dq, record.ddq)  # states not kept: nothing kept
    with block.keeping_shapes(loose):
        assert block._shapes is None


@pytest.mark.parametrize("spec", ["stribeck:velocity", "coulomb:tanh", "sigmoid"])
def test_a_trial_with_the_grid_kept_is_the_trial_evaluated_afresh(problem, spec, monkeypatch):
    robot, model, fixed, states, record = problem
    weights = np.array([1.0, 2.0, 4.0])
    rss = float(weights @ fixed.power - 0.0)
    effect = parse_effects(spec)[0]
    counts = {}

    def trial_of(joint: int, kept: bool):
        block = Block(ModelKind.INTERNAL, robot, type(effect)(joints=(joint,)), len(model.channels))
        calls = counting_evaluations(block)
        if not kept:
            monkeypatch.setattr(trials, "_grid_columns_kept", lambda *arguments: contextlib.nullcontext())
        try:
            trial = trials.try_candidate((joint,), [block], fixed, States(record.q, record.dq, record.ddq, kept=True),
                                         weights, rss)
        finally:
            monkeypatch.undo()
        return trial, calls[0]

    for joint in range(robot.n_joints):
        kept, kept_calls = trial_of(joint, True)
        afresh, afresh_calls = trial_of(joint, False)
        for name in ("rss", "f_statistic", "p_value", "bic"):
            assert getattr(kept, name) == getattr(afresh, name)
        assert np.array_equal(kept.fit.shape, afresh.fit.shape) and np.array_equal(kept.fit.theta, afresh.fit.theta)
        assert kept.fit.iterations == afresh.fit.iterations
        assert kept_calls <= afresh_calls
        counts[joint] = (kept_calls, afresh_calls)
    if spec == "stribeck:velocity":  # its physical screen runs here: the grid's columns are not evaluated twice
        assert any(kept_calls < afresh_calls for kept_calls, afresh_calls in counts.values())
