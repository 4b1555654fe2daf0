"""A wrong law stated with confidence: a truth identified with a declared law that is not its own leaves its
channel far above the noise floor, and ``identify`` must say so (a warning naming the channel)."""

from __future__ import annotations

import warnings

import pytest

from dynamics.models import build_model
from estimation.identification.fit import identify
from tests.corpus.cases import NOISE, SIGN_LAW_ON_TANH, WrongLawCase
from tests.corpus.records import records, robot


def marks(case: WrongLawCase) -> list[pytest.MarkDecorator]:
    return [pytest.mark.xfail(strict=True, reason=case.xfail)] if case.xfail else []


@pytest.mark.parametrize("case", [pytest.param(SIGN_LAW_ON_TANH, id=SIGN_LAW_ON_TANH.name,
                                               marks=marks(SIGN_LAW_ON_TANH))])
def test_identify_flags_the_channel_a_wrong_law_leaves_above_its_floor(case):
    train, validate = records(case.case)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        result = identify(build_model(robot(), "internal", case.declared), train, validate)
    over_floor = {channel: value / NOISE**2 for channel, value in result.validation.mse.items()}
    said = [str(warning.message) for warning in caught] + list(result.warnings)
    print(f"\n{case.name}: after/floor {over_floor}; warnings {said}")
    assert all(over_floor[channel] > 1.5 for channel in case.flagged)  # the case is what it claims to be
    for channel in case.flagged:
        assert any(channel in text for text in said), (channel, over_floor, said)
