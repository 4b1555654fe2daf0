"""Coulomb friction on a joint combination with its own smoothing (coulomb:tanh[q5+q6]), and how the
diagnosis proposes it: one Coulomb law per combination, grouped with the combination's viscous law."""

from __future__ import annotations

import casadi
import numpy as np
import pytest

from dynamics.effects.combination_shapes import TanhCombinationCoulomb, combination_row
from dynamics.effects.joint_lists import EffectSpecError
from dynamics.effects.specs import build_effects, effect_spec
from dynamics.models import build_model
from dynamics.effects.motor import combination_from_label
from dynamics.robots import load_robot
from dynamics.effects.shaped import is_shaped
from estimation.diagnosis.candidates.coupling import combination_groups, combination_taken, coupling_candidates


@pytest.fixture(scope="module")
def robot():
    return load_robot("puma560")


def test_columns_are_r_tanh_of_the_combined_velocity(robot):
    effect = TanhCombinationCoulomb.from_combination(combination_from_label("coulomb", "q5+q6", 6))
    q, dq, ddq, shape = (casadi.SX.sym(name, n) for name, n in (("q", 6), ("dq", 6), ("ddq", 6), ("s", 1)))
    block, _ = effect.shaped_columns(robot, q, dq, ddq, shape)
    function = casadi.Function("columns", [dq, shape], [block])
    velocity = np.array([0.1, -0.2, 0.3, 0.4, 0.02, -0.005])
    value = np.asarray(function(velocity, 0.01)).ravel()
    expected = np.array([0, 0, 0, 0, 1, 1]) * np.tanh((0.02 - 0.005) / 0.01)
    np.testing.assert_allclose(value, expected, rtol=1e-12)
    assert is_shaped(effect, robot)
    assert effect.parameter_names(robot) == ["fc[q5+q6]"]
    assert [p.name for p in effect.shape_parameters(robot)] == ["vc[q5+q6]"]
    assert effect.name == "coulomb[q5+q6]" and effect.spec == "coulomb:tanh[q5+q6]"


def test_the_spec_reads_back_and_builds_a_model(robot):
    effects = build_effects("viscous,coulomb:tanh[q5+q6],viscous[q5+q6]", robot)
    assert isinstance(effects[1], TanhCombinationCoulomb)
    assert [effect_spec(effect) for effect in effects] == ["viscous", "coulomb:tanh[q5+q6]", "viscous[q5+q6]"]
    model = build_model(robot, "internal", effects)
    assert any("fc[q5+q6]" in name for name in model.base.names)
    with pytest.raises(EffectSpecError, match="only coulomb"):
        build_effects("viscous:tanh[q5+q6]", robot)


def test_one_coulomb_law_per_combination_and_the_viscous_law_grouped_with_it(robot):
    sign = combination_from_label("coulomb", "q5+q6", 6)
    smooth = TanhCombinationCoulomb.from_combination(sign)
    viscous = combination_from_label("viscous", "q5+q6", 6)
    other = combination_from_label("coulomb", "q5-q6", 6)
    assert combination_row(sign) == combination_row(smooth) == combination_row(viscous, "viscous")
    assert combination_taken(smooth, [sign]) and combination_taken(sign, [smooth])
    assert not combination_taken(other, [sign, smooth]) and not combination_taken(viscous, [sign])
    groups = combination_groups({0: sign, 1: smooth, 2: viscous, 3: other})
    assert sorted(groups) == [(0, 2), (1, 2)]


def test_each_coulomb_pair_is_also_proposed_smoothed(robot):
    model = build_model(robot, "internal", "viscous")
    candidates = coupling_candidates(model)
    specs = [getattr(effect, "spec", effect.name) for effect in candidates]
    pairs = [spec for spec in specs if spec.startswith("coulomb[")]
    assert len(pairs) == 10 and all(spec.replace("coulomb[", "coulomb:tanh[") in specs for spec in pairs)


def test_rest_rows_of_a_smoothed_combination_are_kept(robot):
    """Its smoothing is given by the rows near the motor's rest: --min-speed must not drop them, or the
    law the diagnosis found could not be fitted again (estimation.data.rest.coulomb_combinations)."""
    from estimation.data.rest import coulomb_combinations

    sign = combination_from_label("coulomb", "q5+q6", 6)
    assert coulomb_combinations((sign,)).tolist() == [[0, 0, 0, 0, 1, 1]]
    assert coulomb_combinations((TanhCombinationCoulomb.from_combination(sign),)) is None
