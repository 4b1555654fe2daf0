"""The diagnosis does not depend on the order of its candidate list: the default candidates, shuffled, give the
same effects and the same estimates (cases where a law is adopted beside an offset, a spring with its offset, and,
slow, one where the search replaces a law it adopted first)."""

from __future__ import annotations

import numpy as np
import pytest

from estimation.diagnosis.candidates.coupling import coupling_candidates
from estimation.diagnosis.search import default_candidates, diagnose
from tests.corpus.cases import CASES
from tests.corpus.records import declared_model, named_pairs, records

ORDER_CASES = ("coulomb + offset", "stribeck + offset", "spring + offset")
SLOW_ORDER_CASES = ("stribeck on every joint",)
SHUFFLES = (1, 2, 3)
SAME_ESTIMATE = 0.1  # standard deviations


def estimates(diagnosis) -> dict[str, tuple[float, float]]:
    values = {}
    for effect in diagnosis.effects:
        values.update({name: (value, std) for name, value, std in zip(effect.parameters, effect.values, effect.std)})
        values.update({name: (value, effect.shape_std.get(name, 0.0)) for name, value in effect.shape.items()})
    return values


@pytest.mark.parametrize("name", [*ORDER_CASES, *(pytest.param(name, marks=pytest.mark.slow) for name in SLOW_ORDER_CASES)])
def test_shuffled_candidates_give_the_same_effects_and_estimates(name):
    (case,) = [case for case in CASES if case.name == name]
    model = declared_model()
    train, validate = records(case)
    listed = default_candidates(model) + coupling_candidates(model, train=train)
    reference = diagnose(model, train, validate, candidates=listed)
    expected = estimates(reference)
    for seed in SHUFFLES:
        order = np.random.default_rng(seed).permutation(len(listed))
        shuffled = diagnose(model, train, validate, candidates=[listed[index] for index in order])
        assert named_pairs(shuffled) == named_pairs(reference), (seed, named_pairs(shuffled), named_pairs(reference))
        found = estimates(shuffled)
        assert set(found) == set(expected), seed
        for parameter, (value, std) in expected.items():
            assert abs(found[parameter][0] - value) <= SAME_ESTIMATE * std, (seed, parameter, found[parameter], value)
