"""The friction drift check (:mod:`estimation.identification.friction_drift`) against simulated truths: a simulated
PUMA 560 (6 joints, exact derivatives, white torque noise of 2 % of each channel's spread), the training record and a
validation record of another motion. The check must find a friction scale the truth puts on the validation record,
within its standard error, and mark nothing where friction holds: the plain class, and a friction law the model does
not hold (a Stribeck bump at low speed), whose fitted scale moves from one motion to the next with no change in time
(h-drift)."""

from __future__ import annotations

import numpy as np
import pytest

from dynamics.measurements import Measurements
from dynamics.models import build_model
from dynamics.robots import load_robot
from estimation.identification.friction_drift import check_friction_drift, drift_z
from oed.fourier import random_fourier
from tests.test_unseen_robots import FRICTION, NOISE, truth


def records(scale: float, law: str = "") -> tuple[object, Measurements, Measurements]:
    """The model fitted (the plain class) and the training (10 s) and validation (4 s) records at 250 Hz, the
    validation record's viscous and Coulomb friction multiplied by ``scale``; ``law``: an effect of the truth
    beyond the model's."""
    robot = load_robot("puma560", joints=6)
    model = build_model(robot, "internal", FRICTION)
    truth_model = build_model(robot, "internal", f"{FRICTION},{law}" if law else FRICTION)
    theta = truth(truth_model)
    names = list(truth_model.parameter_names)
    if law:
        theta[[names.index(f"fs{j}") for j in range(1, 7)]] = np.linspace(1.0, 2.0, 6)
    friction = [index for index, name in enumerate(names) if name[:2] in ("fv", "fc", "fs") and name[2:].isdigit()]
    made = []
    for seed, seconds, factor in ((11, 10.0, 1.0), (12, 4.0, scale)):
        t = np.arange(0.0, seconds, 0.004)
        q, dq, ddq = random_fourier(robot, seed=seed, frequency_hz=0.2).evaluate(t)
        scaled = theta.copy()
        scaled[friction] *= factor
        tau = truth_model.predict(scaled, q, dq, ddq)
        tau = tau + np.random.default_rng(seed).normal(0.0, 1.0, tau.shape) * NOISE * tau.std(axis=0)
        made.append(Measurements(t, q, dq, ddq, tau, None, {}))
    return model, *made


@pytest.mark.parametrize("scale", [0.8, 1.15])
def test_a_friction_that_drifts_between_the_records_is_found_on_every_joint(scale):
    model, train, validation = records(scale)
    drift = check_friction_drift(model, train, validation)
    print(f"\nscale {drift.scale.round(4)} ± {drift.std.round(4)}")
    assert drift.marked.all()
    assert np.all(np.abs(drift.scale - scale) < 4.0 * drift.std), (drift.scale, drift.std)
    message = drift.message()
    assert f"{abs(1.0 - scale):.0%} {'lower' if scale < 1.0 else 'higher'}" in message
    assert ("warming" in message) == (scale < 1.0)
    assert np.all(drift.refitted_mse < drift.held_mse)  # the validation's own friction predicts its other half better
    document = drift.to_dict()
    assert set(document["joints"]) == set(model.robot.joint_names) and document["z_limit"] == drift_z(6)


@pytest.mark.parametrize("law", ["", "stribeck"])
def test_no_drift_is_said_where_friction_holds_even_with_a_law_the_model_lacks(law):
    model, train, validation = records(1.0, law)
    drift = check_friction_drift(model, train, validation)
    print(f"\n{law or 'plain'}: scale {drift.scale.round(4)} ± {drift.std.round(4)} (sampling "
          f"{drift.sampling.round(4)}, between motions {drift.between.round(4)})")
    assert not drift.marked.any() and drift.message() is None


def test_nothing_to_check_without_a_validation_record_or_friction():
    model, train, _ = records(1.0)
    assert check_friction_drift(model, train, None) is None
    rigid = build_model(model.robot, "internal", "offset")
    assert check_friction_drift(rigid, train, train) is None
