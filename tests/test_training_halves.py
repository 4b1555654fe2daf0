"""A torque gain is a sensor's only when the training record's halves agree on it
(:mod:`estimation.consistent.training_halves`): a payload picked up halfway through the training record reads as a
gain on the torques the heavier arm loads, which the two halves fit at two values (h-payload20)."""

import numpy as np
import pytest

from dynamics.measurements import Measurements
from dynamics.models import build_model
from dynamics.robots import load_robot
from dynamics.urdf_export import robot_urdf
from estimation.consistent.training_halves import (PART_TOLERANCE, PARTS, TrainingHalves, gains_halves, part_answer,
                                               training_part)
from estimation.diagnosis.plain_laws import plain_model
from oed.fourier import random_fourier
from tests.test_outside_family_plants import motion_limits
from tests.test_unseen_robot_changes import with_payload
from tests.test_unseen_robots import FRICTION, NOISE, truth


def training(reality: str, folder, seconds: float = 10.0, rate: float = 250.0) -> tuple[object, Measurements]:
    """A 3-joint PUMA's Fourier training record (white noise 2 % of each channel's spread): ``"payload"``, 2 kg on
    the last link from the middle on; ``"sensor"``, joint 2's torque read 1.12x; ``"plain"``, neither."""
    urdf = folder / "robot.urdf"  # the description as the verbs read it (its bodies fix the gains' scale)
    urdf.write_text(robot_urdf(load_robot("puma560", joints=3)))
    robot = load_robot(urdf=urdf)
    model = build_model(robot, "internal", FRICTION)
    theta = truth(model)
    t = np.arange(0.0, seconds, 1.0 / rate)
    q, dq, ddq = random_fourier(motion_limits(robot), seed=11, frequency_hz=0.2).evaluate(t)
    tau = model.predict(theta, q, dq, ddq)
    if reality == "payload":
        later = t >= 0.5 * t[-1]
        tau[later] = model.predict(with_payload(model, theta, 2.0), q[later], dq[later], ddq[later])
    elif reality == "sensor":
        tau[:, 1] *= 1.12
    tau = tau + np.random.default_rng(3).normal(0.0, 1.0, tau.shape) * NOISE * tau.std(axis=0)
    return plain_model(build_model(robot, "internal", "viscous")), Measurements(t=t, q=q, dq=dq, ddq=ddq, tau=tau)


def test_the_halves_said_and_written():
    halves = TrainingHalves(("tau1", "tau2"), np.array([1.04, 1.0]), np.array([1.18, 1.01]), np.array([32.0, 1.0]),
                            np.array([6.6, 6.6]))
    assert halves.changed and halves.disagree.tolist() == [True, False]
    said = halves.message()
    assert "tau1 1.04 against 1.18" in said and "tau2" not in said and "the plant changed during training" in said
    written = halves.to_dict()
    assert written["changed"] and written["channels"]["tau1"]["disagree"] and not written["channels"]["tau2"]["disagree"]
    agreeing = TrainingHalves(("tau1",), np.array([1.04]), np.array([1.04]), np.array([0.3]), np.array([6.0]))
    assert not agreeing.changed and agreeing.message() is None


def test_a_record_too_short_for_the_blocks_is_not_checked(tmp_path):
    model, record = training("plain", tmp_path, seconds=2.0, rate=250.0)  # 500 samples: blocks of 62
    assert gains_halves(model, record) is None


@pytest.mark.parametrize("reality, changed", [("payload", True), ("sensor", False)])
def test_a_payload_picked_up_halfway_splits_the_halves_a_sensors_gain_does_not(reality, changed, tmp_path):
    model, record = training(reality, tmp_path, seconds=4.0)  # 1000 samples: 8 blocks of 125
    halves = gains_halves(model, record)
    assert halves is not None and halves.changed == changed, halves
    if changed:  # the loaded half's gain the higher
        assert np.all(halves.second[halves.disagree] > halves.first[halves.disagree])


def test_a_half_answers_only_when_it_validates_better_beyond_the_tolerance():
    # the whole record's answer validating 1.2, the second half's 0.2: the second half's taken, the scores said
    fitted_on, why = part_answer({"whole": 1.2, "first half": 1.5, "second half": 0.2})
    assert fitted_on == "second half" and "second half's 0.2" in why and "1.2 for the whole record's" in why
    # within the tolerance (a tie keeps the whole record's)
    fitted_on, why = part_answer({"whole": 1.0, "first half": 1.0 / (1.0 + PART_TOLERANCE), "second half": 3.0})
    assert fitted_on == "whole" and "fitted on the whole training record" in why
    # nothing compared (not both chosen on a validation record of another motion): the whole record's, unsaid
    assert part_answer({"whole": None, "first half": 0.5, "second half": None}) == ("whole", "")


def test_the_training_parts_are_its_halves_and_nothing_else(tmp_path):
    t = np.arange(0.0, 1.0, 0.01)
    record = Measurements(t=t, q=np.zeros((t.size, 2)), tau=np.zeros((t.size, 2)))
    first, second = (training_part(record, part) for part in PARTS)
    assert np.array_equal(np.concatenate([first.t, second.t]), t) and first.n_samples == 50
    with pytest.raises(ValueError, match="part must be one of"):
        training_part(record, "third half")
