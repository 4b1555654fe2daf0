"""The payload's excitation design: :mod:`~oed.payload_design.criterion` (the worst relative standard deviation of the mass
and the centre of mass) and :mod:`~oed.payload_design.design` (``oed design --payload``)."""

from oed.payload_design.criterion import MassAndCentre
from oed.payload_design.design import PayloadDesign, PayloadDesignResult, design_payload_excitation, payload_regressor

__all__ = ["MassAndCentre", "PayloadDesign", "PayloadDesignResult", "design_payload_excitation", "payload_regressor"]
