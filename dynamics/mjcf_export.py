"""A robot with identified bodies and joint terms as MuJoCo's MJCF, written at full precision.

Link ``i``'s frame ``F_i = A_i J_i(q) B_i`` (:mod:`dynamics.robot`) is the MJCF body: its ``pos`` and
``xyaxes`` in the parent body are those of ``A_i B_i``, and its joint turns (``hinge``) about, or slides
(``slide``) along, the axis ``B_iᵀ a`` through the point ``B_i⁻¹ 0`` (``B_i⁻¹ J_i(q) B_i`` is that
motion). The body's ``<inertial>`` holds the mass, the centre of mass ``c`` and the inertia about ``c``
(``fullinertia``, the parallel-axis theorem) of its ten standard parameters.

Joint terms, MuJoCo's names for the identified ones: ``armature`` (reflected rotor inertia, ``Ia q̈``),
``damping`` (viscous, ``fv q̇``), ``frictionloss`` (Coulomb, ``fc``, MuJoCo's own dry-friction
constraint), ``stiffness`` and ``springref`` (a spring ``k (q − q_ref)``). Numbers are written with
Python's ``repr`` (the shortest text that reads back to the same double): MuJoCo's own XML writer rounds
to six digits, which moves the inverse dynamics by a few 1e-6.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from xml.etree import ElementTree

import numpy as np
from numpy.typing import ArrayLike, NDArray

from dynamics.robot import N_LINK_PARAMETERS, JointType, RobotModel

__all__ = ["JOINT_ATTRIBUTES", "robot_mjcf"]

#: the joint attributes written, in MuJoCo's names
JOINT_ATTRIBUTES = ("armature", "damping", "frictionloss", "stiffness", "springref")


def _number(value: float) -> str:
    return repr(float(value)).replace("inf", "1e308")


def _numbers(values: ArrayLike) -> str:
    return " ".join(_number(value) for value in np.asarray(values, dtype=float).reshape(-1))


def _inertial(parameters: NDArray[np.float64]) -> ElementTree.Element:
    """``<inertial pos mass fullinertia>`` of one link from its ten standard parameters (in its frame)."""
    mass = parameters[0]
    com = parameters[1:4] / mass if mass > 0 else np.zeros(3)
    ixx, ixy, iyy, ixz, iyz, izz = parameters[4:]
    about_origin = np.array([[ixx, ixy, ixz], [ixy, iyy, iyz], [ixz, iyz, izz]])
    about_com = about_origin - mass * (com @ com * np.eye(3) - np.outer(com, com))
    return ElementTree.Element("inertial", pos=_numbers(com), mass=_number(mass), fullinertia=_numbers(
        [about_com[0, 0], about_com[1, 1], about_com[2, 2], about_com[0, 1], about_com[0, 2], about_com[1, 2]]))


def _comment_text(text: str) -> str:
    """Text an XML comment may hold (no ``--``)."""
    while "--" in text:
        text = text.replace("--", "- -")
    return text


def robot_mjcf(robot: RobotModel, links: ArrayLike, joint_terms: Mapping[str, Mapping[str, float]] | None = None,
               *, notes: Sequence[str] = (), header: str = "") -> str:
    """The MJCF text of ``robot`` with the bodies ``links`` and the joint terms ``joint_terms``.

    Parameters
    ----------
    robot
        The chain (joint placements, axes, limits, gravity).
    links
        ``(n, 10)`` standard parameters of the links, in the order of :mod:`dynamics.robot`.
    joint_terms
        ``{joint name: {attribute: value}}`` with attributes among :data:`JOINT_ATTRIBUTES`.
    notes
        What the model holds that MuJoCo cannot express: written in a comment, one line each.
    header
        A first comment line (where the file comes from).

    Raises
    ------
    ValueError
        Links of another shape, an unknown joint or attribute.
    """
    links = np.asarray(links, dtype=float)
    if links.shape != (robot.n_joints, N_LINK_PARAMETERS):
        raise ValueError(f"expected {robot.n_joints} x {N_LINK_PARAMETERS} link parameters, got shape {links.shape}")
    terms = dict(joint_terms or {})
    unknown = [name for name in terms if name not in robot.joint_names]
    if unknown:
        raise ValueError(f"joint terms for joint(s) {', '.join(unknown)} that {robot.name} lacks")
    root = ElementTree.Element("mujoco", model=robot.name)
    lines = [header] if header else []
    if notes:
        lines += ["Not expressed in MuJoCo (kept out of this file):"] + [f"  - {note}" for note in notes]
    if lines:
        root.append(ElementTree.Comment(_comment_text("\n  " + "\n  ".join(lines) + "\n")))
    ElementTree.SubElement(root, "compiler", angle="radian", autolimits="true", inertiafromgeom="false")
    ElementTree.SubElement(root, "option", gravity=_numbers(robot.gravity))
    parent = ElementTree.SubElement(root, "worldbody")
    for joint, parameters in zip(robot.joints, links):
        body_frame = joint.placement @ joint.link_transform
        inverse = np.linalg.inv(joint.link_transform)
        rotation = body_frame[:3, :3]
        body = ElementTree.SubElement(parent, "body", name=f"link_{joint.name}", pos=_numbers(body_frame[:3, 3]),
                                      xyaxes=_numbers(np.concatenate([rotation[:, 0], rotation[:, 1]])))
        body.append(_inertial(parameters))
        attributes = {"name": joint.name, "type": "hinge" if joint.joint_type is JointType.REVOLUTE else "slide",
                      "pos": _numbers(inverse[:3, 3]), "axis": _numbers(inverse[:3, :3] @ joint.axis)}
        if np.isfinite(joint.lower) and np.isfinite(joint.upper):
            attributes["range"] = _numbers([joint.lower, joint.upper])
        for key, value in dict(terms.get(joint.name, {})).items():
            if key not in JOINT_ATTRIBUTES:
                raise ValueError(f"joint {joint.name}: unknown MuJoCo joint attribute {key!r} (known: "
                                 f"{', '.join(JOINT_ATTRIBUTES)})")
            attributes[key] = _number(value)
        ElementTree.SubElement(body, "joint", attributes)
        parent = body
    ElementTree.indent(root)
    return ElementTree.tostring(root, encoding="unicode") + "\n"
