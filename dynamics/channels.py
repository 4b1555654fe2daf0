"""The rows (channels) of an identification model, by name: the joint torques ``tau1..taun`` and the base wrench
``fx fy fz mx my mz`` (:func:`dynamics.models.channel_names` writes them; the internal model has the first, the
external the second, the combined both).

One place decides what a channel is, for every module that reads a model's channels, a result file's or a record's
columns: :func:`is_joint_torque` and :func:`torque_joint`.
"""

from __future__ import annotations

__all__ = ["WRENCH_CHANNELS", "is_joint_torque", "torque_joint"]

#: the base wrench's channels (the external model's rows), force then moment
WRENCH_CHANNELS: tuple[str, ...] = ("fx", "fy", "fz", "mx", "my", "mz")


def is_joint_torque(channel: str) -> bool:
    """Whether ``channel`` is a joint's torque, ``tau<k>`` with ``k`` written in digits (joint ``k``, counted from 1),
    and not a component of the base wrench (:data:`WRENCH_CHANNELS`) or any other name."""
    return channel.startswith("tau") and channel[3:].isdigit()


def torque_joint(channel: str) -> int:
    """The joint (0-based) whose torque ``channel`` is: ``k - 1`` for ``tau<k>``.

    Raises
    ------
    ValueError
        ``channel`` is not a joint torque (:func:`is_joint_torque`).
    """
    if not is_joint_torque(channel):
        raise ValueError(f"channel {channel!r} is not a joint torque (tau1, tau2, …)")
    return int(channel[3:]) - 1
