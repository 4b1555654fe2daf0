"""The next experiment (``oed design --from``): Jacobians against finite differences, the prior against the
identification's covariance, Ds against the marginal covariance, the CLI's outputs and its bad input."""

from __future__ import annotations

import json
from dataclasses import replace

import casadi
import numpy as np
import pytest

from benchmarks.bench_sequential_design import bic, focus_monte_carlo
from benchmarks.kuka_sequential import URDF, kuka_design
from benchmarks.sequential_case import StribeckCase
from estimation.identification.identified_model import IdentifiedModel
from estimation.identification.model_file import ModelFile
from oed.bounds import PUMA_BOUNDS
from oed.cli import main
from oed.criteria import LogDet
from oed.excitation import DesignSettings
from oed.sequential.criteria import FocusedLogDet, WorstRelativeVariance, focus_names, posterior_criterion
from oed.sequential.discrimination import check_rivals, design_discriminating
from oed.sequential.jacobian import SequentialDesignError, model_jacobian
from oed.sequential.next_experiment import design_next
from oed.sequential.prior import prior_information
from oed.sequential.problem import SequentialDesign
from oed.sequential.starts import screened_start, slowed_start

CASE = StribeckCase()
QUICK = ["--starts", "1", "--max-iter", "15", "--samples", "60", "--constraint-points", "30", "--quiet"]


@pytest.fixture(scope="module")
def first():
    """The first experiment's record and the model identified on it."""
    record = CASE.record(CASE.first_trajectory(), seed=1)
    return record, CASE.model_document([record])


@pytest.fixture(scope="module")
def files(tmp_path_factory, first):
    folder = tmp_path_factory.mktemp("sequential")
    record, document = first
    record.write(folder / "e1.csv")
    (folder / "result.json").write_text(json.dumps({"model_file": document}))
    (folder / "rival.json").write_text(json.dumps({"model_file": CASE.model_document([record], "viscous,coulomb:tanh@2")}))
    return folder


def test_jacobian_matches_finite_differences_of_the_prediction(first):
    record, document = first
    model = IdentifiedModel(ModelFile.from_dict(document))
    jacobian = model_jacobian(model)
    q, dq, ddq = record.q[::50], record.dq[::50], record.ddq[::50]
    J = jacobian.evaluate(q, dq, ddq) * jacobian.noise_std[None, :, None]  # unweighted
    assert np.allclose(J[:, :, :model.model.n_base], model.regressor(q, dq, ddq), atol=1e-10)
    step = 1e-7
    shifted = dict(document, shape={**document["shape"], "vs2": document["shape"]["vs2"] + step})
    moved = IdentifiedModel(ModelFile.from_dict(shifted))
    finite = (moved.predict(q, dq, ddq) - model.predict(q, dq, ddq)) / step
    assert np.allclose(J[:, :, jacobian.names.index("vs2")], finite, rtol=1e-4, atol=1e-4 * np.abs(finite).max())


def test_prior_information_gives_the_identification_standard_deviations(first):
    record, document = first
    model = IdentifiedModel(ModelFile.from_dict(document))
    jacobian = model_jacobian(model)
    prior = prior_information(jacobian, record)
    std = np.sqrt(np.diag(prior.covariance()))
    r = model.model.n_base
    assert np.allclose(std[:r], np.sqrt(np.diag(model.cov)), rtol=0.03)
    assert std[jacobian.names.index("vs2")] == pytest.approx(document["shape_std"]["vs2"], rel=0.03)
    assert prior.duration_s == pytest.approx(10.0) and prior.n_samples == 2000


def test_ds_criterion_is_the_log_determinant_of_the_marginal_covariance():
    generator = np.random.default_rng(0)
    A = generator.normal(size=(40, 6))
    M = A.T @ A
    focus = (1, 4)
    marginal = np.linalg.inv(M)[np.ix_(focus, focus)]
    criterion = FocusedLogDet(focus, 6)
    assert criterion.value(M) == pytest.approx(np.linalg.slogdet(marginal)[1], rel=1e-10)
    symbol = casadi.SX.sym("M", 6, 6)
    function = casadi.Function("ds", [symbol], [criterion.expression(symbol)])
    assert float(function(M)) == pytest.approx(criterion.value(M), rel=1e-10)


def test_worst_relative_criterion_is_a_smooth_maximum_of_the_weighted_variances():
    generator = np.random.default_rng(1)
    A = generator.normal(size=(40, 6))
    M = A.T @ A
    focus, weights = (4, 1, 2), (2.0, 0.5, 3.0)
    variances = np.diag(np.linalg.inv(M))[list(focus)] * weights
    for sharpness in (1.0, 8.0, 200.0):
        criterion = WorstRelativeVariance(focus, 6, weights, sharpness)
        assert criterion.value(M) == pytest.approx(np.log(np.sum(variances ** sharpness)) / sharpness, rel=1e-10)
        assert np.log(variances.max()) <= criterion.value(M) <= np.log(variances.max()) + np.log(3) / sharpness
    symbol = casadi.MX.sym("M", 6, 6)
    expression = criterion.expression(symbol)
    function = casadi.Function("worst", [symbol], [expression, casadi.gradient(expression, symbol)])
    value, gradient = function(M)
    assert float(value) == pytest.approx(criterion.value(M), rel=1e-10)
    step = np.zeros((6, 6))
    step[1, 2] = step[2, 1] = 1e-6
    finite = (criterion.value(M + step) - criterion.value(M - step)) / 2e-6
    assert float(gradient[1, 2] + gradient[2, 1]) == pytest.approx(finite, rel=1e-5)
    with pytest.raises(ValueError, match="weights"):
        WorstRelativeVariance(focus, 6, (1.0, -1.0, 1.0))


def test_worst_relative_criterion_gives_the_focus_groups_relative_variances(first):
    record, document = first
    model = IdentifiedModel(ModelFile.from_dict(document))
    jacobian = model_jacobian(model)
    prior = prior_information(jacobian, record)
    names = ("fc2", "fs2", "vs2")
    criterion = posterior_criterion(jacobian, names, "worst-relative", prior=prior)
    index = list(jacobian.indices(names))
    relative = np.sqrt(np.diag(prior.covariance())[index]) / np.abs(jacobian.estimate[index])
    scale = 1.0 / np.sqrt(np.diag(prior.information))
    posterior = prior.information * scale[:, None] * scale[None, :]
    assert np.exp(criterion.value(posterior) / 2) == pytest.approx(relative.max(), rel=0.04)
    assert isinstance(posterior_criterion(jacobian, names, "d"), LogDet)
    assert isinstance(posterior_criterion(jacobian, names, "ds"), FocusedLogDet)
    with pytest.raises(SequentialDesignError, match="unknown sequential criterion"):
        posterior_criterion(jacobian, names, "a")


def test_screened_start_is_the_best_of_its_slowed_candidates_within_the_bounds(first):
    record, document = first
    model = IdentifiedModel(ModelFile.from_dict(document))
    jacobian = model_jacobian(model)
    prior = prior_information(jacobian, record)
    problem = SequentialDesign(model.robot, model.model.kind, PUMA_BOUNDS, LogDet(), model.model.effects,
                               DesignSettings(cost_samples=60, jit=False), jacobian=jacobian, prior=prior,
                               duration_s=10.0)
    objective = problem.cost_function()
    generator = np.random.default_rng(5)
    pool = [slowed_start(problem, generator) for _ in range(6)]
    chosen = screened_start(problem, np.random.default_rng(5), 6)
    assert np.array_equal(chosen, pool[int(np.argmin([float(objective(x)) for x in pool]))])
    for x in pool:
        _, q, dq, ddq = problem.sample(x)
        assert np.all(np.abs(dq) <= PUMA_BOUNDS.dq_max * (1 + 1e-9))
        assert np.all((q >= PUMA_BOUNDS.q_min - 1e-9) & (q <= PUMA_BOUNDS.q_max + 1e-9))
    speeds = np.array([np.abs(problem.sample(x)[2]).max(axis=0) / PUMA_BOUNDS.dq_max for x in pool])
    assert speeds.min() < 0.2  # some joint slowed well below the plain starts' 30 % of its bound
    with pytest.raises(ValueError, match="candidates"):
        screened_start(problem, generator, 0)


def test_focus_names_accepts_parameters_effect_names_and_specs(first):
    model = IdentifiedModel(ModelFile.from_dict(first[1]))
    jacobian = model_jacobian(model)
    assert focus_names(jacobian, "stribeck") == ("fc2", "fs2", "vs2")
    assert focus_names(jacobian, "stribeck:velocity@2") == ("fc2", "fs2", "vs2")
    assert focus_names(jacobian, "vs2,fv1") == ("fv1", "vs2")
    assert isinstance(posterior_criterion(jacobian, jacobian.names), LogDet)
    with pytest.raises(SequentialDesignError, match="'fs7'.*neither"):
        focus_names(jacobian, "fs2,fs7")


def test_designed_experiment_beats_repeating_the_first_on_the_focus(first):
    record, document = first
    model = IdentifiedModel(ModelFile.from_dict(document))
    settings = DesignSettings(cost_samples=100, constraint_points=40, max_iter=60)
    result = design_next(model, record, bounds=PUMA_BOUNDS, focus="stribeck", settings=settings, starts=1, seed=1)
    worst = result.predicted.worst_relative(result.focus)
    assert worst["after_repeat"] == pytest.approx(worst["now"] / np.sqrt(2), rel=1e-6)  # same duration
    assert worst["after_designed"] < 0.7 * worst["after_repeat"], worst


def test_cli_writes_next_json_with_predicted_std_and_figure(files):
    out, png = files / "next.json", files / "next.png"
    code = main(["design", "--from", str(files / "result.json"), "--data", str(files / "e1.csv"), "--focus", "vs2",
                 "--periods", "4", "--out", str(out), "--plot", str(png), *QUICK])
    assert code == 0
    document = json.loads(out.read_text())
    for key in ("frequency_hz", "harmonics", "q0", "a", "b", "joint_names", "criterion", "bounds", "solver"):
        assert key in document
    assert document["criterion"] == "worst-relative" and document["sequential"]["focus"] == ["vs2"]
    assert document["sequential"]["duration_s"] == pytest.approx(20.0)
    vs2 = document["predicted_std"]["vs2"]
    assert vs2["after_designed"] < vs2["now"] and vs2["after_repeat"] == pytest.approx(vs2["now"] / np.sqrt(3))
    assert png.stat().st_size > 1000
    code = main(["design", "--from", str(files / "result.json"), "--data", str(files / "e1.csv"), "--focus", "stribeck",
                 "--criterion", "ds", "--out", str(out), *QUICK])
    assert code == 0 and json.loads(out.read_text())["criterion"] == "ds-logdet"


def test_cli_discriminates_two_rival_models(files):
    out = files / "discriminate.json"
    code = main(["design", "--from", str(files / "result.json"), "--rival", str(files / "rival.json"), "--discriminate",
                 "--data", str(files / "e1.csv"), "--frequency", "1", "--out", str(out), *QUICK])
    assert code == 0
    discrimination = json.loads(out.read_text())["discrimination"]
    assert discrimination["rival"] == "viscous,coulomb:tanh@2"
    assert json.loads(out.read_text())["criterion"] == "t-optimal"
    for key in ("separation", "separation_after_repeat", "expected_delta_bic"):
        assert set(discrimination[key]) == {"if_from_true", "if_rival_true"}
    assert all(value > 0 for value in discrimination["separation"].values())


def _bad_input(files, capsys, arguments, message):
    out = files / "bad.json"
    before = sorted(path.name for path in files.iterdir())
    code = main(["design", "--out", str(out), *arguments, *QUICK])
    error = capsys.readouterr().err
    assert code == 2, error
    assert message in error, error
    assert sorted(path.name for path in files.iterdir()) == before


def test_bad_input_is_named_and_nothing_is_written(files, capsys, tmp_path):
    model, data = str(files / "result.json"), str(files / "e1.csv")
    _bad_input(files, capsys, ["--from", model, "--data", data, "--focus", "fs9"], "'fs9' is neither a parameter")
    _bad_input(files, capsys, ["--from", model, "--data", data, "--joints", "2"], "is not the model's")
    _bad_input(files, capsys, ["--from", model, "--data", data, "--friction", "coulomb"], "fixes the model")
    _bad_input(files, capsys, ["--from", model, "--data", data, "--rival", model, "--discriminate"], "same model")
    _bad_input(files, capsys, ["--from", model], "--data")
    _bad_input(files, capsys, ["--from", model, "--data", data, "--torque-limits"], "no effort limit")
    _bad_input(files, capsys, ["--from", model, "--data", data, "--floor", "0"], "give --urdf")
    _bad_input(files, capsys, ["--from", model, "--data", data, "--start", "0,0,0"], "--start cannot be combined")
    _bad_input(files, capsys, ["--from", model, "--data", data, "--criterion", "cond"], "a plain design's")
    _bad_input(files, capsys, ["--criterion", "worst-relative"], "--from")
    _bad_input(files, capsys, ["--data", data], "--from")
    bounds = files / "bounds.json"
    bounds.write_text(json.dumps({"q_max": [1, 1], "dq_max": [1, 1], "ddq_max": [1, 1]}))
    _bad_input(files, capsys, ["--from", model, "--data", data, "--bounds", str(bounds)], "2 joints")
    bounds.unlink()
    wrong = files / "wrong.csv"
    wrong.write_text("t,q1,q2,tau1,tau2\n0,0.1,0.2,0.3,0.4\n0.005,0.1,0.2,0.3,0.4\n0.01,0.1,0.2,0.3,0.4\n")  # not zeros: a lost frame
    _bad_input(files, capsys, ["--from", model, "--data", str(wrong)], "do not match the model")
    wrong.unlink()


def test_same_rivals_are_refused(first):
    model = IdentifiedModel(ModelFile.from_dict(first[1]))
    with pytest.raises(SequentialDesignError, match="same model"):
        check_rivals(model, model)


def test_sequential_design_on_the_kuka_lwr4_urdf():
    """Any URDF robot: the 7-joint KUKA LWR4+ (skipped when its URDF is absent)."""
    if not URDF.exists():
        pytest.skip(f"the KUKA LWR4+ URDF is not available: {URDF} is absent")
    settings = DesignSettings(cost_samples=40, constraint_points=30, max_iter=5, jit=False)
    result = kuka_design(starts=1, settings=settings)
    assert result.design.trajectory.n_joints == 7
    predicted = result.predicted
    assert np.all(predicted.after_designed <= predicted.now * (1 + 1e-9))
    assert len(predicted.names) == result.prior.information.shape[0] > 40


@pytest.mark.slow
def test_designed_experiment_shrinks_the_worst_relative_sd_twice_as_much_as_repeating():
    """The Monte Carlo of benchmarks/bench_sequential_design.py --part focus (200 noise realisations: over 50 the
    realised ratio of shrinks scatters by about ±0.3 around its mean, 2.15; over 200 by about ±0.11)."""
    run = focus_monte_carlo(CASE, 200)
    assert run.next_experiment.design.criterion == "worst-relative"
    for key, realised in run.realised.items():  # realised standard deviations within 25 % of the predicted ones
        ratio = realised / run.predicted[key]
        assert np.all((ratio > 0.75) & (ratio < 1.25)), (key, ratio)
    worst = run.worst()
    assert worst["now"] / worst["after_designed"] >= 2 * worst["now"] / worst["after_repeat"], worst
    assert run.shrink_ratio("predicted") >= 2


@pytest.mark.slow
@pytest.mark.parametrize("fs", [0.3, 0.4])
def test_discriminating_experiment_tells_the_true_law_apart(fs):
    """A small Monte Carlo of benchmarks/bench_sequential_design.py --part discrimination (10 realisations)."""
    case = replace(CASE, fs=fs)
    rival = "viscous,coulomb:tanh@2"
    record = case.record(case.first_trajectory(), seed=1)
    result = design_discriminating(case.identified([record]), case.identified([record], rival), record,
                                   bounds=PUMA_BOUNDS, starts=8, seed=0)
    # the design's own prediction: the true law preferred by more than 10 in BIC, and further than by repeating. How far
    # further varies from seed to seed (a separation of 19 to 1 172 at fs 0.4 over seeds 0-3: a multimodal objective,
    # benchmarks/README.md); the realised check below is the target
    assert result.delta_bic["if_from_true"] > 10
    assert result.separation["if_from_true"] > result.separation_after_repeat["if_from_true"]
    told = []
    for i in range(10):
        first = case.record(case.first_trajectory(), seed=1000 + i)
        second = case.record(result.design.trajectory, seed=2000 + i)
        told.append(bic(case, [first, second], rival) - bic(case, [first, second], case.friction) > 10)
    assert np.mean(told) >= 0.9, told
