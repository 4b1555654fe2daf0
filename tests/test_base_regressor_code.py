"""The base regressor is the full regressor's shared expressions sliced (``dynamics.models``): no second
common-subexpression pass, because a column slice of a graph CasADi's ``cse`` already shared has none left to find.
Checked on the generated C code, which is what is compiled, cached (its hash) and evaluated: the same code as with
``cse`` applied again, so the same library and the same values bit for bit."""

from __future__ import annotations

import casadi
import numpy as np
import pytest

from dynamics.codegen.compiled import generated_source
from dynamics.models import build_model
from dynamics.robots import load_robot


@pytest.mark.parametrize("name, joints, kind, effects", [
    ("puma560", 6, "internal", "viscous,coulomb,offset"),
    ("puma560", 3, "combined", "viscous,coulomb:tanh,stribeck,wrench_offset"),
    ("servo_arm", None, "external", "viscous,coulomb,armature"),
])
def test_the_base_regressor_generates_the_code_of_its_columns_shared_again(name, joints, kind, effects):
    robot = load_robot(name, joints=joints)
    model = build_model(robot, kind, effects)
    base = model.base_regressor
    inputs = base.sx_in()
    columns = base.call(inputs)[0]
    again = casadi.Function(base.name(), inputs, [casadi.cse(columns)], base.name_in(), base.name_out())
    assert generated_source(base) == generated_source(again)
    # the columns are those of the full regressor, and the sample evaluator's function is the transposed one
    q, dq, ddq = (np.random.default_rng(seed).normal(size=(20, robot.n_joints)) for seed in (1, 2, 3))
    full = model.evaluate(q, dq, ddq)
    np.testing.assert_array_equal(model.evaluate_base(q, dq, ddq), full[:, :, list(model.base.independent)])


def test_a_second_common_subexpression_pass_would_find_nothing_in_the_sliced_columns():
    """The premise, stated on the expressions themselves: ``cse`` of the sliced columns leaves the number of
    operations as it is (where a graph with repeated subexpressions loses some)."""
    robot = load_robot("puma560", joints=6)
    model = build_model(robot, "internal", "viscous,coulomb,offset")
    base = model.base_regressor
    inputs = base.sx_in()
    columns = base.call(inputs)[0]
    again = casadi.Function("again", inputs, [casadi.cse(columns)])
    assert again.n_instructions() == base.n_instructions()
    x = casadi.SX.sym("x")
    repeated = casadi.vertcat(casadi.sin(x) * 2, casadi.sin(x) * 2)
    assert casadi.Function("r", [x], [casadi.cse(repeated)]).n_instructions() < \
        casadi.Function("r", [x], [repeated]).n_instructions()
