"""Inverse-dynamics control with an identified model (PUMA paper, Figs. 10–12), simulated."""

from __future__ import annotations

import matplotlib

matplotlib.use("Agg")

import numpy as np
import pinocchio as pin
import pytest

from dynamics.simulation.controllers import ComputedTorqueController, RegressorInverseDynamics, computed_torque_gains, pd_gains
from dynamics.models import build_model
from dynamics.pinocchio_bridge import to_pinocchio
from dynamics.robots import load_robot
from dynamics.simulation.simulator import NoiseModel, Simulator
from oed.control import compare_controllers, tracking_experiment
from oed.fourier import FourierTrajectory
from tests.conftest import random_states


@pytest.fixture(scope="module")
def robot():
    return load_robot("puma560", joints=3)


@pytest.fixture(scope="module")
def trajectory():
    generator = np.random.default_rng(3)
    return FourierTrajectory(0.2, np.zeros(3), generator.uniform(-0.15, 0.15, (3, 5)), generator.uniform(-0.15, 0.15, (3, 5)))


@pytest.fixture(scope="module")
def true_robot(robot):
    """The 'real' PUMA: links 2 and 3 heavier/lighter than the catalogue (a physically valid change)."""
    theta = robot.standard_parameters * np.repeat([1.0, 1.25, 0.8], 10)
    return Simulator(robot, theta=tuple(theta), noise=NoiseModel(tau_std=0.2, q_resolution=None))


def test_regressor_inverse_dynamics_matches_pinocchio_rnea_plus_viscous_friction(robot):
    model = build_model(robot, "internal")
    fv = np.array([5.8, 9.5, 3.98])
    inverse_dynamics = RegressorInverseDynamics(model, tuple(model.nominal_parameters(viscous=fv)))
    pinocchio_model = to_pinocchio(robot)
    data = pinocchio_model.createData()
    for q, dq, ddq in zip(*random_states(3, 5, seed=1)):
        expected = pin.rnea(pinocchio_model, data, q, dq, ddq) + fv * dq
        np.testing.assert_allclose(inverse_dynamics(q, dq, ddq), expected, rtol=1e-10, atol=1e-10)


def test_base_and_standard_parameters_give_the_same_control_torque(robot):
    model = build_model(robot, "combined")  # joint rows of the combined model work too
    theta = model.nominal_parameters(viscous=[5.8, 9.5, 3.98])
    standard = RegressorInverseDynamics(model, tuple(theta))
    base = RegressorInverseDynamics(model, tuple(model.base.to_base(theta)))
    assert base.is_base and not standard.is_base
    for q, dq, ddq in zip(*random_states(3, 4, seed=2)):
        np.testing.assert_allclose(base(q, dq, ddq), standard(q, dq, ddq), rtol=1e-9, atol=1e-9)


def test_inverse_dynamics_refuses_a_parameter_vector_of_the_wrong_length(robot):
    model = build_model(robot, "internal")
    with pytest.raises(ValueError, match="theta has 5 values"):
        RegressorInverseDynamics(model, (1.0,) * 5)
    with pytest.raises(ValueError, match="no joint-torque rows"):
        external = build_model(robot, "external")
        RegressorInverseDynamics(external, tuple(external.nominal_parameters()))


def _identify(simulator, trajectory, model):
    """Least squares on the base regressor at the true states (the real estimators live elsewhere)."""
    experiment = simulator.run(trajectory, with_derivatives=True, seed=5)
    data = experiment.measurements
    Y = model.evaluate_base(data.q, data.dq, data.ddq).reshape(-1, model.n_base)
    theta, *_ = np.linalg.lstsq(Y, data.tau.reshape(-1), rcond=None)
    return theta


def test_identified_model_tracks_far_better_than_nominal_model_and_pd(robot, trajectory, true_robot):
    model = build_model(robot, "internal")
    theta_hat = _identify(true_robot, trajectory, model)
    # a random (not optimised) trajectory excites some base parameters poorly, but the fit predicts
    # the noiseless torques of a validation run well below the 0.2 N·m noise
    validation = true_robot.run(trajectory, duration=2.0, with_derivatives=True, seed=6)
    predicted = model.predict(theta_hat, validation.q, validation.dq, validation.ddq)
    assert np.sqrt(np.mean((predicted - validation.tau) ** 2)) < 0.05
    comparison = compare_controllers(true_robot, trajectory, model, theta_hat)
    pd, nominal, identified = (comparison[label].max_error.max() for label in
                               ("PD", "computed torque, nominal", "computed torque, identified"))
    assert identified < nominal / 10 and identified < pd / 10
    assert identified < 1e-3  # rad: the paper's Fig. 12 shows mrad-level errors on joint 1
    table = comparison.table()
    assert "computed torque, identified" in table and len(table.splitlines()) == 4
    figure = comparison.figure()
    assert len(figure.axes) == 6


def test_tracking_result_reports_max_and_rms_error_per_joint(robot, trajectory):
    simulator = Simulator(robot, noise=NoiseModel.none())
    kp, kd = pd_gains(robot)
    from dynamics.simulation.controllers import PDController

    result = tracking_experiment(simulator, trajectory, PDController(kp, kd), label="PD")
    error = result.q - result.q_desired
    np.testing.assert_allclose(result.max_error, np.abs(error).max(axis=0))
    np.testing.assert_allclose(result.rms_error, np.sqrt((error**2).mean(axis=0)))
    assert np.all(result.rms_error <= result.max_error) and result.summary()["label"] == "PD"


def test_computed_torque_gains_shape_the_error_dynamics(robot, trajectory):
    """With the true model, a higher bandwidth tracks better (the error obeys ë + Kd ė + Kp e ≈ 0)."""
    simulator = Simulator(robot, noise=NoiseModel.none())
    model = build_model(robot, "internal")
    theta = simulator.true_theta(model)
    initial = trajectory.evaluate([0.0])
    start = (initial[0][0] + 0.01, initial[1][0])  # start 10 mrad off the reference
    errors = []
    for bandwidth in (2.0, 8.0):
        kp, kd = computed_torque_gains(bandwidth_hz=bandwidth, n_joints=3)
        controller = ComputedTorqueController.from_model(model, theta, kp=kp, kd=kd)
        result = simulator.run(trajectory, controller, duration=0.5, initial_state=start)
        errors.append(np.abs(result.tracking_error[-1]).max())
    assert errors[1] < errors[0] / 10


def test_fast_single_state_call_equals_the_mapped_evaluation(robot):
    model = build_model(robot, "internal")
    inverse_dynamics = RegressorInverseDynamics(model, tuple(model.nominal_parameters(viscous=1.0)))
    q, dq, ddq = random_states(3, 6, seed=9)
    one_by_one = np.array([inverse_dynamics(*state) for state in zip(q, dq, ddq)])
    np.testing.assert_allclose(one_by_one, inverse_dynamics.evaluate(q, dq, ddq), rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(one_by_one, model.predict(inverse_dynamics.theta, q, dq, ddq), rtol=1e-10, atol=1e-10)
