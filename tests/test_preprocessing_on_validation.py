"""The derivatives chosen on a validation record of another motion (issue 34,
estimation.identification.preprocessing_on_validation): every candidate scored on the same recorded validation
samples by the model fitted with it, the choice predicting a test record no choice saw better than the training
record's own blocked cross-validation; a validation that repeats the training motion scores the training record's
candidates by the training record's own score."""

from __future__ import annotations

import json
import warnings
from types import SimpleNamespace

import numpy as np
import pytest

from dynamics.measurements import Measurements
from dynamics.models import build_model
from dynamics.robots import load_robot
from dynamics.simulation.synthetic import simulate, true_parameters
from estimation.consistent.model_selection import validation_base
from estimation.estimators.least_squares import LeastSquares, WeightedLeastSquares, stack
from estimation.identification.fit import identify
from estimation.identification.prepared import PreparationSettings, prepare_records, read_files
from estimation.identification.preprocessing_choice import preferred
from estimation.identification.preprocessing_on_validation import FITS, on_same_samples
from estimation.identification.validation import compare, compare_recorded
from estimation.preprocessing.plan import Preprocessing, ValidationEvidence, prepare
from oed.cli import main
from oed.fourier import random_fourier

NOISE = {"tau1": 0.2, "tau2": 0.2, "tau3": 0.1}
EFFECTS = "viscous,coulomb,offset"
#: position noise, rad: a slow training motion then favours a low cut-off inside its own record
Q_NOISE = 1e-3


@pytest.fixture(scope="module")
def setting(tmp_path_factory):
    """A 3-joint PUMA, positions and torques only: a slow training motion (0.1 Hz, 5 harmonics), a faster
    validation motion and a faster test motion (0.5 Hz, other seeds), and a repeat of the training motion."""
    folder = tmp_path_factory.mktemp("derivatives_on_validation")
    robot = load_robot("puma560", joints=3)
    model = build_model(robot, "internal", EFFECTS)
    theta = true_parameters(model, seed=1, coulomb=[3.0, 2.0, 1.0], offset=[0.5, -0.3, 0.2])
    paths = {}
    for name, seed, frequency, periods, noise_seed in (("train", 5, 0.1, 2, 5), ("validate", 6, 0.5, 4, 6),
                                                       ("test", 7, 0.5, 4, 7), ("repeat", 5, 0.1, 2, 9)):
        data = simulate(model, theta, random_fourier(robot, seed=seed, frequency_hz=frequency), rate_hz=200.0,
                        periods=periods, noise=NOISE, seed=noise_seed)
        q = data.q + np.random.default_rng(noise_seed + 100).normal(0.0, Q_NOISE, data.q.shape)
        paths[name] = folder / f"{name}.csv"
        Measurements(data.t, q, None, None, data.tau, None, {}).write(paths[name])
    return folder, model, paths


def prepared(model, paths, validation="validate", fits=("ols", "wls")):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return prepare_records(model, [paths["train"]], [paths[validation]], [paths["test"]],
                               settings=PreparationSettings(validation_fits=fits))


def test_the_validation_choice_predicts_a_motion_no_choice_saw_better(setting):
    _, model, paths = setting
    records = {"held-out": prepared(model, paths, fits=()), "validation": prepared(model, paths)}
    training_choice, validation_choice = (records[key].preprocessing for key in ("held-out", "validation"))
    assert training_choice.evidence.selection == "held-out" and validation_choice.evidence.selection == "validation"
    assert validation_choice.evidence.held_out_choice == training_choice.without_evidence()
    assert validation_choice.without_evidence() != training_choice.without_evidence(), "the test needs two choices"
    test_mse = {}
    for key, record in records.items():
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            result = identify(model, record.train.measurements, record.test.measurements, weighted=False)
        test_mse[key] = np.array(list(result.validation.mse.values()))
    # the test record is another motion, as the validation is: what predicts one predicts the other
    assert np.all(test_mse["validation"] < test_mse["held-out"]), test_mse
    assert test_mse["validation"].sum() < 0.5 * test_mse["held-out"].sum(), test_mse


def test_every_candidate_is_scored_on_the_same_recorded_validation_samples(setting):
    _, model, paths = setting
    plan = prepared(model, paths).preprocessing
    evidence = plan.evidence.validation
    raw = read_files([paths["validate"]], model, split=False)[0].segments[0]
    assert len(evidence) == len(plan.evidence.candidates) >= 5
    assert {item.samples for item in evidence} == {raw.n_samples}  # every recorded validation sample, each
    assert [item.score for item in evidence] == sorted(item.score for item in evidence)
    assert plan.without_evidence() == evidence[0].preprocessing and np.isfinite(evidence[0].score)
    # the chosen candidate's score, recomputed: its fit on the training record prepared alike, against the
    # validation torques as recorded (never the filtered ones)
    best = evidence[0]
    train = read_files([paths["train"]], model, split=True)[0].segments
    estimator = WeightedLeastSquares() if best.fit == "wls" else LeastSquares()
    estimate = estimator.fit(stack(model, prepare(train, best.preprocessing))).estimate_
    comparison = compare(model, estimate.values, prepare([raw], best.preprocessing, role="validation data"))
    np.testing.assert_array_equal(comparison.measured, raw.tau)
    np.testing.assert_array_equal(comparison.t, raw.t)
    assert comparison.mse == pytest.approx(best.validation_mse, rel=1e-9)
    assert best.fit_mse[best.fit] == best.validation_mse
    # the score: the mean over channels of its error over the smallest any candidate's fit reaches on that channel
    pairs = [item.fit_mse[fit] for item in evidence if np.isfinite(item.score) for fit in FITS if fit in item.fit_mse]
    smallest = {c: min(mse[c] for mse in pairs) for c in comparison.channels}
    for item in evidence:
        if np.isfinite(item.score):
            expected = min(np.mean([item.fit_mse[fit][c] / smallest[c] for c in comparison.channels])
                           for fit in item.fit_mse)
            assert item.score == pytest.approx(expected, rel=1e-12)
    assert best.score == pytest.approx(np.mean([comparison.mse[c] / smallest[c] for c in comparison.channels]),
                                       rel=1e-9)


def test_a_validation_that_repeats_the_training_motion_scores_the_training_record_candidates(setting):
    """A repeat of the training motion is not scored as another motion (no validation fits): the training record's
    candidates are scored on it by the held-out score's model fitted on the whole training record, the same tie
    rule choosing (estimation.identification.preprocessing_choice.choose_on_repeat)."""
    _, model, paths = setting
    repeat = prepared(model, paths, validation="repeat").preprocessing
    trained = prepared(model, paths, fits=()).preprocessing
    assert repeat.evidence.selection == "repeat" and not repeat.evidence.validation
    assert repeat.evidence.held_out_choice == trained.without_evidence()
    assert {item.preprocessing for item in repeat.evidence.candidates} == \
        {item.preprocessing for item in trained.evidence.candidates}
    assert repeat.without_evidence() == preferred(repeat.evidence.candidates)
    assert "a repeat of the training motion" in repeat.describe()


def test_a_candidate_scored_on_other_samples_is_set_aside():
    def item(cutoff, score, samples):
        return ValidationEvidence(Preprocessing("butterworth", cutoff_hz=cutoff), score, {}, "ols", {}, None, 0.0,
                                  samples)

    kept = on_same_samples([(item(2.0, 1.0, 100), "a"), (item(5.0, 0.5, 90), "b"), (item(8.0, 0.9, 100), "c"),
                            (item(12.0, 2.0, 100), "a"), (item(20.0, float("inf"), 0), "")])
    scores = {item.preprocessing.cutoff_hz: item.score for item in kept}
    # the reference: the stamps most candidates of the most samples share ("a"); fewer samples or other stamps: out
    assert scores == {2.0: 1.0, 5.0: float("inf"), 8.0: float("inf"), 12.0: 2.0, 20.0: float("inf")}
    assert "not comparable" in next(item.error for item in kept if item.preprocessing.cutoff_hz == 5.0)


def test_oed_identify_writes_the_validation_candidates_and_says_how_it_chose(setting, capsys):
    folder, _, paths = setting
    out = folder / "result.json"
    assert main(["identify", "--joints", "3", "--data", str(paths["train"]), "--validate", str(paths["validate"]),
                 "--friction", EFFECTS, "--out", str(out)]) == 0
    summary = capsys.readouterr().out
    assert "by the validation error of the model fitted with each" in summary
    assert "blocked cross-validation on the training data preferred" in summary
    document = json.loads(out.read_text())["preprocessing"]
    assert document["selection"] == "validation" and document["held_out_choice"]
    assert document["validation_candidates"][0]["cutoff_hz"] == document["cutoff_hz"]
    assert {candidate["fit"] for candidate in document["validation_candidates"]} <= {"ols", "wls"}


def test_the_consistent_fit_starts_from_the_weighting_the_other_motion_prefers():
    def fitted(**mse):
        return SimpleNamespace(validation=SimpleNamespace(mse=mse, channels=tuple(mse)))

    fits = {"ols": fitted(tau1=1.0, tau2=2.0), "wls": fitted(tau1=1.5, tau2=2.0)}
    assert validation_base(fits.__getitem__, "wls") == "ols"
    fits["wls"] = fitted(tau1=0.5, tau2=2.0)
    assert validation_base(fits.__getitem__, "ols") == "wls"
    fits["wls"] = fitted(tau1=1.0, tau2=2.0)  # a tie: the training record's own preference
    assert validation_base(fits.__getitem__, "wls") == "wls"
    assert validation_base(fits.__getitem__, "ols") == "ols"


def test_diagnose_chooses_the_derivatives_on_the_validation_record_by_the_plain_model(setting):
    """``oed diagnose`` declares the viscous model, whose missing Coulomb friction and offsets must not choose the
    filter that will reveal them: its candidates are scored by the plain model (declared + Coulomb + offset), the
    scores those of the plain model's own choice; the chosen derivatives are in the report."""
    import oed
    from estimation.diagnosis.plain_laws import plain_model

    folder, plain, paths = setting
    declared = build_model(plain.robot, "internal", "viscous")
    assert plain_model(declared).n_base == plain.n_base
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        by_plain = prepare_records(declared, [paths["train"]], [paths["validate"]], settings=PreparationSettings(
            validation_fits=("ols", "wls"), validation_model=plain_model(declared))).preprocessing
    reference = prepared(plain, paths).preprocessing
    assert by_plain.evidence.selection == "validation"
    assert by_plain.without_evidence() == reference.without_evidence()
    assert [item.preprocessing for item in by_plain.evidence.validation] == \
        [item.preprocessing for item in reference.evidence.validation]
    assert [item.score for item in by_plain.evidence.validation] == \
        pytest.approx([item.score for item in reference.evidence.validation], rel=1e-8)
    with pytest.raises(ValueError, match="validation_model has channels"):
        prepare_records(declared, [paths["train"]], [paths["validate"]], settings=PreparationSettings(
            validation_fits=("ols",), validation_model=build_model(plain.robot, "external", "viscous")))
    run = oed.diagnose(joints=3, data=paths["train"], validate=paths["validate"], max_effects=2)
    document = run.to_dict()["preprocessing"]
    assert document["selection"] == "validation" and document["validation_candidates"]
    assert document["cutoff_hz"] == reference.cutoff_hz and document["method"] == reference.method


def test_the_candidates_predictions_are_compare_s_made_a_chunk_at_a_time(setting):
    """The scoring's predictions (estimation.identification.validation.compare_recorded): the errors ``compare``
    gives against the recording, for every fit, whatever the chunk; a wrong-length theta refused."""
    _, model, paths = setting
    train = read_files([paths["train"]], model, split=True)[0].segments
    raw = read_files([paths["validate"]], model, split=False)[0].segments[0]
    plan = Preprocessing("butterworth", cutoff_hz=5.0)
    problem = stack(model, prepare(train, plan))
    thetas = {"ols": LeastSquares().fit(problem).estimate_.values,
              "wls": WeightedLeastSquares().fit(problem).estimate_.values}
    validation = prepare([raw], plan, role="validation data")
    assert validation.recorded is not None  # filtered: the recording is what is compared
    for chunk_size in (7, 1000, raw.n_samples + 1):
        comparisons = compare_recorded(model, thetas, validation, label="validation", chunk_size=chunk_size)
        assert list(comparisons) == ["ols", "wls"]
        for fit, theta in thetas.items():
            expected = compare(model, theta, validation, label="validation")
            np.testing.assert_array_equal(comparisons[fit].t, expected.t)
            np.testing.assert_array_equal(comparisons[fit].measured, expected.measured)
            np.testing.assert_allclose(comparisons[fit].predicted, expected.predicted, rtol=1e-12, atol=1e-12)
            assert comparisons[fit].mse == pytest.approx(expected.mse, rel=1e-12)
    with pytest.raises(ValueError, match="values"):
        compare_recorded(model, {"ols": thetas["ols"][:-1]}, validation)
    with pytest.raises(ValueError, match="chunk_size"):
        compare_recorded(model, thetas, validation, chunk_size=0)


def test_the_training_sums_of_the_blocked_cross_validation_are_those_the_validation_choice_makes(setting,
                                                                                                 monkeypatch):
    """Issue 34's cost: the blocked cross-validation, which prepares each candidate's training window, also sums it
    for the validation choice's fits, which then does not prepare it again. The sums are those the choice made
    itself, bit for bit, and so is every candidate's evidence and the plan chosen; on a repeat of the training
    motion nothing is summed."""
    from dataclasses import replace

    from estimation.estimators.normal_equations import accumulate
    from estimation.identification import prepared as prepared_module
    from estimation.identification import preprocessing_on_validation as on_validation_module
    from estimation.identification.preprocessing_choice import choose_by_evidence, scored_window

    _, model, paths = setting

    def segments(name):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            return [segment for file in read_files([paths[name]], model, split=True) for segment in file.segments]

    train = segments("train")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        choice = choose_by_evidence(model, train, sums_model=model, jobs=1)
    assert len(choice.training_sums) == len(choice.chosen.evidence.candidates)
    window = scored_window(train)
    for plan, sums in choice.training_sums:
        own = accumulate(model, prepare(window, plan), gram=False)
        for name in ("factor", "power"):
            np.testing.assert_array_equal(getattr(sums, name), getattr(own, name))
        assert sums.n_samples == own.n_samples

    calls = []
    choose = on_validation_module.choose_on_validation
    monkeypatch.setattr(on_validation_module, "choose_on_validation",
                        lambda *args, **kwargs: calls.append(kwargs.get("training_sums")) or choose(*args, **kwargs))
    shared = prepared(model, paths)
    shares = prepared_module.shares_training_sums
    monkeypatch.setattr(prepared_module, "shares_training_sums", lambda *args: False)
    own = prepared(model, paths)
    assert calls[0] and not calls[1]
    assert set(calls[0]) <= {item.preprocessing for item in shared.preprocessing.evidence.candidates}
    assert shared.preprocessing == own.preprocessing
    untimed = lambda evidence: [replace(item, seconds=0.0) for item in evidence]  # noqa: E731
    assert untimed(shared.preprocessing.evidence.validation) == untimed(own.preprocessing.evidence.validation)
    np.testing.assert_array_equal(shared.train.measurements.dq, own.train.measurements.dq)

    assert not shares(PreparationSettings(), train, segments("repeat"))
    assert shares(PreparationSettings(), train, segments("validate"))
    assert not shares(PreparationSettings(cutoff_hz=5.0), train, segments("validate"))
