"""A block's latest evaluations kept along kept states (Block.evaluate, effect_blocks.KEPT_EVALUATIONS): a shape asked
again a few evaluations later gives the same arrays (read-only) as its evaluation, not evaluated again; they equal an
evaluation afresh bit for bit; columns kept alone are evaluated again when the derivatives are asked; nothing is kept
along states that are not kept; a candidate's trial that meets kept evaluations is the trial made afresh."""

from __future__ import annotations

import numpy as np
import pytest

from dynamics.effects.linear import parse_effects
from dynamics.models import ModelKind
from estimation.diagnosis.candidates import trials
from estimation.estimators import effect_blocks
from estimation.estimators.effect_blocks import Block, States
from tests.shaped_problem import counting_evaluations, shaped_problem


@pytest.fixture(scope="module")
def problem():
    return shaped_problem(kept=True)


def counted_block(problem, spec: str = "coulomb:tanh", joint: int = 1) -> tuple[Block, list[int]]:
    """A block on ``joint`` whose row functions count their evaluations."""
    effect = parse_effects(spec)[0]
    block = Block(ModelKind.INTERNAL, problem.robot, type(effect)(joints=(joint,)), len(problem.model.channels))
    return block, counting_evaluations(block)


def test_a_shape_asked_again_is_the_kept_evaluation(problem):
    block, calls = counted_block(problem)
    states = problem.states
    first, second = block.evaluate(states, np.array([0.01])), block.evaluate(states, np.array([0.05]))
    assert calls[0] == 2
    again = block.evaluate(states, np.array([0.01]))  # no longer the latest: kept
    assert again is first and calls[0] == 2 and not again.flags.writeable
    fresh, _ = counted_block(problem)
    loose = States(problem.record.q, problem.record.dq, problem.record.ddq)
    evaluated = fresh.evaluate(loose, np.array([0.01]))
    assert np.array_equal(again, evaluated) and again.strides == evaluated.strides
    assert block.evaluate(states, np.array([0.05])) is second and calls[0] == 2


def test_only_the_latest_are_kept(problem):
    block, calls = counted_block(problem)
    states = problem.states
    first = block.evaluate(states, np.array([0.01]))
    for smoothing in np.linspace(0.02, 0.06, effect_blocks.KEPT_EVALUATIONS):
        block.evaluate(states, np.array([smoothing]))
    assert calls[0] == 1 + effect_blocks.KEPT_EVALUATIONS
    again = block.evaluate(states, np.array([0.01]))  # pushed out: evaluated again, the same values
    assert again is not first and np.array_equal(again, first) and calls[0] == 2 + effect_blocks.KEPT_EVALUATIONS
    assert len(block._kept) == effect_blocks.KEPT_EVALUATIONS


def test_the_derivatives_asked_after_the_columns_are_evaluated(problem):
    block, calls = counted_block(problem)
    states = problem.states
    columns = block.evaluate(states, np.array([0.01]))
    block.evaluate(states, np.array([0.05]))
    both, derivative = block.evaluate(states, np.array([0.01]), jacobian=True)
    assert calls[0] == 3 and derivative is not None and np.array_equal(both, columns)
    block.evaluate(states, np.array([0.05]))
    assert block.evaluate(states, np.array([0.01])) is both and calls[0] == 3  # the columns of the evaluation kept


def test_nothing_is_kept_along_states_not_kept(problem):
    block, calls = counted_block(problem)
    loose = States(problem.record.q, problem.record.dq, problem.record.ddq)
    for shape in (0.01, 0.05, 0.01):
        block.evaluate(loose, np.array([shape]))
    assert calls[0] == 3 and not block._kept


def test_kept_evaluations_are_dropped_when_a_block_is_sent(problem):
    block, _ = counted_block(problem)
    block.evaluate(problem.states, np.array([0.01]))
    assert block.__getstate__()["_kept"] == {} and block._kept


@pytest.mark.parametrize("spec", ["stribeck:velocity", "coulomb:tanh", "sigmoid"])
def test_a_trial_that_meets_kept_evaluations_is_the_trial_afresh(problem, spec, monkeypatch):
    # every evaluation of the first trial kept, so that the second meets each of them
    monkeypatch.setattr(effect_blocks, "KEPT_EVALUATIONS", 10_000)
    weights = np.array([1.0, 2.0, 4.0])
    rss = float(weights @ problem.fixed.power)
    for joint in range(problem.robot.n_joints):
        block, calls = counted_block(problem, spec, joint)
        first = trials.try_candidate((joint,), [block], problem.fixed, problem.states, weights, rss)
        afresh_calls = calls[0]
        block._latest = None  # the latest alone would not serve the search's start: what is met is the kept ones
        second = trials.try_candidate((joint,), [block], problem.fixed, problem.states, weights, rss)
        fresh, _ = counted_block(problem, spec, joint)
        afresh = trials.try_candidate((joint,), [fresh], problem.fixed, problem.states, weights, rss)
        for trial in (first, second):
            for name in ("rss", "f_statistic", "p_value", "bic"):
                assert getattr(trial, name) == getattr(afresh, name)
            assert np.array_equal(trial.fit.shape, afresh.fit.shape)
            assert np.array_equal(trial.fit.theta, afresh.fit.theta)
            assert np.array_equal(trial.fit.cov, afresh.fit.cov, equal_nan=True)
        assert calls[0] == afresh_calls  # the second trial evaluated nothing: it met every evaluation kept
