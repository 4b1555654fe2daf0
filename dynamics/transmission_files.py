"""Transmissions read from files: a URDF's ``<transmission>`` elements, or a small JSON file.

The conventions (``θ_m = R q``, ``τ = Rᵀ τ_m``) and the ros_control kinds are described in
:mod:`dynamics.transmission`.
"""

from __future__ import annotations

import json
import xml.etree.ElementTree as ElementTree
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

import numpy as np

from dynamics.robot import RobotModel
from dynamics.servos import ServoLaws
from dynamics.transmission import (
    CouplingShapeError,
    JointDirections,
    Transmission,
    TransmissionError,
    UnknownJointError,
)


def _joint_index(robot: RobotModel, key: Any, where: str) -> int:
    """0-based index of a joint given by name or 1-based number."""
    if isinstance(key, str) and key in robot.joint_names:
        return robot.joint_names.index(key)
    text = str(key).strip()
    if text.isdigit() and 1 <= int(text) <= robot.n_joints:
        return int(text) - 1
    raise UnknownJointError(f"{where}: joint {key!r} is not a joint of {robot.name} "
                            f"(joints: {', '.join(robot.joint_names)}, or 1..{robot.n_joints})")


def transmission_from_json(source: str | Path | Mapping[str, Any], robot: RobotModel) -> Transmission:
    """A transmission from a JSON file (or the parsed document).

    Format (SI; joints by name or 1-based number)::

        {"ratios": {"joint1": -62.61, "joint2": 107.8, ...}   # or a list, one per joint
         "matrix": [[...], ...],                               # or the full R, n x n (motors x joints)
         "joints": ["joint1", ...],                            # optional: the column order of "matrix"
         "couplings": {"6": {"5": 76.69, "4": 1.41}},          # optional: extra entries R[motor][joint]
         "torque_constants": [0.26, ...],                      # optional, N·m/A, per motor
         "offsets": {"joint2": -1.5708}}                       # optional, rad (m): q = R⁻¹ θ_m + offset

    Joints not named in ``ratios`` are direct drive (ratio 1); joints not named in ``offsets`` have none.
    ``offsets`` (by joint name or number, or a list, one per joint) are the joint positions, in the robot
    description's zeros, where the motors' encoders read zero (:class:`dynamics.transmission.Transmission`).
    """
    where = "transmission"
    if isinstance(source, Mapping):
        document = dict(source)
    else:
        path = Path(source)
        where = f"transmission {path}"
        if not path.is_file():
            raise FileNotFoundError(f"transmission file not found: {path}")
        try:
            document = json.loads(path.read_text())
        except json.JSONDecodeError as error:
            raise TransmissionError(f"{where}: not valid JSON ({error})") from None
    if not isinstance(document, dict):
        raise TransmissionError(f"{where}: expected a JSON object with 'ratios' or 'matrix'")
    unknown = sorted(set(document) - {"ratios", "matrix", "joints", "couplings", "torque_constants", "motors",
                                      "offsets", "servos"})
    if unknown:
        raise TransmissionError(f"{where}: unknown key(s) {unknown}; expected ratios, matrix, joints, couplings, "
                                "torque_constants, motors, offsets, servos")
    n = robot.n_joints
    if "matrix" in document:
        if "ratios" in document:
            raise TransmissionError(f"{where}: give 'ratios' or 'matrix', not both")
        matrix = np.array(document["matrix"], dtype=float)
        if matrix.ndim != 2 or matrix.shape[0] != matrix.shape[1]:
            raise CouplingShapeError(f"{where}: matrix must be square (motors x joints), got shape {matrix.shape}")
        order = document.get("joints")
        if order is not None:
            if len(order) != matrix.shape[1]:
                raise CouplingShapeError(f"{where}: {len(order)} joints for a {matrix.shape[1]}-column matrix")
            columns = [_joint_index(robot, key, where) for key in order]
            if matrix.shape[0] != n:
                raise CouplingShapeError(f"{where}: matrix is {matrix.shape[0]} x {matrix.shape[1]}, the robot "
                                         f"{robot.name} has {n} joints: R must be {n} x {n}")
            full = np.zeros((n, n))
            full[:, columns] = matrix
            matrix = full
        elif matrix.shape != (n, n):
            raise CouplingShapeError(f"{where}: matrix is {matrix.shape[0]} x {matrix.shape[1]}, the robot "
                                     f"{robot.name} has {n} joints: R must be {n} x {n}")
    else:
        ratios = document.get("ratios", {})
        matrix = np.eye(n)
        if isinstance(ratios, Mapping):
            for key, value in ratios.items():
                index = _joint_index(robot, key, where)
                matrix[index, index] = float(value)
        else:
            values = np.atleast_1d(np.asarray(ratios, dtype=float))
            if values.shape != (n,):
                raise CouplingShapeError(f"{where}: {values.size} ratios for the {n} joints of {robot.name}")
            matrix = np.diag(values)
    for motor_key, row in dict(document.get("couplings", {})).items():
        motor = _joint_index(robot, motor_key, where)
        for joint_key, value in dict(row).items():
            matrix[motor, _joint_index(robot, joint_key, where)] = float(value)
    offsets = joint_offsets(document["offsets"], robot, where) if document.get("offsets") is not None else None
    servos = None
    if document.get("servos") is not None:  # an MJCF's servo laws, kept with a model file's transmission
        try:
            servos = ServoLaws.from_dict(document["servos"], f"{where}: servos")
        except ValueError as error:
            raise TransmissionError(str(error)) from None
        if servos.n_joints != n:
            raise CouplingShapeError(f"{where}: servos for {servos.n_joints} joints, the robot has {n}")
    return Transmission(matrix, tuple(document.get("motors", ())), document.get("torque_constants"),
                        source=where, offsets=offsets, servos=servos).check(robot)


def joint_offsets(values: Any, robot: RobotModel, where: str = "offsets") -> tuple[float, ...]:
    """One offset a joint (rad, or m) from a mapping by joint name or 1-based number (joints not named: 0) or a
    list of one a joint; :class:`TransmissionError` naming ``where`` for anything else (text, NaN, a wrong count)."""
    return _per_joint(values, robot, where, default=0.0, convert=_offset, what="offsets",
                      example='{"joint2": -1.5708}', unit="numbers (rad, or m)")


def _per_joint(values: Any, robot: RobotModel, where: str, *, default: float, convert: Callable[[Any, str], float],
               what: str, example: str, unit: str) -> tuple[float, ...]:
    """One value a joint, each checked by ``convert``, from a mapping by joint name or 1-based number (joints not
    named: ``default``) or a list of one a joint; :class:`TransmissionError` (or :class:`CouplingShapeError`,
    :class:`UnknownJointError`) naming ``where`` for anything else."""
    n = robot.n_joints
    if isinstance(values, Mapping):
        found = [default] * n
        for key, value in values.items():
            found[_joint_index(robot, key, where)] = convert(value, f"{where}: joint {key!r}")
        return tuple(float(value) for value in found)
    if isinstance(values, (str, bytes)) or not isinstance(values, (list, tuple)):
        raise TransmissionError(f"{where}: {what} must be an object by joint ({example}) or a list of {n} {unit}, "
                                f"got {values!r}")
    if len(values) != n:
        raise CouplingShapeError(f"{where}: {len(values)} {what} for the {n} joints of {robot.name}")
    return tuple(convert(value, f"{where}: {what[:-1]} {index + 1}") for index, value in enumerate(values))


#: the entries of a ``--joint-offsets`` JSON object (any other key is a joint's offset)
CONVENTION_KEYS = ("offsets", "signs", "torque_signs")


def read_joint_offsets(path: str | Path, robot: RobotModel) -> tuple[float, ...]:
    """The joint offsets of ``--joint-offsets FILE`` (rad, or m; added to the recorded joint positions).

    ``.json``: ``{"offsets": {...}}`` (beside it, optionally, ``"signs"`` and ``"torque_signs"``: see
    :func:`read_joint_directions`), or the object itself, by joint name or 1-based number (``{"joint2":
    -1.5708}``), or a list of one a joint; ``.csv``: the columns ``joint`` and ``offset`` (and optionally ``sign``,
    ``torque_sign``), one row a joint. Joints not named: 0. :class:`TransmissionError` (or
    :class:`UnknownJointError`, :class:`CouplingShapeError`) naming the file for anything else.
    """
    return _read_conventions(path, robot)[0]


def read_joint_directions(path: str | Path, robot: RobotModel) -> JointDirections | None:
    """The joints' directions of ``--joint-offsets FILE``, or ``None`` when it declares none reversed.

    ``.json``: ``"signs"`` (the recorded ``q``, ``dq``, ``ddq`` of the joint times it) and ``"torque_signs"`` (its
    recorded torque times it), each an object by joint name or 1-based number (``{"joint2": -1}``; joints not named:
    +1) or a list of one a joint, beside ``"offsets"``; ``.csv``: the columns ``sign`` and ``torque_sign``. Applied
    before the offsets: the description's ``q = sign · recorded q + offset``
    (:class:`dynamics.transmission.JointDirections`).
    """
    directions = _read_conventions(path, robot)[1]
    return directions if directions.reversed else None


def _read_conventions(path: str | Path, robot: RobotModel) -> tuple[tuple[float, ...], JointDirections]:
    path = Path(path)
    where = f"joint offsets {path}"
    if not path.is_file():
        raise FileNotFoundError(f"joint offsets file not found: {path}")
    suffix = path.suffix.lower()
    n = robot.n_joints
    if suffix == ".json":
        try:
            document = json.loads(path.read_text())
        except (json.JSONDecodeError, UnicodeDecodeError) as error:
            raise TransmissionError(f"{where}: not valid JSON ({error})") from None
        if isinstance(document, dict) and document and set(document) <= set(CONVENTION_KEYS):
            offsets = joint_offsets(document["offsets"], robot, where) if "offsets" in document else (0.0,) * n
            return offsets, JointDirections(*(_signs(document.get(key), robot, f"{where}: {key}")
                                              for key in ("signs", "torque_signs")))
        return joint_offsets(document, robot, where), JointDirections((1.0,) * n, (1.0,) * n)
    if suffix == ".csv":
        import pandas as pd

        try:
            frame = pd.read_csv(path, dtype=str)
        except (ValueError, OSError, pd.errors.ParserError) as error:
            raise TransmissionError(f"{where}: cannot read it ({error})") from None
        frame = frame.rename(columns=lambda name: str(name).strip().lower())
        if "joint" not in frame.columns or not {"offset", "sign", "torque_sign"} & set(frame.columns):
            raise TransmissionError(f"{where}: give the columns joint and offset (one row a joint; optionally sign "
                                    f"and torque_sign), got {', '.join(map(str, frame.columns)) or 'none'}")
        joints = [str(value).strip() for value in frame["joint"]]
        if len(set(joints)) != len(joints):
            raise TransmissionError(f"{where}: a joint named twice")
        offsets = (joint_offsets({joint: value for joint, value in zip(joints, frame["offset"].str.strip())
                                  if value == value}, robot, where)  # a blank cell (NaN): the joint's default
                   if "offset" in frame.columns else (0.0,) * n)
        return offsets, JointDirections(*(
            _signs({joint: value for joint, value in zip(joints, frame[column].str.strip()) if value == value},
                   robot, f"{where}: {column}") if column in frame.columns else (1.0,) * n
            for column in ("sign", "torque_sign")))
    raise TransmissionError(f"{where}: give a .json or .csv file")


def _signs(values: Any, robot: RobotModel, where: str) -> tuple[float, ...]:
    """One sign a joint (+1 or -1) from a mapping by joint name or number (joints not named: +1) or a list."""
    if values is None:
        return (1.0,) * robot.n_joints
    return _per_joint(values, robot, where, default=1.0, convert=_sign, what="signs", example='{"joint2": -1}',
                      unit="signs")


def _sign(value: Any, where: str) -> float:
    number = None if isinstance(value, bool) else _number(value)
    if number not in (1.0, -1.0):
        raise TransmissionError(f"{where}: {value!r} is not a sign (+1 or -1)")
    return float(number)


def _number(value: Any) -> float | None:
    try:
        return float(value)
    except (TypeError, ValueError):
        return None


def _offset(value: Any, where: str) -> float:
    if isinstance(value, bool):
        raise TransmissionError(f"{where}: {value!r} is not a number (rad, or m)")
    try:
        number = float(value)
    except (TypeError, ValueError):
        raise TransmissionError(f"{where}: {value!r} is not a number (rad, or m)") from None
    if not np.isfinite(number):
        raise TransmissionError(f"{where}: {value!r} must be finite")
    return number


def _reduction(element: ElementTree.Element | None) -> float:
    if element is None:
        return 1.0
    found = element.find("mechanicalReduction")
    if found is None or found.text is None:
        return 1.0
    try:
        value = float(found.text.strip())
    except ValueError:
        raise TransmissionError(f"mechanicalReduction {found.text!r} is not a number") from None
    if not np.isfinite(value) or value == 0:
        raise TransmissionError(f"mechanicalReduction {found.text!r} must be a finite, non-zero number")
    return value


def transmission_from_urdf(path: str | Path, robot: RobotModel) -> Transmission | None:
    """The transmission declared by a URDF's ``<transmission>`` elements, or ``None`` if it has none.

    Kinds (ros_control ``transmission_interface``): ``SimpleTransmission`` (one joint, one actuator,
    ``mechanicalReduction`` of the actuator, or of the joint in the older format),
    ``DifferentialTransmission`` and ``FourBarLinkageTransmission`` (two joints, two actuators,
    actuator reductions ``ar`` and joint reductions ``jr``, see the module docstring). A joint's ``<offset>``
    (ros_control's joint offset, rad or m) is its offset ``q₀``: ``q = R⁻¹ θ_m + q₀``.

    The transmissions of joints of the file that ``robot`` leaves out (locked: a robot of the named
    joints, :func:`dynamics.urdf.robot_from_urdf`) are ignored; those of its joints are kept.

    Raises
    ------
    UnknownJointError
        A transmission names a joint the robot lacks (and the file's movable joints do not hold).
    TransmissionError
        An unsupported kind, a joint driven by two transmissions, or one coupling a joint of the
        robot with a locked one.
    """
    path = Path(path)
    try:
        root = ElementTree.parse(path).getroot()
    except (ElementTree.ParseError, OSError) as error:
        raise TransmissionError(f"cannot read the transmissions of {path}: {error}") from None
    locked = {joint.get("name") for joint in root.iter("joint")
              if joint.get("type") not in (None, "fixed") and joint.get("name") not in robot.joint_names}
    elements = []
    for element in root.findall("transmission"):
        joint_names = [joint.get("name", "") for joint in element.findall("joint")]
        if joint_names and all(name in locked for name in joint_names):
            continue  # a locked joint's
        if any(name in locked for name in joint_names):
            raise TransmissionError(f"URDF {path}: transmission {element.get('name', '?')!r} couples joints of the "
                                    f"robot with locked joints ({', '.join(joint_names)}): name them all or none")
        elements.append(element)
    if not elements:
        return None
    n = robot.n_joints
    matrix = np.eye(n)
    offsets = np.zeros(n)
    driven: dict[int, str] = {}
    names = [f"m{index}" for index in range(1, n + 1)]
    for element in elements:
        label = element.get("name", "?")
        where = f"URDF {path}: transmission {label!r}"
        kind_element = element.find("type")
        kind = (kind_element.text if kind_element is not None and kind_element.text else element.get("type", "")).strip()
        joints = element.findall("joint")
        actuators = element.findall("actuator")
        indices = [_joint_index(robot, joint.get("name", ""), where) for joint in joints]
        for index, joint in zip(indices, joints):
            if index in driven:
                raise TransmissionError(f"{where}: joint {robot.joint_names[index]!r} is already driven by "
                                        f"transmission {driven[index]!r}")
            driven[index] = label
            found = joint.find("offset")
            if found is not None and found.text is not None:
                offsets[index] = _offset(found.text.strip(), f"{where}: joint {robot.joint_names[index]!r} <offset>")
        short = kind.rsplit("/", 1)[-1]
        if short == "SimpleTransmission":
            if len(joints) != 1 or len(actuators) > 1:
                raise TransmissionError(f"{where}: a SimpleTransmission has one joint and one actuator")
            reduction = _reduction(actuators[0] if actuators else None) * _reduction(joints[0])
            matrix[indices[0], indices[0]] = reduction
            if actuators and actuators[0].get("name"):
                names[indices[0]] = actuators[0].get("name")
        elif short in ("DifferentialTransmission", "FourBarLinkageTransmission"):
            if len(joints) != 2 or len(actuators) != 2:
                raise TransmissionError(f"{where}: a {short} has two joints and two actuators")
            ar = [_reduction(actuator) for actuator in actuators]
            jr = [_reduction(joint) for joint in joints]
            first, second = indices
            matrix[first, first] = matrix[second, second] = 0.0
            if short == "DifferentialTransmission":
                matrix[first, [first, second]] = (jr[0] * ar[0], jr[1] * ar[0])
                matrix[second, [first, second]] = (jr[0] * ar[1], -jr[1] * ar[1])
            else:
                matrix[first, first] = jr[0] * ar[0]
                matrix[second, [first, second]] = (ar[1], jr[1] * ar[1])
            for index, actuator in zip(indices, actuators):
                if actuator.get("name"):
                    names[index] = actuator.get("name")
        else:
            raise TransmissionError(f"{where}: unsupported transmission type {kind!r} (SimpleTransmission, "
                                    "DifferentialTransmission, FourBarLinkageTransmission)")
    return Transmission(matrix, tuple(names), source=f"URDF {path}", offsets=tuple(offsets))
