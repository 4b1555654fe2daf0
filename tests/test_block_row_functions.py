"""A block evaluates its effect's functions on its own rows only (effect_blocks.effect_row_functions): the columns and
derivatives equal the rows taken from the whole functions' evaluation bit for bit, strides included."""

from __future__ import annotations

import numpy as np
import pytest

from dynamics.effects.linear import parse_effects
from dynamics.models import ModelKind
from dynamics.robots import load_robot
from estimation.estimators.effect_blocks import Block, States, evaluate_at_shape, rows_taken


def whole(block: Block, states: States, shape, jacobian: bool):
    """The block's columns (and derivatives) as taken from every channel's evaluation (the former way)."""
    n, m, k = states.n_samples, block.n_channels, block.n_linear
    function = block.jacobian_function if jacobian else block.columns_function
    values = evaluate_at_shape(function, states.q, states.dq, states.ddq, shape)
    columns = rows_taken(values[:, : m * k].reshape(n, m, k), block.rows)
    if not jacobian:
        return columns, None
    derivative = rows_taken(values[:, m * k:].reshape(n, block.n_shape, m, k), block.rows).transpose(1, 0, 2, 3)
    return columns, derivative


@pytest.mark.parametrize("kind", [ModelKind.INTERNAL, ModelKind.COMBINED])
@pytest.mark.parametrize("spec", ["coulomb:tanh", "stribeck:velocity", "ripple", "sigmoid", "viscous", "offset",
                                  "spring"])
def test_the_block_rows_are_the_whole_evaluations_rows(spec, kind):
    robot = load_robot("puma560", joints=3)
    generator = np.random.default_rng(4)
    states = States(*(generator.normal(size=(300, 3)) for _ in range(3)))
    m = 3 if kind is ModelKind.INTERNAL else 9
    effects = parse_effects(spec)
    parts = effects if effects[0].joints is not None else [type(effects[0])(joints=(joint,)) for joint in range(3)]
    for effect in parts:
        try:
            block = Block(kind, robot, effect, m)
        except ValueError:  # no rows in this model
            continue
        shapes = [np.array([p.starts[0] for p in block.parameters]), np.array([p.starts[-1] for p in block.parameters])]
        for shape in shapes:
            for jacobian in (False, True):
                got = block.evaluate(states, shape, jacobian=jacobian)
                got = got if jacobian else (got, None)
                expected = whole(block, states, shape, jacobian)
                for a, b in zip(got, expected):
                    if b is None:
                        assert a is None
                        continue
                    assert a.shape == b.shape and a.strides == b.strides
                    assert np.array_equal(a, b, equal_nan=True)
                    assert np.array_equal(np.signbit(a), np.signbit(b))
