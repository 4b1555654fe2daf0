"""Every library case of the corpus (:mod:`tests.corpus.cases`) through ``diagnose``: the effects named, each
channel's final validation error against its noise floor and against a fit that knows the true law, and the
estimates against the truth."""

from __future__ import annotations

import pytest

from tests.corpus.cases import CASES, SIGMAS, Case
from tests.corpus.records import matches, run


def marks(case: Case) -> list[pytest.MarkDecorator]:
    chosen = [pytest.mark.slow] if case.slow else []
    if case.xfail:
        chosen.append(pytest.mark.xfail(strict=True, reason=case.xfail))
    return chosen


@pytest.mark.parametrize("case", [pytest.param(case, id=case.name, marks=marks(case)) for case in CASES])
def test_the_loop_names_the_truth_and_ends_at_the_floor(case):
    _, outcome = run(case)
    print(f"\n{case.name}: {outcome.summary()}")
    assert matches(case.named, outcome.named), outcome.summary()
    for channel, ratio in outcome.over_floor.items():
        assert ratio <= case.floor_tolerance, (channel, outcome.summary())
    for channel, ratio in outcome.over_known_law.items():
        assert ratio <= case.known_law_tolerance, (channel, outcome.summary())
    for name, sigmas in outcome.sigmas.items():
        assert sigmas <= SIGMAS, (name, outcome.summary())
