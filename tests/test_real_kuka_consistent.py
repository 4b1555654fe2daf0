"""Real data: consistent identification of the KUKA LWR4+ (FloBaRoID runs, ../shared/data/kuka_lwr4).

Identified on run 1 with viscous + Coulomb friction + offsets, validated on runs 2 and 3.
Unconstrained weighted least squares gives fv5, fv7 < 0 and is worse than the URDF's nominal
parameters on joints 3, 5, 6, 7 of run 3; the consistent estimate (no prior, or the URDF as a
prior of weight 1) has no negative friction, every link a rigid body, and beats nominal on every
joint of run 3. Without a prior the bodies sit on the boundary of the consistent set (pseudo-inertia
margins ~1e-10, M(q) nearly singular): too stiff to simulate; with the URDF prior they simulate.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from dynamics.models import build_model
from dynamics.robots import load_robot
from estimation.consistent.identification import identify_consistent
from estimation.consistent.simulation import (
    consistent_controller, consistent_robot, consistent_simulator, mass_matrix_eigenvalues, measured_reference,
)
from estimation.identification.fit import ImplausibleEstimateWarning, identify
from estimation.datasets.kuka import load_kuka_run
from estimation.identification.validation import compare
from tests.conftest import shared_data

pytestmark = pytest.mark.realdata
EFFECTS = "viscous,coulomb,offset"


@pytest.fixture(scope="module")
def kuka():
    folder = shared_data("kuka_lwr4")
    robot = load_robot(urdf=folder / "kuka_lwr4.urdf")
    runs = [load_kuka_run(folder / f"kuka_lwr4_HW_measurements_{index}.npz") for index in (1, 2, 3)]
    nominal = build_model(robot, "internal", "none")
    baseline = [np.array(list(compare(nominal, nominal.nominal_parameters(), run).mse.values())) for run in runs]
    model = build_model(robot, "internal", EFFECTS)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ImplausibleEstimateWarning)
        result = identify(model, runs[0], runs[2])
    return robot, runs, baseline, model, result


@pytest.mark.parametrize("prior_weight", [0.0, 1.0])
def test_consistent_kuka_has_no_negative_friction_real_bodies_and_beats_nominal_on_every_joint_of_run_3(kuka, prior_weight):
    robot, runs, baseline, model, result = kuka
    consistent = identify_consistent(result, runs[0], runs[2], prior_weight=prior_weight)
    estimate = consistent.estimate
    friction = {name: value for name, value in estimate.effect_values().items() if name.startswith(("fv", "fc"))}
    assert all(value >= 0 for value in friction.values()), friction
    assert np.all(estimate.margins > 0), estimate.margins
    unconstrained = np.array(list(result.validation.mse.values()))
    mse = np.array(list(consistent.validation.mse.values()))
    run2 = np.array(list(compare(model, estimate.values, runs[1]).mse.values()))
    print(f"\nKUKA run 3 MSE per joint (prior weight {prior_weight:g}, {estimate.solver['time_s']:.2f} s)\n"
          f"  nominal       {np.round(baseline[2], 3)}\n  unconstrained {np.round(unconstrained, 3)}\n"
          f"  consistent    {np.round(mse, 3)}\n  run 2 consistent {np.round(run2, 3)} nominal {np.round(baseline[1], 3)}")
    assert np.all(mse <= baseline[2]), np.round(mse / baseline[2], 3)
    assert np.all(run2 <= baseline[1]), np.round(run2 / baseline[1], 3)
    assert any(bound.startswith(("fv5", "fv7")) for bound in estimate.active_bounds)


def test_consistent_kuka_simulates_run_3_with_a_positive_definite_mass_matrix(kuka):
    robot, runs, _, model, result = kuka
    estimate = identify_consistent(result, runs[0], prior_weight=1.0).estimate
    identified = consistent_robot(model, estimate)
    assert mass_matrix_eigenvalues(identified, runs[2].q[::10]).min() > 0
    # the unconstrained estimate lifted to standard parameters (minimum-norm around the URDF) is no robot
    K, reference = model.base.K, model.nominal_parameters()
    lifted = reference + np.linalg.lstsq(K, result.estimate.values - K @ reference, rcond=None)[0]
    assert mass_matrix_eigenvalues(robot.with_parameters(lifted[:70]), runs[2].q[::10]).min() < 0
    simulation = consistent_simulator(model, estimate).run(
        measured_reference(runs[2]), consistent_controller(model, estimate), duration=2.0)
    assert np.all(np.isfinite(simulation.q))
    assert mass_matrix_eigenvalues(identified, simulation.q[::10]).min() > 0
    assert np.sqrt(np.mean(simulation.tracking_error**2)) < 0.05  # rad: computed torque tracks the run-3 motion
