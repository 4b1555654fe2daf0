"""Transmissions: gear ratios and the coupling between joint and motor coordinates.

A robot as built drives its joints through gears, belts and differentials. With ``q`` the joint
coordinates and ``θ_m`` the motor (rotor) angles, a rigid transmission is linear::

    θ_m = R (q − q₀),     θ̇_m = R q̇,     θ̈_m = R q̈,     τ = Rᵀ τ_m               (power: τᵀ q̇ = τ_mᵀ θ̇_m)

``q₀`` are the joint offsets (default zero): the joint positions, in the robot description's zeros, where the
motors' encoders read zero, so that ``q = R⁻¹ θ_m + q₀`` (ros_control's ``SimpleTransmission`` ``offset``:
``q = θ_a / reduction + offset``). They shift positions only, never velocities, accelerations or torques.

``R`` is square (one motor per joint) and invertible; its diagonal holds the gear ratios (signed:
a motor that turns backwards has a negative ratio) and off-diagonal entries the coupling (a wrist
whose last motor turns with ``q5 + q6``, a differential, a four-bar linkage). A joint without a
declared transmission is direct drive (ratio 1).

Sources of ``R``:

* :func:`dynamics.transmission_files.transmission_from_urdf`: the ``<transmission>`` elements of a URDF, the kinds
  ros_control describes (``transmission_interface/SimpleTransmission``: ``mechanicalReduction``;
  ``DifferentialTransmission``: ``θ_a1 = (jr1 q1 + jr2 q2) ar1``, ``θ_a2 = (jr1 q1 − jr2 q2) ar2``;
  ``FourBarLinkageTransmission``: ``θ_a1 = jr1 ar1 q1``, ``θ_a2 = (q1 + jr2 q2) ar2``; torques by
  power conservation, ``τ = Rᵀ τ_m``);
* :func:`dynamics.transmission_files.transmission_from_json`: a small JSON file beside the robot;
* :func:`puma560_transmission`: the PUMA 560's gears and coupled wrist.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from dynamics.robot import RobotModel
from dynamics.servos import ServoLaws

#: a coupling matrix whose condition number exceeds this is singular for our purposes
MAX_CONDITION = 1e10


class TransmissionError(ValueError):
    """A transmission that cannot describe this robot or these data."""


class CouplingShapeError(TransmissionError):
    """The coupling matrix is not square with one row and column per joint of the robot."""


class SingularCouplingError(TransmissionError):
    """The coupling matrix is singular: some joint motion turns no motor (or motors are redundant)."""


class UnknownJointError(TransmissionError):
    """A transmission names a joint the robot lacks."""


class TransmissionSignError(TransmissionError):
    """A gear ratio has the wrong sign for the data (the converted torque pushes against the motion)."""


@dataclass(frozen=True, eq=False)
class Transmission:
    """``θ_m = R q`` and ``τ = Rᵀ τ_m`` for one robot.

    Parameters
    ----------
    matrix
        ``R``, ``n x n`` (motors x joints), finite and invertible.
    motor_names
        One per motor (default ``m1..mn``).
    torque_constants
        Motor torque constants ``k_t`` (N·m/A), one per motor, to convert currents
        (``τ_m = k_t i``); ``None`` when unknown.
    source
        Where the transmission comes from (for reports).
    offsets
        Joint offsets ``q₀`` (rad, or m for a prismatic joint), one per joint: ``q = R⁻¹ θ_m + q₀``; ``None``
        when all are zero (the encoders' zeros are the description's).
    servos
        The laws by which each joint's actuator makes its force from its control and the state (an MJCF's
        servos, :func:`dynamics.mjcf.mjcf_servos`): a log of the controls alone read through them; ``None``.
    """

    matrix: NDArray[np.float64]
    motor_names: tuple[str, ...] = ()
    torque_constants: tuple[float, ...] | None = None
    source: str = ""
    offsets: tuple[float, ...] | None = None
    servos: ServoLaws | None = None

    def __post_init__(self) -> None:
        try:
            matrix = np.array(self.matrix, dtype=float)
        except (TypeError, ValueError):
            raise CouplingShapeError("the coupling matrix must be a square array of numbers") from None
        if matrix.ndim == 1:
            matrix = np.diag(matrix)
        if matrix.ndim != 2 or matrix.shape[0] != matrix.shape[1] or matrix.shape[0] == 0:
            raise CouplingShapeError(f"the coupling matrix must be square (motors x joints), got shape {matrix.shape}")
        if not np.all(np.isfinite(matrix)):
            raise TransmissionError("the coupling matrix holds NaN or inf")
        singular = np.linalg.svd(matrix, compute_uv=False)
        if not singular[-1] > singular[0] / MAX_CONDITION:
            zero_rows = [index + 1 for index in np.flatnonzero(~matrix.any(axis=1))]
            zero_columns = [index + 1 for index in np.flatnonzero(~matrix.any(axis=0))]
            detail = (f"motor row(s) {zero_rows} are zero" if zero_rows else
                      f"joint column(s) {zero_columns} turn no motor" if zero_columns else
                      f"condition number {singular[0] / max(singular[-1], 1e-300):.3g}")
            raise SingularCouplingError(f"the coupling matrix is singular ({detail}): θ_m = R q must be invertible")
        matrix.flags.writeable = False
        object.__setattr__(self, "matrix", matrix)
        n = matrix.shape[0]
        names = tuple(self.motor_names) or tuple(f"m{index}" for index in range(1, n + 1))
        if len(names) != n:
            raise CouplingShapeError(f"{len(names)} motor names for {n} motors")
        object.__setattr__(self, "motor_names", names)
        if self.torque_constants is not None:
            constants = np.atleast_1d(np.asarray(self.torque_constants, dtype=float))
            if constants.shape != (n,) or not np.all(np.isfinite(constants)) or np.any(constants == 0):
                raise TransmissionError(f"torque_constants: give {n} finite, non-zero values (N·m/A), one per motor")
            object.__setattr__(self, "torque_constants", tuple(float(value) for value in constants))
        if self.offsets is not None:
            try:
                offsets = np.atleast_1d(np.asarray(self.offsets, dtype=float))
            except (TypeError, ValueError):
                raise TransmissionError(f"offsets: give {n} numbers (rad, or m), one per joint") from None
            if offsets.shape != (n,) or not np.all(np.isfinite(offsets)):
                raise TransmissionError(f"offsets: give {n} finite numbers (rad, or m), one per joint; got "
                                        f"{offsets.size} value(s)" + ("" if np.all(np.isfinite(offsets)) else
                                                                      " with NaN or inf"))
            object.__setattr__(self, "offsets", None if not np.any(offsets) else
                               tuple(float(value) for value in offsets))

    @property
    def n_motors(self) -> int:
        return self.matrix.shape[0]

    @property
    def ratios(self) -> NDArray[np.float64]:
        """The diagonal of ``R`` (gear ratios, signed)."""
        return np.diag(self.matrix).copy()

    @property
    def is_coupled(self) -> bool:
        return bool(np.any(self.matrix[~np.eye(self.n_motors, dtype=bool)] != 0))

    def coupled_motors(self) -> tuple[int, ...]:
        """0-based indices of the motors that turn with more than one joint."""
        return tuple(int(index) for index in np.flatnonzero(np.count_nonzero(self.matrix, axis=1) > 1))

    def check(self, robot: RobotModel) -> Transmission:
        """Raise :class:`CouplingShapeError` unless there is one motor per joint of ``robot``."""
        if self.n_motors != robot.n_joints:
            raise CouplingShapeError(f"the transmission has {self.n_motors} motors ({self.source or 'given'}), "
                                     f"the robot {robot.name} {robot.n_joints} joints: R must be "
                                     f"{robot.n_joints} x {robot.n_joints}")
        return self

    def truncated(self, n_joints: int) -> Transmission:
        """The transmission of the first ``n_joints`` joints (``dynamics.robots.truncate``); refused
        when a kept motor turns with a joint left out."""
        if n_joints == self.n_motors:
            return self
        if np.any(self.matrix[:n_joints, n_joints:]):
            raise TransmissionError(f"motors 1..{n_joints} turn with joints beyond {n_joints}: keep more joints")
        constants = None if self.torque_constants is None else self.torque_constants[:n_joints]
        offsets = None if self.offsets is None else self.offsets[:n_joints]
        return Transmission(self.matrix[:n_joints, :n_joints], self.motor_names[:n_joints], constants, self.source,
                            offsets, None if self.servos is None else self.servos.truncated(n_joints))

    @property
    def joint_offsets(self) -> NDArray[np.float64]:
        """``q₀``, one per joint (zeros when none were declared)."""
        return np.zeros(self.n_motors) if self.offsets is None else np.array(self.offsets)

    def motor_positions(self, q: ArrayLike) -> NDArray[np.float64]:
        """``θ_m = R (q − q₀)`` for ``(N, n)`` joint positions (without offsets, also velocities and accelerations:
        :meth:`motor_rates`)."""
        return (np.asarray(q, dtype=float) - self.joint_offsets) @ self.matrix.T

    def joint_positions(self, theta_m: ArrayLike) -> NDArray[np.float64]:
        """``q = R⁻¹ θ_m + q₀`` for ``(N, n)`` motor positions (without offsets, also velocities and
        accelerations: :meth:`joint_rates`)."""
        return self.joint_rates(theta_m) + self.joint_offsets

    def motor_rates(self, dq: ArrayLike) -> NDArray[np.float64]:
        """``θ̇_m = R q̇`` for ``(N, n)`` joint velocities (or accelerations): no offset."""
        return np.asarray(dq, dtype=float) @ self.matrix.T

    def joint_rates(self, dtheta_m: ArrayLike) -> NDArray[np.float64]:
        """``q̇ = R⁻¹ θ̇_m`` for ``(N, n)`` motor velocities (or accelerations): no offset."""
        return np.linalg.solve(self.matrix, np.asarray(dtheta_m, dtype=float).T).T

    def joint_torques(self, tau_m: ArrayLike) -> NDArray[np.float64]:
        """``τ = Rᵀ τ_m`` for ``(N, n)`` motor torques."""
        return np.asarray(tau_m, dtype=float) @ self.matrix

    def motor_torques(self, tau: ArrayLike) -> NDArray[np.float64]:
        """``τ_m = R⁻ᵀ τ`` for ``(N, n)`` joint torques."""
        return np.linalg.solve(self.matrix.T, np.asarray(tau, dtype=float).T).T

    def torques_from_currents(self, currents: ArrayLike) -> NDArray[np.float64]:
        """Motor torques ``τ_m = k_t i`` from ``(N, n)`` currents (A)."""
        if self.torque_constants is None:
            raise TransmissionError("currents given but the transmission has no torque_constants (N·m/A)")
        return np.asarray(currents, dtype=float) * np.array(self.torque_constants)

    def combination_label(self, motor: int, joint_names: Sequence[str] | None = None) -> str:
        """``q5+q6``-style text of the joint combination motor ``motor`` (0-based) turns with, the
        coefficients scaled by the largest."""
        row = self.matrix[motor]
        scale = row[np.argmax(np.abs(row))]
        terms = []
        for index in np.flatnonzero(row):
            coefficient = row[index] / scale
            name = f"q{index + 1}" if joint_names is None else joint_names[index]
            sign = "-" if coefficient < 0 else "+"
            magnitude = "" if np.isclose(abs(coefficient), 1.0) else f"{abs(coefficient):.3g}*"
            terms.append(f"{sign}{magnitude}{name}")
        return "".join(terms).lstrip("+")

    def to_dict(self) -> dict[str, Any]:
        """The JSON form :func:`dynamics.transmission_files.transmission_from_json` reads."""
        document: dict[str, Any] = {"matrix": self.matrix.tolist(), "motors": list(self.motor_names)}
        if self.torque_constants is not None:
            document["torque_constants"] = list(self.torque_constants)
        if self.offsets is not None:
            document["offsets"] = list(self.offsets)
        if self.servos is not None:
            document["servos"] = self.servos.to_dict()
        return document


# Corke, Robotics Toolbox mdl_puma560 gear ratios G1..G6 (also in dynamics.simulation.joint_effects): checked
# against the toolbox's source (L(1).G = -62.6111 … L(6).G = 76.686, also its puma560akb.m)
_PUMA560_GEARS = (-62.6111, 107.815, -53.7063, 76.0364, 71.923, 76.686)
#: PUMA 560 wrist coupling ratios G45, G46, G56 (dimensionless): NOT verified, see :func:`puma560_transmission`
PUMA560_WRIST_COUPLING: tuple[float, float, float] = (0.0130, 0.0184, 0.0133)


@dataclass(frozen=True)
class JointDirections:
    """The recorded joints' directions against the robot description's axes (``--joint-offsets FILE``'s ``signs``
    and ``torque_signs``).

    A log whose joint turns the other way than the URDF's axis: the description's ``q = s q_recorded + q₀``,
    ``q̇ = s q̇_recorded``, ``q̈ = s q̈_recorded`` with ``s = signs[j]``, and its joint torque ``τ = t τ_recorded``
    with ``t = torque_signs[j]`` (both ``-1``: the URDF's joint with its ``<axis>`` reversed; ``signs`` alone: the
    encoder counts the other way, the torque does not). Each entry ``+1`` or ``-1``.
    """

    signs: tuple[float, ...]
    torque_signs: tuple[float, ...]

    def __post_init__(self) -> None:
        if len(self.signs) != len(self.torque_signs):
            raise CouplingShapeError(f"{len(self.signs)} signs for {len(self.torque_signs)} torque signs")
        for name in ("signs", "torque_signs"):
            values = getattr(self, name)
            if any(value not in (1.0, -1.0) for value in values):
                raise TransmissionError(f"joint {name} must be +1 or -1, got {list(values)}")
            object.__setattr__(self, name, tuple(float(value) for value in values))

    @property
    def reversed(self) -> bool:
        """Whether any joint's direction is reversed (else the directions change nothing)."""
        return any(value < 0 for value in (*self.signs, *self.torque_signs))

    def to_dict(self) -> dict[str, list[float]]:
        return {"signs": list(self.signs), "torque_signs": list(self.torque_signs)}


def puma560_transmission(n_joints: int = 6) -> Transmission:
    """The PUMA 560's gears and coupled wrist.

    ::

        θ_m1..3 = G1..3 q1..3,   θ_m4 = G4 q4,
        θ_m5 = G5 (G45 q4 + q5),
        θ_m6 = G6 (G46 q4 + G56 q5 + q6)

    The wrist motors sit in the forearm and drive joints 5 and 6 through shafts concentric with
    joint 4's, so turning joint 4 turns motors 5 and 6, and turning joint 5 turns motor 6: the
    matrix is lower triangular in the wrist.

    Sources, and what is verified:

    * the gear ratios ``G1..G6`` are those of Corke's Robotics Toolbox (``mdl_puma560``,
      ``puma560akb``, from Armstrong, Khatib & Burdick, "The explicit dynamic model and inertial
      parameters of the PUMA 560 arm", ICRA 1986), checked against the toolbox's source; the
      toolbox does not model the wrist coupling;
    * the coupling ratios :data:`PUMA560_WRIST_COUPLING` (``G45, G46, G56``) and the form above were
      written from memory of P. I. Corke, *Visual Control of Robots* (1996), and are **not verified**:
      a search of public code, documentation and web pages (Armstrong, Khatib & Burdick 1986; Corke
      & Armstrong-Hélouvry, "A search for consensus among model parameters reported for the PUMA
      560 robot", ICRA 1994; the toolbox's PUMA models in MATLAB, Python and Scilab; other
      repositories modelling the PUMA) found no table of them. Treat them as an order of
      magnitude (about one motor turn in a hundred of the joint's for each coupling), and declare
      a real robot's values with a transmission file.

    The simulated checks of issue 18 (``tests/test_asbuilt_puma.py``) do not depend on these
    values being right: they simulate with the transmission they identify.
    """
    g = np.array(_PUMA560_GEARS)
    g45, g46, g56 = PUMA560_WRIST_COUPLING
    matrix = np.diag(g)
    matrix[4, 3] = g45 * g[4]
    matrix[5, 3] = g46 * g[5]
    matrix[5, 4] = g56 * g[5]
    return Transmission(matrix, source="puma560 (gears: Corke's toolbox; wrist coupling unverified)").truncated(n_joints)


#: a joint whose positions span less than this (rad, or m) over a record is not judged by :func:`check_power_signs`:
#: at rest its velocity is the derivative of the encoder's noise and the sign of its mean power is chance
MIN_SWEEP = 0.01


def check_power_signs(transmission: Transmission, dq: ArrayLike, tau: ArrayLike, *, source: str = "data",
                      tolerance: float = 0.2, q: ArrayLike | None = None) -> None:
    """Raise :class:`TransmissionSignError` when a joint's converted torque pushes against its motion.

    Over a record, friction dissipates: the mean power ``τ_j q̇_j`` of each joint is positive or
    near zero (gravity and inertia give and take it back over a periodic motion). A mean power
    below ``−tolerance`` times the mean absolute power means the torque and the motion of that
    joint disagree in sign: a gear ratio or torque constant of the wrong sign for the data
    (when positions are joint-side, e.g. link encoders, and torques motor-side).

    With the positions ``q`` (rows as ``dq``), a joint whose positions span less than :data:`MIN_SWEEP` is not
    judged: a record at rest (a robot holding its pose under gravity) dissipates nothing, and the sign of
    ``τ_j q̇_j`` there follows the encoder's noise (a Stäubli TX40's record at rest was refused as a wrong gear
    sign on joint 3).

    Limit: on a joint whose torque is mostly gravity (given and taken back over the motion), the
    dissipated part may be too small to show. In the 3-joint simulated PUMA of
    ``tests/test_asbuilt_cli.py`` a flipped ratio is named on joint 1 but not on joint 2.
    """
    dq, tau = np.asarray(dq, dtype=float), np.asarray(tau, dtype=float)
    power = tau * dq
    mean, scale = power.mean(axis=0), np.abs(power).mean(axis=0)
    moves = np.ones(power.shape[1], dtype=bool) if q is None else np.ptp(np.asarray(q, dtype=float), axis=0) >= MIN_SWEEP
    check_mean_power(transmission, mean, scale, moves, source=source, tolerance=tolerance)


def check_mean_power(transmission: Transmission, mean: ArrayLike, scale: ArrayLike, moves: ArrayLike, *,
                     source: str = "data", tolerance: float = 0.2) -> None:
    """:func:`check_power_signs`' rule on a record's mean power ``τ_j q̇_j`` and mean absolute power by joint
    (``moves``: the joints whose positions span at least :data:`MIN_SWEEP`, judged): what a record read in blocks
    accumulates (:func:`estimation.data.motor_side.joint_side_copies`)."""
    mean, scale, moves = np.asarray(mean, dtype=float), np.asarray(scale, dtype=float), np.asarray(moves, dtype=bool)
    wrong = [index for index in range(mean.shape[0])
             if moves[index] and scale[index] > 0 and mean[index] < -tolerance * scale[index]]
    if wrong:
        index = wrong[0]
        raise TransmissionSignError(
            f"{source}: the torque of joint {index + 1} converted through the transmission pushes against its motion "
            f"(mean power {mean[index]:.3g} W, {-100 * mean[index] / scale[index]:.0f} % of its mean |power|): "
            f"the gear ratio or torque constant of motor {index + 1} ({transmission.matrix[index, index]:+.6g}) has the "
            "wrong sign for the data" + (f" (also joint(s) {[i + 1 for i in wrong[1:]]})" if len(wrong) > 1 else ""))
