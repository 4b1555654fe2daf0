"""The zero-copy evaluation path gives exactly the model's own evaluation."""

from __future__ import annotations

import numpy as np
import pytest

from dynamics.fast_eval import evaluate_base_fast, evaluate_fast
from dynamics.models import build_model
from dynamics.robots import load_robot
from tests.conftest import random_states


@pytest.mark.parametrize("kind", ["internal", "external", "combined"])
def test_buffer_evaluation_equals_evaluate_and_evaluate_base(kind):
    model = build_model(load_robot("puma560", joints=3), kind, "viscous,wrench_offset")
    q, dq, ddq = random_states(3, 37, seed=4)
    np.testing.assert_array_equal(evaluate_base_fast(model, q, dq, ddq), model.evaluate_base(q, dq, ddq))
    # non-contiguous input (a column slice of a wider array) is handled
    wide = np.hstack([q, dq])
    np.testing.assert_array_equal(evaluate_fast(model, wide[:, :3], dq, ddq), model.evaluate(q, dq, ddq))
