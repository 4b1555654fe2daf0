"""The simulated sensors: encoder quantisation of positions, Gaussian noise on torques and on the
force-plate wrench (what :class:`dynamics.simulation.simulator.Simulator` records)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Literal

import numpy as np
from numpy.typing import NDArray

from dynamics.robot import RobotModel
from dynamics.simulation.joint_effects import PUMA560_GEAR_RATIOS, is_puma560

ENCODER_COUNTS = 4 * 4096  # quadrature-decoded counts per motor revolution
DEFAULT_GEAR = 100.0


def encoder_resolution(robot: RobotModel) -> NDArray[np.float64]:
    """Joint resolution ``2π / (4·4096·|G|)`` rad (PUMA gear ratios; ``G = 100`` otherwise; 1 µm prismatic)."""
    gear = np.full(robot.n_joints, DEFAULT_GEAR)
    if is_puma560(robot) and robot.n_joints <= 6:
        gear = np.abs(np.array(PUMA560_GEAR_RATIOS[: robot.n_joints]))
    resolution = 2 * np.pi / (ENCODER_COUNTS * gear)
    prismatic = np.array([joint.joint_type.value == "prismatic" for joint in robot.joints])
    return np.where(prismatic, 1e-6, resolution)


@dataclass(frozen=True)
class NoiseModel:
    """Sensor models: Gaussian noise on torques and wrench, encoder quantisation of positions.

    Attributes
    ----------
    tau_std
        Standard deviation of the torque noise, N·m (one value or one per joint).
    wrench_std
        Standard deviation of the plate noise, one value or six (``fx fy fz`` in N, ``mx my mz``
        in N·m).
    q_resolution
        ``"encoder"`` (default, :func:`encoder_resolution`), a resolution in rad (one or per
        joint), or ``None`` for exact positions.
    """

    tau_std: float | tuple[float, ...] = 0.2
    wrench_std: float | tuple[float, ...] = (0.5, 0.5, 0.5, 0.1, 0.1, 0.1)
    q_resolution: float | tuple[float, ...] | Literal["encoder"] | None = "encoder"

    def __post_init__(self) -> None:
        for name in ("tau_std", "wrench_std"):
            values = np.atleast_1d(np.asarray(getattr(self, name), dtype=float))
            if not np.all(np.isfinite(values)) or np.any(values < 0):
                raise ValueError(f"{name} must be finite and non-negative, got {values.tolist()}")
        if np.atleast_1d(self.wrench_std).shape[0] not in (1, 6):
            raise ValueError("wrench_std takes one value or six (fx fy fz mx my mz)")
        if self.q_resolution not in (None, "encoder"):
            values = np.atleast_1d(np.asarray(self.q_resolution, dtype=float))
            if not np.all(np.isfinite(values)) or np.any(values <= 0):
                raise ValueError(f"q_resolution must be positive, got {values.tolist()}")

    @classmethod
    def none(cls) -> NoiseModel:
        """Exact sensors: no noise, no quantisation."""
        return cls(0.0, 0.0, None)

    def resolution(self, robot: RobotModel) -> NDArray[np.float64] | None:
        if self.q_resolution is None:
            return None
        if self.q_resolution == "encoder":
            return encoder_resolution(robot)
        return np.broadcast_to(np.asarray(self.q_resolution, dtype=float), (robot.n_joints,)).copy()

    def describe(self, robot: RobotModel) -> dict[str, Any]:
        resolution = self.resolution(robot)
        return {
            "tau_std": np.broadcast_to(self.tau_std, (robot.n_joints,)).tolist(),
            "wrench_std": np.broadcast_to(self.wrench_std, (6,)).tolist(),
            "q_resolution": None if resolution is None else resolution.tolist(),
        }
