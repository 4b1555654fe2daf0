"""Constraints on the payload record's information: the robot model's share of the payload's uncertainty held to a
reference's.

A payload design for the record's noise alone (:class:`oed.payload_design.criterion.MassAndCentre` without
``robot_cov``) drives the motion where the robot model is least known: measured on the PUMA, the robot model's share
of the mass's standard deviation grew about four times over random excitations', so that in total the design knew
the mass worse than a random excitation (benchmarks/README.md, payload section). :class:`RobotShareBound` keeps each
of the four relative quantities ``u = T π`` (the mass, the centre of mass's three axes) at most as uncertain through
the robot model as on a reference motion,

    g_k = log r_k − log v_k(M) ≥ 0 ,     v_k(M) = (T M_kk⁻¹ M_kb Σ_θ M_bk M_kk⁻¹ Tᵀ)_kk ,

``v`` the robot model's share of the variance of ``u_k`` (:meth:`MassAndCentre.relative_variances`: it does not
depend on the record's length or its noise, only on where the motion goes) and ``r_k`` the reference's, by default the
median over random excitations of the same period and bounds (:func:`reference_robot_share`). In logarithms the rows
are of the order of one whatever the payload's size, and IPOPT meets them to its tolerance.

Like the torque, floor and collision constraints (:mod:`oed.design_constraints`) a constraint is a small object: its
rows as a CasADi expression of the information (``expression``) and as numbers (``margins``), here of the whole
record's information rather than of one sample (:class:`oed.payload_design.design.PayloadDesign` evaluates it).
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass
from typing import Any, ClassVar

import casadi
import numpy as np
from numpy.typing import ArrayLike, NDArray

from oed.payload_design.criterion import MassAndCentre

__all__ = ["QUANTITIES", "RobotShareBound", "reference_robot_share"]

#: the four relative quantities ``u`` the rows are on, in order
QUANTITIES = ("mass", "com_x", "com_y", "com_z")


@dataclass(frozen=True, eq=False)
class RobotShareBound:
    """``v_k(M) ≤ r_k`` for the mass and the three axes of the centre of mass (module docstring).

    Parameters
    ----------
    criterion
        The :class:`MassAndCentre` whose guess and ``robot_cov`` (``Σ_θ``, required) define ``u`` and ``v``.
    reference
        ``r`` (4): the robot model's share of the relative variances ``u`` allowed, each positive.
    """

    criterion: MassAndCentre
    reference: NDArray[np.float64]
    name: ClassVar[str] = "robot_share"

    def __post_init__(self) -> None:
        if not isinstance(self.criterion, MassAndCentre):
            raise TypeError(f"criterion must be a MassAndCentre, got {type(self.criterion).__name__}")
        if self.criterion.robot_cov is None:
            raise ValueError("RobotShareBound needs the robot model's covariance: a MassAndCentre with robot_cov")
        reference = np.asarray(self.reference, dtype=float).reshape(-1)
        if reference.shape != (len(QUANTITIES),) or not np.all(np.isfinite(reference)) or np.any(reference <= 0):
            raise ValueError(f"reference must be {len(QUANTITIES)} positive variances, got {self.reference!r}")
        object.__setattr__(self, "reference", reference)

    @property
    def size(self) -> int:
        """The rows of the information the constraint takes: 10 + r (the payload's columns, then the robot's)."""
        return self.criterion.size

    @property
    def labels(self) -> tuple[str, ...]:
        return QUANTITIES

    def expression(self, M: Any) -> Any:
        """``g`` (4 x 1) of the information ``M`` (``(10 + r) x 10`` or square), ``≥ 0`` when met."""
        _, robot = self.criterion.variance_expressions(M)
        return casadi.log(casadi.DM(self.reference)) - casadi.log(robot)

    def margins(self, M: ArrayLike) -> NDArray[np.float64]:
        """``g`` as numbers: ``log r_k − log v_k`` (``< 0``: the robot model's share above the reference's)."""
        _, robot = self.criterion.relative_variances(M)
        with np.errstate(divide="ignore"):
            return np.log(self.reference) - np.log(robot)

    def describe(self) -> dict[str, Any]:
        return {"name": self.name, "quantities": list(QUANTITIES),
                "bound_relative_std": np.sqrt(self.reference).tolist(),
                "rule": "the robot model's share of the variance of the relative mass and of each axis of the centre "
                        "of mass at most the reference's"}


def reference_robot_share(criterion: MassAndCentre, informations: Iterable[ArrayLike]) -> NDArray[np.float64]:
    """``r``: the median, per quantity, of the robot model's share of the relative variances over the informations
    of reference motions (each ``(10 + r)`` square, per sample or not: the share does not depend on its scale).

    Raises
    ------
    ValueError
        Without any information, or without ``criterion.robot_cov``.
    """
    if criterion.robot_cov is None:
        raise ValueError("the robot model's share needs its covariance: a MassAndCentre with robot_cov")
    shares = [criterion.relative_variances(M)[1] for M in informations]
    if not shares:
        raise ValueError("reference_robot_share needs the information of at least one reference motion")
    return np.median(np.array(shares), axis=0)

