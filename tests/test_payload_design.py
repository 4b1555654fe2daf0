"""The payload's excitation design (oed.payload_design, `oed design --payload --from`): its criterion against plain linear
algebra, and a designed period that determines the mass and the centre of mass better than random excitations
within the same bounds."""

from __future__ import annotations

import json

import casadi
import numpy as np
import pandas as pd
import pytest

from dynamics.models import build_model
from dynamics.robots import load_robot
from dynamics.simulation.synthetic import simulate
from oed.bounds import JointBounds
from oed.cli import main
from oed.fourier import random_fourier
from oed.payload_design import MassAndCentre
from tests.test_payload import VISCOUS, robot_model_file


def test_criterion_is_the_smooth_maximum_of_the_relative_variances():
    generator = np.random.default_rng(0)
    A = generator.normal(size=(40, 10))
    M = A.T @ A
    criterion = MassAndCentre(mass=2.0, com=(0.01, -0.02, 0.08), length=0.1)
    covariance = np.linalg.inv(M)
    # u = (m/m0, (h - c0 m)/(m0 l)): its variances straight from the covariance
    T = criterion.combinations
    assert np.allclose(criterion.relative_std(M) ** 2, np.diag(T @ covariance @ T.T))
    worst = np.max(np.log(criterion.relative_std(M) ** 2))
    assert worst <= criterion.value(M) <= worst + np.log(4) / criterion.sharpness
    symbol = casadi.SX.sym("M", 10, 10)
    function = casadi.Function("J", [symbol], [criterion.expression(symbol)])
    assert float(function(M)) == pytest.approx(criterion.value(M), rel=1e-10)
    with pytest.raises(ValueError, match="mass must be a positive"):
        MassAndCentre(mass=0.0)


def test_robot_share_bound_rows_are_the_propagated_covariance_against_the_reference():
    """RobotShareBound: its rows are log r_k − log v_k with v the robot model's share of the relative variances,
    T A⁻¹ B Σ_θ Bᵀ A⁻¹ Tᵀ straight from the blocks, as numbers and as a CasADi expression of the (10 + r) x 10 block."""
    from oed.payload_design.constraints import RobotShareBound, reference_robot_share

    generator = np.random.default_rng(2)
    r = 7
    columns = generator.normal(size=(60, 10 + r))
    M = columns.T @ columns
    root = generator.normal(size=(r, r))
    cov = root @ root.T / 100
    criterion = MassAndCentre(mass=2.0, com=(0.01, -0.02, 0.08), length=0.1, robot_cov=cov)
    T, A, B = criterion.combinations, M[:10, :10], M[:10, 10:]
    sensitivity = np.linalg.solve(A, B)
    share = np.diag(T @ sensitivity @ cov @ sensitivity.T @ T.T)
    reference = share * np.array([2.0, 0.5, 1.0, 4.0])
    bound = RobotShareBound(criterion, reference)
    assert np.allclose(bound.margins(M), np.log([2.0, 0.5, 1.0, 4.0]), atol=1e-10)
    symbol = casadi.SX.sym("M", 10 + r, 10)
    rows = casadi.Function("g", [symbol], [bound.expression(symbol)])
    assert np.allclose(np.asarray(rows(M[:, :10])).ravel(), bound.margins(M), atol=1e-10)
    # the share does not depend on the record's length (the information's scale); the reference is the median
    assert np.allclose(reference_robot_share(criterion, [M, 3 * M, 0.5 * M]), share)
    others = [columns[rows_].T @ columns[rows_] for rows_ in (slice(0, 30), slice(30, 60), slice(10, 50))]
    assert np.allclose(reference_robot_share(criterion, others),
                       np.median([criterion.relative_variances(other)[1] for other in others], axis=0))
    with pytest.raises(ValueError, match="robot model's covariance"):
        RobotShareBound(MassAndCentre(), np.ones(4))
    with pytest.raises(ValueError, match="4 positive variances"):
        RobotShareBound(criterion, [1.0, 1.0, 0.0, 1.0])


@pytest.mark.parametrize("width", [5, 40])
def test_information_sum_per_sample_and_stacked_equal_the_plain_sum(width):
    """oed.design_solver.stacked_information (the payload and the sequential designs): the per-sample JᵀJ up to
    STACKED_ABOVE columns, one product of the stacked transposes above; both the plain Σ J_kᵀ J_k."""
    from oed.design_solver import STACKED_ABOVE, stacked_information

    generator = np.random.default_rng(1)
    weights = generator.normal(size=(3 * 2, width))
    q, dq, ddq = (casadi.SX.sym(name, 2) for name in ("q", "dq", "ddq"))
    J = casadi.reshape(casadi.mtimes(casadi.DM(weights).T, casadi.vertcat(casadi.sin(q), dq * ddq, q * dq)), width, 1)
    function = casadi.Function("J", [q, dq, ddq], [casadi.repmat(J.T, 3, 1) * casadi.DM([[1], [2], [3]])])
    states = [generator.normal(size=(2, 7)) for _ in range(3)]
    symbols = [casadi.MX.sym(name, 2, 7) for name in ("q", "dq", "ddq")]
    total = casadi.Function("total", symbols, [stacked_information(function, symbols, False)])(*states)
    expected = sum(np.asarray(function(*(state[:, k] for state in states))).T
                   @ np.asarray(function(*(state[:, k] for state in states))) for k in range(7))
    assert (width > STACKED_ABOVE) == (width == 40)
    assert np.allclose(np.asarray(total), expected, rtol=1e-12, atol=1e-12)


@pytest.fixture(scope="module")
def robot_json(tmp_path_factory):
    folder = tmp_path_factory.mktemp("payload_design")
    robot = load_robot("puma560")
    model = build_model(robot, "internal", "viscous")
    theta = model.nominal_parameters(viscous=VISCOUS)
    noise = {f"tau{j}": value for j, value in zip(range(1, 7), (0.15, 0.15, 0.2, 0.05, 0.05, 0.05))}
    train = simulate(model, theta, random_fourier(robot, seed=1, frequency_hz=0.1), rate_hz=500.0, periods=3, noise=noise,
                     seed=3)
    path = folder / "robot.json"
    path.write_text(json.dumps({"model_file": robot_model_file(model, train).file.to_dict()}))
    bounds = folder / "bounds.json"
    bounds.write_text(json.dumps(JointBounds.from_robot(robot, ddq_max=[15, 15, 15, 20, 20, 20], scale=0.9).to_dict()))
    return folder, path, bounds


def test_designed_period_beats_random_excitations(robot_json, capsys):
    """The default: the record's noise below random excitations' while the robot model's share of the mass and of each
    axis of the centre of mass stays at most their median (the bound a design for the record's noise alone breaks)."""
    folder, path, bounds = robot_json
    out, csv = folder / "d.json", folder / "d.csv"
    assert main(["design", "--payload", "--from", str(path), "--bounds", str(bounds), "--starts", "1",
                 "--samples", "200", "--out", str(out), "--csv", str(csv)]) == 0
    document = json.loads(out.read_text())
    assert document["frequency_hz"] == 0.1 and len(document["a"][0]) == 10
    design = document["payload_design"]
    assert design["link"] == "joint6" and design["duration_s"] == 10.0
    designed, random = design["predicted_std"]["designed"], design["predicted_std"]["random_median"]
    # the default criterion: the record's torque noise, the robot model given; its share bounded, reported apart
    assert design["criterion"]["robot_share"] == "bounded" and design["criterion"]["counts"] == "record_noise"
    assert design["predicted_std"]["random_excitations"] == 12
    assert set(designed) == set(random) == {"mass", "com", "record_noise", "robot_model"}
    total = np.hypot(designed["record_noise"]["mass"], designed["robot_model"]["mass"])
    assert designed["mass"] == pytest.approx(total, rel=1e-9) and designed["robot_model"]["mass"] > 0
    # the robot model's share no worse than random excitations' (1 %: the bound holds on the optimiser's samples)
    assert designed["robot_model"]["mass"] <= 1.01 * random["robot_model"]["mass"]
    assert np.all(np.array(designed["robot_model"]["com"]) <= 1.01 * np.array(random["robot_model"]["com"]))
    bound = design["robot_share_bound"]
    assert bound["quantities"] == ["mass", "com_x", "com_y", "com_z"] and min(bound["margins"]) > -0.02
    # and so the total better, the record's noise well below
    assert designed["mass"] < random["mass"] and max(designed["com"]) < max(random["com"])
    assert designed["record_noise"]["mass"] < random["record_noise"]["mass"] / 1.3
    assert max(designed["record_noise"]["com"]) < max(random["record_noise"]["com"]) / 2
    table = pd.read_csv(csv)
    assert table.shape == (10_000, 19) and table["t"].iloc[-1] < 10.0
    # within the bounds on the 1 kHz grid
    limits = json.loads(bounds.read_text())
    for j in range(6):
        assert np.abs(table[f"dq{j + 1}"]).max() <= limits["dq_max"][j] * (1 + 1e-6)
        assert np.abs(table[f"ddq{j + 1}"]).max() <= limits["ddq_max"][j] * (1 + 1e-6)
    err = capsys.readouterr().err
    assert "payload excitation for link 6" in err and "the robot model's share, apart" in err
    assert "at most random excitations'" in err and "warning" not in err and design["warnings"] == []


def test_noise_only_design_halves_the_record_noise_and_warns_of_the_robot_share(robot_json, capsys):
    """``--payload-noise-only``: nothing holds the robot model's share; the record's noise at least 2x below random
    excitations' (issue 37's target), and a warning whenever the total is worse than theirs."""
    folder, path, bounds = robot_json
    out = folder / "noise_only.json"
    assert main(["design", "--payload", "--from", str(path), "--bounds", str(bounds), "--starts", "1",
                 "--samples", "200", "--payload-noise-only", "--out", str(out)]) == 0
    design = json.loads(out.read_text())["payload_design"]
    assert design["criterion"]["robot_share"] == "ignored" and design["robot_share_bound"] is None
    designed, random = design["predicted_std"]["designed"], design["predicted_std"]["random_median"]
    assert designed["record_noise"]["mass"] < random["record_noise"]["mass"] / 2
    assert max(designed["record_noise"]["com"]) < max(random["record_noise"]["com"]) / 2
    # what the default's bound holds: unbounded, the robot model's share of the mass grows past random excitations'
    assert designed["robot_model"]["mass"] > 1.2 * random["robot_model"]["mass"]
    err = capsys.readouterr().err
    worse = designed["mass"] > random["mass"]
    assert ("warning: in total (the robot model's share included) the design's mass std" in err) == worse
    assert any("design's mass" in warning for warning in design["warnings"]) == worse


def test_payload_design_needs_the_robots_model(robot_json, capsys):
    folder, path, bounds = robot_json
    assert main(["design", "--payload", "--bounds", str(bounds), "--out", str(folder / "x.json")]) != 0
    assert "give its result.json" in capsys.readouterr().err
    assert main(["design", "--payload", "--from", str(path), "--criterion", "logdet", "--bounds", str(bounds),
                 "--out", str(folder / "x.json")]) != 0
    assert "not with --payload" in capsys.readouterr().err
    assert main(["design", "--payload", "--from", str(path), "--link", "wrist", "--bounds", str(bounds),
                 "--out", str(folder / "x.json")]) != 0
    assert "no link 'wrist'" in capsys.readouterr().err
    assert main(["design", "--link", "joint6", "--out", str(folder / "x.json")]) != 0
    assert "give --payload too" in capsys.readouterr().err
    assert main(["design", "--payload-robot-share", "--out", str(folder / "x.json")]) != 0
    assert "give --payload too" in capsys.readouterr().err
    assert main(["design", "--payload", "--from", str(path), "--payload-noise-only", "--payload-robot-share",
                 "--bounds", str(bounds), "--out", str(folder / "x.json")]) != 0
    assert "give one" in capsys.readouterr().err


def test_robot_share_in_the_criterion_on_request(robot_json):
    """``robot_share="counted"`` (``--payload-robot-share``): the criterion counts the robot model's share too (the
    stacked columns [Y_k | Y_b]); the design's report is the same two parts either way."""
    from estimation.identification.identified_model import IdentifiedModel
    from oed.design_settings import DesignSettings
    from oed.payload_design import design_payload_excitation

    folder, path, bounds = robot_json
    model = IdentifiedModel.load(path)
    settings = DesignSettings(frequency_hz=0.1, harmonics=10, cost_samples=100, max_iter=20)
    result = design_payload_excitation(model, bounds=JointBounds.from_dict(json.loads(bounds.read_text())),
                                       robot_share="counted", settings=settings, starts=1)
    assert result.criterion.robot_cov is not None and result.criterion.size > 30  # the stacked information sum
    assert result.to_dict()["payload_design"]["criterion"]["counts"] == "record_noise+robot_model"
    designed = result.designed_std
    assert designed["robot_model"]["mass"] > 0 and result.warnings == () and result.constraints == ()
    assert designed["mass"] == pytest.approx(np.hypot(designed["record_noise"]["mass"], designed["robot_model"]["mass"]))


class _TwoRows:
    """A per-sample constraint of two rows (``1 − q₁² ≥ 0``, ``2 + dq₁ ≥ 0``), for the order of the rows."""

    name, unit, labels = "two_rows", "1", ("a", "b")

    def function(self):
        q, dq, ddq = (casadi.SX.sym(name, 6) for name in ("q", "dq", "ddq"))
        return casadi.Function("two_rows", [q, dq, ddq], [casadi.vertcat(1 - q[0] ** 2, 2 + dq[0])])

    def margins(self, q, dq, ddq):
        return np.column_stack([1 - np.asarray(q)[:, 0] ** 2, 2 + np.asarray(dq)[:, 0]])


def test_information_constraints_follow_the_pointwise_ones(robot_json):
    """PayloadDesign: the information constraints' rows come after the per-sample constraints' (torque limits here),
    their values those of RobotShareBound on the cost samples' information, and their multipliers are kept as they
    are when constraint points are added."""
    from estimation.identification.identified_model import IdentifiedModel
    from oed.design_settings import DesignSettings
    from oed.payload_design import PayloadDesign, RobotShareBound, payload_regressor

    folder, path, bounds = robot_json
    model = IdentifiedModel.load(path)
    settings = DesignSettings(frequency_hz=0.1, harmonics=3, cost_samples=60, constraint_points=10, jit=False)
    criterion = MassAndCentre(samples=settings.period_samples, robot_cov=model.cov)
    limits = JointBounds.from_dict(json.loads(bounds.read_text()))
    robot = model.robot
    probe = PayloadDesign(robot, model.file.model, limits, criterion, (), settings,
                          regressor=payload_regressor(model, 6, with_robot=True))
    x = probe.random_start(np.random.default_rng(4))
    reference = 1.5 * criterion.relative_variances(probe.cost_grid_information(x))[1]
    bound = RobotShareBound(criterion, reference)
    problem = PayloadDesign(robot, model.file.model, limits, MassAndCentre(samples=settings.period_samples), (),
                            settings, constraints=(_TwoRows(),),
                            regressor=payload_regressor(model, 6, with_robot=True), information_constraints=(bound,))
    points = problem.base_points()
    g = np.asarray(problem.nonlinear_function(points)(x)).ravel()
    pointwise = 2 * points.size
    assert g.size == pointwise + 4
    assert np.allclose(g[pointwise:], np.log(1.5), atol=1e-8)
    assert np.allclose(g[pointwise:], bound.margins(problem.cost_grid_information(x)), atol=1e-10)
    multipliers = np.arange(3 * robot.n_joints * points.size + g.size, dtype=float)
    extended = problem._extend_multipliers(multipliers, (), (3,))
    assert extended.size == multipliers.size + 3 * robot.n_joints + 2
    assert np.array_equal(extended[-4:], multipliers[-4:])
    with pytest.raises(ValueError, match="takes the information of"):
        PayloadDesign(robot, model.file.model, limits, MassAndCentre(), (), settings,
                      regressor=payload_regressor(model, 6), information_constraints=(bound,))


def test_a_mapped_output_found_once_is_the_output_casadi_gives():
    """oed.payload_design.design.evaluated: a sparse per-sample output mapped over samples, written into a dense array
    at the nonzero positions found once (nonzero_positions, read-only) or found at the call: both bit for bit the
    dense value CasADi gives."""
    from oed.payload_design.design import evaluated, nonzero_positions

    q, dq, ddq = (casadi.SX.sym(name, 2) for name in ("q", "dq", "ddq"))
    Y = casadi.SX(3, 4)  # structural zeros in every column but the last
    Y[0, 0], Y[1, 1], Y[2, 1] = casadi.sin(q[0]) * dq[1], q[1] * ddq[0], casadi.cos(dq[0])
    Y[:, 3] = casadi.vertcat(q[0], dq[1], ddq[1])
    mapped = casadi.Function("Y", [q, dq, ddq], [Y]).map(5)
    samples = [np.random.default_rng(seed).normal(size=(5, 2)) for seed in range(3)]
    expected = np.asarray(casadi.densify(mapped(*(values.T for values in samples))))
    positions = nonzero_positions(mapped)
    assert positions.size == mapped.sparsity_out(0).nnz() < expected.size and not positions.flags.writeable
    for given in (positions, None):
        assert np.array_equal(evaluated(mapped, *samples, positions=given), expected)
