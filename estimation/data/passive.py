"""Passive (unactuated) joints in a log: their torque is zero by physics.

A joint that no motor drives (a Pendubot's or Acrobot's free joint, a cable-driven arm's passive wrist, a gimbal,
an axis whose brake is released) has ``τ_j = 0`` at every sample: its row of the inverse dynamics,
``0 = Y_j(q, q̇, q̈) θ`` (its own friction in ``Y_j``), is an equation of the fit like any measured torque, one that
makes parameters of the bodies it couples identifiable (the free joint's equation of motion: Spong, *Underactuated
mechanical systems*, 1998). The log has no torque column for it, or one the toolkit does not read:
the column is the zero the physics gives (:func:`with_passive_torques`), in memory and streamed alike, so that every
verb (the fit, the errors, ``oed predict``) reads it as any torque channel.

A driven joint whose torque is not logged is another thing (its torque is unknown, not zero): it is not passive, and
naming it so would fit a wrong equation. The toolkit refuses a missing torque column and names both readings
(:func:`estimation.data.loading.require_columns`).
"""

from __future__ import annotations

import warnings

import numpy as np
import pandas as pd

__all__ = ["PassiveJointWarning", "floored_variance", "passive_channels", "with_passive_torques"]


class PassiveJointWarning(UserWarning):
    """A passive joint's logged torque column is not read (its torque is zero by physics), or the description's joint
    without a motor was read as passive because the log has no torque column for it."""


def passive_channels(model) -> tuple[str, ...]:
    """The torque channels (``tau3``…) of ``model``'s robot's passive joints; none for another kind of model."""
    robot = getattr(model, "robot", None)
    joints = getattr(robot, "joints", ())
    return tuple(f"tau{index + 1}" for index, joint in enumerate(joints) if not getattr(joint, "actuated", True))


def with_passive_torques(frame: pd.DataFrame, model, source: str) -> pd.DataFrame:
    """``frame`` with each passive joint's torque column ``tau{j}`` set to 0 (added where it is absent), when the
    frame holds the torques of the other joints (a positions-only log stays one). A passive joint's column that the
    log holds with values other than 0 is not read, and a :class:`PassiveJointWarning` says so (its mean and spread):
    the joint's torque is zero by physics, and a sensor on a free joint reads its own bias and noise."""
    channels = passive_channels(model)
    if not channels:
        return frame
    n_joints = len(model.robot.joints)
    others = [f"tau{j + 1}" for j in range(n_joints) if f"tau{j + 1}" not in channels]
    if others and not any(column in frame.columns for column in others):
        return frame
    logged = [column for column in channels if column in frame.columns]
    read = [column for column in logged if (pd.to_numeric(frame[column], errors="coerce").fillna(0.0) != 0.0).any()]
    if read:
        warnings.warn(
            f"{source}: column(s) {', '.join(read)} of the passive joint(s) not read: a passive joint's torque is zero "
            "by physics (its friction is in the model); the fit takes 0 = Y_j θ for it", PassiveJointWarning,
            stacklevel=4)
    frame = frame.copy()
    for column in channels:
        frame[column] = 0.0
    return frame



def floored_variance(variance, floor, zero):
    """Each channel's residual variance for a weighted fit's weight ``1/σ²``: at least its ``floor`` (a noise-free
    channel's weight kept finite), and for a channel of zeros (``zero``: a passive joint's torque) at least the
    smallest variance of the channels that carry a torque. A passive joint's zero has no sensor noise, but its
    equation ``0 = Y_j θ`` holds only up to the derivatives' and the model's errors, and it is homogeneous: a weight
    without bound would let the iterated fit meet it by parameters near zero (the bodies it shares with the other
    rows collapsed, their torques the worse). It is trusted as much as the most precise torque sensor of the robot,
    never more. Without a channel of zeros: ``numpy.maximum(variance, floor)``, bit for bit."""
    floored = np.maximum(variance, floor)
    zero = np.asarray(zero, dtype=bool)
    if zero.any() and (~zero).any():
        floored[zero] = np.maximum(floored[zero], np.min(floored[~zero]))
    return floored
