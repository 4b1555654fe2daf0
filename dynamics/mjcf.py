"""Robots from a MuJoCo MJCF model (a ``<mujoco>`` file, as in MuJoCo Menagerie), read as a URDF is.

The file is read here, element by element, as MuJoCo compiles it (MuJoCo XML reference, "Compiler",
"Default" and "Body" sections):

* ``<include file>`` elements are replaced by the included file's children (paths beside the file);
* ``<compiler angle eulerseq autolimits>``: angles in degrees unless ``angle="radian"`` (``range`` of
  hinges, ``euler``, ``axisangle``), Euler sequences in the compiler's convention (lower case: axes that
  turn with the frame), a ``range`` limiting its joint unless ``limited="false"``;
* default classes (``<default class>``, nested; ``class`` and ``childclass``) give the joints' attributes;
* a body's frame is ``pos`` then one orientation (``quat`` ``w x y z``, ``axisangle``, ``euler``,
  ``xyaxes``, ``zaxis``) in its parent's; ``<frame>`` elements add theirs;
* ``<inertial pos mass diaginertia|fullinertia>`` (with an orientation for ``diaginertia``): the mass,
  centre of mass and inertia about it, in the body frame;
* ``hinge`` and ``slide`` joints turn about, or slide along, ``axis`` through ``pos`` in the body frame,
  by ``q − ref``; several joints in one body act in order. ``<option gravity>`` is the gravity.

Joint ``i``'s frame is its body's frame moved to the joint's ``pos``, at ``q = 0`` (the model's zero,
which is MuJoCo's ``qpos = 0``, not ``qpos0 = ref``); link ``i``'s frame is its body's frame
(``link_transform`` ``B_i``: the body in the joint frame; the joint frame itself when a later joint of
the chain sits in the same body), so that an MJCF written by :func:`dynamics.mjcf_export.robot_mjcf`
reads back with the same links. Link ``i`` holds every body that moves with joint ``i`` and no later
joint of the chain, its inertia summed in that frame.

What a serial chain cannot take is refused by name (:class:`~dynamics.errors.RobotDescriptionError`):
free joints (a floating base), ball joints, several chains, a fixed tendon or an equality constraint on
a joint of the chain, spatial tendons and closed loops (``connect``, ``weld``), a moving body whose
inertia MuJoCo would compute from its geoms (no ``<inertial>``, or ``inertiafromgeom="true"``).
With the names of the logged joints (``joint_names``), every other joint is locked (at ``locked_at``,
default 0; a ball joint at its reference) and the bodies it carries are merged into the link they hang
from, as :func:`dynamics.urdf.robot_from_urdf` does; the constraints on locked joints (a gripper's
fingers coupled by an equality) and bodies that do not move with the chain (a free object) are then
left out. :func:`mjcf_logged_chain` finds those names for a log of ``n`` joints when the tree determines
one chain.

Joint terms (:func:`mjcf_joint_terms`): ``damping`` (viscous) and ``frictionloss`` (Coulomb) are the
description's friction where the toolkit reads a URDF's ``<dynamics damping friction>`` (the nominal
torque of ``oed design --torque-limits``); with ``armature`` they are also the joints' ``armature``, ``damping``
and ``friction`` (:class:`dynamics.robot.Joint`), the consistent fit's prior for those laws
(:mod:`estimation.consistent.effect_prior`). ``stiffness`` is not read (the identification fits its own
``spring`` effect), said once in a :class:`MjcfIgnoredWarning`.
Actuators (:func:`transmission_from_mjcf`): each joint transmission's ``gear`` is its joint's ratio.
Geometry (``<geom>``, meshes) is not read: ``oed design --floor/--self-collision`` need a URDF.
"""

from __future__ import annotations

import re
import warnings
import xml.etree.ElementTree as ElementTree
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from dynamics.errors import RobotDescriptionError
from dynamics.robot import DEFAULT_GRAVITY, Joint, JointType, RobotModel, inertial_parameters
from dynamics.servos import ServoLaws
from dynamics.transmission import Transmission, TransmissionError

__all__ = ["MjcfIgnoredWarning", "MjcfLayout", "is_mjcf", "is_mjcf_text", "mjcf_text", "mjcf_joint_terms", "mjcf_logged_chain",
           "mjcf_actuated_joints", "mjcf_layout", "mjcf_servos", "robot_from_mjcf", "transmission_from_mjcf"]

#: the joint terms read (MuJoCo's names) and the toolkit's names of what they are
READ_JOINT_TERMS: dict[str, str] = {"damping": "viscous", "frictionloss": "coulomb"}
#: joint attributes MuJoCo simulates that are not read (said when not zero)
IGNORED_JOINT_TERMS: tuple[str, ...] = ("stiffness",)
#: the elements of ``<actuator>`` (MuJoCo XML reference, "actuator"): each acts through one transmission
ACTUATOR_TAGS = ("general", "motor", "position", "velocity", "intvelocity", "damper", "cylinder", "muscle",
                 "adhesion", "plugin")
#: an actuator's transmission attributes, in MuJoCo's order (``refsite`` goes with ``site``)
ACTUATOR_TRANSMISSIONS = ("joint", "jointinparent", "tendon", "site", "body", "cranksite")
_MOVABLE = ("hinge", "slide")
_ORIENTATIONS = ("quat", "axisangle", "euler", "xyaxes", "zaxis")
#: worldbody elements that make bodies this reader does not build
_NOT_READ = {"replicate": "repeated bodies", "attach": "a model attached from another file",
             "composite": "generated bodies", "flexcomp": "a deformable body"}
_FLOAT = re.compile(r"[+-]?(\d+\.?\d*|\.\d+)([eE][+-]?\d+)?")


class MjcfIgnoredWarning(UserWarning):
    """Something an MJCF model states that the chain read from it does not use (armature, springs, gravity
    compensation)."""


def is_mjcf(path: str | Path) -> bool:
    """Whether ``path`` is an XML file whose root element is ``<mujoco>`` (False when it cannot be read)."""
    try:
        for _, element in ElementTree.iterparse(str(path), events=("start",)):
            return element.tag == "mujoco"
    except (ElementTree.ParseError, OSError):
        return False
    return False


def is_mjcf_text(text: str) -> bool:
    """Whether ``text`` is XML whose root element is ``<mujoco>``."""
    try:
        return ElementTree.fromstring(text).tag == "mujoco"
    except ElementTree.ParseError:
        return False


@dataclass(frozen=True)
class _JointElement:
    """One ``<joint>`` with its class's attributes resolved."""

    name: str
    kind: str
    body: str
    position: NDArray[np.float64]
    axis: NDArray[np.float64]
    reference: float
    lower: float
    upper: float
    effort: float
    terms: dict[str, float]
    parent: str | None  # the joint before it (in the same body, or in the nearest ancestor body with joints)


@dataclass(frozen=True)
class _BodyElement:
    """One ``<body>``: its pose in its parent body (``<frame>`` elements folded in), inertial and joints."""

    name: str
    parent: str | None
    pose: NDArray[np.float64]
    mass: float
    com: NDArray[np.float64]
    inertia: NDArray[np.float64]  # about the centre of mass, in the body frame
    joints: tuple[str, ...]
    has_inertial: bool
    has_geoms: bool
    gravity_compensation: float


@dataclass(frozen=True)
class _ActuatorElement:
    """One ``<actuator>`` child with its class's attributes resolved: how its force reaches the joints."""

    label: str  # ``<motor name='a1'>``
    name: str | None
    kind: str  # joint, jointinparent, tendon, site, body, slidercrank
    target: str  # the joint, tendon, site, body or crank site it acts through
    gear: float  # the first number of ``gear``: a joint's torque per unit of actuator force
    tag: str = ""  # motor, position, velocity, general...
    attributes: Mapping[str, str] = field(default_factory=dict)  # the element's, its class's defaults merged in


@dataclass
class _Model:
    """The file as read: bodies in document order, joints, and what a chain cannot take."""

    path: Path
    name: str
    gravity: NDArray[np.float64] | None
    bodies: dict[str, _BodyElement] = field(default_factory=dict)
    joints: dict[str, _JointElement] = field(default_factory=dict)
    tendons: list[tuple[str, tuple[str, ...] | None]] = field(default_factory=list)  # (label, joints or None: spatial)
    equalities: list[tuple[str, tuple[str, ...] | None]] = field(default_factory=list)  # (label, joints or None: loop)
    inertia_from_geoms: bool = False
    actuators: list[_ActuatorElement] = field(default_factory=list)
    sites: dict[str, str] = field(default_factory=dict)  # site name -> the body that holds it
    body_elements: dict[str, ElementTree.Element] = field(default_factory=dict)
    joint_elements: dict[str, ElementTree.Element] = field(default_factory=dict)
    root: ElementTree.Element | None = None
    degrees: bool = True  # the compiler's angle unit

    def error(self, text: str) -> RobotDescriptionError:
        return RobotDescriptionError(f"MJCF {self.path}: {text}")


def _floats(model_path: Path, element: ElementTree.Element, attribute: str, count: int | None,
                 default: Sequence[float] | None = None) -> NDArray[np.float64] | None:
    """The numbers of ``attribute`` (``count`` of them), each finite and plain; ``default`` when absent."""
    text = element.get(attribute)
    if text is None:
        return None if default is None else np.asarray(default, dtype=float)
    tokens = text.split()
    if (count is not None and len(tokens) != count) or not tokens or not all(_FLOAT.fullmatch(token) for token in tokens):
        name = element.get("name")
        raise RobotDescriptionError(
            f"MJCF {model_path}: <{element.tag}{f' name={name!r}' if name else ''} {attribute}=\"{text}\"> is not "
            + (f"{count} finite number(s)" if count is not None else "finite numbers"))
    values = np.asarray([float(token) for token in tokens])
    if not np.all(np.isfinite(values)):
        raise RobotDescriptionError(f"MJCF {model_path}: <{element.tag} {attribute}=\"{text}\"> is not finite")
    return values


def _expanded(path: Path, root: ElementTree.Element, depth: int = 0) -> ElementTree.Element:
    """``root`` with its ``<include file>`` elements replaced by the included files' children."""
    if depth > 20:
        raise RobotDescriptionError(f"MJCF {path}: <include> elements nest more than 20 deep (a loop?)")
    for parent in list(root.iter()):
        for index, child in reversed(list(enumerate(parent))):
            if child.tag != "include":
                continue
            included = path.parent / (child.get("file") or "")
            if not included.is_file():
                raise RobotDescriptionError(f"MJCF {path}: <include file={child.get('file')!r}>: file not found")
            try:
                sub = ElementTree.parse(included).getroot()
            except ElementTree.ParseError as error:
                raise RobotDescriptionError(f"cannot parse MJCF {included}: not well-formed XML ({error})") from None
            sub = _expanded(included, sub, depth + 1)
            parent.remove(child)
            for offset, element in enumerate(sub):
                parent.insert(index + offset, element)
    return root


def mjcf_text(path: str | Path) -> str:
    """The MJCF file's text with its ``<include>`` files in place: one file that reads as the original wherever
    it is kept (how a model file embeds its robot)."""
    path = Path(path)
    try:
        root = ElementTree.parse(path).getroot()
    except (ElementTree.ParseError, OSError) as error:
        raise RobotDescriptionError(f"cannot read MJCF {path}: {error}") from None
    return ElementTree.tostring(_expanded(path, root), encoding="unicode") + "\n"


def _rotation(axis: NDArray[np.float64], angle: float) -> NDArray[np.float64]:
    """Rotation by ``angle`` about the unit ``axis`` (Rodrigues)."""
    x, y, z = axis
    skew = np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])
    return np.eye(3) + np.sin(angle) * skew + (1 - np.cos(angle)) * skew @ skew


def _unit(path: Path, element: ElementTree.Element, vector: NDArray[np.float64], what: str) -> NDArray[np.float64]:
    norm = float(np.linalg.norm(vector))
    if norm < 1e-12:
        raise RobotDescriptionError(f"MJCF {path}: <{element.tag} name={element.get('name')!r}>: {what} is zero")
    return vector / norm


@dataclass(frozen=True)
class _Compiler:
    degrees: bool = True
    euler_sequence: str = "xyz"
    autolimits: bool = True

    def angle(self, value: float) -> float:
        return float(np.deg2rad(value)) if self.degrees else float(value)


def _orientation(path: Path, element: ElementTree.Element, compiler: _Compiler) -> NDArray[np.float64]:
    """The rotation an element's orientation attribute gives (MuJoCo XML reference, "Frame orientations")."""
    given = [name for name in _ORIENTATIONS if element.get(name) is not None]
    if len(given) > 1:
        raise RobotDescriptionError(f"MJCF {path}: <{element.tag} name={element.get('name')!r}> has several "
                                    f"orientations ({', '.join(given)}): give one")
    if not given:
        return np.eye(3)
    kind = given[0]
    if kind == "quat":
        w, x, y, z = _unit(path, element, _floats(path, element, "quat", 4), "quat")
        return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                         [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                         [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])
    if kind == "axisangle":
        values = _floats(path, element, "axisangle", 4)
        return _rotation(_unit(path, element, values[:3], "the axis of axisangle"), compiler.angle(values[3]))
    if kind == "euler":
        angles = _floats(path, element, "euler", 3)
        rotation = np.eye(3)
        for letter, angle in zip(compiler.euler_sequence, angles):
            step = _rotation(np.eye(3)["xyz".index(letter.lower())], compiler.angle(angle))
            rotation = rotation @ step if letter.islower() else step @ rotation
        return rotation
    if kind == "xyaxes":
        values = _floats(path, element, "xyaxes", 6)
        x_axis = _unit(path, element, values[:3], "the x axis of xyaxes")
        y_axis = _unit(path, element, values[3:] - (values[3:] @ x_axis) * x_axis, "the y axis of xyaxes")
        return np.column_stack([x_axis, y_axis, np.cross(x_axis, y_axis)])
    z_axis = _unit(path, element, _floats(path, element, "zaxis", 3), "zaxis")
    cross = np.cross([0.0, 0.0, 1.0], z_axis)
    if np.linalg.norm(cross) < 1e-12:
        return np.eye(3) if z_axis[2] > 0 else np.diag([1.0, -1.0, -1.0])
    return _rotation(cross / np.linalg.norm(cross), float(np.arccos(np.clip(z_axis[2], -1.0, 1.0))))


def _pose(path: Path, element: ElementTree.Element, compiler: _Compiler) -> NDArray[np.float64]:
    pose = np.eye(4)
    pose[:3, :3] = _orientation(path, element, compiler)
    pose[:3, 3] = _floats(path, element, "pos", 3, (0.0, 0.0, 0.0))
    return pose


def _compiler(path: Path, root: ElementTree.Element) -> _Compiler:
    degrees, sequence, autolimits = True, "xyz", True
    for element in root.findall("compiler"):
        angle = element.get("angle", "degree" if degrees else "radian")
        if angle not in ("degree", "radian"):
            raise RobotDescriptionError(f"MJCF {path}: <compiler angle={angle!r}>: degree or radian")
        degrees = angle == "degree"
        sequence = element.get("eulerseq", sequence)
        if len(sequence) != 3 or any(letter not in "xyzXYZ" for letter in sequence):
            raise RobotDescriptionError(f"MJCF {path}: <compiler eulerseq={sequence!r}>: three of x, y, z, X, Y, Z")
        autolimits = element.get("autolimits", "true" if autolimits else "false") == "true"
    return _Compiler(degrees, sequence, autolimits)


def _default_classes(root: ElementTree.Element) -> dict[str, dict[str, dict[str, str]]]:
    """``{class: {element tag: attributes}}``: each class's defaults, its parents' merged in (top: ``main``)."""
    classes: dict[str, dict[str, dict[str, str]]] = {}

    def visit(element: ElementTree.Element, inherited: dict[str, dict[str, str]], top: bool) -> None:
        name = element.get("class", "main" if top else "")
        own = {tag: dict(values) for tag, values in inherited.items()}
        for child in element:
            if child.tag != "default":  # MuJoCo keeps one actuator default a class: its shortcuts all set it
                tag = "actuator" if child.tag in ACTUATOR_TAGS else child.tag
                own[tag] = {**own.get(tag, {}), **child.attrib}
        classes[name] = own
        for child in element.findall("default"):
            visit(child, own, False)

    for element in root.findall("default"):
        visit(element, classes.get("main", {}), True)
    classes.setdefault("main", {})
    return classes


def _read(path: Path) -> _Model:
    """The file's bodies, joints, tendons and equalities (module docstring)."""
    if not path.is_file():
        raise RobotDescriptionError(f"MJCF file {path} is a folder" if path.is_dir() else f"MJCF file not found: {path}")
    try:
        root = ElementTree.parse(path).getroot()
    except ElementTree.ParseError as error:
        raise RobotDescriptionError(f"cannot parse MJCF {path}: not well-formed XML ({error})") from None
    if root.tag != "mujoco":
        raise RobotDescriptionError(f"{path}: the root element is <{root.tag}>, not <mujoco>: not an MJCF model"
                                    + (" (a URDF: give --urdf)" if root.tag == "robot" else ""))
    root = _expanded(path, root)
    compiler = _compiler(path, root)
    classes = _default_classes(root)
    option = root.find("option")
    gravity = None if option is None else _floats(path, option, "gravity", 3)
    model = _Model(path, root.get("model") or path.stem, gravity, root=root, degrees=compiler.degrees,
                   inertia_from_geoms=any(element.get("inertiafromgeom") == "true" for element in root.findall("compiler")))
    worldbody = root.find("worldbody")
    if worldbody is None:
        raise model.error("no <worldbody>")
    for element in root.findall("compiler"):
        if float(element.get("settotalmass", "-1")) > 0:
            raise model.error(f"<compiler settotalmass={element.get('settotalmass')!r}> rescales the bodies' masses, "
                              "which this reader does not: remove it, or write the scaled masses")
    for element in worldbody.iter():
        if element.tag in _NOT_READ:
            raise model.error(f"<{element.tag}> in the worldbody ({_NOT_READ[element.tag]}) is not read: write its "
                              "bodies out (MuJoCo's compiled model, saved with mj_saveLastXML, holds them)")
    unnamed = iter(range(1_000_000))

    def attributes(element: ElementTree.Element, childclass: str) -> dict[str, str]:
        name = element.get("class", childclass)
        if name not in classes:
            raise model.error(f"<{element.tag} name={element.get('name')!r}> names class {name!r}, which no "
                              "<default> defines")
        return {**classes[name].get(element.tag, {}), **element.attrib}

    def joint(element: ElementTree.Element, body: str, childclass: str, parent: str | None) -> _JointElement:
        values = ElementTree.Element(element.tag, attributes(element, childclass))
        kind = "free" if element.tag == "freejoint" else values.get("type", "hinge")
        name = values.get("name") or f"{body}_joint{next(unnamed)}"
        if name in model.joints:
            raise model.error(f"two joints named {name!r}")
        if kind not in ("hinge", "slide", "ball", "free"):
            raise model.error(f"joint {name!r}: unknown type {kind!r}")
        angular = kind in ("hinge", "ball")
        axis = _unit(path, values, _floats(path, values, "axis", 3, (0.0, 0.0, 1.0)), "axis")
        lower, upper, effort = -np.inf, np.inf, np.inf
        limits = _floats(path, values, "range", 2)
        limited = values.get("limited", "auto")
        if limits is not None and (limited == "true" or (limited == "auto" and compiler.autolimits)):
            if limits[0] > limits[1]:
                raise model.error(f"joint {name!r}: range {values.get('range')!r}: lower above upper")
            lower, upper = (compiler.angle(value) if angular else float(value) for value in limits)
        forces = _floats(path, values, "actuatorfrcrange", 2)
        force_limited = values.get("actuatorfrclimited", "auto")
        if forces is not None and (force_limited == "true" or (force_limited == "auto" and compiler.autolimits)):
            effort = float(np.max(np.abs(forces))) or np.inf
        terms = {}
        for term in (*READ_JOINT_TERMS, "armature", *IGNORED_JOINT_TERMS):
            number = _floats(path, values, term, 1)
            if number is not None:
                terms[term] = float(number[0])
        reference = float(_floats(path, values, "ref", 1, (0.0,))[0])
        return _JointElement(name, kind, body, _floats(path, values, "pos", 3, (0.0, 0.0, 0.0)), axis,
                             compiler.angle(reference) if kind == "hinge" else reference, lower, upper, effort, terms,
                             parent)

    def body(element: ElementTree.Element, parent: str | None, offset: NDArray[np.float64], childclass: str,
             last_joint: str | None) -> None:
        childclass = element.get("childclass", childclass)
        name = element.get("name") or f"body{next(unnamed)}"
        if name in model.bodies:
            raise model.error(f"two bodies named {name!r}")
        if element.get("childclass") is not None and element.get("childclass") not in classes:
            raise model.error(f"body {name!r} names childclass {element.get('childclass')!r}, which no <default> "
                              "defines")
        inertial = element.find("inertial")
        mass, com, inertia = 0.0, np.zeros(3), np.zeros((3, 3))
        if inertial is not None:
            mass = float(_floats(path, inertial, "mass", 1)[0]) if inertial.get("mass") is not None else None
            if mass is None or mass < 0:
                raise model.error(f"body {name!r}: <inertial> needs a mass of at least 0 kg")
            com = _floats(path, inertial, "pos", 3, (0.0, 0.0, 0.0))
            full = _floats(path, inertial, "fullinertia", 6)
            if full is not None:
                if any(inertial.get(kind) is not None for kind in _ORIENTATIONS):
                    raise model.error(f"body {name!r}: <inertial> with fullinertia takes no orientation")
                xx, yy, zz, xy, xz, yz = full
                inertia = np.array([[xx, xy, xz], [xy, yy, yz], [xz, yz, zz]])
            else:
                diagonal = _floats(path, inertial, "diaginertia", 3)
                if diagonal is None:
                    raise model.error(f"body {name!r}: <inertial> needs diaginertia or fullinertia")
                if np.any(diagonal < 0):
                    raise model.error(f"body {name!r}: diaginertia {inertial.get('diaginertia')!r} is negative")
                rotation = _orientation(path, inertial, compiler)
                inertia = rotation @ np.diag(diagonal) @ rotation.T
        joints: list[str] = []
        for child in element:
            if child.tag in ("joint", "freejoint"):
                read = joint(child, name, childclass, joints[-1] if joints else last_joint)
                model.joints[read.name] = read
                model.joint_elements[read.name] = child
                joints.append(read.name)
        model.body_elements[name] = element
        model.bodies[name] = _BodyElement(
            name, parent, offset @ _pose(path, element, compiler), mass, com, inertia, tuple(joints),
            inertial is not None, any(child.tag == "geom" for child in element),
            float(_floats(path, element, "gravcomp", 1, (0.0,))[0]))
        children(element, name, np.eye(4), childclass, joints[-1] if joints else last_joint)

    def children(element: ElementTree.Element, parent: str | None, offset: NDArray[np.float64], childclass: str,
                 last_joint: str | None) -> None:
        for child in element:
            if child.tag == "site":
                model.sites[child.get("name") or f"site{next(unnamed)}"] = parent or "world"
            if child.tag == "body":
                body(child, parent, offset, childclass, last_joint)
            elif child.tag == "frame":
                children(child, parent, offset @ _pose(path, child, compiler), child.get("childclass", childclass),
                         last_joint)

    children(worldbody, None, np.eye(4), "main", None)
    for section in root.findall("tendon"):
        for tendon in section:
            label = f"<{tendon.tag}" + (f" name={tendon.get('name')!r}" if tendon.get("name") else "") + ">"
            model.tendons.append((f"tendon {label}", tuple(child.get("joint", "") for child in tendon.findall("joint"))
                                  if tendon.tag == "fixed" else None))
    for section in root.findall("actuator"):
        for element in section:
            if element.tag not in ACTUATOR_TAGS:
                continue
            values = {**classes.get(element.get("class", "main"), {}).get("actuator", {}), **element.attrib}
            label = f"<{element.tag}" + (f" name={values['name']!r}" if values.get("name") else "") + ">"
            given = [kind for kind in ACTUATOR_TRANSMISSIONS if values.get(kind)]
            gear = _floats(path, ElementTree.Element(element.tag, values), "gear", None, (1.0,))
            kind = ("slidercrank" if given[0] == "cranksite" else given[0]) if len(given) == 1 else ", ".join(given)
            model.actuators.append(_ActuatorElement(label, values.get("name"), kind,
                                                    values[given[0]] if len(given) == 1 else "", float(gear[0]),
                                                    element.tag, dict(values)))
    for section in root.findall("equality"):
        for equality in section:
            if equality.get("active", "true") == "false":
                continue
            label = f"equality <{equality.tag}" + (f" name={equality.get('name')!r}" if equality.get("name") else "") + ">"
            if equality.tag == "joint":
                model.equalities.append((label, (equality.get("joint1", ""), equality.get("joint2", ""))))
            elif equality.tag == "tendon":
                coupled = {equality.get("tendon1"), equality.get("tendon2")}
                model.equalities.append((label, tuple(
                    child.get("joint", "") for tendons in root.findall("tendon") for tendon in tendons
                    if tendon.get("name") in coupled and tendon.tag == "fixed" for child in tendon.findall("joint"))))
            else:
                model.equalities.append((label, None))
    return model


def _chain_ancestry(model: _Model, joint: str) -> list[str]:
    """The joints from the base to ``joint`` (each the parent of the next)."""
    chain = [joint]
    while model.joints[chain[-1]].parent is not None:
        chain.append(model.joints[chain[-1]].parent)
    return chain[::-1]


def _unsupported_joint(model: _Model, joint: _JointElement) -> RobotDescriptionError:
    return model.error(f"joint {joint.name!r} of body {joint.body!r} is a {joint.kind} joint ("
                       + ("a floating body" if joint.kind == "free" else "three degrees of freedom")
                       + "): serial chains of hinge and slide joints only; name the logged joints "
                       "(joint_names, --joint-names) and the others are locked")


def _check_constraints(model: _Model, chain: Sequence[str], named: bool) -> None:
    """Refuse what a serial chain of ``chain`` cannot take (module docstring)."""
    for name in chain:
        for ancestor in _chain_ancestry(model, name):
            kind = model.joints[ancestor].kind
            if kind == "free":
                raise model.error(f"joint {ancestor!r} of body {model.joints[ancestor].body!r} is a free joint: a "
                                  "floating base is not a serial chain fixed to the ground (fix the base: remove the "
                                  "free joint)")
    others = [joint for joint in model.joints.values() if joint.name not in chain]
    for joint in others:
        if joint.kind in ("free", "ball") and not named:
            raise _unsupported_joint(model, joint)
    for label, joints in [*model.tendons, *model.equalities]:
        if joints is None:
            if label.startswith("tendon"):
                raise model.error(f"{label}: a spatial tendon acts on bodies through sites; tendons are not supported")
            raise model.error(f"{label}: a closed loop (connect, weld) is not a serial chain")
        coupled = [name for name in joints if name in chain]
        if coupled or not named:
            raise model.error(f"{label} couples joints {', '.join(joints)}: coupled joints are not supported (the "
                              "chain would be identified as if it moved freely)" + (
                                  "" if coupled else "; name the logged joints (joint_names, --joint-names) and "
                                  "the coupled ones, if not among them, are locked"))


def _serial_chain(model: _Model) -> list[str]:
    """All movable joints of the file, when they form one chain from the base."""
    names = list(model.joints)
    if not names:
        raise model.error("no joint: nothing moves")
    for index, name in enumerate(names):
        joint = model.joints[name]
        if joint.kind not in _MOVABLE:
            raise _unsupported_joint(model, joint)
        expected = names[index - 1] if index else None
        if joint.parent != expected:
            base = _chain_ancestry(model, joint.parent) if joint.parent is not None else []
            raise model.error(
                f"joint {name!r} (body {joint.body!r}) hangs from "
                + (f"{joint.parent!r}" if joint.parent else "the world") + ", not from the previous joint "
                + (f"{expected!r}" if expected else "") + ": several chains or a branching tree; name the logged "
                "joints, base to tip (joint_names, --joint-names)"
                + (f" (the chain from the base to the branch: --joint-names {','.join(base)})" if base else ""))
    return names


def _named_chain(model: _Model, joint_names: Sequence[str]) -> list[str]:
    if isinstance(joint_names, str):
        joint_names = [name.strip() for name in joint_names.split(",")]
    names = list(joint_names)
    if not names or not all(isinstance(name, str) and name for name in names):
        raise model.error(f"joint names must be non-empty strings, got {names!r}")
    repeated = sorted({name for name in names if names.count(name) > 1})
    if repeated:
        raise model.error(f"joint(s) {', '.join(repeated)} named twice")
    movable = [name for name, joint in model.joints.items() if joint.kind in _MOVABLE]
    for name in names:
        if name not in model.joints:
            raise model.error(f"joint {name!r} is not a joint of the file; its hinge and slide joints are "
                              + ", ".join(movable))
        if model.joints[name].kind not in _MOVABLE:
            raise model.error(f"joint {name!r} is a {model.joints[name].kind} joint: name hinge or slide joints")
    for previous, name in zip([None, *names], names):
        ancestors = [joint for joint in _chain_ancestry(model, name)[:-1] if joint in names]
        if (ancestors[-1] if ancestors else None) != previous:
            raise model.error(f"the named joints are not one chain from the base to the tip in this order: {name!r} "
                              "hangs below " + (repr(ancestors[-1]) if ancestors else "no named joint")
                              + (f", not below {previous!r}" if previous else ""))
    return names


def _transform(rotation: NDArray[np.float64] | None = None, translation: NDArray[np.float64] | None = None) -> NDArray:
    pose = np.eye(4)
    if rotation is not None:
        pose[:3, :3] = rotation
    if translation is not None:
        pose[:3, 3] = translation
    return pose


def _motion(joint: _JointElement, value: float) -> NDArray[np.float64]:
    """The body's motion by joint ``joint`` at ``value``, in the body frame (MuJoCo turns by ``q − ref``)."""
    if joint.kind == "slide":
        return _transform(translation=joint.axis * (value - joint.reference))
    if joint.kind == "hinge":
        turn = _transform(_rotation(joint.axis, value - joint.reference))
        return _transform(translation=joint.position) @ turn @ _transform(translation=-joint.position)
    return np.eye(4)  # ball and free joints locked at their reference


def _chain_frames(model: _Model, chain: Sequence[str], locked_at: Mapping[str, float]) -> tuple[dict, dict, dict, dict]:
    """``world`` (each body's frame at the chain's zero), ``frames`` (each chain joint's), ``owner`` (the chain joint
    each body moves with, ``None``: the base) and ``link_frames`` (each link's: its body's frame, for the last chain
    joint in it)."""
    for name, value in locked_at.items():
        if name in chain:
            raise model.error(f"joint {name!r} is both named (logged) and locked")
        if name not in model.joints:
            raise model.error(f"locked joint {name!r} is not a joint of the file")
        if model.joints[name].kind not in _MOVABLE and value != 0:
            raise model.error(f"joint {name!r} is a {model.joints[name].kind} joint: it is locked at its reference, "
                              "not at one number")
        if not np.isfinite(float(value)):
            raise model.error(f"joint {name!r} locked at {value}: not a finite number")
    world: dict[str, NDArray[np.float64]] = {}  # each body's frame in the world at the chain's zero
    frames: dict[str, NDArray[np.float64]] = {}  # each chain joint's frame in the world
    owner: dict[str, str | None] = {}  # the chain joint each body moves with (None: the base)
    for body in model.bodies.values():
        pose = (np.eye(4) if body.parent is None else world[body.parent]) @ body.pose
        moved_by = None if body.parent is None else owner[body.parent]
        for name in body.joints:
            joint = model.joints[name]
            if name in chain:
                frames[name] = pose @ _transform(translation=joint.position)
                moved_by = name
            pose = pose @ _motion(joint, 0.0 if name in chain else float(locked_at.get(name, 0.0)))
        world[body.name], owner[body.name] = pose, moved_by
        if moved_by is not None and (model.inertia_from_geoms or (not body.has_inertial and body.has_geoms)):
            raise model.error(f"body {body.name!r} moves with joint {moved_by!r} and MuJoCo computes its inertia from "
                              "its geoms (" + ("inertiafromgeom=\"true\"" if model.inertia_from_geoms else "no <inertial>")
                              + "), which this reader does not: give the body an <inertial>")
    link_frames = {name: frames[name] for name in chain}  # a body's frame, for the last chain joint in it
    for body in model.bodies.values():
        if body.joints and owner[body.name] in body.joints:
            link_frames[owner[body.name]] = world[body.name]
    return world, frames, owner, link_frames


def _link_sums(model: _Model, chain: Sequence[str], world: dict, owner: dict, link_frames: dict,
               leave_out: Sequence[str] = ()) -> dict[str, NDArray[np.float64]]:
    """Each link's standard parameters in its frame: the sum of the bodies that move with its joint (but
    ``leave_out``)."""
    links = {name: np.zeros(10) for name in chain}
    for body in model.bodies.values():
        if owner[body.name] is None or body.name in leave_out or (body.mass == 0 and not np.any(body.inertia)):
            continue
        relative = np.linalg.inv(link_frames[owner[body.name]]) @ world[body.name]
        rotation, offset = relative[:3, :3], relative[:3, 3]
        links[owner[body.name]] += inertial_parameters(body.mass, rotation @ body.com + offset,
                                                       rotation @ body.inertia @ rotation.T)
    return links


def _chain_model(model: _Model, chain: list[str], locked_at: Mapping[str, float], gravity) -> RobotModel:
    """The chain's joints, every other joint locked, each body's inertia in the frame of the joint it moves with."""
    world, frames, owner, link_frames = _chain_frames(model, chain, locked_at)
    for body in model.bodies.values():
        if owner[body.name] is not None and body.gravity_compensation != 0:
            warnings.warn(f"MJCF {model.path}: body {body.name!r} has gravcomp={body.gravity_compensation:g} (MuJoCo "
                          "cancels its weight); ignored: measured torques hold gravity", MjcfIgnoredWarning, stacklevel=4)
    links = _link_sums(model, chain, world, owner, link_frames)
    joints, previous = [], np.eye(4)
    for name in chain:  # at the chain's zero: the bodies' poses hold the turns by -ref, the joints' motions are 1
        joint = model.joints[name]
        joints.append(Joint(name=name, joint_type=JointType.REVOLUTE if joint.kind == "hinge" else JointType.PRISMATIC,
                            axis=joint.axis, placement=np.linalg.inv(previous) @ frames[name],
                            link_transform=np.linalg.inv(frames[name]) @ link_frames[name], inertial=links[name],
                            lower=joint.lower, upper=joint.upper, effort=joint.effort,
                            armature=joint.terms.get("armature", 0.0), damping=joint.terms.get("damping", 0.0),
                            friction=joint.terms.get("frictionloss", 0.0)))
        previous = link_frames[name]
    return RobotModel(name=model.name, joints=tuple(joints), gravity=np.asarray(
        (DEFAULT_GRAVITY if model.gravity is None else model.gravity) if gravity is None else gravity, dtype=float))


def robot_from_mjcf(path: str | Path, *, gravity: np.ndarray | None = None, joint_names: Sequence[str] | None = None,
                    locked_at: Mapping[str, float] | None = None) -> RobotModel:
    """Read a serial chain from a MuJoCo MJCF file, or the chain of the named joints of any MJCF model.

    Parameters
    ----------
    path
        The MJCF file (root ``<mujoco>``; ``<include>`` files beside it).
    gravity
        Gravity in the base frame; default the file's ``<option gravity>``, else ``(0, 0, -9.81)``.
    joint_names
        The logged joints, from the base to the tip of one chain (hinge or slide); every other joint is
        locked and the bodies it carries merged into the link they hang from. ``None``: the file's
        joints must be one serial chain (all of them, in document order).
    locked_at
        Positions of locked joints (rad or m, MuJoCo's ``qpos``; default 0 for each).

    Raises
    ------
    RobotDescriptionError
        What the module docstring lists, naming the element: a file that is not MJCF or cannot be read,
        a number that is not one, free or ball joints, several chains, tendons and equality constraints
        on the chain, closed loops, moving bodies without ``<inertial>``.
    """
    path = Path(path)
    model = _read(path)
    if joint_names is None:
        if locked_at:
            raise model.error(f"locked joints ({', '.join(locked_at)}) given without the names of the logged joints "
                              "(joint_names, --joint-names)")
        chain = _serial_chain(model)
        _check_constraints(model, chain, named=False)
    else:
        chain = _named_chain(model, joint_names)
        _check_constraints(model, chain, named=True)
    ignored = sorted({term for name in chain for term, value in model.joints[name].terms.items()
                      if term in IGNORED_JOINT_TERMS and value != 0})
    if ignored:
        warnings.warn(f"MJCF {path}: the joints' {' and '.join(ignored)} values are not read (the identification fits "
                      "its own spring effects when asked: --friction ...,spring)", MjcfIgnoredWarning, stacklevel=2)
    robot = _chain_model(model, chain, dict(locked_at or {}), gravity)
    if joint_names is None:
        return robot
    described, apart = _description_joints(model, chain)
    return replace(robot, description_joints=described, apart_joints=apart)


def _description_joints(model: _Model, chain: Sequence[str]) -> tuple[tuple[str, ...], frozenset[str]]:
    """The file's joints in document order (MuJoCo's ``qpos`` order) and those apart from ``chain``
    (:attr:`~dynamics.robot.RobotModel.apart_joints`: neither on its path from the world nor carried by it), as
    :func:`dynamics.urdf.robot_from_urdf` gives them; ``((), frozenset())`` where the file holds a free or ball
    joint (more than one number a joint in a log) or its joints are the chain's."""
    described = tuple(model.joints)
    if any(joint.kind not in ("hinge", "slide") for joint in model.joints.values()) or set(described) <= set(chain):
        return (), frozenset()
    above = set().union(*(_chain_ancestry(model, name) for name in chain))
    apart = frozenset(name for name in described if name not in above
                      and not set(_chain_ancestry(model, name)) & set(chain))
    return described, apart


@dataclass(frozen=True, eq=False)
class MjcfLayout:
    """Where the links of a chain read from an MJCF file sit in the file (for a writer that edits the file).

    ``root`` is the file as read (``<include>`` files in place; its comments are not kept), ``bodies`` the
    ``<body>`` element whose frame is each link's (``None`` for a joint that shares its body with a later joint
    of the chain: its link has no body of its own), ``joints`` each chain joint's ``<joint>`` element, ``others``
    the standard parameters, in the link's frame, of the other bodies that move with each link (bodies fixed to it,
    and those carried by locked joints at their positions), ``terms`` each chain joint's attributes as the file
    gives them (``armature``, ``damping``, ``frictionloss``, ``stiffness``; its classes resolved), ``gravity``
    the file's ``<option gravity>`` (``None``: MuJoCo's default) and ``degrees`` whether its hinge angles
    (``range``, ``ref``, ``springref``) are in degrees (``<compiler angle>``).
    """

    root: ElementTree.Element
    bodies: Mapping[str, ElementTree.Element | None]
    joints: Mapping[str, ElementTree.Element]
    others: Mapping[str, NDArray[np.float64]]
    terms: Mapping[str, Mapping[str, float]]
    gravity: NDArray[np.float64] | None
    degrees: bool = True


def mjcf_layout(path: str | Path, *, joint_names: Sequence[str] | None = None,
                locked_at: Mapping[str, float] | None = None) -> MjcfLayout:
    """The :class:`MjcfLayout` of the chain :func:`robot_from_mjcf` reads from ``path`` with the same arguments."""
    model = _read(Path(path))
    chain = _serial_chain(model) if joint_names is None else _named_chain(model, joint_names)
    world, _, owner, link_frames = _chain_frames(model, chain, dict(locked_at or {}))
    holders = {name: model.joints[name].body for name in chain if owner[model.joints[name].body] == name}
    others = _link_sums(model, chain, world, owner, link_frames, leave_out=tuple(holders.values()))
    return MjcfLayout(model.root, {name: model.body_elements[holders[name]] if name in holders else None
                                   for name in chain},
                      {name: model.joint_elements[name] for name in chain}, others,
                      {name: dict(model.joints[name].terms) for name in chain}, model.gravity, model.degrees)


def mjcf_joint_terms(path: str | Path, robot: RobotModel) -> dict[str, dict[str, float]]:
    """``{joint: {"viscous": damping, "coulomb": frictionloss}}`` of ``robot``'s joints in the MJCF file (0 where
    unset): the description's friction, as a URDF's ``<dynamics damping friction>``."""
    model = _read(Path(path))
    missing = [name for name in robot.joint_names if name not in model.joints]
    if missing:
        raise model.error(f"no joint {', '.join(map(repr, missing))} of {robot.name}")
    return {name: {ours: model.joints[name].terms.get(theirs, 0.0) for theirs, ours in READ_JOINT_TERMS.items()}
            for name in robot.joint_names}


def _moving_bodies(model: _Model, chain: Sequence[str]) -> set[str]:
    """The bodies that move with a joint of ``chain`` (the body holding it and every body below)."""
    moving: set[str] = set()
    for body in model.bodies.values():  # parents come first (document order)
        if (body.parent in moving) or any(name in chain for name in body.joints):
            moving.add(body.name)
    return moving


def transmission_from_mjcf(path: str | Path, robot: RobotModel) -> Transmission | None:
    """The transmission the MJCF file's ``<actuator>`` elements declare for ``robot``'s joints, or ``None`` when none
    of its joints has an actuator.

    An actuator with a joint transmission (``joint`` or ``jointinparent``) and ``gear`` ``g`` pushes its joint with
    ``τ = g f`` for an actuator force ``f`` (MuJoCo's ``actuator_force``; a ``<motor>``'s is its ``ctrl``), and its
    length is ``g q``: the motor-side ``θ_m = g q``, ``τ = g τ_m`` of :mod:`dynamics.transmission`, so a log of actuator
    forces as ``taum1..taumn`` (and actuator lengths as ``qm1..qmn``) identifies as joint torques do. The ratio is
    ``g`` whatever the actuator's gain and bias (they make ``f`` from ``ctrl``, not ``τ`` from ``f``); a joint without an
    actuator is direct drive (ratio 1). Actuators of locked joints, and those acting on bodies that do not move
    with the chain (a free object's), are left out.

    Raises
    ------
    TransmissionError
        Naming the actuator: one whose force is not one joint's torque (a tendon on a joint of the chain, a site,
        body or slider-crank transmission on a body that moves with it: a wrench, not a ratio), a zero gear, or two
        actuators with different gears on one joint (which one's forces are logged?).
    """
    path = Path(path)
    model = _read(path)
    where = f"MJCF {path}"
    ratios: dict[str, tuple[float, _ActuatorElement]] = {}
    moving = _moving_bodies(model, robot.joint_names)
    tendons = {tendon.get("name"): tendon for section in (model.root.findall("tendon") if model.root is not None else [])
               for tendon in section}
    for actuator in model.actuators:
        if actuator.kind not in (*ACTUATOR_TRANSMISSIONS, "slidercrank"):
            raise TransmissionError(f"{where}: actuator {actuator.label} names " + (
                f"several transmissions ({actuator.kind})" if actuator.kind else
                "no transmission (joint, tendon, site, body…)"))
        if actuator.kind in ("joint", "jointinparent"):
            if actuator.target not in model.joints:
                raise TransmissionError(f"{where}: actuator {actuator.label} acts on joint {actuator.target!r}, which "
                                        "is not a joint of the file")
            if actuator.target not in robot.joint_names:
                continue  # a locked joint's
            if actuator.gear == 0:
                raise TransmissionError(f"{where}: actuator {actuator.label} on joint {actuator.target!r} has gear 0: "
                                        "its force reaches no joint")
            previous = ratios.get(actuator.target)
            if previous is not None and previous[0] != actuator.gear:
                raise TransmissionError(f"{where}: actuators {previous[1].label} and {actuator.label} drive joint "
                                        f"{actuator.target!r} with gears {previous[0]:g} and {actuator.gear:g}: which "
                                        "one's forces does the log hold? Declare the ratio with --transmission FILE")
            ratios[actuator.target] = (actuator.gear, actuator)
            continue
        if actuator.kind == "tendon":
            tendon = tendons.get(actuator.target)
            joints = [] if tendon is None else [child.get("joint") for child in tendon.findall("joint")]
            spatial = tendon is not None and tendon.tag == "spatial"
            if not spatial and not any(name in robot.joint_names for name in joints):
                continue  # a locked joint's (a gripper's split tendon)
            reason = "a spatial tendon" if spatial else f"a tendon over joints {', '.join(joints)}"
        else:
            body = actuator.target if actuator.kind == "body" else model.sites.get(actuator.target)
            if body is not None and body not in moving:
                continue  # on a body the chain does not move
            reason = (f"a {actuator.kind} transmission" + (f" (site {actuator.target!r} on body {body!r})"
                                                          if actuator.kind != "body" else f" (body {body!r})"))
        raise TransmissionError(f"{where}: actuator {actuator.label} acts through {reason}: its force is not one "
                                "joint's torque, and only joint transmissions are read as gear ratios; declare the "
                                "joints' transmission with --transmission FILE (a JSON file; {\"matrix\": [1, 1, …]} "
                                "when the log holds joint torques)")
    if not ratios:
        return None
    names = tuple((ratios[name][1].name if name in ratios else None) or f"m{index + 1}"
                  for index, name in enumerate(robot.joint_names))
    return Transmission(np.array([ratios[name][0] if name in ratios else 1.0 for name in robot.joint_names]), names,
                        source=f"MJCF {path.name} <actuator> gears", servos=_servos_or_none(path, robot))


def mjcf_actuated_joints(path: str | Path) -> frozenset[str] | None:
    """The joints an MJCF file's ``<actuator>`` elements drive, or ``None`` when it has no actuator (it says nothing
    then): the joint of a joint transmission (``joint``, ``jointinparent``) and the joints of a fixed tendon an
    actuator pulls. A joint of a file with actuators that none drives has no motor: the verbs read it as passive when
    the log has no torque column for it (:func:`dynamics.urdf.urdf_actuated_joints`, the same rule)."""
    model = _read(Path(path))
    if not model.actuators:
        return None
    tendons = {tendon.get("name"): tendon for section in (model.root.findall("tendon") if model.root is not None else [])
               for tendon in section}
    driven: set[str] = set()
    for actuator in model.actuators:
        if actuator.kind in ("joint", "jointinparent"):
            driven.add(actuator.target)
        elif actuator.kind == "tendon" and actuator.target in tendons:
            driven |= {child.get("joint") for child in tendons[actuator.target].findall("joint")} - {None}
        else:  # a site, body or slider-crank actuator: what it drives is not one joint; say nothing
            return None
    return frozenset(driven)


def mjcf_logged_chain(path: str | Path, n_logged: int) -> tuple[tuple[str, ...], tuple[str, ...]] | None:
    """The chain a log of ``n_logged`` joints determines in an MJCF model that is not one plain serial chain
    (as :func:`dynamics.urdf.logged_chain`): the one path of ``n_logged`` hinge or slide joints from the base,
    none coupled to another by an equality or a fixed tendon; with the file's other joints (held fixed).

    Returns ``None`` when the file reads as one serial chain without names, or cannot be read
    (:func:`robot_from_mjcf` names the problem).

    Raises
    ------
    RobotDescriptionError
        When no path, or more than one, of ``n_logged`` joints from the base fits.
    """
    try:
        model = _read(Path(path))
    except RobotDescriptionError:
        return None
    try:
        _check_constraints(model, _serial_chain(model), named=False)
        return None
    except RobotDescriptionError:
        pass  # not one plain chain: the log's joints may determine one
    coupled = {name for _, joints in [*model.tendons, *model.equalities] for name in (joints or ())}
    usable = [name for name, joint in model.joints.items() if joint.kind in _MOVABLE and name not in coupled]
    paths: list[list[str]] = [[]]
    for _ in range(max(n_logged, 0)):
        paths = [chain + [name] for chain in paths for name in usable
                 if (model.joints[name].parent == (chain[-1] if chain else None))]
    chains = [tuple(chain) for chain in paths] if n_logged > 0 else []
    if len(chains) != 1:
        what = ("no chain of " if not chains else f"{len(chains)} chains of ") + f"{n_logged} joint(s) from the base"
        raise model.error(f"the tree branches or holds coupled or free joints, and the log's {n_logged} joint "
                          f"column(s) determine {what}" + (" (" + "; ".join(",".join(c) for c in chains[:4]) + ")"
                                                           if chains else "")
                          + ": name the logged joints, base to tip (joint_names, --joint-names A,B,C); the others "
                          "are locked")
    return chains[0], tuple(name for name in model.joints if name not in chains[0])


#: the actuator elements whose force is a law of the control and the state (no activation state of their own)
SERVO_TAGS = ("motor", "position", "velocity", "damper", "general")


def _limits(path: Path, values: Mapping[str, str], tag: str, attribute: str, limited: str,
            autolimits: bool) -> NDArray[np.float64]:
    """``(2,)`` an actuator's (or joint's) ``attribute`` range where ``limited`` says it applies (``auto``: given and
    the compiler's ``autolimits``), else ``(-inf, inf)``."""
    bounds = _floats(path, ElementTree.Element(tag, dict(values)), attribute, 2)
    flag = values.get(limited, "auto")
    if bounds is None or not (flag == "true" or (flag == "auto" and autolimits)):
        return np.array([-np.inf, np.inf])
    return np.asarray(bounds, dtype=float)


def _servo_law(path: Path, actuator: _ActuatorElement) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """``(gain (3,), bias (3,))`` of one actuator (:mod:`dynamics.servos`), or a :class:`RobotDescriptionError`
    naming what gives it a state of its own (activation dynamics) or needs the model's mass (``dampratio``)."""
    values = actuator.attributes
    element = ElementTree.Element(actuator.tag, dict(values))
    where = f"MJCF {path}: actuator {actuator.label}"
    if actuator.tag not in SERVO_TAGS:
        raise RobotDescriptionError(f"{where}: a <{actuator.tag}> has an activation state of its own (or a plugin's "
                                    "law): its force is not a law of the control and the joints' state")
    number = lambda name, default: float(_floats(path, element, name, 1, (default,))[0])  # noqa: E731
    if actuator.tag == "motor":
        return np.array([1.0, 0.0, 0.0]), np.zeros(3)
    if actuator.tag == "position":
        if number("timeconst", 0.0) > 0:
            raise RobotDescriptionError(f"{where}: timeconst > 0 filters the control (an activation state the log "
                                        "does not hold)")
        if values.get("dampratio") is not None:
            raise RobotDescriptionError(f"{where}: dampratio sets kv from the joint's inertia at the reference pose "
                                        "(MuJoCo's compiler); write kv")
        if number("inheritrange", 0.0) > 0:
            raise RobotDescriptionError(f"{where}: inheritrange sets ctrlrange from the joint's range; write ctrlrange")
        kp, kv = number("kp", 1.0), number("kv", 0.0)
        return np.array([kp, 0.0, 0.0]), np.array([0.0, -kp, -kv])
    if actuator.tag == "velocity":
        kv = number("kv", 1.0)
        return np.array([kv, 0.0, 0.0]), np.array([0.0, 0.0, -kv])
    if actuator.tag == "damper":
        return np.array([0.0, 0.0, -number("kv", 0.0)]), np.zeros(3)
    dynamics = values.get("dyntype", "none")
    if dynamics != "none":
        raise RobotDescriptionError(f"{where}: dyntype {dynamics!r} gives it an activation state the log does not hold")
    gain_type, bias_type = values.get("gaintype", "fixed"), values.get("biastype", "none")
    if gain_type not in ("fixed", "affine") or bias_type not in ("none", "affine"):
        raise RobotDescriptionError(f"{where}: gaintype {gain_type!r}, biastype {bias_type!r}: only fixed or affine "
                                    "laws are computed here")
    gain = np.zeros(3)
    given = _floats(path, element, "gainprm", None, (1.0,))
    gain[:min(3, given.size)] = given[:3]
    if gain_type == "fixed":
        gain[1:] = 0.0
    bias = np.zeros(3)
    if bias_type == "affine":
        given = _floats(path, element, "biasprm", None, (0.0,))
        bias[:min(3, given.size)] = given[:3]
    return gain, bias


def _servos_or_none(path: Path, robot: RobotModel) -> ServoLaws | None:
    """:func:`mjcf_servos`, or ``None`` where an actuator's force is no law of its control and the state: the
    transmission's gears stand without them (a log of the controls alone is then refused, naming the forces)."""
    try:
        return mjcf_servos(path, robot)
    except RobotDescriptionError:
        return None


def mjcf_servos(path: str | Path, robot: RobotModel) -> ServoLaws | None:
    """The laws by which the MJCF file's actuators make their force from their controls and the state
    (:class:`dynamics.servos.ServoLaws`, MuJoCo's actuator model), one a joint of ``robot``; ``None`` when a joint
    of the chain has no actuator with a joint transmission, or one has several (which one's control is logged?),
    or the file's option disables control clamping in a way not read here.

    Raises
    ------
    RobotDescriptionError
        Naming the actuator: activation dynamics (``timeconst``, ``dyntype``, ``<intvelocity>``, ``<cylinder>``,
        ``<muscle>``), ``dampratio`` or ``inheritrange`` (set from the model by MuJoCo's compiler), a gain or
        bias law other than fixed or affine.
    """
    path = Path(path)
    model = _read(path)
    compiler = _compiler(path, model.root) if model.root is not None else None
    autolimits = True if compiler is None else compiler.autolimits
    driving: dict[str, list[_ActuatorElement]] = {}
    for actuator in model.actuators:
        if actuator.kind in ("joint", "jointinparent") and actuator.target in robot.joint_names:
            driving.setdefault(actuator.target, []).append(actuator)
    if set(driving) != set(robot.joint_names) or any(len(found) != 1 for found in driving.values()):
        return None
    gear, gain, bias, ctrl, force, torque, labels = [], [], [], [], [], [], []
    for name in robot.joint_names:
        (actuator,) = driving[name]
        law = _servo_law(path, actuator)
        gear.append(actuator.gear)
        gain.append(law[0])
        bias.append(law[1])
        ctrl.append(_limits(path, actuator.attributes, actuator.tag, "ctrlrange", "ctrllimited", autolimits))
        force.append(_limits(path, actuator.attributes, actuator.tag, "forcerange", "forcelimited", autolimits))
        joint = model.joint_elements.get(name)
        torque.append(np.array([-np.inf, np.inf]) if joint is None else
                      _limits(path, joint.attrib, joint.tag, "actuatorfrcrange", "actuatorfrclimited", autolimits))
        labels.append(actuator.label)
    return ServoLaws(np.array(gear), np.array(gain), np.array(bias), np.array(ctrl), np.array(force),
                     np.array(torque), tuple(labels), source=f"MJCF {path.name} <actuator>")
