"""The diagnosis's forward selection (estimation.diagnosis.forward_selection.DiagnosisSearch) on prescribed
fits: which candidate it adopts, and the reason it gives every other one, whatever computes the fits."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pytest

from dynamics.effects.linear import CoulombFriction, JointOffset
from dynamics.models import build_model
from dynamics.robots import load_robot
from estimation.diagnosis.candidates.trials import Trial
from estimation.diagnosis.confirmation import Comparison
from estimation.diagnosis.forward_selection import DiagnosisSearch, SearchSettings, candidate_blocks
from estimation.estimators.variable_projection import ShapeFit


@dataclass(frozen=True)
class Fit:
    rss: float
    validation_error: float


class PrescribedFits:
    """Fits whose p-values and validation errors are given per candidate group (the ``Fits`` protocol)."""

    def __init__(self, p_values: dict, errors: dict) -> None:
        self.p_values, self.errors, self.extended = p_values, errors, []
        self.delay_adopted = False

    def fit_current(self, weights):
        return Fit(10.0 - len(self.extended), 1.0)

    def keep_searching(self, current, added):
        return True

    def trial(self, group, members, weights, rss):
        theta = np.ones(sum(block.n_linear for block in members))
        fit = ShapeFit(np.zeros(0), theta, np.full((theta.size, theta.size), np.nan), rss / 2, (), 0, None)
        p_value = self.p_values.get(group, 1.0)
        return Trial(group, tuple(members), fit, rss / 2, 100.0, p_value, np.log(p_value + 1e-300))

    def refine(self, trials, current, weights, first_round):
        return trials

    def compare(self, trial, weights):
        residual = np.full((3, 1), 1.0)
        return Comparison(weights, self.errors.get(trial.group, 0.5), residual, 1.0, residual)

    def extend(self, adopted):
        self.extended += [item.index for item in adopted]

    def delay_trials(self, adopted, weights, rss, others):
        return []


@pytest.fixture(scope="module")
def model():
    return build_model(load_robot("puma560", joints=3), "internal", "viscous")


def search(model, fits, max_effects=20):
    candidates = (CoulombFriction(joints=(0,)), JointOffset(joints=(0,)), CoulombFriction(joints=(1,)))
    blocks, rejected = candidate_blocks(model, candidates)
    settings = SearchSettings(alpha=1e-3, min_improvement=0.01, max_effects=max_effects, n_tests=len(candidates))
    return DiagnosisSearch(model, blocks, rejected, fits, np.ones(3), settings)


def test_the_best_confirmed_candidate_is_adopted_and_every_other_gets_its_reason(model):
    # coulomb on joint 1 confirmed; the offset significant but worse on validation; joint 2's coulomb not significant
    fits = PrescribedFits({(0,): 1e-12, (1,): 1e-10, (2,): 0.5}, {(1,): 2.0})
    outcome = search(model, fits).run()
    assert [(item.index, item.effect.name) for item in outcome.adopted] == [(0, "coulomb")]
    assert fits.extended == [0]
    assert outcome.rejected[1].reason == ("significant on training (p = 1e-10) but raises the validation error "
                                          "(1 -> 2)")
    assert outcome.rejected[2].reason == "not significant"
    assert sorted(outcome.rejected) == [1, 2] and not outcome.stopped_at_floor


def test_the_cap_on_effects_ends_the_search(model):
    outcome = search(model, PrescribedFits({(0,): 1e-12, (1,): 1e-10}, {}), max_effects=1).run()
    assert len(outcome.adopted) == 1
    assert {entry.reason for entry in outcome.rejected.values()} == {"not tested: 1 effects already added"}


def test_a_second_coulomb_law_on_a_joint_is_refused(model):
    declared = build_model(model.robot, "internal", ("viscous", CoulombFriction(joints=(0,))))
    blocks, rejected = candidate_blocks(declared, (CoulombFriction(joints=(0,)),))
    settings = SearchSettings(alpha=1e-3, min_improvement=0.01, max_effects=20, n_tests=1)
    outcome = DiagnosisSearch(declared, blocks, rejected, PrescribedFits({(0,): 1e-12}, {}), np.ones(3), settings).run()
    assert outcome.adopted == ()
    assert outcome.rejected[0].reason == "its joint already has a Coulomb-like friction law"


@pytest.mark.parametrize("same_effect_adopted", [True, False])
def test_a_candidate_given_twice_is_reported_by_each_paths_rule(model, same_effect_adopted):
    # the in-memory diagnosis counts the second copy of an adopted effect as adopted; the streamed one
    # reports it with the candidates the search did not test
    coulomb = CoulombFriction(joints=(0,))
    blocks, rejected = candidate_blocks(model, (coulomb, coulomb))
    settings = SearchSettings(alpha=1e-3, min_improvement=0.01, max_effects=1, n_tests=2,
                              same_effect_adopted=same_effect_adopted)
    fits = PrescribedFits({(0,): 1e-12, (1,): 1e-11}, {})
    outcome = DiagnosisSearch(model, blocks, rejected, fits, np.ones(3), settings).run()
    assert [item.index for item in outcome.adopted] == [0]
    assert sorted(outcome.rejected) == ([] if same_effect_adopted else [1])
