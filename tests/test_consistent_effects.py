"""The physically consistent fit with the diagnosed effects (estimation.consistent.fixed_shapes): shaped laws at
their fitted shapes, a delay, offsets, laws on joint combinations; `oed identify --consistent` with them, then
`oed predict --consistent` and `oed export`. Simulated 3-joint PUMA with tanh-smoothed Coulomb friction and offsets."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest

from dynamics.effects.linear import CoulombFriction
from dynamics.effects.specs import build_effects
from dynamics.models import build_model
from dynamics.physical_parameters import PhysicalParametrisation, is_consistent, project_link
from dynamics.robots import load_robot
from dynamics.transmission import puma560_transmission
from dynamics.simulation.synthetic import simulate
from estimation.consistent.identification import consistent_fit, consistent_refit, consistent_refit_file
from estimation.consistent.least_squares import ConsistentLeastSquares
from estimation.consistent.simulation import consistent_simulator
from estimation.identification.fit import identify
from estimation.preprocessing.delay import DelayBounds
from oed.cli import main
from oed.fourier import random_fourier

SMOOTHING = 0.04  # rad/s: the true tanh smoothing of the Coulomb law
NOISE = 0.1  # N·m on every joint
COULOMB = (6.0, 4.0, 2.0)
OFFSET = (1.0, -0.5, 0.3)


def _truth(robot):
    """Consistent bodies (the description's, projected, link 1 given a mass, scaled by 0.9..1.1), viscous
    friction, the Coulomb law ``fc tanh(dq / 0.04)`` and offsets."""
    generator = np.random.default_rng(0)
    model = build_model(robot, "internal", ("viscous", CoulombFriction(smoothing=SMOOTHING), "offset"))
    links = []
    for k in range(robot.n_joints):
        link = project_link(robot.joints[k].inertial, floor=0.05)
        if link[0] < 1.0:
            link = project_link(link + np.array([5.0, 0, 0, 0, 0.1, 0, 0.1, 0, 0, 0.1]), floor=0.05)
        links.append(link * generator.uniform(0.9, 1.1))
    assert all(is_consistent(link) for link in links)
    theta = np.concatenate([*links, generator.uniform(2.0, 10.0, 3), COULOMB, OFFSET])
    return model, theta


@pytest.fixture(scope="module")
def puma():
    robot = load_robot("puma560", joints=3)
    truth, theta = _truth(robot)
    noise = {f"tau{j}": NOISE for j in (1, 2, 3)}
    train, validate, test = (simulate(truth, theta, random_fourier(robot, seed=seed), rate_hz=250.0, periods=2,
                                      noise=noise, seed=seed) for seed in (5, 6, 7))
    model = build_model(robot, "internal", "viscous,coulomb:tanh,offset")
    # the truth in the shaped model's parameter order: links, fv, fc (tanh), off
    return robot, model, theta, train, validate, test


def test_consistent_fit_with_coulomb_tanh_at_the_true_shape_recovers_the_parameters_and_predicts_at_the_floor(puma):
    robot, model, theta, train, validate, test = puma
    starts = {f"vc{j}": SMOOTHING for j in (1, 2, 3)}
    result = identify(model, train, validate, shape_starts=starts, shape_search=False)
    fit = consistent_fit(result, train, validate)  # the prior's weight chosen on the validation record
    estimate = fit.estimate
    assert fit.prior_weight_choice == "held-out" and len(fit.prior_weight_search) == 5
    assert all(is_consistent(link) for link in estimate.link_parameters())
    truth = model.base.K @ theta
    z = (estimate.values - truth) / estimate.std
    assert np.max(np.abs(z)) < 4.0, dict(zip(estimate.names, np.round(z, 2)))
    effects = estimate.effect_values()
    for j in range(3):
        assert effects[f"fc{j + 1}"] >= 0 and effects[f"fv{j + 1}"] >= 0
        assert abs(effects[f"fc{j + 1}"] - COULOMB[j]) < 4 * estimate.std[list(estimate.names).index(f"fc{j + 1}")]
        assert abs(effects[f"off{j + 1}"] - OFFSET[j]) < 4 * estimate.std[list(estimate.names).index(f"off{j + 1}")]
    # a record no choice saw, at the noise floor (σ² = 0.01), predicted at the fixed shapes
    predicted = fit.predict(test)
    mse = np.mean((test.tau - predicted) ** 2, axis=0)
    assert np.all(mse < 1.1 * NOISE**2), mse
    assert np.allclose(fit.predict(validate), fit.validation.predicted)
    document = fit.to_dict()["consistent"]
    assert document["shape"] == pytest.approx(starts) and document["delay"] is None


def test_the_shapes_searched_and_a_delay_are_held_at_the_unconstrained_fit_values(puma):
    robot, model, theta, train, validate, test = puma
    result = identify(model, train, validate, delay=DelayBounds())
    assert result.delay is not None and result.shaped_fit is not None
    fit = consistent_refit(result, train, validate, prior_weight=1.0)
    assert fit.prior_weight_choice == "given" and fit.estimate.prior_weight == 1.0
    document = fit.to_dict()["consistent"]
    assert document["delay"] == pytest.approx(result.delay.value)
    assert set(document["shape"]) == {"vc1", "vc2", "vc3"}
    # consistency costs nothing measurable on consistent truth: the validation error is the unconstrained one's
    ratios = np.array(list(document["price"]["validation"].values()))
    assert np.all(ratios < 1.05), ratios
    assert np.allclose(fit.predict(test), fit.predict(test))
    mse = np.mean((test.tau - fit.predict(test)) ** 2, axis=0)
    assert np.all(mse < 1.15 * NOISE**2), mse


def test_a_law_on_a_joint_combination_enters_and_stays_non_negative(puma):
    robot, model, theta, train, validate, test = puma
    combined = build_model(robot, "internal", build_effects("viscous,coulomb:tanh,offset,coulomb:tanh[q2+q3]", robot))
    starts = {**{f"vc{j}": SMOOTHING for j in (1, 2, 3)}, "vc[q2+q3]": 0.05}
    result = identify(combined, train, validate, shape_starts=starts, shape_search=False)
    fit = consistent_fit(result, train, validate, prior_weight=1.0)
    effects = fit.estimate.effect_values()
    assert effects["fc[q2+q3]"] >= 0  # the truth has none: an estimate below zero is held at its bound
    assert all(is_consistent(link) for link in fit.estimate.link_parameters())
    mse = np.mean((test.tau - fit.predict(test)) ** 2, axis=0)
    assert np.all(mse < 1.15 * NOISE**2), mse


def test_a_shaped_model_from_measurements_alone_is_refused_with_the_way_out(puma):
    robot, model, theta, train, validate, test = puma
    with pytest.raises(NotImplementedError, match="fixed_problem"):
        ConsistentLeastSquares().fit(model, train)
    with pytest.raises(TypeError, match="diagnosis"):
        consistent_refit(object(), train)
    # the simulator's Coulomb law has one smoothing for all joints: a fitted tanh law is named, not simulated wrongly
    result = identify(model, train, shape_starts={f"vc{j}": SMOOTHING for j in (1, 2, 3)}, shape_search=False)
    fit = consistent_fit(result, train, prior_weight=1.0)
    with pytest.raises(ValueError, match="coulomb:tanh"):
        consistent_simulator(model, fit.estimate)


def test_friction_of_motors_and_joint_combinations_is_non_negative():
    six = load_robot("puma560")
    motors = build_model(six, "internal", build_effects("viscous,motor_viscous@5-6,motor_inertia@6,motor_coulomb@6",
                                                        six, puma560_transmission()))
    names = [name for effect in motors.effects for name in effect.parameter_names(six)]
    kind = dict(zip(names, PhysicalParametrisation.of_model(motors).effect_kinds))
    assert kind["fvm5"] == kind["fvm6"] == kind["Jm6"] == kind["fcm6"] == "nonnegative"
    robot = load_robot("puma560", joints=3)
    effects = build_effects("viscous,coulomb[q2+q3],coulomb:tanh[q2-q3],ripple@1,offset", robot)
    model = build_model(robot, "internal", effects)
    kinds = PhysicalParametrisation.of_model(model).effect_kinds
    names = [name for effect in model.effects for name in effect.parameter_names(robot)]
    kind = dict(zip(names, kinds))
    assert kind["fc[q2+q3]"] == "nonnegative" and kind["fc[q2-q3]"] == "nonnegative"
    assert kind["fv1"] == "nonnegative" and kind["rs1"] == "free" and kind["off2"] == "free"


@pytest.fixture(scope="module")
def files(puma, tmp_path_factory):
    robot, model, theta, train, validate, test = puma
    folder = tmp_path_factory.mktemp("consistent_effects")
    paths = []
    for name, record in (("train", train), ("validate", validate), ("test", test)):
        paths.append(folder / f"{name}.csv")
        record.write(paths[-1])
    return folder, paths


def test_identify_consistent_with_shaped_laws_and_a_delay_then_predict_and_export(files, capsys):
    folder, (train, validate, _) = files
    result, metrics, predictions = folder / "result.json", folder / "metrics.json", folder / "p.csv"
    urdf, friction = folder / "out.urdf", folder / "friction.json"
    assert main(["identify", "--joints", "3", "--data", str(train), "--validate", str(validate), "--friction",
                 "viscous,coulomb:tanh,offset,delay", "--consistent", "--out", str(result)]) == 0
    document = json.loads(result.read_text())
    consistent = document["consistent"]
    assert set(consistent["shape"]) == {"vc1", "vc2", "vc3"} and consistent["delay"] is not None
    assert document["model_file"]["consistent"] is not None
    assert main(["predict", "--consistent", "--model", str(result), "--data", str(validate), "--out",
                 str(predictions), "--metrics", str(metrics)]) == 0
    measured = json.loads(metrics.read_text())["mse"]
    reported = consistent["validation"]["mse"]
    assert max(abs(measured[c] / reported[c] - 1) for c in reported) < 1e-6
    assert main(["export", "--model", str(result), "--urdf", str(urdf), "--friction", str(friction)]) == 0
    joints = json.loads(friction.read_text())["joints"]
    for j, name in enumerate(["joint1", "joint2", "joint3"]):
        terms = joints[name]
        assert terms["coulomb"] == pytest.approx(consistent["effects"][f"fc{j + 1}"])
        assert terms["coulomb_smoothing"] == pytest.approx(consistent["shape"][f"vc{j + 1}"])
        assert {"viscous", "offset"} <= set(terms)


def test_diagnose_consistent_refits_the_adopted_model_and_predict_uses_it(files, capsys):
    folder, (train, validate, test) = files
    report, metrics, predictions = folder / "report.json", folder / "d_metrics.json", folder / "d.csv"
    assert main(["diagnose", "--joints", "3", "--data", str(train), "--validate", str(validate), "--test", str(test),
                 "--friction", "viscous", "--out", str(report), "--consistent"]) == 0
    document = json.loads(report.read_text())
    consistent = document["consistent"]
    adopted = {effect["name"] for effect in document["effects"]}
    assert any(name.startswith("coulomb") for name in adopted), adopted
    assert consistent["prior_weight_choice"] == "held-out"
    assert document["model_file"]["consistent"] is not None and len(document["links"]) == 3
    assert all(value >= 0 for name, value in consistent["effects"].items() if name.startswith(("fv", "fc")))
    # the consistent refit with the adopted effects predicts the untouched record at the noise floor (σ² = 0.01)
    assert all(value < 1.15 * NOISE**2 for value in consistent["test"]["mse"].values()), consistent["test"]
    assert main(["predict", "--consistent", "--model", str(report), "--data", str(test), "--out", str(predictions),
                 "--metrics", str(metrics)]) == 0
    measured = json.loads(metrics.read_text())["mse"]
    assert max(abs(measured[c] / consistent["test"]["mse"][c] - 1) for c in measured) < 1e-6
    assert "consistent (prior weight" in capsys.readouterr().out
    # the same refit from the report's model file and the record files (library: consistent_refit_file)
    again = consistent_refit_file(report, [train], [validate])
    assert again.estimate.prior_weight == consistent["prior_weight"]
    reported = consistent["validation"]["mse"]
    assert max(abs(again.validation.mse[c] / reported[c] - 1) for c in reported) < 1e-4


def _law_torques(terms: dict, q, dq):
    """One joint's friction.json terms as torques, from the formulas its ``laws`` name (independent of the library)."""
    tau = np.zeros_like(dq)
    tau += terms.get("viscous", 0.0) * dq + terms.get("offset", 0.0)
    if "coulomb" in terms:
        smoothing = terms.get("coulomb_smoothing")
        tau += terms["coulomb"] * (np.sign(dq) if smoothing is None else np.tanh(dq / smoothing))
    if "stribeck" in terms:
        tau += terms["stribeck"]["fs"] * np.exp(-((dq / terms["stribeck"]["velocity"]) ** 2)) * np.sign(dq)
    if "sigmoid" in terms:
        p1, p2, p3 = (terms["sigmoid"][key] for key in ("phi1", "phi2", "phi3"))
        tau += p1 / (1 + np.exp(-p2 * (dq + p3))) - p1 / (1 + np.exp(-p2 * p3))
    if "ripple" in terms:
        r = terms["ripple"]
        tau += r["rs"] * np.sin(r["n"] * q) + r["rc"] * np.cos(r["n"] * q)
    return tau


def test_exported_shaped_laws_reproduce_predict_consistent_through_pinocchio(files):
    import pandas as pd
    import pinocchio as pin

    folder, (train, validate, _) = files
    result, predictions, metrics = folder / "shaped.json", folder / "shaped.csv", folder / "shaped_metrics.json"
    urdf, friction = folder / "shaped.urdf", folder / "shaped_friction.json"
    assert main(["identify", "--joints", "3", "--data", str(train), "--validate", str(validate), "--friction",
                 "viscous,offset,stribeck:velocity@1,sigmoid@2,ripple@3,coulomb:tanh@3", "--consistent",
                 "--out", str(result)]) == 0
    assert main(["export", "--model", str(result), "--urdf", str(urdf), "--friction", str(friction),
                 "--allow-implausible"]) == 0  # link 1 of the 3-joint PUMA: only its z inertia is seen
    assert main(["predict", "--consistent", "--model", str(result), "--data", str(validate), "--out",
                 str(predictions), "--metrics", str(metrics)]) == 0
    document = json.loads(friction.read_text())
    assert {"stribeck", "coulomb"} <= set(document["joints"]["joint1"]) and "sigmoid" in document["joints"]["joint2"]
    assert {"ripple", "coulomb_smoothing"} <= set(document["joints"]["joint3"])
    record = pd.read_csv(validate)
    q, dq, ddq = (record[[f"{prefix}{j}" for j in (1, 2, 3)]].to_numpy() for prefix in ("q", "dq", "ddq"))
    model = pin.buildModelFromUrdf(str(urdf))
    model.gravity = pin.Motion(np.asarray(document["gravity"], dtype=float), np.zeros(3))
    data = model.createData()
    tau = np.array([pin.rnea(model, data, a, b, c).copy() for a, b, c in zip(q, dq, ddq)])
    for j, name in enumerate(["joint1", "joint2", "joint3"]):
        tau[:, j] += _law_torques(document["joints"][name], q[:, j], dq[:, j])
    predicted = pd.read_csv(predictions)
    rows = np.searchsorted(record["t"].to_numpy(), predicted["t"].to_numpy())
    expected = predicted[["tau1", "tau2", "tau3"]].to_numpy()
    assert np.max(np.abs(tau[rows] - expected)) / np.max(np.abs(expected)) < 1e-6


@pytest.mark.parametrize("shaped", [True, False])
def test_the_prior_weight_search_evaluating_each_regressor_once_is_the_refits_one_by_one_bit_for_bit(puma, shaped):
    """consistent_fit's search (the training problem built once, each record's regressor once for every weight) gives
    what choose_prior_weight over identify_consistent at each weight gives, to the last bit: the estimate, every
    comparison (as recorded and filtered), the search; with shaped laws and a delay held, and on a linear model."""
    from estimation.consistent.identification import choose_prior_weight, identify_consistent
    from estimation.preprocessing.plan import choose_preprocessing, prepare

    robot, model, theta, train, validate, test = puma
    if shaped:
        result = identify(model, train, validate, delay=DelayBounds())
        assert result.delay is not None and result.shaped_fit is not None
    else:  # filtered channels (a Butterworth filter): the comparisons as recorded and filtered
        linear = build_model(robot, "internal", "viscous,coulomb,offset")
        train, validate = (dataclasses.replace(record, dq=None, ddq=None) for record in (train, validate))
        plan = choose_preprocessing(train, cutoff_hz=20.0)
        train, validate = prepare(train, plan), prepare(validate, plan)
        assert train.recorded is not None
        result = identify(linear, train, validate)
    searched = consistent_fit(result, train, validate)

    def refit(weight, warm):
        return identify_consistent(result, train, validate, prior_weight=weight, warm_start=warm, undetermined=False)

    one_by_one = choose_prior_weight(refit, result)
    assert searched.prior_weight_search == one_by_one.prior_weight_search
    assert np.array_equal(searched.estimate.values, one_by_one.estimate.values)
    assert np.array_equal(searched.estimate.cov, one_by_one.estimate.cov)
    for name in ("train", "validation"):
        mine, theirs = getattr(searched, name), getattr(one_by_one, name)
        assert np.array_equal(mine.predicted, theirs.predicted) and np.array_equal(mine.measured, theirs.measured)
        assert (mine.filtered is None) == (theirs.filtered is None)
        if mine.filtered is not None:
            assert np.array_equal(mine.filtered.predicted, theirs.filtered.predicted)
        assert mine.label == theirs.label and mine.segments == theirs.segments
