"""Logs as robot vendors' controllers and drivers write them, read without a column map.

A controller's or driver's log names each joint quantity by a word and the joint by an index or its name:
Universal Robots' RTDE recorder ``actual_q_0..5``, ``actual_qd_0..5``, ``actual_current_0..5``, ``target_moment_0..5``;
libfranka's ``q[0]..q[6]``, ``tau_J[0]..``, ``tau_J_d[0]..``, ``tau_ext_hat_filtered[0]..``; KUKA's FRI
``measured_joint_position``, ``measured_torque``, ``commanded_torque``, ``external_torque`` (or ``msrJntPos1..``,
``AxisActPos_A1..``); a Kinova Kortex export's ``actuators[0].position``; a ``joint_states`` table's
``/joint_states/<joint>/effort``; a cell holding the whole array (``"[0.1, 0.2, ...]"``). One rule reads them all:

1. **Joint groups.** Columns whose names differ only in one number (``actual_q_0``, ``actual_q_1``…, the number
   anywhere in the name: ``actuators[3].position``) and whose numbers are ``0..n-1`` or ``1..n`` for the robot's
   ``n`` joints form a group, numbered from 0 or from 1 (joint 1 is index 0, or 1); so do columns that differ only
   in the robot's joint names (in the robot's order), or whose index a column of joint names beside them gives. A
   cell holding an array (``"[0.1, 0.2]"``) is read as one column an element first.
2. **What a group holds**, by the words of its name (camelCase and ``_ . / [ ]`` split, case ignored):
   :data:`QUANTITY_WORDS` (a position, velocity, acceleration, torque or current); :data:`COMMAND_WORDS` make it
   a command (``target``, ``cmd``, ``desired``, franka's ``_d``...), :data:`EXTERNAL_WORDS` an external torque,
   :data:`ESTIMATE_WORDS` a torque estimate (franka's ``_hat``); :data:`OTHER_WORDS` make it no joint quantity
   (the tool's speed, a temperature). A unit in brackets (``[deg]``, ``(mA)``) is turned into SI units. Two
   formats name the quantity by the message rather than a word: ABB EGM's ``feedBack.joints`` (measured) and
   ``planned.joints`` (a command) are joint angles in degrees by the protocol (:data:`EGM_JOINT_WORDS`), MuJoCo's
   ``mjData`` arrays ``qpos``/``qvel``/``qacc``, ``qfrc_actuator`` (a measured joint torque), ``actuator_force``
   (actuator forces, motor side) and ``ctrl`` (controls: never a force) (:data:`MUJOCO_WORDS`).
3. **What is read**: the measured group of each quantity. Two measured groups of one quantity are a
   :class:`AmbiguousColumnsError` naming both and the map that chooses (never a guess). A measured joint torque
   is read as ``tau``; without one, measured currents as the motor currents ``im1..imn`` (turned into joint
   torques through the transmission's torque constants, ``--transmission``, as a motor-side log's: never read as
   torques in N·m); MuJoCo's actuator forces come before currents, as the motor-side ``taum1..taumn`` (joint torques
   through the gears of the MJCF's ``<actuator>``). Commanded, external and estimated torques are never read as
   the measured torque: where they are the only torques, the error names them and the map that reads one if it is
   the measured torque; MuJoCo's controls alone are refused naming the arrays that hold the force.

The reader says what it chose and what it left aside (:class:`VendorColumnsWarning`), with the ``--columns`` map
that reads the file so.
"""

from __future__ import annotations

import re
import shlex
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import pandas as pd

from dynamics.servos import ServoLaws
from estimation.data.loading import CONVERTED_UNITS, MeasurementWarning, MissingColumnError

__all__ = ["AmbiguousColumnsError", "JointGroup", "VendorColumnsWarning", "VendorReading", "array_cells",
           "joint_groups", "vendor_columns"]

#: the words naming a joint quantity, by group (``current``: a motor current, read as ``im``)
QUANTITY_WORDS = {
    "q": ("q", "pos", "position", "positions", "angle", "angles"),
    "dq": ("qd", "dq", "vel", "velocity", "velocities", "speed", "speeds"),
    "ddq": ("qdd", "ddq", "acc", "accel", "acceleration", "accelerations"),
    "tau": ("tau", "torque", "torques", "effort", "efforts", "moment", "moments", "trq"),
    "current": ("current", "currents", "cur", "curr"),
}
#: words that make a group a command (a target, a setpoint, franka's ``_d`` for desired, KUKA's ``ipo``)
COMMAND_WORDS = frozenset({"target", "commanded", "command", "cmd", "desired", "des", "d", "setpoint", "set", "ref",
                           "reference", "planned", "ipo", "demand", "demanded", "goal"})
#: words that make a torque an external one (a contact's, estimated by the controller)
EXTERNAL_WORDS = frozenset({"external", "ext", "contact", "interaction"})
#: words that make a torque an estimate rather than a measurement (franka's ``tau_ext_hat``)
ESTIMATE_WORDS = frozenset({"estimated", "estimate", "est", "hat"})
#: words that make a group no joint quantity (the tool's or the Cartesian speed, a temperature, a gain)
OTHER_WORDS = frozenset({"tcp", "tool", "cartesian", "cart", "ee", "flange", "elbow", "wrench", "force", "pose",
                         "temperature", "temperatures", "temp", "voltage", "power", "stiffness", "damping", "gain",
                         "gains", "limit", "limits", "max", "min", "error", "mode", "status", "frame", "base",
                         "world", "theta", "dtheta", "dtau", "scaling", "fraction"})
#: words that make a position, velocity or torque the motor's (a rotor's angle: not the joint's); a motor's current
#: is the current read
MOTOR_WORDS = frozenset({"motor", "motors", "rotor"})
#: ABB EGM's ``EgmJoints`` (egm.proto): a group named ``joints`` within the robot's feedback (``feedBack.joints``, the
#: measured position) or its plan (``planned.joints``, a command), no quantity word: joint angles, in degrees by the
#: protocol ("Array of 6 joint values for TCP robot in degrees"); ``externalJoints`` are the additional axes (a
#: track's, in mm or degrees), no joint of the robot's
EGM_JOINT_WORDS = frozenset({"joints"})
EGM_MESSAGE_WORDS = (frozenset({"feedback"}), frozenset({"feed", "back"}), frozenset({"planned"}))
#: the factor that turns EGM's joint angles (degrees) into radians
EGM_DEGREES = float(CONVERTED_UNITS["q"]["deg"])
#: words naming the joints by index (a ``JointState``'s ``name[0..]``)
NAME_WORDS = frozenset({"name", "names"})
#: the roles of a group, from its words
MEASURED, COMMAND, EXTERNAL, ESTIMATE = "measured", "commanded", "external", "estimated"
#: MuJoCo's ``mjData`` arrays of a joint chain (MuJoCo's API reference, ``mjData``): ``qpos``, ``qvel``, ``qacc`` the
#: joints' positions, velocities, accelerations; ``qfrc_actuator`` the actuators' joint torques (gear and
#: transmission applied: what a joint torque sensor measures of the drives), the other ``qfrc_*`` arrays not a
#: drive's (``qfrc_bias`` the model's own Coriolis and gravity, ``qfrc_passive`` its springs and damping);
#: ``actuator_force`` each actuator's force, the joint's torque through its gear (the MJCF's ``<actuator>``, read as
#: the motor-side ``taum`` through the transmission); ``ctrl`` the controls: a ``<motor>``'s force, but a
#: servo's setpoint (``<position>``: ``kp (ctrl - gear q) - kv gear q̇``; ``<velocity>``, ``<general>`` with a bias):
#: never read as a force
MUJOCO_WORDS = {"qpos": "q", "qvel": "dq", "qacc": "ddq"}
MUJOCO_FORCE = "qfrc"
ACTUATOR_FORCE_WORDS = frozenset({"actuator", "force"})
CONTROL_WORDS = frozenset({"ctrl", "control", "controls"})
#: the format's column group each quantity is read as (``actuator``: an actuator's force, motor side)
READ_AS = {"q": "q", "dq": "dq", "ddq": "ddq", "tau": "tau", "current": "im", "actuator": "taum", "control": "ctrl"}
#: units a current's name may carry, with their factor to A
CURRENT_UNITS = {"a": 1.0, "amp": 1.0, "amps": 1.0, "ma": 1e-3}
_WORD = re.compile(r"[A-Z]+(?![a-z])|[A-Z]?[a-z]+")
_UNIT = re.compile(r"\s*[\[(]([^\[\]()]*)[\])]\s*$")
_ARRAY_CELL = re.compile(r"^\s*[\[(](.*)[\])]\s*$")


class VendorColumnsWarning(MeasurementWarning):
    """A table without the format's ``q1..`` columns was read as a controller's or driver's log: the message names
    the groups read, those left aside (commands, external torques, temperatures...) and the ``--columns`` map
    that reads the file so."""


class AmbiguousColumnsError(MissingColumnError):
    """Two groups of columns could each be the measured joint position, velocity or torque, and no rule chooses:
    the message names both and the ``--columns`` map that reads either."""


@dataclass(frozen=True)
class JointGroup:
    """Columns holding one quantity of every joint.

    Attributes
    ----------
    pattern
        The columns' name with the joint's place as ``{}`` (``actual_q_{}``).
    columns
        One column a joint, in the robot's order.
    quantity
        A key of :data:`QUANTITY_WORDS`, or ``""`` for no joint quantity (a temperature).
    role
        :data:`MEASURED`, :data:`COMMAND`, :data:`EXTERNAL` or :data:`ESTIMATE`.
    factor
        What turns the values into SI units (a unit in the name: ``[deg]``), 1 otherwise.
    numbering
        How the joints are told: ``"numbered from 0"``, ``"numbered from 1"``, ``"by the robot's joint names"``,
        ``"by the joint names logged beside"``.
    note
        What the reading took from the format rather than the name (EGM's degrees), for the messages; ``""``.
    """

    pattern: str
    columns: tuple[str, ...]
    quantity: str
    role: str
    factor: float
    numbering: str
    note: str = ""

    @property
    def shown(self) -> str:
        """The group for a message: ``actual_q_0..actual_q_5``."""
        return f"{self.columns[0]}..{self.columns[-1]}" if len(self.columns) > 1 else self.columns[0]


@dataclass(frozen=True)
class VendorReading:
    """What :func:`vendor_columns` read: ``columns`` the column map (``{"q1": "actual_q_0", ...}``), ``chosen`` and
    ``aside`` the groups read and left, ``message`` what a :class:`VendorColumnsWarning` says."""

    columns: dict[str, str]
    chosen: tuple[JointGroup, ...]
    aside: tuple[JointGroup, ...]
    message: str


def name_words(text: str) -> list[str]:
    """The words of a column's name, lower case: camelCase and every other character split (``msrJntPos`` as
    ``msr jnt pos``, ``tau_J_d`` as ``tau j d``, ``actual_TCP_speed`` as ``actual tcp speed``)."""
    return [word.lower() for word in _WORD.findall(text)]


def array_cells(frame: pd.DataFrame) -> pd.DataFrame:
    """``frame`` with each column whose cells hold arrays (``"[0.1, 0.2, 0.3]"``, ``"(1 2 3)"``, the same length on
    every row) read as one column an element, named ``<column>[k]`` from 0; other columns as they are."""
    expanded: dict[str, pd.Series] = {}
    changed = False
    for column in frame.columns:
        values = frame[column]
        if pd.api.types.is_numeric_dtype(values) or not len(values):
            expanded[column] = values
            continue
        cells = values.astype(str)
        inner = cells.str.extract(_ARRAY_CELL, expand=False)
        if inner.isna().any():
            expanded[column] = values
            continue
        parts = inner.str.strip().str.split(r"\s*[,;]\s*|\s+", regex=True)
        lengths = parts.map(len)
        if lengths.nunique() != 1 or int(lengths.iloc[0]) < 2:
            expanded[column] = values
            continue
        table = pd.DataFrame(parts.tolist(), index=frame.index)
        numbers = table.apply(pd.to_numeric, errors="coerce")
        table = numbers if numbers.notna().all().all() else table.apply(lambda part: part.str.strip("'\" "))
        for index in table.columns:
            expanded[f"{column}[{index}]"] = table[index]
        changed = True
    return pd.DataFrame(expanded, index=frame.index) if changed else frame


def _unit_factor(pattern: str, quantity: str) -> float | None:
    """The factor to SI of a unit in brackets at the end of ``pattern`` (``[deg]``, ``(mA)``): 1 for SI or no unit,
    ``None`` for a unit of another quantity."""
    found = _UNIT.search(pattern.replace("{}", ""))
    unit = re.sub(r"[\s·.*^]", "", found.group(1)).lower() if found else ""
    if not unit:
        return 1.0
    if quantity == "current":
        return CURRENT_UNITS.get(unit)
    group = "tau" if quantity == "tau" else quantity
    if unit in CONVERTED_UNITS.get(group, {}):
        return float(CONVERTED_UNITS[group][unit])
    return 1.0 if unit in {"rad", "m", "rad/s", "m/s", "rad/s2", "rad/s²", "m/s2", "nm", "n"} else None


def _egm_joints(pattern: str, words: set[str]) -> tuple[str, str, float, str] | None:
    """``(quantity, role, factor, note)`` of ABB EGM's joint angles (:data:`EGM_JOINT_WORDS`): ``feedBack.joints``
    measured, ``planned.joints`` commanded, in degrees unless the name's unit says otherwise; ``None`` for any other
    group (``externalJoints``: the additional axes)."""
    if not words & EGM_JOINT_WORDS or words & EXTERNAL_WORDS or words & OTHER_WORDS or words & MOTOR_WORDS:
        return None
    if not any(message <= words for message in EGM_MESSAGE_WORDS):
        return None
    unit = _UNIT.search(pattern.replace("{}", ""))
    named = unit is not None and bool(unit.group(1).strip())
    factor = _unit_factor(pattern, "q") if named else EGM_DEGREES
    if factor is None:
        return None
    role = COMMAND if words & COMMAND_WORDS else MEASURED
    return "q", role, factor, "" if named else "ABB EGM's joint angles, degrees by its protocol"


def _mujoco_group(words: set[str]) -> tuple[str, str, float, str] | None:
    """``(quantity, role, factor, note)`` of MuJoCo's ``mjData`` arrays (:data:`MUJOCO_WORDS`): ``qpos``/``qvel``/
    ``qacc`` measured, ``qfrc_actuator`` a measured joint torque, ``actuator_force`` actuator forces, ``ctrl`` the
    controls (``control``, commanded), any other ``qfrc_*`` no joint quantity; ``None`` for other names."""
    if words & OTHER_WORDS - {"force"} or words & MOTOR_WORDS:
        return None
    named = [MUJOCO_WORDS[word] for word in words if word in MUJOCO_WORDS]
    if len(named) == 1 and len(words) == 1:
        return named[0], MEASURED, 1.0, ""
    if MUJOCO_FORCE in words:
        return ("tau", MEASURED, 1.0, "MuJoCo's actuators' joint torques") if "actuator" in words \
            else ("", MEASURED, 1.0, "")
    if words == ACTUATOR_FORCE_WORDS:
        return "actuator", MEASURED, 1.0, ""
    if words & CONTROL_WORDS and len(words) == 1:
        return "control", COMMAND, 1.0, ""
    return None


def _described(pattern: str) -> tuple[str, str, float, str]:
    """``(quantity, role, factor, note)`` of a group's pattern by its words (module docstring, 2)."""
    words = set(name_words(_UNIT.sub("", pattern.replace("{}", " "))))
    mujoco = _mujoco_group(words)
    if mujoco is not None:
        return mujoco
    quantities = {quantity for quantity, names in QUANTITY_WORDS.items() if words & set(names)}
    if not quantities:
        egm = _egm_joints(pattern, words)
        if egm is not None:
            return egm
    if len(quantities) != 1 or words & OTHER_WORDS:
        return "", MEASURED, 1.0, ""
    quantity = quantities.pop()
    if quantity != "current" and words & MOTOR_WORDS:
        return "", MEASURED, 1.0, ""
    role = MEASURED
    if words & COMMAND_WORDS:
        role = COMMAND
    elif quantity in ("tau", "current") and words & EXTERNAL_WORDS:
        role = EXTERNAL
    elif quantity in ("tau", "current") and words & ESTIMATE_WORDS:
        role = ESTIMATE
    factor = _unit_factor(pattern, quantity)
    return (quantity, role, factor, "") if factor is not None else ("", MEASURED, 1.0, "")


def _named_indices(frame: pd.DataFrame, by_pattern: dict[str, dict[int, str]],
                   joint_names: Sequence[str] | None) -> dict[frozenset[int], dict[int, int]]:
    """For index groups beside a group of joint names (``name[0..]``, text), the robot's joint (1-based) of each
    index, by the index set the names cover; only where every robot joint is named, the same on every row."""
    found: dict[frozenset[int], dict[int, int]] = {}
    if not joint_names:
        return found
    for pattern, indexed in by_pattern.items():
        if not set(name_words(pattern.replace("{}", " "))) & NAME_WORDS:
            continue
        cells = frame[[indexed[index] for index in sorted(indexed)]].astype(str)
        if not len(cells) or not (cells == cells.iloc[0]).all().all():
            continue
        logged = [str(value).strip() for value in cells.iloc[0]]
        if all(name in logged for name in joint_names):
            found[frozenset(indexed)] = {index: list(joint_names).index(name) + 1
                                         for index, name in zip(sorted(indexed), logged) if name in joint_names}
    return found


def joint_groups(frame: pd.DataFrame, joint_names: Sequence[str] | None, n_joints: int) -> list[JointGroup]:
    """The joint groups of ``frame`` (module docstring, 1 and 2): each group's columns in the robot's order, a
    column in one group at most (a group by the robot's joint names first), in the order of the columns."""
    columns = [str(column) for column in frame.columns]
    by_name: dict[str, dict[int, str]] = {}
    names = sorted(((str(name), index) for index, name in enumerate(joint_names or (), start=1)),
                   key=lambda item: -len(item[0]))
    for column in columns:
        for name, index in names:
            found = re.search(rf"(?<![A-Za-z0-9]){re.escape(name)}(?![A-Za-z0-9])", column, flags=re.IGNORECASE)
            if found:
                by_name.setdefault(column[:found.start()] + "{}" + column[found.end():], {})[index] = column
                break
    by_index: dict[str, dict[int, str]] = {}
    for column in columns:
        for found in re.finditer(r"\d+", column):
            pattern = column[:found.start()] + "{}" + column[found.end():]
            by_index.setdefault(pattern, {})[int(found.group())] = column
    named_indices = _named_indices(frame, by_index, joint_names)
    groups: list[JointGroup] = []
    taken: set[str] = set()
    candidates: list[tuple[str, dict[int, str], str]] = []
    for pattern, joints in by_name.items():
        if sorted(joints) == list(range(1, n_joints + 1)):
            candidates.append((pattern, joints, "by the robot's joint names"))
    for pattern, indexed in by_index.items():
        indices = sorted(indexed)
        if frozenset(indices) in named_indices and not set(name_words(pattern.replace("{}", " "))) & NAME_WORDS:
            mapping = named_indices[frozenset(indices)]
            candidates.append((pattern, {mapping[index]: indexed[index] for index in mapping}, "by the joint names logged beside"))
        elif indices == list(range(n_joints)):
            candidates.append((pattern, {index + 1: indexed[index] for index in indices}, "numbered from 0"))
        elif indices == list(range(1, n_joints + 1)):
            candidates.append((pattern, dict(indexed), "numbered from 1"))
    for pattern, joints, numbering in candidates:
        group_columns = tuple(joints[joint] for joint in range(1, n_joints + 1))
        if taken & set(group_columns):
            continue
        values = frame[list(group_columns)]
        if not all(pd.api.types.is_numeric_dtype(values[column]) for column in group_columns):
            continue  # text (joint names, modes)
        quantity, role, factor, note = _described(pattern)
        groups.append(JointGroup(pattern, group_columns, quantity, role, factor, numbering, note))
        taken.update(group_columns)
    return sorted(groups, key=lambda group: columns.index(group.columns[0]))


def _entries(group: JointGroup, key: str, frame: pd.DataFrame) -> dict[str, str]:
    """The column map entries that read ``group`` as ``key`` (``q``, ``im``): one by prefix where the joint's number
    ends the name and no other column shares the prefix, else one a joint."""
    scale = "" if group.factor == 1.0 else f"{group.factor!r}*"
    prefix = group.pattern[:-2] if group.pattern.endswith("{}") else None
    if prefix and group.numbering in ("numbered from 0", "numbered from 1") and key not in ("im", "taum", "ctrl"):
        sharing = [column for column in frame.columns if re.fullmatch(re.escape(prefix) + r"\d+", str(column))]
        if len(sharing) == len(group.columns):
            return {key: f"{scale}{prefix}"}
    return {f"{key}{joint}": f"{scale}{column}" for joint, column in enumerate(group.columns, start=1)}


#: what each quantity's group holds, for messages
SHOWN = {"q": "positions", "dq": "velocities", "ddq": "accelerations", "tau": "torques", "current": "currents",
         "actuator": "actuator forces", "control": "controls", "": ""}


def _measured(groups: list[JointGroup], quantity: str) -> list[JointGroup]:
    return [group for group in groups if group.quantity == quantity and group.role == MEASURED]


def vendor_columns(frame: pd.DataFrame, joint_names: Sequence[str] | None, n_joints: int, source: str, *,
                   torque: bool = True, time: str | None = None, controls: bool = False) -> VendorReading | None:
    """The column map that reads ``frame`` as a controller's log (module docstring), for the format's groups it
    lacks (no ``q1``...); ``None`` where it lacks none or no joint group of its names is measured.

    Parameters
    ----------
    frame
        The table as read (arrays in cells already split, :func:`array_cells`).
    joint_names
        The robot's joints, in its order (columns and ``name[k]`` cells are matched to them), or ``None``.
    n_joints
        The robot's number of joints.
    source
        The file, for messages.
    torque
        Whether the joint torques are needed (an internal model): only then are commanded or external torques
        without a measured one an error.
    time
        The column map's entry of the time where the file names it otherwise (``timestamp``): the maps the messages
        give read the whole file.
    controls
        Whether the servos' laws are known (an MJCF's, :class:`dynamics.servos.ServoLaws`): MuJoCo's controls, where
        no force is logged, are then read as ``ctrl1..ctrln`` for the reader to compute the force from; otherwise
        they are refused.

    Raises
    ------
    AmbiguousColumnsError
        Two measured groups of one quantity.
    MissingColumnError
        Torques needed and only commanded, external or estimated ones logged; positions logged as commands only.
    """
    present = {str(column) for column in frame.columns}
    lacking = [key for key in ("q", "dq", "ddq", "tau") if f"{key}1" not in present]
    if not lacking or n_joints < 1:
        return None
    groups = joint_groups(frame, joint_names, n_joints)
    chosen: dict[str, JointGroup] = {}
    ambiguous: dict[str, list[JointGroup]] = {}
    for quantity in lacking:
        measured = _measured(groups, quantity)
        if len(measured) > 1:
            ambiguous[quantity] = measured
        elif measured:
            chosen[quantity] = measured[0]
    if "tau" in lacking and "tau" not in chosen and "tau" not in ambiguous and not {"im1", "taum1"} & present:
        for motor_side in ("actuator", "current"):  # an actuator's force (a gear from the torque), else a current
            measured = _measured(groups, motor_side)
            if len(measured) > 1:
                ambiguous[motor_side] = measured
            elif measured:
                chosen[motor_side] = measured[0]
            if measured:
                break

    def mapped(quantity: str | None = None, group: JointGroup | None = None) -> str:
        """``--columns`` reading the chosen groups (and ``group`` as ``quantity``), quoted for a shell."""
        entries = {"t": time} if time else {}
        for key, value in chosen.items():
            entries.update(_entries(value, READ_AS[key], frame))
        if group is not None:
            entries.update(_entries(group, READ_AS[quantity], frame))
        return "--columns " + shlex.quote(",".join(f"{key}={value}" for key, value in entries.items()))

    if ambiguous:
        quantity, measured = next(iter(ambiguous.items()))
        raise AmbiguousColumnsError(
            f"{source}: {' and '.join(group.shown for group in measured)} could each be the measured joint "
            f"{SHOWN[quantity]}, and no rule chooses between them: name yours, "
            + " or ".join(mapped(quantity, group) for group in measured[:2]))
    if "tau" in lacking and torque and not {"tau", "current", "actuator"} & set(chosen) \
            and not {"im1", "taum1"} & present:
        found = [group for group in groups if group.quantity == "control"]
        if found and controls and ("q" in chosen or "q" not in lacking):
            chosen["control"] = found[0]  # a servo's setpoint: its force computed from the MJCF's law and the state
        controls = [] if "control" in chosen else found
        if controls and ("q" in chosen or "q" not in lacking):
            raise MissingColumnError(
                f"{source}: no measured joint torque: {controls[0].shown} are MuJoCo's controls, not forces: a "
                "servo's (<position>, <velocity>, a <general> with a bias) is its setpoint, the force it makes "
                "depends on the state and its gains; log data.qfrc_actuator (the actuators' joint torques) or "
                "data.actuator_force (their forces, read through the gears of the MJCF's <actuator>); if every "
                "actuator is a <motor> (gain 1, no bias, its ctrl its force), read the controls as the actuator "
                "forces with " + mapped("actuator", controls[0]))
        others = [group for group in groups if group.quantity == "tau"]
        if others and ("q" in chosen or "q" not in lacking):
            raise MissingColumnError(
                f"{source}: no measured joint torque: the torques logged are "
                + ", ".join(f"{group.shown} ({group.role})" for group in others)
                + ", and a commanded, external or estimated torque is not the torque the joint measured; if one is"
                " (a controller that logs its measurement so), read it with " + mapped("tau", others[0]))
    if "q" in lacking and "q" not in chosen:
        commanded = [group for group in groups if group.quantity == "q"]
        if commanded and (chosen or "tau" not in lacking):
            raise MissingColumnError(
                f"{source}: no measured joint positions: the positions logged are "
                + ", ".join(f"{group.shown} ({group.role})" for group in commanded)
                + "; the motion the joints made is needed (if one is it: " + mapped("q", commanded[0]) + ")")
    if "q" not in chosen and ("q" in lacking or not chosen):
        return None
    columns: dict[str, str] = {}
    for quantity, group in chosen.items():
        columns.update(_entries(group, READ_AS[quantity], frame))
    aside = tuple(group for group in groups if group not in chosen.values()  # the format's own columns are read
                  and not re.fullmatch(r"(q|dq|ddq|tau|im|taum)\{\}", group.pattern))
    said = [f"{READ_AS[quantity]} from {group.shown} ({group.numbering}"
            + (f", x{group.factor:g} to SI" if group.factor != 1.0 else "")
            + (f": {group.note}" if group.note else "")
            + (", motor currents: turned into joint torques by the transmission's torque constants, --transmission"
               if quantity == "current" else "")
            + (", actuator forces: turned into joint torques by the actuators' gears (the MJCF's <actuator>, or "
               "--transmission)" if quantity == "actuator" else "")
            + (", the servos' controls: their joint torques computed from them and the joints' state by the MJCF's "
               "<actuator> laws" if quantity == "control" else "") + ")" for quantity, group in chosen.items()]
    left = [f"{group.shown} ({group.role} {SHOWN[group.quantity]})" if group.quantity else f"{group.shown} (no joint "
            "position, velocity, torque or current)" for group in aside]
    if "tau" in chosen and any(group.quantity == "current" for group in aside):
        left.append("the currents: a measured joint torque is read rather than a current")
    if "tau" in chosen and any(group.quantity == "actuator" for group in aside):
        left.append("the actuator forces: a measured joint torque is read rather than an actuator's force")
    message = (f"{source}: no columns " + ", ".join(f"{key}1.." for key in lacking) + "; read as a controller's log: "
               + "; ".join(said) + (". Left aside: " + "; ".join(left) if left else "") + f" ({mapped()})")
    return VendorReading(columns, tuple(chosen.values()), aside, message)


class ServoForcesWarning(MeasurementWarning):
    """A MuJoCo log holding its servos' controls and no force: the joint torques were computed from the controls
    and the joints' state by the MJCF's actuator laws (:class:`dynamics.servos.ServoLaws`)."""


def with_servo_torques(frame: pd.DataFrame, servos: ServoLaws, n_joints: int, source: str) -> tuple[pd.DataFrame, str]:
    """``frame`` with its servos' controls ``ctrl1..ctrln`` replaced by the joint torques ``tau1..taun`` they make
    in the state of each row (``q1..``, ``dq1..``: :meth:`dynamics.servos.ServoLaws.joint_torques`, MuJoCo's
    ``qfrc_actuator``), and the message that says so.

    Raises
    ------
    MissingColumnError
        The laws use the joints' velocities (a damping gain ``kv``, a velocity servo) and the log holds none: the
        force is the servo's at the logged velocity, which no derivative of the positions gives back exactly."""
    controls = [f"ctrl{joint}" for joint in range(1, n_joints + 1)]
    positions = [f"q{joint}" for joint in range(1, n_joints + 1)]
    rates = [f"dq{joint}" for joint in range(1, n_joints + 1)]
    if servos.n_joints != n_joints:
        raise MissingColumnError(f"{source}: the servo laws ({servos.source}) are for {servos.n_joints} joints, the "
                                 f"robot has {n_joints}")
    if not all(name in frame.columns for name in positions):
        raise MissingColumnError(f"{source}: the servos' controls need the joints' positions beside them")
    has_rates = all(name in frame.columns for name in rates)
    if servos.uses_velocity and not has_rates:
        raise MissingColumnError(
            f"{source}: the servos' forces depend on the joints' velocities (their kv: {servos.source}) and the log "
            "holds no velocity: log data.qvel beside data.ctrl, or data.qfrc_actuator / data.actuator_force")

    def numbers(names: list[str]) -> np.ndarray:
        return frame[names].apply(pd.to_numeric, errors="coerce").to_numpy(dtype=float)

    torques = servos.joint_torques(numbers(controls), numbers(positions), numbers(rates) if has_rates else None)
    out = frame.drop(columns=controls)
    for joint in range(n_joints):
        out[f"tau{joint + 1}"] = torques[:, joint]
    laws = ", ".join(servos.actuators) if servos.actuators else "the actuators"
    message = (f"{source}: the joint torques computed from the servos' controls ctrl1..ctrl{n_joints} and the "
               f"joints' {'positions and velocities' if servos.uses_velocity else 'positions'} by {servos.source}'s laws "
               f"({laws}: f = gain·ctrl + bias(gear·q, gear·dq), clamped to the ranges, tau = gear·f), as MuJoCo "
               "computes qfrc_actuator; the force is the servo's model, not a measurement: log data.qfrc_actuator "
               "to read the torque MuJoCo applied")
    return out, message
