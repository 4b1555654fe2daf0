"""The derivatives chosen on a weak validation record (issue 34,
estimation.identification.preprocessing_on_validation): each candidate's standard error of its score's difference
to the best's, from the validation record's five contiguous blocks, and whether the validation record tells it from
the best (``tied``: within two standard errors and within EQUIVALENT). Reported, not acted on: the tie-breaks
measured (the training record's held-out blocks, the median cut-off of the tied ones, the median over the blocks)
each made a real or simulated case worse (benchmarks/README.md, h-weakval2).

On the real Stäubli TX40 at 2.5 kHz the 1.5 s validation record chose a 125 Hz filter by 0.4 % of the score over
75 Hz, and the test record was predicted 9 % worse. Here a simulated 3-joint PUMA at 1 kHz: one 1.5 s validation
motion with four noise realisations (torque noise eight times the training record's): the choice flips between
10 Hz and 6 Hz with the noise, and every realisation flags the two as tied. (Until the choice's scores became
steadier, seeds 0-3 flipped it between 10 and 17 Hz; at 6d10335 seeds 0-10 all choose 10 Hz, 6 Hz within 0.3-1.3 %
and tied in each, and seed 11 chooses 6 Hz: the test takes it as its fourth realisation.)"""

from __future__ import annotations

import warnings

import numpy as np
import pytest

import estimation.identification.preprocessing_on_validation as module
from dynamics.measurements import Measurements
from dynamics.models import build_model
from dynamics.robots import load_robot
from dynamics.simulation.synthetic import simulate, true_parameters
from estimation.identification.prepared import PreparationSettings, prepare_records
from estimation.identification.preprocessing_on_validation import BLOCKS, with_standard_errors
from estimation.preprocessing.plan import Preprocessing, ValidationEvidence
from oed.fourier import random_fourier

NOISE = {"tau1": 0.2, "tau2": 0.2, "tau3": 0.1}
#: position noise, rad
Q_NOISE = 1e-4
RATE_HZ = 1000.0
#: the validation record's torque noise over the training record's
VALIDATION_NOISE = 8.0
NOISE_SEEDS = (0, 1, 2, 11)


@pytest.fixture(scope="module")
def records(tmp_path_factory):
    folder = tmp_path_factory.mktemp("weak_validation")
    robot = load_robot("puma560", joints=3)
    model = build_model(robot, "internal", "viscous,coulomb,offset")
    theta = true_parameters(model, seed=1, coulomb=[3.0, 2.0, 1.0], offset=[0.5, -0.3, 0.2])

    def write(name, seed, periods, noise_seed, seconds=None, scale=1.0):
        data = simulate(model, theta, random_fourier(robot, seed=seed, frequency_hz=0.3), rate_hz=RATE_HZ,
                        periods=periods, noise={key: scale * value for key, value in NOISE.items()}, seed=noise_seed)
        q = data.q + np.random.default_rng(noise_seed + 100).normal(0.0, Q_NOISE, data.q.shape)
        keep = slice(None) if seconds is None else slice(0, int(seconds * RATE_HZ))
        path = folder / f"{name}.csv"
        Measurements(data.t[keep], q[keep], None, None, data.tau[keep], None, {}).write(path)
        return path

    paths = {"train": write("train", 5, 3, 5), "test": write("test", 7, 1, 7)}
    for seed in NOISE_SEEDS:
        paths[seed] = write(f"validate{seed}", 20, 1, 40 + seed, seconds=1.5, scale=VALIDATION_NOISE)
    return model, paths


@pytest.mark.slow
def test_a_choice_that_flips_with_the_validation_noise_is_flagged_tied(records):
    model, paths = records
    plans = {}
    for seed in NOISE_SEEDS:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            plans[seed] = prepare_records(model, [paths["train"]], [paths[seed]], [paths["test"]],
                                          settings=PreparationSettings(validation_fits=("ols", "wls"))).preprocessing
    chosen = {plan.without_evidence() for plan in plans.values()}
    assert len(chosen) > 1, "the test needs a choice that flips with the noise"
    for plan in plans.values():
        evidence = plan.evidence.validation
        assert evidence[0].preprocessing == plan.without_evidence()  # the smallest score is still chosen
        tied = {item.preprocessing for item in evidence if item.tied}
        assert chosen <= tied
        assert all(not item.tied for item in evidence if item.score > (1 + module.EQUIVALENT) * evidence[0].score)
        assert "standard errors of its score: the validation record does not tell them apart" in plan.describe()
        document = plan.to_dict()["validation_candidates"]
        assert document[0]["standard_error"] == 0.0 and document[0]["tied"] is True


def item(cutoff, blocks, fit="ols"):
    """A candidate with per-block MSE on one channel (equal blocks: the score's mean is the blocks' mean)."""
    mse = float(np.mean(blocks))
    return ValidationEvidence(Preprocessing("butterworth", cutoff_hz=cutoff), 1.0, {"tau1": mse}, fit, {}, None,
                              0.0, 10 * BLOCKS, {fit: {"tau1": mse}}, {fit: {"tau1": tuple(blocks)}})


def test_the_standard_error_is_that_of_the_blocks_paired_differences():
    best = item(10.0, [1.0, 2.0, 1.0, 2.0, 1.0])
    close = item(20.0, [1.0, 2.05, 0.99, 2.0, 1.03])  # 1 % worse, the blocks' differences noisy
    steady = item(30.0, [1.03, 2.06, 1.03, 2.06, 1.03])  # 2 % worse on every block alike (ratios 1.03)
    far = item(40.0, [1.2, 2.4, 1.2, 2.4, 1.2])  # 20 % worse: never tied (EQUIVALENT)
    scored = module.rescored([best, close, steady, far], ("tau1",))
    result = {entry.preprocessing.cutoff_hz: entry for entry in with_standard_errors(scored, ("tau1",))}
    floor = 1.4  # the best's MSE: the scores are ratios to it
    differences = (np.array([0.0, 0.05, -0.01, 0.0, 0.03])) / floor
    expected = np.std(differences, ddof=1) / np.sqrt(BLOCKS)
    assert result[20.0].standard_error == pytest.approx(expected, rel=1e-12)
    assert result[20.0].score - result[10.0].score == pytest.approx(differences.mean(), rel=1e-12)
    assert result[10.0].tied and result[10.0].standard_error == 0.0
    assert result[20.0].tied  # 1.25 standard errors
    assert not result[30.0].tied  # a difference with no spread is measured, however small
    assert not result[40.0].tied


def test_the_smallest_score_is_chosen_whether_or_not_others_are_tied():
    noisy = [0.0, 0.06, -0.05, 0.04, -0.05]
    entries = [item(125.0, [1.0] * 5), item(75.0, [1.004 + n for n in noisy]), item(42.5, [1.03 + 0.9 * n for n in noisy]),
               item(10.0, [1.5] * 5)]
    evidence = with_standard_errors(sorted(module.rescored(entries, ("tau1",)), key=lambda entry: entry.score),
                                    ("tau1",))
    assert [entry.tied for entry in evidence] == [True, True, True, False]
    assert module.decided(evidence).cutoff_hz == 125.0
    assert module.decided([evidence[-1].__class__(Preprocessing("butterworth", cutoff_hz=1.0), float("inf"), {})]) \
        is None


def test_too_few_validation_samples_for_the_blocks_tie_nothing():
    few = [item(10.0, [1.0] * 5), item(20.0, [1.01] * 5)]
    few = [entry.__class__(entry.preprocessing, 1.0, entry.validation_mse, "ols", {}, None, 0.0, BLOCKS - 1,
                           entry.fit_mse, {}) for entry in few]
    evidence = with_standard_errors(module.rescored(few, ("tau1",)), ("tau1",))
    assert not any(entry.tied for entry in evidence) and all(entry.standard_error is None for entry in evidence)


def test_with_the_weighting_chosen_later_the_derivatives_are_scored_by_ols():
    """``oed identify`` (auto method) and ``oed diagnose`` score the derivative candidates by the OLS fit alone: the
    weighting is chosen afterwards, on the same record, with the derivatives chosen; the minimum over (candidate,
    fit) pairs picked a lucky pair (tx40-sub2: 125 Hz by its WLS fit, 0.4 % ahead; by OLS 75 Hz, 2.9 % ahead)."""
    from types import SimpleNamespace

    from oed.workflows.diagnose import derivatives_on_validation
    from oed.workflows.identify import validation_fits

    model = build_model(load_robot("puma560", joints=3), "internal", "viscous,coulomb,offset")
    assert validation_fits(SimpleNamespace(method="auto"), model, None) == ("ols",)
    assert validation_fits(SimpleNamespace(method="wls"), model, None) == ("wls",)
    assert derivatives_on_validation(model, None)["validation_fits"] == ("ols",)


@pytest.mark.slow
def test_scored_by_ols_alone_no_fewer_noise_draws_take_the_filter_that_predicts_the_test_record_better(records):
    from estimation.identification.fit import identify

    model, paths = records
    test_mse, chosen = {}, {}
    for fits in (("ols", "wls"), ("ols",)):
        for seed in NOISE_SEEDS:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                plan = prepare_records(model, [paths["train"]], [paths[seed]], [paths["test"]],
                                       settings=PreparationSettings(validation_fits=fits)).preprocessing
            chosen[fits, seed] = plan.without_evidence()
    for plan in set(chosen.values()):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            prepared = prepare_records(model, [paths["train"]], [], [paths["test"]],
                                       settings=PreparationSettings(cutoff_hz=plan.cutoff_hz))
            test_mse[plan] = sum(identify(model, prepared.train.measurements, prepared.test.measurements,
                                          weighted=False).validation.mse.values())
    best = min(test_mse.values())
    right = {fits: sum(test_mse[chosen[fits, seed]] <= 1.05 * best for seed in NOISE_SEEDS)
             for fits in (("ols", "wls"), ("ols",))}
    # measured: 2 of 4 by OLS alone (17 Hz, 0.33 against 0.48 for 10 Hz), 1 of 4 by the better of OLS and WLS
    assert right[("ols",)] >= right[("ols", "wls")], right
