"""The PUMA 560, as data.

Kinematics: the standard DH table of Corke's Robotics Toolbox (``mdl_puma560``), with
``d3 = 0.15005 m``. Inertial data: Armstrong, Khatib & Burdick, "The explicit dynamic model and
inertial parameters of the PUMA 560 arm", Proc. IEEE ICRA 1986, pp. 510–518, in the link frames
of that table (as tabulated by Corke, Robotics Toolbox ``mdl_puma560``). Armstrong et al. did not
measure the mass of link 1 (it does not enter the joint torques); it is 0 here as in Corke's
table, so the external model sees links 2–6 only.

Joint limits: for joints 1–3, the symmetric position and velocity bounds used in the PUMA
identification paper (Azevedo, eq. 19); for joints 4–6, Corke's ``qlim``.
"""

from __future__ import annotations

import numpy as np

from dynamics.dh import DHLink, robot_from_dh
from dynamics.robot import RobotModel, inertial_parameters

_DEG = np.pi / 180.0

# (a, alpha, d, mass, centre of mass, inertia about the COM (Ixx, Iyy, Izz, Ixy, Iyz, Ixz),
#  (lower, upper) limit, velocity limit)
_TABLE = (
    (0.0, np.pi / 2, 0.0, 0.0, (0.0, 0.0, 0.0), (0.0, 0.35, 0.0, 0, 0, 0), (-2.5089, 2.5089), 1.4312),
    (0.4318, 0.0, 0.0, 17.4, (-0.3638, 0.006, 0.2275), (0.13, 0.524, 0.539, 0, 0, 0), (-1.6760, 1.6760), 0.9425),
    (0.0203, -np.pi / 2, 0.15005, 4.8, (-0.0203, -0.0141, 0.070), (0.066, 0.086, 0.0125, 0, 0, 0), (-2.1049, 2.1049), 2.1293),
    (0.0, np.pi / 2, 0.4318, 0.82, (0.0, 0.019, 0.0), (1.8e-3, 1.3e-3, 1.8e-3, 0, 0, 0), (-110 * _DEG, 170 * _DEG), 4.0),
    (0.0, -np.pi / 2, 0.0, 0.34, (0.0, 0.0, 0.0), (0.3e-3, 0.4e-3, 0.3e-3, 0, 0, 0), (-100 * _DEG, 100 * _DEG), 4.0),
    (0.0, 0.0, 0.0, 0.09, (0.0, 0.0, 0.032), (0.15e-3, 0.15e-3, 0.04e-3, 0, 0, 0), (-266 * _DEG, 266 * _DEG), 4.0),
)

PUMA560_DH: tuple[DHLink, ...] = tuple(
    DHLink(
        a=a, alpha=alpha, d=d,
        inertial=tuple(inertial_parameters(mass, com, inertia)),
        lower=limits[0], upper=limits[1], velocity=velocity,
    )
    for a, alpha, d, mass, com, inertia, limits, velocity in _TABLE
)


def puma560() -> RobotModel:
    """The six-joint PUMA 560 (use :func:`dynamics.robots.load_robot` with ``joints=3`` for the paper's case)."""
    return robot_from_dh("puma560", PUMA560_DH)
