"""Payload identification: the mass, centre of mass and inertia of a rigid body fixed to a link, from records made
with it, the robot's identified model held fixed (:mod:`~estimation.payload.fit`, :mod:`~estimation.payload.body`).

::

    from estimation.identification.identified_model import IdentifiedModel
    from estimation.payload import identify_payload

    result = identify_payload(IdentifiedModel.load("robot.json"), ["loaded.csv"], validate=["loaded2.csv"])
    result.body.mass, result.body.com, result.body.inertia, result.to_dict()
"""

from estimation.payload.body import BODY_NAMES, INERTIA_KEYS, PayloadBody, body_values
from estimation.payload.fit import PayloadError, PayloadResult, identify_payload, payload_rows, resolve_link

__all__ = ["BODY_NAMES", "INERTIA_KEYS", "PayloadBody", "PayloadError", "PayloadResult", "body_values",
           "identify_payload", "payload_rows", "resolve_link"]
