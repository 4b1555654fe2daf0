"""A known load the logger subtracted from the joint torques, given by the robot's description.

Many controllers log "compensated" or "external" torques: the motor torque less the controller's own gravity model,
which is usually the robot description's bodies. The logged torque is then ``τ_log = Y θ − g_desc(q)``, with
``g_desc(q) = Y(q, 0, 0) θ_desc`` the gravity torque of the description's nominal bodies (its standard parameters,
no friction), at the description's gravity. No model of the robot alone holds that log: the model with the
description's gravity fits a gravity load the log lacks, the model without gravity cannot hold the difference between
the true bodies' load and the description's (on a simulated PUMA 6 with bodies ±20 % off the description, joints 2
and 3 stayed 3.6x and 5.5x their noise floor without gravity: ``benchmarks/README.md``, h-gravity). The exact model
of such a log is the robot's model less the same known load: the torques with ``g_desc(q)`` added back are the
robot's, fitted as any log is, and the model predicts what the log records by subtracting it again.

:class:`SubtractedLoad` names the load (``kind``; the one measured and built is :data:`DESCRIPTION_GRAVITY`: the
description's gravity torque). It is what the result file's ``model_file.subtracted`` holds; a file without the key
subtracts nothing (a file of an earlier release). Why only the gravity torque: it is what a controller's
gravity-compensation mode removes, and it is the only load a description gives in full (its friction, when a URDF's
``<dynamics>`` holds any, is not a drive's friction model, and the inertial torque needs accelerations a controller
does not subtract from its log). Another kind is added as a new name, never by changing this one.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, replace
from typing import Any, Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from dynamics.channels import is_joint_torque, torque_joint
from dynamics.measurements import Measurements
from dynamics.models import IdentificationModel, ModelKind, build_model
from dynamics.robot import RobotModel
from estimation.data.passive import passive_channels
from estimation.identification.prepared import PreparedRecord, PreparedRecords

__all__ = ["DESCRIPTION_GRAVITY", "SUBTRACTED_KINDS", "SubtractedLoad", "added_back", "added_back_records",
           "load_channels", "subtracted_torque"]

#: the description's gravity torque: its nominal bodies at rest, at the description's gravity
DESCRIPTION_GRAVITY = "description_gravity"
#: the kinds of load a log may have subtracted (``model_file.subtracted.kind``)
SUBTRACTED_KINDS = (DESCRIPTION_GRAVITY,)


@dataclass(frozen=True)
class SubtractedLoad:
    """A load of the description that the logged joint torques have subtracted (module docstring).

    Attributes
    ----------
    kind
        :data:`DESCRIPTION_GRAVITY`: the gravity torque of the description's nominal bodies at its gravity.
    """

    kind: Literal["description_gravity"] = DESCRIPTION_GRAVITY

    def __post_init__(self) -> None:
        if self.kind not in SUBTRACTED_KINDS:
            raise ValueError(f"a subtracted load's kind must be one of {list(SUBTRACTED_KINDS)}, got {self.kind!r}")

    def to_dict(self) -> dict[str, Any]:
        """``{"kind": …, "meaning": …}`` (the result file's ``model_file.subtracted``)."""
        return {"kind": self.kind, "meaning": "the logged joint torques are the model's less the gravity torque of "
                "the description's nominal bodies at the description's gravity"}

    @classmethod
    def from_dict(cls, document: Any) -> SubtractedLoad:
        """The load of a ``model_file.subtracted`` entry; :class:`ValueError` naming what is wrong."""
        if not isinstance(document, Mapping) or "kind" not in document:
            raise ValueError(f"subtracted must be an object with a kind (one of {list(SUBTRACTED_KINDS)}), "
                             f"got {document!r}")
        return cls(kind=document["kind"])

    def words(self) -> str:
        """The load in a few words, for the summary and the notes."""
        return "the description's gravity torque (its bodies at rest) subtracted by the logger"


def subtracted_torque(load: SubtractedLoad, robot: RobotModel, q: ArrayLike) -> NDArray[np.float64]:
    """``(N, n)``: the joint torques ``load`` removes at the positions ``q`` (``(N, n)``), of ``robot`` as its
    description gives it (its gravity and nominal bodies; a robot turned to another gravity is not the description)."""
    if not isinstance(load, SubtractedLoad):
        raise TypeError(f"load must be a SubtractedLoad, got {type(load).__name__}")
    q = np.atleast_2d(np.asarray(q, dtype=float))
    rigid = build_model(robot, ModelKind.INTERNAL, ())
    rest = np.zeros_like(q)
    return np.asarray(rigid.predict(rigid.nominal_parameters(), q, rest, rest), dtype=float)


def load_channels(model: IdentificationModel) -> tuple[int, ...]:
    """The joint index (0-based) of each of ``model``'s channels, or ``()`` when a channel is not a joint torque
    (``tau<k>``): only a model of the joint torques can carry a subtracted load; nor a model with a passive joint's
    channel (its zero is physics, not a logger's subtraction: :mod:`estimation.data.passive`)."""
    indices = []
    for channel in model.channels:
        if not is_joint_torque(channel) or channel in passive_channels(model):
            return ()
        indices.append(torque_joint(channel))
    return tuple(indices)


def added_back(measurements: Measurements, load: SubtractedLoad, robot: RobotModel) -> Measurements:
    """``measurements`` with the load added back to the joint torques (and to the torques as recorded beside them,
    at their own positions): the robot's torques, which the model fits."""
    recorded = None if measurements.recorded is None else added_back(measurements.recorded, load, robot)
    if measurements.tau is None:
        return replace(measurements, recorded=recorded)
    return replace(measurements, tau=measurements.tau + subtracted_torque(load, robot, measurements.q),
                   recorded=recorded)


def added_back_records(records: PreparedRecords, load: SubtractedLoad, robot: RobotModel) -> PreparedRecords:
    """``records`` with the load added back to every record's torques (:func:`added_back`: the prepared
    measurements and the segments as read, whose noise floors the diagnosis compares with)."""
    def back(record: PreparedRecord | None) -> PreparedRecord | None:
        if record is None:
            return None
        files = tuple(replace(file, segments=tuple(added_back(segment, load, robot) for segment in file.segments))
                      for file in record.files)
        return replace(record, files=files, measurements=added_back(record.measurements, load, robot))
    return replace(records, train=back(records.train), validation=back(records.validation), test=back(records.test))
