"""The criterion of the choices made on a validation record (estimation.identification.relative_error; issue 34):
each channel's error over the best any candidate reaches on it, averaged over the channels. One candidate's large
loss on one joint is not traded for gains on the others, the scores do not depend on the channels' units nor on
the order of the candidates, and the derivative, weighting and model choices use it alike."""

from __future__ import annotations

import itertools
from types import SimpleNamespace

import numpy as np
import pytest

from estimation.consistent.model_selection import Candidate, scores, validation_base
from estimation.identification.preprocessing_choice import geometric_mean
from estimation.identification.preprocessing_on_validation import rescored
from estimation.identification.relative_error import relative_scores
from estimation.preprocessing.plan import Preprocessing, ValidationEvidence

CHANNELS = ("tau1", "tau2", "tau3", "tau4")
#: the torso and arm of tests/test_unseen_robots.py, in the shape it took: a candidate that gains on three joints
#: (0.13x, 0.5x, 0.5x) and loses 20x on the torso, which the geometric mean over channels prefers
STEADY = {"tau1": 1.0, "tau2": 1.0, "tau3": 1.0, "tau4": 1.0}
TRADING = {"tau1": 20.0, "tau2": 0.13, "tau3": 0.5, "tau4": 0.5}


def test_a_candidate_that_loses_20x_on_one_joint_for_gains_elsewhere_is_not_chosen():
    # the geometric mean takes the trade (its log-losses cancel): the case the criterion replaces
    assert geometric_mean(np.array(list(TRADING.values()))) < geometric_mean(np.array(list(STEADY.values())))
    found = relative_scores({"steady": STEADY, "trading": TRADING}, CHANNELS)
    assert found["steady"] < found["trading"]
    # each channel by its ratio to the best: steady (1, 1/0.13, 2, 2), trading (20, 1, 1, 1)
    assert found["steady"] == pytest.approx((1 + 1 / 0.13 + 2 + 2) / 4)
    assert found["trading"] == pytest.approx((20 + 1 + 1 + 1) / 4)
    # a candidate best on every channel scores 1
    assert relative_scores({"a": STEADY, "b": {c: 2 * v for c, v in STEADY.items()}}, CHANNELS)["a"] == 1.0


def test_the_scores_do_not_depend_on_the_order_of_the_candidates_nor_on_the_channels_units():
    generator = np.random.default_rng(3)
    errors = {f"c{k}": dict(zip(CHANNELS, generator.uniform(0.1, 10.0, len(CHANNELS)))) for k in range(5)}
    errors["failed"] = {**STEADY, "tau2": float("nan")}
    reference = relative_scores(errors, CHANNELS)
    for order in itertools.permutations(errors):
        assert relative_scores({key: errors[key] for key in order}, CHANNELS) == pytest.approx(reference, rel=1e-15)
    # a channel in other units (N instead of kN, say): every candidate's error on it scaled alike
    scaled = {key: {**mse, "tau3": 1e6 * mse["tau3"]} for key, mse in errors.items()}
    assert relative_scores(scaled, CHANNELS) == pytest.approx(reference, rel=1e-12)
    assert reference["failed"] == float("inf") and relative_scores({"x": None}, CHANNELS) == {"x": float("inf")}
    # the failed candidate sets no channel's best
    assert {k: v for k, v in reference.items() if k != "failed"} == pytest.approx(
        relative_scores({k: v for k, v in errors.items() if k != "failed"}, CHANNELS), rel=1e-15)


def fitted(mse):
    return SimpleNamespace(validation=SimpleNamespace(mse=dict(mse), channels=tuple(mse)),
                           train=None, estimate=SimpleNamespace(method="ols"))


def test_the_model_and_weighting_choices_use_the_criterion():
    candidates = [Candidate("ols", fitted(STEADY)), Candidate("wls", fitted(TRADING))]
    assert scores(candidates) == relative_scores({"ols": STEADY, "wls": TRADING}, CHANNELS)
    assert scores(candidates[::-1]) == scores(candidates)
    fits = {"ols": fitted(STEADY), "wls": fitted(TRADING)}
    assert validation_base(fits.__getitem__, "wls") == "ols"  # the geometric mean preferred wls here
    fits = {"ols": fitted(TRADING), "wls": fitted(STEADY)}
    assert validation_base(fits.__getitem__, "ols") == "wls"


def evidence(cutoff: float, **fit_mse) -> ValidationEvidence:
    first = next(iter(fit_mse.values()))
    return ValidationEvidence(Preprocessing("butterworth", cutoff_hz=cutoff), 1.0, dict(first), "ols", {}, None,
                              0.0, 100, {fit: dict(mse) for fit, mse in fit_mse.items()})


def test_the_derivative_choice_scores_every_fit_of_every_candidate_together_whatever_their_order():
    items = [evidence(2.0, ols=STEADY, wls={c: 1.1 * v for c, v in STEADY.items()}),
             evidence(5.0, ols=TRADING, wls={c: 1.2 * v for c, v in TRADING.items()}),
             evidence(10.0, ols={c: 3.0 for c in CHANNELS}, wls={c: 2.5 for c in CHANNELS}),
             ValidationEvidence(Preprocessing("butterworth", cutoff_hz=0.5), float("inf"), {}, error="too short")]
    pool = {(item.preprocessing.cutoff_hz, fit): mse for item in items for fit, mse in item.fit_mse.items()}
    expected = relative_scores(pool, CHANNELS)
    reference = None
    for order in itertools.permutations(items):
        found = {item.preprocessing.cutoff_hz: item for item in rescored(list(order), CHANNELS)}
        chosen = min(found.values(), key=lambda item: item.score).preprocessing.cutoff_hz
        assert chosen == 2.0  # not the 5 Hz filter that trades the torso for the arm
        summary = {cutoff: (item.score, item.fit, item.fit_scores) for cutoff, item in found.items()}
        reference = reference or summary
        assert summary == reference
    assert found[10.0].fit == "wls" and found[10.0].validation_mse == {c: 2.5 for c in CHANNELS}
    assert found[10.0].score == pytest.approx(expected[(10.0, "wls")])
    assert found[2.0].fit_scores == pytest.approx({"ols": expected[(2.0, "ols")], "wls": expected[(2.0, "wls")]})
    assert found[0.5].score == float("inf") and found[0.5].error == "too short"
