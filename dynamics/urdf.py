"""Robots from a URDF file, parsed with Pinocchio.

Without joint names, only serial chains of one-degree-of-freedom revolute (including ``continuous``)
and prismatic joints are accepted; fixed joints are merged by Pinocchio. With the names of the logged
joints (``joint_names``), any URDF is accepted (branching trees, mimic joints, floating or planar
joints): every other joint is locked (at ``locked_at``, default 0; a ``<mimic>`` joint at
``multiplier·q_driver + offset`` of its locked driver) and the bodies it carries are merged into the
link they hang from (Pinocchio's ``buildReducedModel``), so the named joints form the serial chain.
:func:`logged_chain` finds those names for a log of ``n`` joints when the tree determines one chain.
The inertia of the root link is ignored: it does not move, so it adds only a constant to the base
wrench, which the plate-offset columns absorb.
"""

from __future__ import annotations

import contextlib
import copy
import os
import re
import sys
import tempfile
import threading
import warnings
import xml.etree.ElementTree as ElementTree
from collections.abc import Iterator, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from dynamics.errors import RobotDescriptionError
from dynamics.robot import DEFAULT_GRAVITY, Joint, JointType, RobotModel


#: numeric attributes checked before Pinocchio reads the file (urdfdom turns a bad number into 0)
_NUMERIC_ATTRIBUTES: dict[str, tuple[str, ...]] = {
    "mass": ("value",),
    "inertia": ("ixx", "ixy", "ixz", "iyy", "iyz", "izz"),
    "origin": ("xyz", "rpy"),
    "axis": ("xyz",),
    "limit": ("lower", "upper", "velocity", "effort"),
}


#: a number as urdfdom reads it: no blanks, underscores, hexadecimal, inf or nan
_NUMBER = re.compile(r"[+-]?(\d+\.?\d*|\.\d+)([eE][+-]?\d+)?")


def _urdf_numbers(text: str, *, vector: bool) -> bool:
    """Whether urdfdom reads ``text`` as intended: one number, or for a vector numbers split on
    single spaces, each plain decimal and finite (urdfdom skips leading blanks, not trailing ones)."""
    tokens = [token for token in text.split(" ") if token] if vector else [text.lstrip(" ")]
    if not tokens or (vector and len(tokens) != 3):
        return False
    return all(_NUMBER.fullmatch(token) and np.isfinite(float(token)) for token in tokens)

#: what a message adds where a file holds xacro's macros or expressions, not yet expanded
_XACRO_HINT = (": a xacro file, not yet expanded; expand it first (`xacro robot.urdf.xacro > robot.urdf`, "
               "its arguments given) and read the URDF it writes")


def _check_numbers(path: Path) -> ElementTree.Element:
    """The file's XML root, after checking that every number of the links' inertial elements and of
    the joints is a finite number.

    urdfdom prints "Error: … is not a float" and carries on with 0 (a massless link), so such a
    file would give silently wrong dynamics; here it is a :class:`RobotDescriptionError` naming
    the element. A joint limit with ``lower > upper`` is refused as well.
    """
    try:
        root = ElementTree.parse(path).getroot()
    except ElementTree.ParseError as error:
        raise RobotDescriptionError(f"cannot parse URDF {path}: not well-formed XML ({error})"
                                    + (_XACRO_HINT if "xacro" in path.read_text(errors="replace") else "")) from None
    macros = sorted({element.tag.split("}")[-1] for element in root.iter()
                     if isinstance(element.tag, str) and "xacro" in element.tag.split("}")[0]})
    if macros:  # urdfdom skips what it does not know: the links and joints inside a macro would be lost unsaid
        raise RobotDescriptionError(f"URDF {path} holds xacro elements ({', '.join(f'xacro:{tag}' for tag in macros)})"
                                    + _XACRO_HINT)
    for kind in ("link", "joint"):
        for element in root.iter(kind):
            owner = f"{kind} {element.get('name')!r}"
            scope = element.find("inertial") if kind == "link" else element
            if scope is None:
                continue
            for tag, attributes in _NUMERIC_ATTRIBUTES.items():
                for child in scope.iter(tag):
                    for attribute in attributes:
                        text = child.get(attribute)
                        if text is None:
                            continue
                        if not _urdf_numbers(text, vector=attribute in ("xyz", "rpy")):
                            raise RobotDescriptionError(
                                f"URDF {path}: {owner}: <{tag} {attribute}=\"{text}\"> is not "
                                + ("three finite numbers" if attribute in ("xyz", "rpy") else "one finite number")
                                + " (plain decimal numbers, separated by single spaces)"
                                + (_XACRO_HINT if "${" in text or "$(" in text else ""))
            limit = element.find("limit") if kind == "joint" else None
            if limit is not None and limit.get("lower") is not None and limit.get("upper") is not None:
                if float(limit.get("lower")) > float(limit.get("upper")):
                    raise RobotDescriptionError(f"URDF {path}: {owner}: lower limit {limit.get('lower')} is above "
                                                f"upper limit {limit.get('upper')}")
    return root


class _CapturedText:
    """What a C library wrote to the process's standard error inside :func:`_captured_stderr`
    (filled in when the block ends)."""

    def __init__(self) -> None:
        self.text = ""


#: one redirection of file descriptor 2 at a time (another thread's would restore the wrong one)
_STDERR_LOCK = threading.Lock()


@contextlib.contextmanager
def _captured_stderr() -> Iterator[_CapturedText]:
    """Redirect file descriptor 2 (where urdfdom prints "Error: … at line 262 in model.cpp") to a
    temporary file, so that its words can go into one readable message instead of C++ noise.
    Without a usable descriptor 2 or temporary folder, nothing is captured."""
    captured = _CapturedText()
    with _STDERR_LOCK:
        if sys.stderr is not None:
            sys.stderr.flush()
        try:
            stream = tempfile.TemporaryFile()
            saved = os.dup(2)
        except OSError:
            yield captured
            return
        with stream:
            try:
                os.dup2(stream.fileno(), 2)
                yield captured
            finally:
                os.dup2(saved, 2)
                os.close(saved)
                stream.seek(0)
                captured.text = stream.read().decode(errors="replace")


def _refuse_mimic_joints(path: Path, root: ElementTree.Element) -> None:
    """A ``<mimic>`` joint follows another (``q_j = multiplier·q_i + offset``): Pinocchio would read it
    as an independent joint and the constraint would be silently dropped, so it is refused by name."""
    for joint in root.iter("joint"):
        mimic = joint.find("mimic")
        if mimic is not None:
            raise RobotDescriptionError(
                f"URDF {path}: joint {joint.get('name')!r} mimics joint {mimic.get('joint')!r} (a <mimic> coupling): "
                "coupled joints are not supported; the chain would be identified as if it moved freely. Name the "
                "logged joints (joint_names, --joint-names): the others are locked and a <mimic> joint follows its "
                "locked driver")


def _check_total_mass(path: Path, root: ElementTree.Element, parsed: float, parser_report: str = "") -> None:
    """The masses Pinocchio read must add up to those the file (``root``) states (urdfdom reads a
    number it cannot parse, e.g. with a tab or a blank around it, as 0 and drops the link's inertial data)."""
    stated = sum(float(element.get("value", "0")) for element in root.findall("link/inertial/mass"))
    if not np.isclose(parsed, stated, rtol=1e-9, atol=1e-12):
        raise RobotDescriptionError(f"URDF {path}: the links' masses add up to {stated:g} kg in the file but to "
                                    f"{parsed:g} kg as read: an inertial element could not be parsed (blanks or tabs "
                                    "inside a number?)" + (f"; the parser reported: {parser_report}" if parser_report else ""))


def robot_from_urdf(path: str | Path, *, gravity: np.ndarray | None = None, joint_names: Sequence[str] | None = None,
                    locked_at: Mapping[str, float] | None = None) -> RobotModel:
    """Read a serial chain from a URDF file, or the chain of the named joints of any URDF.

    Parameters
    ----------
    path
        The URDF file.
    gravity
        Gravity in the base frame; default ``(0, 0, -9.81)``.
    joint_names
        The logged joints, from the base to the tip of one chain (revolute, continuous or prismatic);
        every other joint of the file is locked and the bodies it carries merged into the link they
        hang from. ``None``: the file must be a serial chain (all its movable joints, in order).
    locked_at
        Positions of locked joints (rad or m; default 0 for each, whatever its limits: a lock is not
        a motion). A ``<mimic>`` joint follows its locked driver (``multiplier·q + offset``).

    Raises
    ------
    RobotDescriptionError
        If the file cannot be parsed; without ``joint_names``, if the chain branches, or holds a joint
        that is not a one-degree-of-freedom revolute or prismatic joint, or a ``<mimic>`` joint; with
        them, if a name is not a movable joint of the file, the named joints are not one chain from
        base to tip in the order given, or a body with mass moves with a named joint through a
        ``<mimic>`` coupling.
    """
    path = Path(path)
    if not path.is_file():
        raise RobotDescriptionError(f"URDF file {path} is a folder" if path.is_dir() else f"URDF file not found: {path}")
    root = _check_numbers(path)
    if joint_names is None:
        if locked_at:
            raise RobotDescriptionError(f"URDF {path}: locked joints ({', '.join(locked_at)}) given without the names "
                                        "of the logged joints (joint_names, --joint-names)")
        _refuse_mimic_joints(path, root)
        model = _pinocchio_model(path, root)
        _check_serial_chain(path, model)
    else:
        model = _named_joints_model(path, root, _checked_names(path, joint_names), dict(locked_at or {}))
    described, apart = ((), frozenset()) if joint_names is None else _description_joints(root, list(model.names[1:]))
    robot = RobotModel(
        name=model.name or path.stem,
        joints=tuple(_joint(path, model, joint_id) for joint_id in range(1, model.njoints)),
        gravity=np.asarray(DEFAULT_GRAVITY if gravity is None else gravity, dtype=float),
        description_joints=described,
        apart_joints=apart,
    )
    _check_lengths(path, robot)
    return robot


#: the longest chain of joints a description may span, m (the largest serial manipulators reach under 5 m, a
#: gantry's beam and column a few metres more): beyond it the file's lengths are not metres
LONGEST_CHAIN_M = 50.0
#: a chain longer than this (m) is a large robot's, which carries heavy links: below, no check of its mass
LONG_CHAIN_M = 5.0
#: a chain from this span (m) up to :data:`LONG_CHAIN_M` is judged as well when a moving link weighs
#: :data:`LEAST_LINK_MASS` or more: a desktop arm of 3 to 13 cm in inches spans 1 to 5 m (a 10 cm arm of 0.14 kg
#: reads as 4.1 m, 0.002 kg/m³); placeholder masses (a gram per link, as an export for a simulator writes them)
#: are not bodies, and are not judged there
SMALL_ARM_CHAIN_M = 1.0
#: the mass (kg) from which a moving link counts as a body for the judgement of a chain under :data:`LONG_CHAIN_M`
LEAST_LINK_MASS = 0.01
#: the least mass of a robot's moving links over its span cubed (kg/m³): arms of 0.3 to 2 m weigh 1 to 200 kg/m³
#: of it (a KUKA LWR4+ 1.0, a UR10e 5, a PUMA 22, a TX40 50), a gantry of 10 m several tonnes; a description in
#: inches reads as a 40-times longer arm of the same mass (a PUMA: 40 m, 0.0004 kg/m³)
LEAST_ARM_DENSITY = 0.01
#: below this mass over its span cubed (kg/m³) a description not refused by :data:`LEAST_ARM_DENSITY`'s rule (a chain
#: under :data:`SMALL_ARM_CHAIN_M`, or every moving link under :data:`LEAST_LINK_MASS`) is said to weigh too little:
#: the lightest description measured weighs 0.8 (a pendubot), a desktop arm of 2 cm or of 8 g in inches 0.002 and
#: 0.0001, a simulator's placeholders of a gram a link on a PUMA (1.0 m) 0.006
LIGHT_ARM_DENSITY = 0.1


def _check_lengths(path: Path, robot: RobotModel) -> None:
    """Refuse a description whose lengths are not metres (a CAD export in millimetres): the chain's span, the sum of
    the distances from each joint to the next and to its link's frame (the base's mount included), above
    :data:`LONGEST_CHAIN_M`. URDF lengths are metres (ROS REP 103); a file in millimetres reads as a robot 1000
    times larger, whose dynamics no fit of the log's torques can match, and nothing else would say so. A file in
    inches (39.37 times longer, masses in kg) is refused by its mass: a chain over :data:`LONG_CHAIN_M`, or over
    :data:`SMALL_ARM_CHAIN_M` with a moving link of :data:`LEAST_LINK_MASS` or more, whose moving links weigh under
    :data:`LEAST_ARM_DENSITY` times its span cubed (a desktop arm of 10 cm in inches: 4.1 m, read before at 3.4
    times the error of its description in metres on a joint, with no word). A description not judged so (a chain
    under 1 m, or every moving link under 10 g) whose moving links weigh under :data:`LIGHT_ARM_DENSITY` times its
    span cubed is read with a warning naming placeholders and inches (a 2 cm arm in inches, a 10 cm arm of 8 g links
    in inches: read without a word before)."""
    span = sum(float(np.linalg.norm(joint.placement[:3, 3])) + float(np.linalg.norm(joint.link_transform[:3, 3]))
               for joint in robot.joints)
    if span > LONGEST_CHAIN_M:
        raise RobotDescriptionError(
            f"URDF {path}: its joints span {span:.4g} m from the base to the tip (above {LONGEST_CHAIN_M:g} m for "
            "any robot arm): URDF lengths are metres; a file in millimetres must have its lengths (every <origin "
            "xyz>, a prismatic joint's limits) divided by 1000 and its inertias in kg m^2")
    masses = [float(joint.inertial[0]) for joint in robot.joints]
    mass = sum(masses)
    judged = span > LONG_CHAIN_M or (span > SMALL_ARM_CHAIN_M and max(masses) >= LEAST_LINK_MASS)
    if judged and 0 < mass < LEAST_ARM_DENSITY * span ** 3:
        raise RobotDescriptionError(
            f"URDF {path}: its joints span {span:.4g} m from the base to the tip, but its moving links weigh "
            f"{mass:.4g} kg in all ({mass / span ** 3:.2g} kg over its span cubed, m^3; a real arm that long weighs "
            f"over {LEAST_ARM_DENSITY:g} times its span cubed): lengths in inches? URDF lengths are metres; multiply every <origin "
            "xyz> (and a prismatic joint's limits) by 0.0254, and give masses in kg and inertias in kg m^2")
    if 0 < mass < LIGHT_ARM_DENSITY * span ** 3:  # not judged above (under 1 m, or links under 10 g): said
        warnings.warn(
            f"URDF {path}: its moving links weigh {mass:.3g} kg in all over a {span:.3g} m chain "
            f"({mass / span ** 3:.2g} kg over its span cubed, m^3; robots' descriptions weigh 0.8 to 50): placeholder "
            "bodies (a simulator's), or a small arm's lengths in inches (multiply every <origin xyz> by 0.0254)? The "
            "description's bodies are the consistent fit's prior and the yardstick of its link checks", stacklevel=3)


def urdf_actuated_joints(path: str | Path) -> frozenset[str] | None:
    """The joints a URDF file declares driven, or ``None`` when it declares none (it says nothing then).

    A joint is declared driven by a ``<transmission>`` naming it (``<joint name=…>``, ROS 1 and ``gazebo_ros_control``;
    the ``transmission_interface`` types, one joint or several) or by a ``<ros2_control>`` block whose
    ``<joint name=…>`` has a ``<command_interface>``. A file that declares some joints driven and not another leaves
    that one without a motor: the verbs read it as passive when the log has no torque column for it
    (``oed identify --passive``, docs/guides/robots-and-logs.md)."""
    root = ElementTree.parse(Path(path)).getroot()
    driven = {joint.get("name") for transmission in root.iter("transmission")
              for joint in transmission.findall("joint")}
    driven |= {joint.get("name") for block in root.iter("ros2_control") for joint in block.findall("joint")
               if joint.find("command_interface") is not None}
    driven.discard(None)
    return frozenset(driven) if driven else None


def logged_chain(path: str | Path, n_logged: int) -> tuple[tuple[str, ...], tuple[str, ...]] | None:
    """The chain a log of ``n_logged`` joints (columns ``q1..qn``) determines in a URDF that is not a plain
    serial chain (it branches, or holds a ``<mimic>`` joint): the one path of ``n_logged`` movable joints
    from the base, each hanging from the one before, none a ``<mimic>`` joint; with the joints held fixed.

    Returns
    -------
    ``(chain, held)``: the chain's joint names (base to tip) and the file's other movable joints (locked at
    0, a ``<mimic>`` joint following its driver, their bodies merged as with ``joint_names``);
    ``None`` when the file reads as a serial chain without names (read it as before).

    Raises
    ------
    RobotDescriptionError
        When no path, or more than one, of ``n_logged`` joints from the base fits: the message names
        ``--joint-names`` with the candidates.
    """
    path = Path(path)
    if not path.is_file():
        return None  # robot_from_urdf names the problem
    root = _check_numbers(path)
    mimics = _mimics(root)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # said again when the chain is read
        model = _pinocchio_model(path, root)
    serial = all(model.parents[joint_id] == joint_id - 1 for joint_id in range(1, model.njoints))
    if serial and not mimics:
        return None
    names = list(model.names)
    usable = {joint_id for joint_id in range(1, model.njoints)
              if names[joint_id] not in mimics and model.joints[joint_id].nv == 1}
    paths: list[list[int]] = [[]]
    for _ in range(max(n_logged, 0)):
        paths = [chain + [joint_id] for chain in paths for joint_id in sorted(usable)
                 if model.parents[joint_id] == (chain[-1] if chain else 0)]
    chains = [tuple(names[joint_id] for joint_id in chain) for chain in paths] if n_logged > 0 else []
    if len(chains) != 1:
        what = ("no chain of " if not chains else f"{len(chains)} chains of ") + f"{n_logged} joint(s) from the base"
        raise RobotDescriptionError(
            f"URDF {path}: the tree branches or holds <mimic> joints, and the log's {n_logged} joint column(s) "
            f"determine {what}" + (" (" + "; ".join(",".join(chain) for chain in chains[:4]) + ")" if chains else "")
            + ": name the logged joints, base to tip (joint_names, --joint-names A,B,C); the others are locked"
            + ("" if chains else "; " + _said_chains(model, frozenset(mimics))))
    held = tuple(names[joint_id] for joint_id in range(1, model.njoints) if names[joint_id] not in chains[0])
    return chains[0], held


#: the URDF joint types of one degree of freedom (a log's joint columns)
MOVABLE_TYPES = ("revolute", "continuous", "prismatic")


def _description_joints(root: ElementTree.Element, chain: list[str]) -> tuple[tuple[str, ...], frozenset[str]]:
    """The file's movable joints (:data:`MOVABLE_TYPES`, ``<mimic>`` joints left out: they follow another) in the
    order it declares them, and those of them apart from ``chain`` (:attr:`RobotModel.apart_joints`): neither an
    ancestor of a chain joint (on its path from the root) nor a descendant of one (carried by the chain).
    ``((), frozenset())`` where the file's movable joints are the chain's."""
    mimics = _mimics(root)
    declared = [joint for joint in root.findall("joint")
                if joint.get("type") in MOVABLE_TYPES and joint.get("name") not in mimics]
    described = tuple(str(joint.get("name")) for joint in declared)
    if set(described) <= set(chain):
        return (), frozenset()
    by_child: dict[str, ElementTree.Element] = {}
    for joint in root.findall("joint"):
        child = joint.find("child")
        if child is not None:
            by_child[str(child.get("link"))] = joint

    def ancestors(joint: ElementTree.Element) -> set[str]:
        found: set[str] = set()
        parent = joint.find("parent")
        link = None if parent is None else parent.get("link")
        while link in by_child and len(found) <= len(by_child):
            above = by_child[link]
            found.add(str(above.get("name")))
            parent = above.find("parent")
            link = None if parent is None else parent.get("link")
        return found

    above_chain = set().union(*(ancestors(joint) for joint in declared if joint.get("name") in chain))
    apart = frozenset(str(joint.get("name")) for joint in declared if joint.get("name") not in chain
                      and joint.get("name") not in above_chain and not ancestors(joint) & set(chain))
    return described, apart


def _checked_names(path: Path, joint_names: Sequence[str]) -> list[str]:
    """The joint names as a list of distinct non-empty strings."""
    if isinstance(joint_names, str):
        joint_names = [name.strip() for name in joint_names.split(",")]
    names = list(joint_names)
    if not names or not all(isinstance(name, str) and name for name in names):
        raise RobotDescriptionError(f"URDF {path}: joint names must be non-empty strings, got {names!r}")
    repeated = sorted({name for name in names if names.count(name) > 1})
    if repeated:
        raise RobotDescriptionError(f"URDF {path}: joint(s) {', '.join(repeated)} named twice")
    return names


def _mimics(root: ElementTree.Element) -> dict[str, tuple[str, float, float]]:
    """``{joint: (driver, multiplier, offset)}`` of the file's ``<mimic>`` joints."""
    found = {}
    for joint in root.iter("joint"):
        mimic = joint.find("mimic")
        if mimic is not None:
            found[joint.get("name", "")] = (mimic.get("joint", ""), float(mimic.get("multiplier", "1")),
                                            float(mimic.get("offset", "0")))
    return found


def _named_joints_model(path: Path, root: ElementTree.Element, names: list[str], locked_at: dict[str, float]) -> Any:
    """Pinocchio's model of the named joints: the file's full tree (``<mimic>`` joints read as
    independent joints) with every other joint locked, its bodies merged (``buildReducedModel``)."""
    import pinocchio as pin

    full = _pinocchio_model(path, root)
    movable = {full.names[joint_id]: joint_id for joint_id in range(1, full.njoints)}
    declared = {joint.get("name"): joint.get("type") for joint in root.iter("joint")}
    mimics = _mimics(root)
    for name in names:
        if name in mimics:
            raise RobotDescriptionError(f"URDF {path}: joint {name!r} mimics joint {mimics[name][0]!r} (a <mimic> "
                                        f"coupling): name its driver {mimics[name][0]!r} instead")
        if name not in movable:
            what = (f"a {declared[name]} joint" if name in declared else "not a joint of the file")
            raise RobotDescriptionError(f"URDF {path}: joint {name!r} is {what}; its movable joints are "
                                        + ", ".join(movable))
    for name, value in locked_at.items():
        if name in names:
            raise RobotDescriptionError(f"URDF {path}: joint {name!r} is both named (logged) and locked")
        if name not in movable:
            raise RobotDescriptionError(f"URDF {path}: locked joint {name!r} is not a movable joint of the file "
                                        "(its movable joints are " + ", ".join(movable) + ")")
        if name in mimics:
            raise RobotDescriptionError(f"URDF {path}: joint {name!r} mimics {mimics[name][0]!r}: lock its driver")
        if not np.isfinite(float(value)):
            raise RobotDescriptionError(f"URDF {path}: joint {name!r} locked at {value}: not a finite number")
    named_ids = {movable[name] for name in names}

    def locked_value(name: str, depth: int = 0) -> float:
        if name not in mimics:
            return float(locked_at.get(name, 0.0))
        driver, multiplier, offset = mimics[name]
        if driver not in movable or depth > len(mimics):
            raise RobotDescriptionError(f"URDF {path}: joint {name!r} mimics {driver!r}, which is not a movable joint "
                                        "(or the <mimic> couplings form a loop)")
        if driver in names:
            joint_id = movable[name]
            carried = sum(full.inertias[index].mass for index in full.subtrees[joint_id])
            if named_ids & set(full.subtrees[joint_id]) or carried > 0:
                raise RobotDescriptionError(
                    f"URDF {path}: joint {name!r} mimics the named joint {driver!r} and carries "
                    + ("named joints" if named_ids & set(full.subtrees[joint_id]) else f"{carried:g} kg")
                    + ": a body moving with a named joint through a <mimic> coupling is not supported (lock "
                    f"{driver!r}, or describe the coupled body as part of {driver!r}'s link)")
            return offset  # massless and no named joint below: where it stands changes no torque
        return multiplier * locked_value(driver, depth + 1) + offset

    q = pin.neutral(full)
    for name, joint_id in movable.items():
        if joint_id in named_ids:
            continue
        joint_model = full.joints[joint_id]
        value = locked_value(name)
        start = joint_model.idx_q
        if joint_model.nq == 1:
            q[start] = value
        elif joint_model.nq == 2 and joint_model.nv == 1:  # continuous: (cos, sin)
            q[start : start + 2] = (np.cos(value), np.sin(value))
        elif value != 0:
            raise RobotDescriptionError(f"URDF {path}: joint {name!r} has {joint_model.nv} degrees of freedom: it is "
                                        "locked at its neutral position, not at one number")
    locked_ids = [joint_id for joint_id in movable.values() if joint_id not in named_ids]
    reduced = pin.buildReducedModel(full, locked_ids, q) if locked_ids else full
    chain = list(reduced.names)[1:]
    for joint_id in range(1, reduced.njoints):
        parent = reduced.parents[joint_id]
        if parent != joint_id - 1:
            raise RobotDescriptionError(
                f"URDF {path}: the named joints are not one chain: {reduced.names[joint_id]!r} does not hang below "
                + (f"{reduced.names[joint_id - 1]!r}" if joint_id > 1 else "the base")
                + " (name the joints of one chain from the base to the tip; a branching set is not supported)")
    if chain != names:
        raise RobotDescriptionError(f"URDF {path}: name the joints from the base to the tip: {','.join(chain)} "
                                    f"(given: {','.join(names)})")
    return reduced


#: joint types of a base that moves in the world (URDF's ``floating``: six degrees of freedom; ``planar``: three)
_BASE_MOTION_TYPES = ("floating", "planar")
#: a ``<limit>`` Pinocchio reads as no limit (:func:`_joint` takes equal bounds and a zero speed as unset)
_NO_LIMIT = {"lower": "0", "upper": "0", "effort": "0", "velocity": "0"}


def _as_read(path: Path, root: ElementTree.Element) -> tuple[str | None, list[str]]:
    """The description as the chain's dynamics read it, when that differs from the file (``None`` when it does
    not), and the base joints read as fixed.

    - A ``floating`` or ``planar`` joint from a root link (one that is no joint's child, e.g. ``world``) is the
      base's motion in the world, which a log of the arm's joints does not hold: it is read as ``fixed`` at its
      origin (the base still), said in a warning. Such a joint elsewhere is left to be refused.
    - A revolute, continuous or prismatic joint without ``<limit>`` (the URDF specification asks for one on
      revolute and prismatic joints; hand-written files leave it out, and urdfdom then refuses the whole file)
      is read without position, speed or effort limits, as a continuous joint is, said in a warning.
    """
    children = {child.get("link") for joint in root.iter("joint") for child in joint.iter("child")}
    floating, open_joints = [], []
    read = copy.deepcopy(root)
    for joint in read.iter("joint"):
        parent = joint.find("parent")
        if joint.get("type") in _BASE_MOTION_TYPES and parent is not None and parent.get("link") not in children:
            floating.append(f"{joint.get('name')!r} ({joint.get('type')}, from {parent.get('link')!r})")
            joint.set("type", "fixed")
        elif joint.get("type") in ("revolute", "prismatic") and joint.find("limit") is None:
            open_joints.append(repr(joint.get("name")))
            ElementTree.SubElement(joint, "limit", _NO_LIMIT)
    if floating:
        warnings.warn(f"URDF {path}: joint {', '.join(floating)} moves the base in the world, which the log's joints "
                      "do not hold: read as fixed at its origin (a base standing still)", stacklevel=4)
    if open_joints:
        warnings.warn(f"URDF {path}: joint(s) {', '.join(open_joints)} without <limit>: read without position, "
                      "speed or effort limits", stacklevel=4)
    return (ElementTree.tostring(read, encoding="unicode") if floating or open_joints else None), floating


def _pinocchio_model(path: Path, root: ElementTree.Element) -> Any:
    """Pinocchio's model of the file, refused when the parser failed, read no movable joint, lost
    mass or could not read all of it; what the parser remarked on otherwise is warned about (for
    the caller of :func:`robot_from_urdf`)."""
    import pinocchio as pin

    with _captured_stderr() as parser_output:
        try:
            text, floating = _as_read(path, root)
            model = pin.buildModelFromUrdf(str(path)) if text is None else pin.buildModelFromXML(text)
        except (RuntimeError, ValueError) as error:
            failure = str(error)
        else:
            failure = None
    details = " ".join(line.strip() for line in parser_output.text.splitlines()
                       if line.strip() and not line.strip().startswith("at line")).removeprefix("Error:").strip()
    if failure is not None:
        raise RobotDescriptionError(f"cannot parse URDF {path}: {details or failure}")
    if model.njoints <= 1:
        raise RobotDescriptionError(f"URDF {path} has no movable joint" + (
            f" (joint {', '.join(floating)} read as a fixed base: floating and planar joints are not identified)"
            if floating else ""))
    _check_total_mass(path, root, sum(model.inertias[index].mass for index in range(model.njoints)), details)
    if "Error" in parser_output.text:  # urdfdom drops what it cannot read and goes on: not here
        raise RobotDescriptionError(f"URDF {path}: the parser could not read all of it: {details}")
    if details:  # the parser remarked on something but read it all: say so once, readably
        warnings.warn(f"URDF {path}: the parser reported: {details}", stacklevel=3)
    return model


def _check_serial_chain(path: Path, model: Any) -> None:
    """Refuse a branching chain: every joint of Pinocchio's ``model`` must hang from the one before. The message
    names the chain from the base to the branch (when the branch is above the base) and the description's
    chains from the base to each tip (:func:`_chains_from_base`)."""
    for joint_id in range(1, model.njoints):
        parent = model.parents[joint_id]
        if parent != joint_id - 1:
            to_branch = (" (the chain from the base to the branch: --joint-names "
                         + ",".join(model.names[index] for index in range(1, parent + 1)) + ")") if parent > 0 else ""
            raise RobotDescriptionError(
                f"URDF {path}: joint {model.names[joint_id]!r} hangs from {model.names[parent]!r}, "
                "not from the previous joint: branching chains are not supported (serial chains only); name the "
                "logged joints, base to tip (joint_names, --joint-names), and the others are locked" + to_branch
                + "; " + _said_chains(model)
            )


def _chains_from_base(model: Any, excluded: frozenset[str] = frozenset()) -> list[tuple[str, ...]]:
    """The chains of Pinocchio's ``model`` from the base to each tip: every path of one-degree-of-freedom joints,
    each hanging from the one before, from a joint on the base to a joint no such joint hangs from (a branch
    starts a chain of its own), in the description's joint order; the joints named in ``excluded`` (``<mimic>``
    joints) left out."""
    usable = [joint_id for joint_id in range(1, model.njoints)
              if model.joints[joint_id].nv == 1 and model.names[joint_id] not in excluded]
    children = {joint_id: [child for child in usable if model.parents[child] == joint_id] for joint_id in usable}
    chains: list[tuple[str, ...]] = []

    def grow(chain: list[int]) -> None:
        below = children[chain[-1]]
        if not below:
            chains.append(tuple(model.names[joint_id] for joint_id in chain))
        for child in below:
            grow([*chain, child])

    for joint_id in usable:
        if model.parents[joint_id] == 0:
            grow([joint_id])
    return chains


def _said_chains(model: Any, excluded: frozenset[str] = frozenset(), limit: int = 6) -> str:
    """The description's chains from the base (:func:`_chains_from_base`) as the options that read each."""
    chains = _chains_from_base(model, excluded)
    said = "; ".join(f"--joint-names {','.join(chain)}" for chain in chains[:limit])
    more = f" and {len(chains) - limit} more" if len(chains) > limit else ""
    return f"the description's {len(chains)} chain(s) from the base to a tip: {said}{more}"


def _joint(path: Path, model: Any, joint_id: int) -> Joint:
    """Joint ``joint_id`` of Pinocchio's ``model``: revolute or prismatic about its motion subspace's
    axis, with its placement, inertia and limits (unset or absurd limits infinite)."""
    import pinocchio as pin

    joint_model = model.joints[joint_id]
    name = model.names[joint_id]
    kind = joint_model.shortname()
    if joint_model.nv != 1:
        raise RobotDescriptionError(
            f"URDF {path}: joint {name!r} is a {kind.removeprefix('JointModel')} joint with "
            f"{joint_model.nv} degrees of freedom (floating, planar and spherical joints are not "
            "supported: serial chains of revolute and prismatic joints only)"
        )
    data = joint_model.createData()
    joint_model.calc(data, pin.neutral(model)[joint_model.idx_q : joint_model.idx_q + joint_model.nq])
    subspace = np.asarray(data.S).reshape(6)
    linear, angular = subspace[:3], subspace[3:]
    if np.linalg.norm(angular) > 1e-12 and np.linalg.norm(linear) < 1e-12:
        joint_type, axis = JointType.REVOLUTE, angular
    elif np.linalg.norm(linear) > 1e-12 and np.linalg.norm(angular) < 1e-12:
        joint_type, axis = JointType.PRISMATIC, linear
    else:
        raise RobotDescriptionError(f"URDF {path}: joint {name!r} ({kind}) is neither revolute nor prismatic")
    index_q = joint_model.idx_q
    index_v = joint_model.idx_v
    lower = float(model.lowerPositionLimit[index_q]) if joint_model.nq == 1 else -np.inf
    upper = float(model.upperPositionLimit[index_q]) if joint_model.nq == 1 else np.inf
    if lower >= upper:  # Pinocchio stores unset limits as ±max double, or equal values
        lower, upper = -np.inf, np.inf
    velocity = float(model.velocityLimit[index_v])
    effort = float(model.effortLimit[index_v])
    return Joint(
        name=name,
        joint_type=joint_type,
        axis=axis,
        placement=model.jointPlacements[joint_id].homogeneous,
        link_transform=np.eye(4),
        inertial=np.asarray(model.inertias[joint_id].toDynamicParameters()).reshape(-1),
        lower=lower if np.isfinite(lower) and abs(lower) < 1e30 else -np.inf,
        upper=upper if np.isfinite(upper) and abs(upper) < 1e30 else np.inf,
        velocity=velocity if 0 < velocity < 1e30 else np.inf,
        effort=effort if 0 < effort < 1e30 else np.inf,
    )
