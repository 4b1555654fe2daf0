"""A wrong law stated with confidence: a truth identified with a declared law that is not its own leaves its
channel far above the noise floor, and ``identify`` must say so (a warning naming the channel)."""

from __future__ import annotations

import json
import warnings

import pytest

from dynamics.models import build_model
from estimation.identification.fit import identify
from oed.cli import main
from tests.corpus.cases import NOISE, SIGN_LAW_ON_TANH, WrongLawCase
from tests.corpus.records import records, robot


def marks(case: WrongLawCase) -> list[pytest.MarkDecorator]:
    return [pytest.mark.xfail(strict=True, reason=case.xfail)] if case.xfail else []


@pytest.mark.parametrize("case", [pytest.param(SIGN_LAW_ON_TANH, id=SIGN_LAW_ON_TANH.name,
                                               marks=marks(SIGN_LAW_ON_TANH))])
def test_identify_flags_the_channel_a_wrong_law_leaves_above_its_floor(case, tmp_path, capsys):
    train, validate = records(case.case)
    with warnings.catch_warnings(record=True):
        warnings.simplefilter("always")
        result = identify(build_model(robot(), "internal", case.declared), train, validate)
    over_floor = {channel: value / NOISE**2 for channel, value in result.validation.mse.items()}
    assert all(over_floor[channel] > 1.5 for channel in case.flagged)  # the case is what it claims to be
    # oed identify, as a user runs it, holds the validation error to the floor of the record as read
    train.write(tmp_path / "train.csv")
    validate.write(tmp_path / "validate.csv")
    out = tmp_path / "result.json"
    assert main(["identify", "--joints", "3", "--friction", case.declared, "--data", str(tmp_path / "train.csv"),
                 "--validate", str(tmp_path / "validate.csv"), "--frequency", "0.2", "--out", str(out)]) == 0
    said = capsys.readouterr().err
    print(f"\n{case.name}: after/floor {over_floor}; oed identify said {said}")
    ratios = json.loads(out.read_text())["validation"]["mse_over_floor"]
    for channel in case.flagged:
        assert ratios[channel] > 1.5
        assert f"{channel}: " in said and "above its floor" in said and "oed diagnose" in said, said
