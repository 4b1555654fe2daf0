"""One rule for a model's channels (dynamics.channels): which are joint torques, and whose."""

import pytest

from dynamics import build_model, is_joint_torque, load_robot, torque_joint
from dynamics.channels import WRENCH_CHANNELS
from dynamics.models import ModelKind, channel_names


@pytest.mark.parametrize("kind", list(ModelKind))
def test_every_channel_a_model_has_is_told_apart(kind):
    """Against the names the models are built with: the torques of joints 1..n, in order, and the wrench's six."""
    robot = load_robot("puma560")
    channels = build_model(robot, kind, ()).channels
    assert channels == channel_names(robot, kind)
    torques = [channel for channel in channels if is_joint_torque(channel)]
    assert [torque_joint(channel) for channel in torques] == list(range(len(torques)))
    assert len(torques) == (0 if kind is ModelKind.EXTERNAL else robot.n_joints)
    assert [channel for channel in channels if not is_joint_torque(channel)] == (
        [] if kind is ModelKind.INTERNAL else list(WRENCH_CHANNELS))


def test_joint_numbers_of_more_than_one_digit():
    assert is_joint_torque("tau12") and torque_joint("tau12") == 11


@pytest.mark.parametrize("channel", ["tau", "taux", "tau_1", "tau1 ", "torque1", "fz", "mx", "q1", "Tau1"])
def test_other_names_are_not_joint_torques(channel):
    assert not is_joint_torque(channel)
    with pytest.raises(ValueError, match="not a joint torque"):
        torque_joint(channel)
