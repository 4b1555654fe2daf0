"""Truths outside the candidate families (:data:`tests.corpus.cases.OUTSIDE`): Dahl's hysteresis, a Coulomb law whose
level varies along the travel, Stribeck's law with the exponent 1, and the issue's sigmoid and Stribeck truths
confirmed on a repeat of the training motion. No wrong answers with confidence: the diagnosis names no effect the
truth does not hold (it may name the Coulomb-like part a friction law holds), and says which channels stay above
their noise floor."""

from __future__ import annotations

import pytest

from tests.corpus.cases import OUTSIDE, Case
from tests.corpus.records import matches, run


def marks(case: Case) -> list[pytest.MarkDecorator]:
    chosen = [pytest.mark.slow] if case.slow else []
    if case.xfail:
        chosen.append(pytest.mark.xfail(strict=True, reason=case.xfail))
    return chosen


@pytest.mark.parametrize("case", [pytest.param(case, id=case.name, marks=marks(case)) for case in OUTSIDE])
def test_a_truth_outside_the_candidates_gets_no_false_effect_and_a_floor_warning(case):
    diagnosis, outcome = run(case)
    print(f"\n{case.name}: {outcome.summary()}")
    assert matches(case.named, outcome.named, case.allowed), outcome.summary()
    comparison = diagnosis.statistics.comparison["after"]
    for channel in case.above_floor:  # the case is what it claims: its truth leaves this channel above the floor
        assert comparison[channel].above, (channel, outcome.summary())
        assert "above its floor" in diagnosis.statistics.statements[channel], diagnosis.statistics.statements
