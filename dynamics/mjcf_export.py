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

:func:`robot_mjcf` writes the chain alone (bodies and joints); :func:`mjcf_with_inertials` writes the identified
bodies and joint terms into the user's own MJCF file, everything else kept (the robot was read from it).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from xml.etree import ElementTree

import numpy as np
from numpy.typing import ArrayLike, NDArray

from dynamics.mjcf import mjcf_layout
from dynamics.physical_parameters import consistency_margin
from dynamics.robot import N_LINK_PARAMETERS, JointType, RobotModel

__all__ = ["JOINT_ATTRIBUTES", "MjcfBodyError", "mjcf_with_inertials", "robot_mjcf"]


class MjcfBodyError(ValueError):
    """The identified links cannot be written into the user's MJCF bodies (a link without a body of its own, or
    one whose fixed bodies weigh more than it): :func:`robot_mjcf` writes the chain instead."""

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


def _check_terms(robot: RobotModel, terms: Mapping[str, Mapping[str, float]]) -> None:
    unknown = [name for name in terms if name not in robot.joint_names]
    if unknown:
        raise ValueError(f"joint terms for joint(s) {', '.join(unknown)} that {robot.name} lacks")
    for joint, values in terms.items():
        for key in values:
            if key not in JOINT_ATTRIBUTES:
                raise ValueError(f"joint {joint}: unknown MuJoCo joint attribute {key!r} (known: "
                                 f"{', '.join(JOINT_ATTRIBUTES)})")


def _comment(lines: Sequence[str]) -> ElementTree.Element:
    return ElementTree.Comment(_comment_text("\n  " + "\n  ".join(lines) + "\n"))


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
    _check_terms(robot, terms)
    root = ElementTree.Element("mujoco", model=robot.name)
    lines = [header] if header else []
    if notes:
        lines += ["Not expressed in MuJoCo (kept out of this file):"] + [f"  - {note}" for note in notes]
    if lines:
        root.append(_comment(lines))
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
            attributes[key] = _number(value)
        ElementTree.SubElement(body, "joint", attributes)
        parent = body
    ElementTree.indent(root)
    return ElementTree.tostring(root, encoding="unicode") + "\n"


#: MuJoCo's compiler attributes naming the folders of asset files (``meshdir`` and ``texturedir`` default to
#: ``assetdir``, which defaults to the model file's folder)
_ASSET_FOLDERS = ("meshdir", "texturedir")


def _absolute_assets(root: ElementTree.Element, folder: Path) -> str | None:
    """Point the compiler's asset folders at ``folder`` (the user's model's), so that the file written elsewhere
    finds the meshes and textures; the sentence that says so, or ``None`` when the model names no asset file."""
    if not any(element.get("file") for element in root.iter() if element.tag != "include"):
        return None
    compilers = root.findall("compiler") or [ElementTree.Element("compiler")]
    if compilers[0] not in list(root):
        root.insert(0, compilers[0])
    given = {key: value for element in compilers for key, value in element.attrib.items()}
    base = given.get("assetdir", "")
    for key in _ASSET_FOLDERS:
        value = given.get(key, base)
        absolute = str(folder / value) if not Path(value).is_absolute() else value
        for element in compilers:
            element.attrib.pop(key, None)
        compilers[-1].set(key, absolute)
    compilers[-1].attrib.pop("assetdir", None)
    for element in compilers[:-1]:
        element.attrib.pop("assetdir", None)
    return f"asset files (meshes, textures) are read from {folder} (the folder of the model identified)"


def mjcf_with_inertials(path: str | Path, robot: RobotModel, links: ArrayLike,
                        joint_terms: Mapping[str, Mapping[str, float]] | None = None, *,
                        joint_names: Sequence[str] | None = None, locked_at: Mapping[str, float] | None = None,
                        assets: str | Path | None = None, notes: Sequence[str] = (),
                        header: str = "") -> tuple[str, tuple[str, ...]]:
    """The user's MJCF file ``path`` with the identified bodies and joint terms of ``robot`` (the chain
    :func:`dynamics.mjcf.robot_from_mjcf` read from it with ``joint_names`` and ``locked_at``) in place of its own,
    everything else kept: geoms, sites, actuators, sensors, contacts, the locked joints and their bodies.

    Link ``i``'s ``<inertial>`` goes to the ``<body>`` whose frame is the link's (the one holding joint ``i``), less
    the other bodies that move with it (fixed to it, or carried by a locked joint at its locked position), which
    keep theirs: MuJoCo's inverse dynamics of the file, its locked joints at their positions and still, is then
    the chain's with ``links``. The chain joints' ``armature``, ``damping``, ``frictionloss``, ``stiffness`` and
    ``springref`` are set to ``joint_terms`` (0 where a term is not given: the model holds none), and the file's
    ``<option gravity>`` to ``robot.gravity``. ``assets``: the folder of the user's model, where its asset files
    (meshes) are found (the compiler's ``meshdir`` and ``texturedir`` are made absolute). Comments of the file are
    not kept.

    Returns
    -------
    text, changes
        The MJCF text (``notes`` and ``header`` in a first comment) and one sentence per value of the file the
        model replaced by zero (a term of the file the model does not hold) or per asset folder moved.

    Raises
    ------
    MjcfBodyError
        A link without a ``<body>`` of its own holding mass, or whose other bodies leave no rigid body for its own
        (the identified link lighter than the bodies fixed to it).
    """
    links = np.asarray(links, dtype=float)
    if links.shape != (robot.n_joints, N_LINK_PARAMETERS):
        raise ValueError(f"expected {robot.n_joints} x {N_LINK_PARAMETERS} link parameters, got shape {links.shape}")
    terms = {name: dict(values) for name, values in dict(joint_terms or {}).items()}
    _check_terms(robot, terms)
    layout = mjcf_layout(path, joint_names=joint_names, locked_at=locked_at)
    if list(layout.joints) != list(robot.joint_names):
        raise ValueError(f"the MJCF's chain ({', '.join(layout.joints)}) is not {robot.name}'s "
                         f"({', '.join(robot.joint_names)})")
    changes: list[str] = []
    for name, parameters in zip(robot.joint_names, links):
        body = layout.bodies[name]
        if body is None:
            if np.any(parameters):
                raise MjcfBodyError(f"joint {name!r} shares its <body> with a later joint of the chain: its link, "
                                    f"{parameters[0]:.4g} kg, has no body of its own in the file")
            continue
        own = parameters - layout.others[name]
        if not own[0] > 0 or consistency_margin(own) <= 0:
            raise MjcfBodyError(f"link {name!r} ({parameters[0]:.6g} kg identified) less the bodies that move with it "
                                f"in the file ({layout.others[name][0]:.6g} kg) is not a rigid body for "
                                f"<body name={body.get('name')!r}>")
        for element in body.findall("inertial"):
            body.remove(element)
        body.insert(0, _inertial(own))
    for name in robot.joint_names:
        element = layout.joints[name]
        for key in JOINT_ATTRIBUTES:
            value = terms.get(name, {}).get(key, 0.0)
            if value == 0 and layout.terms[name].get(key, 0.0) != 0:
                changes.append(f"joint {name}: {key} {layout.terms[name][key]:g} of the file set to 0 (the model "
                               "holds none)")
            if key == "springref" and value == 0 and element.get(key) is None:
                continue
            if key == "springref" and layout.degrees and robot.joints[robot.joint_names.index(name)].joint_type \
                    is JointType.REVOLUTE:
                value = np.rad2deg(value)  # the file's angle unit
            element.set(key, _number(value))
    options = layout.root.findall("option") or [ElementTree.Element("option")]
    if options[0] not in list(layout.root):
        layout.root.insert(0, options[0])
    for element in options:
        element.set("gravity", _numbers(robot.gravity))
    if assets is not None:
        moved = _absolute_assets(layout.root, Path(assets))
        changes.extend([] if moved is None else [moved])
    lines = [header] if header else []
    if notes:
        lines += ["Not expressed in MuJoCo (kept out of this file):"] + [f"  - {note}" for note in notes]
    if changes:
        lines += ["Changed from the file identified:"] + [f"  - {change}" for change in changes]
    if lines:
        layout.root.insert(0, _comment(lines))
    ElementTree.indent(layout.root)
    return ElementTree.tostring(layout.root, encoding="unicode") + "\n", tuple(changes)
