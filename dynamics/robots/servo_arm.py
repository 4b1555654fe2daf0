"""The 4-DOF hobby-servo arm of the servo-arm identification paper, as data.

Masses: Table 1 of the paper (0.294, 0.239, 0.144, 0.072 kg for joints 1–4). The paper gives no
geometry; **assumed here** (a typical desktop servo arm): a base yaw joint ``rho`` about the
vertical axis, its shoulder 0.065 m above the base plate; then three pitch joints
``theta1..theta3`` with links of 0.105 m, 0.098 m and 0.060 m. Each arm link is a slender rod
(centre of mass at mid-length, inertia m·l²/12 about its transverse axes, 1e-6 kg·m² about its
own axis); the base link is a cylinder of radius 0.04 m. Limits: the paper's joint ranges
(section 4.2), 5.2 rad/s (a 0.2 s/60° servo) and 1.0 N·m (a metal-gear hobby servo).
"""

from __future__ import annotations

import numpy as np

from dynamics.dh import DHLink, robot_from_dh
from dynamics.robot import RobotModel, inertial_parameters

SERVO_ARM_MASSES: tuple[float, ...] = (0.294, 0.239, 0.144, 0.072)
SERVO_ARM_RANGES: tuple[tuple[float, float], ...] = ((-1.26, 1.20), (0.562, 1.972), (0.9617, 3.142), (0.5108, 4.5))
SERVO_ARM_LENGTHS: tuple[float, ...] = (0.065, 0.105, 0.098, 0.060)
_BASE_RADIUS = 0.04


def _rod(mass: float, length: float) -> np.ndarray:
    # DH frame i sits at the distal end with x along the link: the COM is at -l/2 on x.
    transverse = mass * length**2 / 12.0
    return inertial_parameters(mass, (-length / 2, 0.0, 0.0), (1e-6, transverse, transverse, 0, 0, 0))


def servo_arm() -> RobotModel:
    """The four-joint servo arm (joint names ``rho, theta1, theta2, theta3``)."""
    base_mass = SERVO_ARM_MASSES[0]
    base_inertia = base_mass * _BASE_RADIUS**2
    links = [
        DHLink(
            a=0.0, alpha=np.pi / 2, d=SERVO_ARM_LENGTHS[0],
            # DH frame 1 has y along the base z axis: the cylinder's axis is y.
            inertial=tuple(
                inertial_parameters(base_mass, (0.0, -SERVO_ARM_LENGTHS[0] / 2, 0.0), (base_inertia / 4, base_inertia / 2, base_inertia / 4, 0, 0, 0))
            ),
            lower=SERVO_ARM_RANGES[0][0], upper=SERVO_ARM_RANGES[0][1], velocity=5.2, effort=1.0,
        )
    ]
    for mass, length, (lower, upper) in zip(SERVO_ARM_MASSES[1:], SERVO_ARM_LENGTHS[1:], SERVO_ARM_RANGES[1:]):
        links.append(
            DHLink(a=length, alpha=0.0, d=0.0, inertial=tuple(_rod(mass, length)), lower=lower, upper=upper, velocity=5.2, effort=1.0)
        )
    return robot_from_dh("servo_arm", links, joint_names=("rho", "theta1", "theta2", "theta3"))
