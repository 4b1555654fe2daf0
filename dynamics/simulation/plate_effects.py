"""The true force-plate effects of a simulated robot: constant offsets and a cable's pull.

They act on the force-plate reading only (a moment from tightened screws, a cable pulling on
the plate), not on the robot's motion::

    wrench_measured = wrench_rigid_body(q, dq, ddq) + Σ plate_wrench(q)

Each is a small frozen dataclass naming its wrench channels and true values, like the joint
effects of :mod:`dynamics.simulation.joint_effects`.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import ClassVar

import numpy as np
from numpy.typing import NDArray

from dynamics.effects import linear as model_effects
from dynamics.channels import WRENCH_CHANNELS
from dynamics.robot import RobotModel
from dynamics.simulation.joint_effects import finite_floats

@dataclass(frozen=True)
class PlateOffset:
    """Constant offsets of force-plate channels (N, N·m): tightened screws, sensor bias.

    Wrench rows only; modelled by :class:`dynamics.effects.linear.WrenchOffset` on the same channels.
    The default of ``plate_moment`` is a moment of 2 N·m about z (the screws of the PUMA paper).
    """

    channels_: tuple[str, ...] = ("mz",)
    values: tuple[float, ...] = (2.0,)
    name: ClassVar[str] = "plate_offset"

    def __post_init__(self) -> None:
        channels = tuple(self.channels_)
        unknown = [channel for channel in channels if channel not in WRENCH_CHANNELS]
        if unknown or len(set(channels)) != len(channels):
            raise ValueError(f"plate offset: channels must be distinct names among {WRENCH_CHANNELS}, got {channels}")
        object.__setattr__(self, "channels_", channels)
        values = finite_floats(self.values, "plate offset values")
        if len(values) != len(channels):
            raise ValueError(f"plate offset: {len(values)} values for channels {channels}")
        object.__setattr__(self, "values", values)

    def channels(self, robot):
        return self.channels_

    def parameters(self, robot):
        return {f"{channel}_off": value for channel, value in zip(self.channels_, self.values)}

    def plate_wrench(self, robot: RobotModel, q: NDArray) -> NDArray[np.float64]:
        """``(N, 6)`` added to the wrench at positions ``q`` ``(N, n)``."""
        offset = np.zeros(6)
        for channel, value in zip(self.channels_, self.values):
            offset[WRENCH_CHANNELS.index(channel)] = value
        return np.broadcast_to(offset, (q.shape[0], 6)).copy()

    def model_effect(self):
        return model_effects.WrenchOffset(channels=self.channels_)

    @classmethod
    def default(cls, robot):
        return cls(WRENCH_CHANNELS, (1.5, -1.0, 3.0, 0.5, -0.3, 2.0))

    @classmethod
    def from_json(cls, robot, value):
        if not isinstance(value, Mapping):
            raise ValueError('plate offsets are given by channel, e.g. {"fz": 3.0, "mz": 2.0}')
        return cls(tuple(value), tuple(value.values()))


@dataclass(frozen=True)
class PlateCable:
    """A cable pulling on the plate: ``channel += k (q_joint − q_ref)`` (N·m/rad), wrench rows only.

    The PUMA paper blames such a moment about x for its poor combined-model estimates.
    """

    joint: int = 1
    stiffness: float = 3.0
    q_ref: float = 0.0
    channel: str = "mx"
    name: ClassVar[str] = "cable"

    def __post_init__(self) -> None:
        if self.channel not in WRENCH_CHANNELS:
            raise ValueError(f"cable: channel {self.channel!r} is not one of {WRENCH_CHANNELS}")
        for label in ("stiffness", "q_ref"):
            if not np.isfinite(getattr(self, label)):
                raise ValueError(f"cable {label} must be finite")

    def channels(self, robot):
        return (self.channel,)

    def parameters(self, robot):
        return {f"k_cable_{self.channel}": self.stiffness, f"q_ref_cable_{self.channel}": self.q_ref}

    def plate_wrench(self, robot, q):
        if not 1 <= self.joint <= robot.n_joints:
            raise ValueError(f"effect 'cable': joint {self.joint} outside 1..{robot.n_joints}")
        wrench = np.zeros((q.shape[0], 6))
        wrench[:, WRENCH_CHANNELS.index(self.channel)] = self.stiffness * (q[:, self.joint - 1] - self.q_ref)
        return wrench

    def model_effect(self):
        return None

    @classmethod
    def default(cls, robot):
        return cls()

    @classmethod
    def from_json(cls, robot, value):
        return cls(**value) if isinstance(value, Mapping) else cls(stiffness=float(value))


@dataclass(frozen=True)
class PlateMoment(PlateOffset):
    """``plate_moment``: a constant moment offset only (default 2 N·m about z)."""

    name: ClassVar[str] = "plate_moment"

    @classmethod
    def default(cls, robot):
        return cls(("mz",), (2.0,))


PLATE_EFFECTS = (PlateOffset, PlateCable)
