"""Truths outside the candidate families (:data:`tests.corpus.cases.OUTSIDE`): Dahl's hysteresis, a Coulomb law whose
level varies along the travel, Stribeck's law with the exponent 1, and the issue's sigmoid and Stribeck truths
confirmed on a repeat of the training motion. No wrong answers with confidence: the diagnosis names no effect the
truth does not hold (it may name the Coulomb-like part a friction law holds), and says which channels stay above
their noise floor."""

from __future__ import annotations

import dataclasses

import pytest

from tests.corpus.cases import ALONE, OUTSIDE, OUTSIDE_LONG, OUTSIDE_PLANTS, OUTSIDE_POSITIONS, PAIRS, Case
from tests.corpus.records import matches, run


def marks(case: Case) -> list[pytest.MarkDecorator]:
    chosen = [pytest.mark.slow] if case.slow else []
    if case.xfail:
        chosen.append(pytest.mark.xfail(strict=True, reason=case.xfail))
    return chosen


@pytest.mark.parametrize("case", [pytest.param(case, id=case.name, marks=marks(case)) for case in OUTSIDE + OUTSIDE_POSITIONS + OUTSIDE_LONG
                                                   + OUTSIDE_PLANTS])
def test_a_truth_outside_the_candidates_gets_no_false_effect_and_a_floor_warning(case):
    diagnosis, outcome = run(case)
    print(f"\n{case.name}: {outcome.summary()}")
    assert matches(case.named, outcome.named, case.allowed), outcome.summary()
    comparison = diagnosis.statistics.comparison["after"]
    for channel in case.above_floor:  # the case is what it claims: its truth leaves this channel above the floor
        assert comparison[channel].above, (channel, outcome.summary())
        assert "above its floor" in diagnosis.statistics.statements[channel], diagnosis.statistics.statements


#: truths in and outside the families on a repeat of the training motion, confirmed also on the stretches of the
#: motion each fit did not see (``diagnose(unseen_stretches=True)``): the right effects still found, nothing false
REPEATS = tuple(case for case in OUTSIDE if case.repeat) + tuple(
    dataclasses.replace(case, name=f"{case.name}, validation repeats the motion", repeat=True)
    for case in ALONE + PAIRS if case.name in ("coulomb sign", "offset", "spring", "ripple", "coupled coulomb q2+q3",
                                               "coulomb + offset", "spring + offset"))


@pytest.mark.parametrize("case", [pytest.param(case, id=case.name) for case in REPEATS])
def test_on_unseen_stretches_of_a_repeated_motion_the_right_effects_and_nothing_else(case):
    diagnosis, outcome = run(case, unseen_stretches=True)
    print(f"\n{case.name}: {outcome.summary()}")
    assert matches(case.named, outcome.named, case.allowed), outcome.summary()
    comparison = diagnosis.statistics.comparison["after"]
    for channel in case.above_floor:
        assert comparison[channel].above, (channel, outcome.summary())
    for channel, ratio in outcome.over_known_law.items():
        assert ratio <= case.known_law_tolerance, (channel, outcome.summary())
