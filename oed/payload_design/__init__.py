"""The payload's excitation design: :mod:`~oed.payload_design.criterion` (the worst relative standard deviation of the mass
and the centre of mass), :mod:`~oed.payload_design.constraints` (the robot model's share of it held to random
excitations') and :mod:`~oed.payload_design.design` (``oed design --payload``)."""

from oed.payload_design.constraints import RobotShareBound, reference_robot_share
from oed.payload_design.criterion import MassAndCentre
from oed.payload_design.design import (
    PayloadDesign,
    PayloadDesignResult,
    RobotShare,
    design_payload_excitation,
    payload_regressor,
)

__all__ = ["MassAndCentre", "PayloadDesign", "PayloadDesignResult", "RobotShare", "RobotShareBound",
           "design_payload_excitation", "payload_regressor", "reference_robot_share"]
