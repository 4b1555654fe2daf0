"""A smoothed Coulomb law whose smoothing the data do not determine is the sign law (estimation.diagnosis.limit_laws)."""

from __future__ import annotations

from dynamics.effects.linear import CoulombFriction, ViscousFriction
from dynamics.effects.shaped import ShapedStribeckFriction, TanhCoulombFriction
from estimation.diagnosis.limit_laws import limit_law


def test_the_limit_of_a_tanh_coulomb_law_is_the_plain_law_on_the_same_joints():
    assert limit_law(TanhCoulombFriction(joints=(4,))) == CoulombFriction(joints=(4,))
    assert limit_law(TanhCoulombFriction()) == CoulombFriction()


def test_other_laws_have_no_limit_here():
    assert limit_law(ShapedStribeckFriction(joints=(1,))) is None
    assert limit_law(ViscousFriction()) is None
