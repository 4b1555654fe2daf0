"""Each effect judged in the equations it enters (issue 34): an effect's gain on the validation error of the
channels it acts on counts (estimation.diagnosis.confirmation.own_rows_gain), and a joint's diagnosed effects give way to
the plain law (Coulomb friction and an offset) when that law predicts the joint better on another motion
(estimation.diagnosis.plain_laws)."""

from __future__ import annotations

from dataclasses import replace
from types import SimpleNamespace

import numpy as np
import pytest

from dynamics.effects.linear import CoulombFriction, JointOffset, Spring
from dynamics.models import build_model
from dynamics.robots import load_robot
from dynamics.simulation.synthetic import simulate, true_parameters
from estimation.diagnosis.confirmation import CandidateComparison, own_rows_gain
from estimation.diagnosis.plain_laws import plain_law_choice, plain_model_effects
from estimation.identification.fit import identify
from oed.fourier import random_fourier

NOISE = {"tau1": 0.2, "tau2": 0.2, "tau3": 0.1}


def _comparison(current: list[float], candidate: list[float]) -> CandidateComparison:
    current_residual = np.sqrt(np.asarray(current))[:, None]
    residual = np.sqrt(np.asarray(candidate))[:, None]
    weights = np.ones(len(current))
    return CandidateComparison(weights, float(np.sum(candidate)), residual, float(np.sum(current)), current_residual)


def test_a_joints_gain_is_not_diluted_by_the_other_channels():
    model = SimpleNamespace(channels=("tau1", "tau2", "tau3", "tau4", "tau5", "tau6", "tau7"))
    trial = SimpleNamespace(blocks=(SimpleNamespace(rows=(2,)),))
    # joint 3 4 % better: the sum of seven equal channels moves by 0.6 %, its own equation by 4 %
    assert own_rows_gain(trial, _comparison([1.0] * 7, [1, 1, 0.96, 1, 1, 1, 1]), 0.01, model) == ""
    reason = own_rows_gain(trial, _comparison([1.0] * 7, [0.94, 0.94, 0.998, 0.94, 0.94, 0.94, 0.94]), 0.01, model)
    assert reason.startswith("lowers by less than 1 % the validation error of the channels it acts on (tau3")
    reason = own_rows_gain(trial, _comparison([1.0] * 7, [0.9, 0.9, 1.02, 0.9, 0.9, 0.9, 0.9]), 0.01, model)
    assert reason.startswith("raises the validation error of the channels it acts on (tau3")


def test_a_joints_gain_that_is_mostly_on_other_channels_is_not_its_own():
    """A 1.2 % gain on one joint confirms the effect when it holds most of the sum's gain, not when the sum gains
    mostly on channels the effect does not act on (the PUMA notebook's spring on tau1: 29 % of the sum's gain)."""
    model = SimpleNamespace(channels=("tau1", "tau2", "tau3", "mz"))
    trial = SimpleNamespace(blocks=(SimpleNamespace(rows=(0,)),))
    assert own_rows_gain(trial, _comparison([1.0] * 4, [0.988, 1, 0.999, 1]), 0.01, model) == ""
    reason = own_rows_gain(trial, _comparison([1.0] * 4, [0.988, 0.99, 0.99, 0.99]), 0.01, model)
    assert reason.startswith("lowers the validation error of the channels it acts on (tau1: 1 -> 0.988) by under "
                             "50 % of the sum's gain"), reason


@pytest.fixture(scope="module")
def records():
    """A 3-joint PUMA whose joint 2 has Coulomb friction and an offset (nothing else beyond viscous friction): a
    training motion, another motion for validation, and a repeat of the training motion."""
    robot = load_robot("puma560", joints=3)
    truth = build_model(robot, "internal", (*build_model(robot, "internal", "viscous").effects,
                                            CoulombFriction(joints=(1,)), JointOffset(joints=(1,))))
    theta = true_parameters(truth, seed=1, coulomb=[3.0], offset=[0.8])
    made = {}
    for name, seed, noise_seed in (("train", 5, 5), ("other", 6, 6), ("repeat", 5, 9)):
        made[name] = simulate(truth, theta, random_fourier(robot, seed=seed), rate_hz=100.0, periods=1, noise=NOISE,
                              seed=noise_seed)
    return build_model(robot, "internal", "viscous"), made


def test_the_plain_model_adds_coulomb_and_offset_where_not_declared():
    robot = load_robot("puma560", joints=3)
    declared = build_model(robot, "internal", "viscous,offset")
    assert [(effect.name, effect.joints) for effect in plain_model_effects(declared, [0, 2])] == \
        [("coulomb", (0,)), ("coulomb", (2,))]


def test_an_effect_that_fits_training_but_not_another_motion_gives_way_to_the_plain_law(records):
    declared, made = records
    wrong = Spring(joints=(1,))  # a spring on joint 2 soaks up some of its offset and friction on this motion
    model = build_model(declared.robot, "internal", declared.effects + (wrong,))
    after = identify(model, made["train"], made["other"])
    choice = plain_law_choice(declared, after, [wrong], made["train"], made["other"], min_improvement=0.01)
    assert choice is not None
    assert [(effect.name, effect.joints) for effect in choice.plain] == [("coulomb", (1,)), ("offset", (1,))]
    assert [effect for effect, _ in choice.dropped] == [wrong]
    assert "validates better" in choice.dropped[0][1]
    assert choice.scores[1] < choice.scores[0]
    assert choice.after.validation.mse["tau2"] < 0.99 * after.validation.mse["tau2"]
    # joints 1 and 3 have nothing the plain law would add: they keep the diagnosed model
    assert {effect.joints for effect in choice.effects} == {(1,)}



def test_a_fit_of_the_same_effects_is_made_once_and_is_that_fit(records, monkeypatch):
    """One joint swaps: its swap is the mixed model, fitted once; the choice's model is the fit made directly."""
    import estimation.diagnosis.plain_laws as plain_laws

    declared, made = records
    wrong = Spring(joints=(1,))
    after = identify(build_model(declared.robot, "internal", declared.effects + (wrong,)), made["train"], made["other"])
    fitted = []

    def spy(model, *arguments, **options):
        fitted.append(model.effects)
        return identify(model, *arguments, **options)

    monkeypatch.setattr(plain_laws, "identify", spy)
    choice = plain_law_choice(declared, after, [wrong], made["train"], made["other"], min_improvement=0.01)
    assert choice is not None and len(fitted) == len(set(fitted))  # the mixed model is joint 2's swap: not again
    assert declared.effects + choice.effects in fitted
    direct = identify(build_model(declared.robot, "internal", declared.effects + choice.effects), made["train"],
                      made["other"], weighted=after.estimate.method == "wls", shape_search=False)
    assert np.array_equal(choice.after.estimate.values, direct.estimate.values)
    assert np.array_equal(choice.after.estimate.cov, direct.estimate.cov)
    assert choice.after.validation.mse == direct.validation.mse

def test_nothing_is_swapped_on_a_repeat_of_the_training_motion(records):
    declared, made = records
    wrong = Spring(joints=(1,))
    model = build_model(declared.robot, "internal", declared.effects + (wrong,))
    after = identify(model, made["train"], made["repeat"])
    assert plain_law_choice(declared, after, [wrong], made["train"], made["repeat"], min_improvement=0.01) is None


def test_a_right_effect_is_kept(records):
    declared, made = records
    right = (CoulombFriction(joints=(1,)), JointOffset(joints=(1,)))
    model = build_model(declared.robot, "internal", declared.effects + right)
    after = identify(model, made["train"], made["other"])
    assert plain_law_choice(declared, after, list(right), made["train"], made["other"], min_improvement=0.01) is None


def test_a_plain_term_within_its_noise_is_not_named():
    """Joint 3 has an offset and no Coulomb friction: the plain law that replaces a wrong spring there is the
    offset alone (the Coulomb term, within its noise in the mixed model, is left out)."""
    robot = load_robot("puma560", joints=3)
    declared = build_model(robot, "internal", "viscous")
    truth = build_model(robot, "internal", (*declared.effects, JointOffset(joints=(2,))))
    theta = true_parameters(truth, seed=1, offset=[1.5])
    made = {name: simulate(truth, theta, random_fourier(robot, seed=seed), rate_hz=100.0, periods=1, noise=NOISE,
                           seed=seed) for name, seed in (("train", 5), ("other", 6))}
    wrong = Spring(joints=(2,))
    after = identify(build_model(robot, "internal", declared.effects + (wrong,)), made["train"], made["other"])
    choice = plain_law_choice(declared, after, [wrong], made["train"], made["other"], min_improvement=0.01,
                              threshold=1e-3 / 50)
    assert choice is not None
    assert [(effect.name, effect.joints) for effect in choice.plain] == [("offset", (2,))]


def test_a_swap_refused_on_the_fits_score_alone_is_returned_only_when_asked(records):
    """The diagnosed model made to validate far better on joints 1 and 3 (its predictions there moved toward the
    record) keeps joint 2's screen and confirmation but wins the score: the mixed model is refused (``None``), and
    with ``keep_refused`` returned marked ``adopted=False`` for the default answer to judge
    (oed.workflows.diagnose.judged_swap)."""
    declared, made = records
    wrong = Spring(joints=(1,))
    after = identify(build_model(declared.robot, "internal", declared.effects + (wrong,)), made["train"], made["other"])
    arguments = (declared, after, [wrong], made["train"], made["other"])
    adopted = plain_law_choice(*arguments, min_improvement=0.01, keep_refused=True)
    assert adopted is not None and adopted.adopted
    validation = after.validation
    predicted = validation.predicted.copy()
    for column in (0, 2):
        predicted[:, column] = validation.measured[:, column] + 0.01 * (predicted[:, column]
                                                                       - validation.measured[:, column])
    better = replace(after, validation=replace(validation, predicted=predicted))
    assert better.validation.mse["tau2"] == pytest.approx(after.validation.mse["tau2"])
    arguments = (declared, better, [wrong], made["train"], made["other"])
    assert plain_law_choice(*arguments, min_improvement=0.01) is None
    refused = plain_law_choice(*arguments, min_improvement=0.01, keep_refused=True)
    assert refused is not None and not refused.adopted
    assert not refused.scores[1] < refused.scores[0]
    assert [(effect.name, effect.joints) for effect in refused.plain] == [("coulomb", (1,)), ("offset", (1,))]
    assert "as fitted, but the better of it as fitted and its consistent refit" in refused.dropped[0][1]
