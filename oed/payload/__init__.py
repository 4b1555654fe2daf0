"""The payload's excitation design: :mod:`~oed.payload.criterion` (the worst relative standard deviation of the mass
and the centre of mass) and :mod:`~oed.payload.design` (``oed design --payload``)."""

from oed.payload.criterion import MassAndCentre
from oed.payload.design import PayloadDesign, PayloadDesignResult, design_payload_excitation, payload_regressor

__all__ = ["MassAndCentre", "PayloadDesign", "PayloadDesignResult", "design_payload_excitation", "payload_regressor"]
