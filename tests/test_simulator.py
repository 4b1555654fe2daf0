"""The simulated robot: dynamic consistency, effects on the right channels, sensors, reproducibility."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from dynamics.effects import linear as model_effects
from dynamics.simulation.controllers import PDController, RegressorInverseDynamics
from dynamics.models import build_model
from dynamics.pinocchio_bridge import to_pinocchio
from dynamics.robots import load_robot
from dynamics.simulation.effects import (
    SimulatedArmature, Coulomb, Offset, PlateCable, PlateOffset, SimulatedSpring, Viscous, effects_from_names, puma560_link_friction,
)
from dynamics.simulation.sensors import encoder_resolution
from dynamics.simulation.simulator import NoiseModel, Simulator, simulate_controlled
from oed.fourier import FourierTrajectory


@pytest.fixture(scope="module")
def robot():
    return load_robot("puma560", joints=3)


@pytest.fixture(scope="module")
def trajectory():
    """Random small coefficients: |dq| < 1 rad/s on the 3 PUMA joints, 5 harmonics of 0.2 Hz."""
    generator = np.random.default_rng(7)
    return FourierTrajectory(0.2, generator.uniform(-0.2, 0.2, 3), generator.uniform(-0.12, 0.12, (3, 5)),
                             generator.uniform(-0.12, 0.12, (3, 5)))


def test_trajectory_fixture_is_gentle(trajectory):
    _, _, dq, _ = trajectory.sample(1000)
    assert np.abs(dq).max() < 1.0


def test_default_puma_friction_is_corke_motor_data_reflected_through_the_gears():
    values = puma560_link_friction(3)
    np.testing.assert_allclose(values["viscous"], [5.80, 9.50, 3.98], atol=0.01)
    np.testing.assert_allclose(values["coulomb"], [0.415 * 62.6111, 0.0985 * 107.815, 0.1185 * 53.7063])
    np.testing.assert_allclose(values["armature"], [200e-6 * 62.6111**2, 200e-6 * 107.815**2, 200e-6 * 53.7063**2])


def test_recorded_torques_equal_the_model_prediction_at_the_true_states(robot, trajectory):
    simulator = Simulator(robot, (Viscous.default(robot), Coulomb.default(robot), Offset.default(robot),
                                  SimulatedArmature.default(robot)), noise=NoiseModel.none())
    result = simulator.run(trajectory, duration=2.0)
    model = build_model(robot, "internal", ("viscous", model_effects.CoulombFriction(smoothing=0.05), "offset", "armature"))
    predicted = model.predict(simulator.true_theta(model), result.q, result.dq, result.ddq)
    np.testing.assert_allclose(predicted, result.tau, atol=1e-8 * np.abs(result.tau).max())
    # the record is a solution of the ODE: its velocity integrates to its position (trapezoid rule,
    # error h³/12 · jerk; the acceleration jumps at the samples, where the held torque changes)
    h = 1e-3
    np.testing.assert_allclose(np.diff(result.q, axis=0), h * (result.dq[1:] + result.dq[:-1]) / 2, atol=1e-7)


def test_integration_has_converged_at_one_step_per_sample(robot, trajectory):
    effects = "coulomb,armature"
    coarse = Simulator(robot, effects, noise=NoiseModel.none()).run(trajectory, duration=2.0)
    fine = Simulator(robot, effects, noise=NoiseModel.none(), substeps=8).run(trajectory, duration=2.0)
    assert np.abs(coarse.q - fine.q).max() < 1e-8  # far below the encoder resolution (~2e-6 rad)


def test_wrench_is_the_rigid_body_base_wrench_friction_is_internal(robot, trajectory):
    simulator = Simulator(robot, "coulomb,offset", noise=NoiseModel.none())
    result = simulator.run(trajectory, duration=2.0)
    external = build_model(robot, "external", ())
    predicted = external.predict(simulator.true_theta(external), result.q, result.dq, result.ddq)
    np.testing.assert_allclose(result.wrench, predicted, atol=1e-8 * np.abs(predicted).max())


def test_robot_held_still_reads_its_weight(robot):
    q0 = np.array([0.3, -0.4, 0.5])
    still = FourierTrajectory(0.5, q0, np.zeros((3, 1)), np.zeros((3, 1)))
    simulator = Simulator(robot, noise=NoiseModel.none())
    model = build_model(robot, "internal")
    gravity = RegressorInverseDynamics(model, tuple(simulator.true_theta(model)))
    result = simulator.run(still, PDController([100.0] * 3, [10.0] * 3, gravity=gravity))
    np.testing.assert_allclose(result.q, np.tile(q0, (result.t.shape[0], 1)), atol=1e-12)
    pinocchio_model = to_pinocchio(robot)
    data = pinocchio_model.createData()
    com = pin.centerOfMass(pinocchio_model, data, q0)
    mass = sum(joint.inertial[0] for joint in robot.joints)
    weight = mass * 9.81
    expected = np.array([0.0, 0.0, weight, com[1] * weight, -com[0] * weight, 0.0])
    np.testing.assert_allclose(result.wrench, np.tile(expected, (result.t.shape[0], 1)), atol=1e-9)


def _residuals(robot, trajectory, effects):
    simulator = Simulator(robot, (Viscous.default(robot), *effects), noise=NoiseModel.none())
    result = simulator.run(trajectory, duration=2.0)
    internal, external = build_model(robot, "internal"), build_model(robot, "external", ())
    tau = result.tau - internal.predict(simulator.true_theta(internal), result.q, result.dq, result.ddq)
    wrench = result.wrench - external.predict(simulator.true_theta(external), result.q, result.dq, result.ddq)
    return result, np.abs(tau).max(axis=0), np.abs(wrench).max(axis=0)


@pytest.mark.parametrize(
    ("effect", "tau_rows", "wrench_rows"),
    [
        (Coulomb((3.0, 2.0, 1.0)), [0, 1, 2], []),
        (Offset((0.0, 1.5, 0.0)), [1], []),
        (SimulatedSpring(joints=(1,), stiffness=(5.0,), q_ref=(0.4,)), [0], []),
        (PlateOffset(("mz",), (2.0,)), [], [5]),
        (PlateCable(joint=1, stiffness=3.0, q_ref=0.1, channel="mx"), [], [3]),
    ],
    ids=["coulomb", "offset", "spring", "plate_moment", "cable"],
)
def test_effects_appear_on_their_channels_only(robot, trajectory, effect, tau_rows, wrench_rows):
    _, tau_residual, wrench_residual = _residuals(robot, trajectory, (effect,))
    floor = 1e-8
    assert np.all(tau_residual[tau_rows] > 0.1) and np.all(wrench_residual[wrench_rows] > 0.1)
    assert np.all(np.delete(tau_residual, tau_rows) < floor)
    assert np.all(np.delete(wrench_residual, wrench_rows) < floor)


def test_plate_effects_have_their_true_values(robot, trajectory):
    cable = PlateCable(joint=1, stiffness=3.0, q_ref=0.1, channel="mx")
    result, _, _ = _residuals(robot, trajectory, (cable, PlateOffset(("mz",), (2.0,))))
    plate = result.wrench - result.wrench_rigid_body
    np.testing.assert_allclose(plate[:, 3], 3.0 * (result.q[:, 0] - 0.1), atol=1e-12)
    np.testing.assert_allclose(plate[:, 5], 2.0)


def test_pd_tracks_and_computed_torque_with_true_parameters_tracks_far_better(robot, trajectory):
    from dynamics.simulation.controllers import ComputedTorqueController, computed_torque_gains

    simulator = Simulator(robot, "coulomb,armature", noise=NoiseModel.none())
    pd = simulator.run(trajectory, duration=3.0)
    model = build_model(robot, "internal", ("viscous", model_effects.CoulombFriction(smoothing=0.05), "armature"))
    kp, kd = computed_torque_gains(n_joints=3)
    controller = ComputedTorqueController.from_model(model, simulator.true_theta(model), kp=kp, kd=kd)
    computed = simulator.run(trajectory, controller, duration=3.0)
    pd_error, ct_error = np.abs(pd.tracking_error).max(), np.abs(computed.tracking_error).max()
    assert 1e-4 < pd_error < 0.05
    # a perfect model leaves the error of holding the torque over each 1 ms sample (O(h): ~0.1 mrad)
    assert ct_error < pd_error / 50


def test_seeds_reproduce_and_noise_has_the_requested_level(robot, trajectory):
    noise = NoiseModel(tau_std=0.3, wrench_std=(1.0, 1.0, 1.0, 0.2, 0.2, 0.2), q_resolution=None)
    simulator = Simulator(robot, noise=noise)
    first, again = (simulator.run(trajectory, duration=2.0, seed=11) for _ in range(2))
    other = simulator.run(trajectory, duration=2.0, seed=12)
    np.testing.assert_array_equal(first.measurements.tau, again.measurements.tau)
    np.testing.assert_array_equal(first.measurements.wrench, again.measurements.wrench)
    assert not np.allclose(first.measurements.tau, other.measurements.tau)
    np.testing.assert_allclose((first.measurements.tau - first.tau).std(axis=0), 0.3, rtol=0.1)
    np.testing.assert_allclose((first.measurements.wrench - first.wrench).std(axis=0), noise.wrench_std, rtol=0.1)
    assert first.metadata["seed"] == 11 and first.metadata["true_parameters"]["fv2"] == pytest.approx(9.4969, abs=1e-3)


def test_positions_are_quantised_to_the_encoder_resolution(robot, trajectory):
    result = Simulator(robot).run(trajectory, duration=1.0, seed=0)
    resolution = encoder_resolution(robot)
    np.testing.assert_allclose(resolution, 2 * np.pi / (4 * 4096 * np.array([62.6111, 107.815, 53.7063])))
    counts = result.measurements.q / resolution
    np.testing.assert_allclose(counts, np.round(counts), atol=1e-6)
    assert np.all(np.abs(result.measurements.q - result.q) <= resolution / 2 + 1e-15)
    assert np.abs(result.measurements.q - result.q).max() > resolution.min() / 10  # not left exact


def test_derivatives_are_written_only_when_asked(robot, trajectory):
    plain = simulate_controlled(robot, trajectory, periods=1, seed=0)
    assert plain.dq is None and plain.ddq is None and plain.tau.shape == (5000, 3) and plain.wrench.shape == (5000, 6)
    simulator = Simulator(robot)
    full = simulator.run(trajectory, duration=1.0, with_derivatives=True, seed=0)
    np.testing.assert_array_equal(full.measurements.dq, full.dq)
    np.testing.assert_array_equal(full.measurements.ddq, full.ddq)


def test_whole_periods_record_the_frequency_for_the_fourier_fit(robot, trajectory):
    from estimation.identification.fit import identify
    from estimation.preprocessing.differentiation import FourierDifferentiation, fill_derivatives

    periodic = simulate_controlled(robot, trajectory, periods=1, seed=0)
    assert periodic.metadata["frequency_hz"] == pytest.approx(0.2) and periodic.metadata["harmonics"] == 5
    assert fill_derivatives(periodic).metadata["differentiation"] == "fourier"
    # why three times the reference's harmonics: the tracking error adds harmonics above them, and a
    # fit with the reference's own count leaves the estimates many standard deviations off
    generator = np.random.default_rng(8)
    reference = FourierTrajectory(0.5, np.zeros(3), generator.uniform(-0.5, 0.5, (3, 3)), generator.uniform(-0.5, 0.5, (3, 3)))
    simulator = Simulator(robot)
    record = simulator.run(reference, periods=4, warmup_periods=1, seed=5).measurements
    model = build_model(robot, "internal", "viscous")
    truth = model.base.to_base(simulator.true_theta(model))
    largest = {}
    for label, method in (("reference's 3", FourierDifferentiation(0.5, 3)), ("default", None)):
        filled = fill_derivatives(record, method, held_torques=True)
        estimate = identify(model, filled).estimate
        largest[label] = np.max(np.abs(estimate.values - truth) / estimate.std)
    assert len(filled.metadata["fourier_fit"]["a"][0]) == 9
    assert largest["reference's 3"] > 6 and largest["default"] < 4, largest  # measured: 9.9 and 1.9
    cut = Simulator(robot).run(trajectory, duration=1.0, seed=0).measurements
    assert cut.metadata["frequency_hz"] is None
    assert fill_derivatives(cut).metadata["differentiation"] == "butterworth"


def test_warmup_starts_the_record_in_the_periodic_steady_state(robot):
    fast = FourierTrajectory(1.0, np.zeros(3), np.full((3, 2), 0.1), np.full((3, 2), -0.1))
    simulator = Simulator(robot, noise=NoiseModel.none())
    result = simulator.run(fast, periods=1, warmup_periods=3)
    assert result.t[0] == 0.0 and result.t.shape == (1000,)
    # one period later the state repeats: compare the record's start with its extrapolated end
    following = simulator.run(fast, periods=1, warmup_periods=4)
    np.testing.assert_allclose(result.q, following.q, atol=1e-6)


@pytest.mark.parametrize(
    ("make", "message"),
    [
        (lambda robot: Simulator(robot, "magnets"), "unknown effect 'magnets'"),
        (lambda robot: Simulator(robot, (Coulomb((1.0, 2.0)),)), "2 values for a robot of 3 joints"),
        (lambda robot: Simulator(robot, theta=(1.0,) * 10), "30 finite standard parameters"),
        (lambda robot: Simulator(robot, (SimulatedSpring(joints=(4,)),)), "joint 4 outside 1..3"),
        (lambda robot: effects_from_names("coulomb", robot, {"cable": 2.0}), "not simulated"),
        (lambda robot: NoiseModel(tau_std=-1.0), "tau_std"),
        (lambda robot: PlateOffset(("mq",), (1.0,)), "channels"),
        (lambda robot: Viscous((-5.0, 1.0, 1.0)), "viscous values must be non-negative"),
        (lambda robot: Simulator(robot, (Viscous(()),)), "0 values for a robot of 3 joints"),
        (lambda robot: Simulator(robot, rate_hz=float("inf")), "rate_hz must be a positive finite number"),
        (lambda robot: Simulator(robot, (Coulomb((1e308,) * 3),)).substeps_needed(), "friction is too stiff"),
        (lambda robot: Simulator(robot, rate_hz=1e-3).run(
            FourierTrajectory(0.2, np.zeros(3), np.zeros((3, 1)), np.zeros((3, 1)))), "gives 0 sample"),
    ],
)
def test_bad_settings_raise_clear_errors(robot, make, message):
    with pytest.raises(ValueError, match=message):
        make(robot)


def test_trajectory_with_the_wrong_joint_count_is_refused(robot):
    other = FourierTrajectory(0.2, np.zeros(4), np.zeros((4, 1)), np.zeros((4, 1)))
    with pytest.raises(ValueError, match="trajectory has 4 joints, the robot 3"):
        Simulator(robot).run(other)


def test_unstable_gains_report_divergence(robot, trajectory):
    with pytest.raises(RuntimeError, match="diverged"):
        Simulator(robot).run(trajectory, PDController([1e8] * 3, [1e6] * 3), duration=1.0)


def test_stiff_friction_on_a_light_joint_gets_more_integration_steps():
    servo = load_robot("servo_arm")
    light = Simulator(servo, (Viscous((0.01,) * 4), Coulomb((0.05,) * 4)), noise=NoiseModel.none())
    assert light.substeps_needed() > 1
    middle = (servo.lower + servo.upper) / 2
    still = FourierTrajectory(1.0, middle, np.full((4, 1), 0.2), np.zeros((4, 1)))
    result = light.run(still, duration=0.5)
    reference = Simulator(servo, light.effects, noise=NoiseModel.none(), substeps=4 * light.substeps_needed())
    np.testing.assert_allclose(result.q, reference.run(still, duration=0.5).q, atol=1e-7)
    assert result.metadata["integrator"].endswith(f"{light.substeps_needed()} substep(s) per sample")


def test_simulated_effects_keeps_its_public_names_after_the_split():
    """``dynamics.simulation.effects`` is the catalogue; the effects live in a joint and a plate module."""
    import dynamics.simulation.effects as catalogue
    import dynamics.simulation.joint_effects as joint
    import dynamics.simulation.plate_effects as plate

    for name in catalogue.__all__:
        assert hasattr(catalogue, name), name
    assert catalogue.Coulomb is joint.Coulomb and catalogue.PlateCable is plate.PlateCable
    assert set(catalogue.SIMULATED_EFFECTS) == {
        "viscous", "coulomb", "offset", "armature", "spring", "plate_offset", "plate_moment", "cable"}
    assert all(cls.__module__ == joint.__name__ for cls in joint.JOINT_EFFECTS)
    assert catalogue.is_plate_effect(plate.PlateOffset()) and not catalogue.is_plate_effect(joint.Viscous((1.0,)))
    assert all(cls.__module__ == plate.__name__ for cls in plate.PLATE_EFFECTS)


def test_a_massless_chain_and_a_too_coarse_encoder_are_named(robot, trajectory, tmp_path):
    massless = tmp_path / "massless.urdf"
    massless.write_text(
        '<robot name="r"><link name="base"/><link name="a"><inertial><mass value="0"/>'
        '<inertia ixx="0" ixy="0" ixz="0" iyy="0" iyz="0" izz="0"/></inertial></link>'
        '<joint name="j1" type="revolute"><parent link="base"/><child link="a"/><axis xyz="0 0 1"/>'
        '<limit lower="-1" upper="1" effort="1" velocity="1"/></joint></robot>')
    one_joint = FourierTrajectory(0.2, np.zeros(1), np.full((1, 1), 0.1), np.zeros((1, 1)))
    with pytest.raises(ValueError, match="mass matrix is singular"):  # was "diverged… lower the gains"
        Simulator(load_robot(urdf=massless), effects="none").run(one_joint, seed=0)
    with pytest.raises(ValueError, match="position resolution 10 of joint 1 is coarser than its motion"):
        Simulator(robot, noise=NoiseModel(q_resolution=10.0)).run(trajectory, duration=1.0, seed=0)
