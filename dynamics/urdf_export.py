"""A robot with new inertial parameters as URDF text, for Pinocchio, simulators and controllers.

Two ways, one result for the dynamics:

* :func:`urdf_with_inertials`: a URDF as given, every moving link's ``<inertial>`` replaced (joint and
  link names, geometry, limits, visuals kept). Pinocchio merges the links hung on fixed joints into
  the moving link before them, and :func:`dynamics.urdf.robot_from_urdf` reads that merged body: their
  ``<inertial>`` elements are removed, the identified body holds them.
* :func:`robot_urdf`: a URDF written from a :class:`~dynamics.robot.RobotModel` (a DH table, say):
  joint ``i``'s origin in link ``i−1`` is ``B_{i−1} A_i`` and link ``i``'s frame is the joint frame,
  so the parameters given in ``F_i = L_i B_i`` are moved by ``B_i`` (module :mod:`dynamics.robot`).

A robot with passive (unactuated) joints keeps them so in either file: a ``<transmission>`` is written for each
driven joint (:func:`declare_motors`), the declaration :func:`dynamics.urdf.urdf_actuated_joints` reads, when the file
does not already declare its motors.

An ``<inertial>`` holds the mass, the centre of mass ``c`` (``origin xyz``) and the inertia about
``c`` (``I_c = I_O − m (cᵀc 𝟙 − c cᵀ)``, the parallel-axis theorem), here with ``rpy = 0``.
"""

from __future__ import annotations

import math
from xml.etree import ElementTree

import numpy as np
from numpy.typing import ArrayLike, NDArray

from dynamics.errors import RobotDescriptionError
from dynamics.robot import N_LINK_PARAMETERS, RobotModel

__all__ = ["declare_motors", "inertial_element", "robot_urdf", "urdf_with_inertials", "with_joint_friction"]


def _rotational(parameters: NDArray[np.float64]) -> NDArray[np.float64]:
    ixx, ixy, iyy, ixz, iyz, izz = parameters[4:]
    return np.array([[ixx, ixy, ixz], [ixy, iyy, iyz], [ixz, iyz, izz]])


def _number(value: float) -> str:
    return repr(float(value))


def inertial_element(parameters: ArrayLike, frame: ArrayLike | None = None) -> ElementTree.Element:
    """``<inertial>`` of one link from its ten standard parameters (in ``F``), written in the frame ``L``
    with ``F = L · frame`` (4x4; default: the same frame)."""
    parameters = np.asarray(parameters, dtype=float).reshape(-1)
    if parameters.shape != (N_LINK_PARAMETERS,):
        raise ValueError(f"a link has {N_LINK_PARAMETERS} standard parameters, got {parameters.shape[0]}")
    transform = np.eye(4) if frame is None else np.asarray(frame, dtype=float)
    rotation, offset = transform[:3, :3], transform[:3, 3]
    mass = parameters[0]
    com = parameters[1:4] / mass if mass > 0 else np.zeros(3)
    about_com = _rotational(parameters) - mass * (com @ com * np.eye(3) - np.outer(com, com))
    com, about_com = rotation @ com + offset, rotation @ about_com @ rotation.T
    element = ElementTree.Element("inertial")
    ElementTree.SubElement(element, "origin", xyz=" ".join(map(_number, com)), rpy="0 0 0")
    ElementTree.SubElement(element, "mass", value=_number(mass))
    ElementTree.SubElement(element, "inertia", ixx=_number(about_com[0, 0]), ixy=_number(about_com[0, 1]),
                           ixz=_number(about_com[0, 2]), iyy=_number(about_com[1, 1]), iyz=_number(about_com[1, 2]),
                           izz=_number(about_com[2, 2]))
    return element


def _link_parameters(robot: RobotModel, link_parameters: ArrayLike) -> NDArray[np.float64]:
    values = np.asarray(link_parameters, dtype=float).reshape(-1, N_LINK_PARAMETERS)
    if values.shape[0] != robot.n_joints:
        raise ValueError(f"{robot.name} has {robot.n_joints} links, got parameters for {values.shape[0]}")
    return values


def _rpy(rotation: NDArray[np.float64]) -> tuple[float, float, float]:
    """Roll, pitch, yaw of ``R = R_z(yaw) R_y(pitch) R_x(roll)`` (URDF's convention)."""
    pitch = math.atan2(-rotation[2, 0], math.hypot(rotation[0, 0], rotation[1, 0]))
    if abs(math.cos(pitch)) < 1e-12:  # gimbal lock: put the rotation into yaw
        return 0.0, pitch, math.atan2(-rotation[0, 1], rotation[1, 1])
    return math.atan2(rotation[2, 1], rotation[2, 2]), pitch, math.atan2(rotation[1, 0], rotation[0, 0])


def _finite_limit(value: float, fallback: float) -> str:
    return _number(value if np.isfinite(value) else fallback)


def robot_urdf(robot: RobotModel, link_parameters: ArrayLike | None = None, *, base_link: str = "base_link") -> str:
    """URDF text of ``robot`` (module docstring), its links holding ``link_parameters`` (``(n, 10)``;
    default the robot's own)."""
    values = _link_parameters(robot, robot.standard_parameters if link_parameters is None else link_parameters)
    root = ElementTree.Element("robot", name=robot.name.replace("[", "_").replace("]", ""))
    ElementTree.SubElement(root, "link", name=base_link)
    parent, previous = base_link, np.eye(4)
    for index, joint in enumerate(robot.joints):
        child = f"{joint.name}_link"
        link = ElementTree.SubElement(root, "link", name=child)
        link.append(inertial_element(values[index], joint.link_transform))
        element = ElementTree.SubElement(root, "joint", name=joint.name, type=joint.joint_type.value)
        placement = previous @ joint.placement
        ElementTree.SubElement(element, "origin", xyz=" ".join(map(_number, placement[:3, 3])),
                               rpy=" ".join(map(_number, _rpy(placement[:3, :3]))))
        ElementTree.SubElement(element, "parent", link=parent)
        ElementTree.SubElement(element, "child", link=child)
        ElementTree.SubElement(element, "axis", xyz=" ".join(map(_number, joint.axis)))
        ElementTree.SubElement(element, "limit", lower=_finite_limit(joint.lower, -1e3), upper=_finite_limit(joint.upper, 1e3),
                               velocity=_finite_limit(joint.velocity, 1e3), effort=_finite_limit(joint.effort, 1e6))
        parent, previous = child, joint.link_transform
    declare_motors(root, robot)
    ElementTree.indent(root)
    return ElementTree.tostring(root, encoding="unicode") + "\n"


def urdf_with_inertials(urdf_text: str, robot: RobotModel, link_parameters: ArrayLike, *,
                        merge_locked: bool = False) -> str:
    """``urdf_text`` with the ``<inertial>`` of each of ``robot``'s moving links replaced by
    ``link_parameters`` (``(n, 10)``, in the child-link frames), the links fixed to them emptied
    (module docstring); everything else as it was.

    ``merge_locked``: ``robot`` is the chain of the named joints of the file (:func:`dynamics.urdf.robot_from_urdf`
    with ``joint_names``), whose bodies hold those the locked joints carry: the links below a locked joint
    (up to the next named joint) are emptied too, so that reading the file again with the same names gives the
    identified bodies, wherever the locked joints stand."""
    values = _link_parameters(robot, link_parameters)
    try:
        root = ElementTree.fromstring(urdf_text)
    except ElementTree.ParseError as error:
        raise RobotDescriptionError(f"cannot parse the URDF: {error}") from None
    links = {link.get("name"): link for link in root.findall("link")}
    joints = {joint.get("name"): joint for joint in root.findall("joint")}
    children: dict[str, list[ElementTree.Element]] = {}
    for joint in joints.values():
        children.setdefault(joint.find("parent").get("link"), []).append(joint)
    for index, joint_model in enumerate(robot.joints):
        joint = joints.get(joint_model.name)
        if joint is None:
            raise RobotDescriptionError(f"the URDF has no joint {joint_model.name!r} of {robot.name}")
        child = links[joint.find("child").get("link")]
        _replace_inertial(child, inertial_element(values[index]))
        pending = list(children.get(child.get("name"), []))
        while pending:  # the links fixed to this one: merged into its body by the parser
            fixed = pending.pop()
            if fixed.get("type") != "fixed" and (not merge_locked or fixed.get("name") in robot.joint_names):
                continue
            link = links[fixed.find("child").get("link")]
            _replace_inertial(link, None)
            pending.extend(children.get(link.get("name"), []))
    declare_motors(root, robot)
    return ElementTree.tostring(root, encoding="unicode") + "\n"


def with_joint_friction(urdf_text: str, friction: dict[str, tuple[float, float]]) -> tuple[str, tuple[str, ...]]:
    """``urdf_text`` with each ``<dynamics>`` element of the joints named in ``friction`` holding ``damping`` and
    ``friction`` (the viscous, N m s/rad or N s/m, and Coulomb, N m or N, friction given), and the names of those
    joints. A URDF's ``<dynamics damping friction>`` is what a simulator (Gazebo) takes for the joint's friction:
    left as the description had it, it would contradict the identified model beside it. A joint without such an
    element is left as it is (the friction JSON holds every joint's laws). ``(urdf_text, ())`` when no named joint
    has one."""
    root = ElementTree.fromstring(urdf_text)
    changed = []
    for joint in root.findall("joint"):
        name = joint.get("name")
        element = joint.find("dynamics")
        if element is None or name not in friction:
            continue
        damping, coulomb = friction[name]
        element.set("damping", _number(damping))
        element.set("friction", _number(coulomb))
        changed.append(str(name))
    if not changed:
        return urdf_text, ()
    return ElementTree.tostring(root, encoding="unicode") + "\n", tuple(changed)


def declare_motors(root: ElementTree.Element, robot: RobotModel) -> bool:
    """Append to the URDF ``root`` a ``<transmission>`` (``transmission_interface/SimpleTransmission``, one joint, one
    actuator) for each of ``robot``'s driven joints, when ``robot`` has a passive (unactuated) joint and ``root``
    declares no motor (no ``<transmission>`` and no ``<ros2_control>`` joint with a ``<command_interface>``): the file
    read again says which joints have no motor (:func:`dynamics.urdf.urdf_actuated_joints`), as the model it was
    written from did. A file that declares its motors is left as it is (it is the user's word). Returns whether
    anything was appended."""
    if not robot.passive_joints or all(not joint.actuated for joint in robot.joints):
        return False  # no passive joint, or no driven one to declare
    declared = any(transmission.find("joint") is not None for transmission in root.iter("transmission")) or any(
        joint.find("command_interface") is not None for block in root.iter("ros2_control")
        for joint in block.findall("joint"))
    if declared:
        return False
    children = list(root)
    if children and (children[-1].tail is None or not children[-1].tail.strip()):
        children[-1].tail = "\n  "  # the appended elements indented as a URDF's top level, the rest as it was
    for joint in robot.joints:
        if not joint.actuated:
            continue
        transmission = ElementTree.SubElement(root, "transmission", name=f"{joint.name}_transmission")
        ElementTree.SubElement(transmission, "type").text = "transmission_interface/SimpleTransmission"
        driven = ElementTree.SubElement(transmission, "joint", name=joint.name)
        ElementTree.SubElement(driven, "hardwareInterface").text = "hardware_interface/EffortJointInterface"
        actuator = ElementTree.SubElement(transmission, "actuator", name=f"{joint.name}_motor")
        ElementTree.SubElement(actuator, "mechanicalReduction").text = "1"
        ElementTree.indent(transmission, space="  ", level=1)
        transmission.tail = "\n  "
    transmission.tail = "\n"
    return True


def _replace_inertial(link: ElementTree.Element, inertial: ElementTree.Element | None) -> None:
    for old in link.findall("inertial"):
        link.remove(old)
    if inertial is not None:
        link.insert(0, inertial)
