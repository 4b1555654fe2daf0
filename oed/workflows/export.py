"""``oed export`` as a library call: a physically consistent identified model as a URDF and/or MuJoCo's MJCF (and
its friction as JSON) for other tools.

:func:`export` returns an :class:`ExportRun`: ``write(urdf, mjcf=..., friction=...)`` writes the URDF, the MJCF and
the friction JSON (``to_dict()``), ``summary()`` the lines ``oed export`` prints. A body that is not plausible is refused unless
``allow_implausible``.
"""

from __future__ import annotations

import json
import xml.etree.ElementTree as ElementTree
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from dynamics.runtime.output_files import OutputFiles, json_text
from estimation.identification.export import (
    MjcfExport,
    exported_mjcf,
    exported_model,
    exported_urdf,
    urdf_dynamics_joints,
    friction_document,
    gravity_note,
    implausible_links,
)
from oed.workflows.consistent import prior_source_scale
from oed.workflows.options import check_json_path, check_mjcf_path, check_urdf_path

__all__ = ["ExportRun", "check_outputs", "export"]


@dataclass(frozen=True)
class ExportRun:
    """What ``oed export`` computed: the URDF text, the MJCF (its text and what MuJoCo cannot express), the model
    it came from and the bodies found implausible."""

    urdf: str = field(repr=False)
    model: Any = field(repr=False)
    findings: tuple[str, ...]
    lines: tuple[str, ...]
    mjcf: MjcfExport | None = field(default=None, repr=False)
    note: str | None = None
    #: the model was fitted with another gravity than its description's: the mount to write into the URDF
    #: (:func:`estimation.identification.export.gravity_note`); ``None``: the description's gravity
    gravity: str | None = None

    @property
    def warnings(self) -> tuple[str, ...]:
        """The warnings ``oed export`` prints: the model written when it is not the chosen one (``note``), a gravity
        that is not the description's (``gravity``: the URDF holds none), and each implausible body exported as
        asked."""
        return (*(() if self.note is None else (self.note,)), *(() if self.gravity is None else (self.gravity,)),
                *(f"exported as asked (--allow-implausible), not plausible: {message}" for message in self.findings))

    def to_dict(self) -> dict[str, Any]:
        """The friction JSON (``--friction``): per joint viscous, coulomb, offset, armature…, other effects."""
        return friction_document(self.model)

    def summary(self) -> list[str]:
        """The bodies exported (their masses)."""
        return list(self.lines)

    def write(self, urdf: str | Path | None = None, *, mjcf: str | Path | None = None,
              friction: str | Path | None = None) -> None:
        """The URDF at ``urdf``, MuJoCo's MJCF at ``mjcf`` and the friction JSON at ``friction`` (each may be left
        out): all or none. A path named like another format is refused before anything is written
        (:class:`~oed.workflows.options.OutputPathError`, as ``oed export`` refuses it)."""
        check_outputs(urdf, mjcf=mjcf, friction=friction)
        if mjcf is not None and self.mjcf is None:
            raise ValueError("this export holds no MJCF: call export(..., mjcf=True)")
        document = self.to_dict() if friction is not None else None
        with OutputFiles() as outputs:  # all files or none
            if urdf is not None:
                with outputs.open(urdf) as stream:
                    stream.write(self.urdf)
            if mjcf is not None:
                with outputs.open(mjcf) as stream:
                    stream.write(self.mjcf.text)
            if document is not None:
                with outputs.open(friction) as stream:
                    stream.write(json_text(document))


def check_outputs(urdf: str | Path | None = None, *, mjcf: str | Path | None = None,
                  friction: str | Path | None = None) -> None:
    """Refuse outputs named like another format (:class:`~oed.workflows.options.OutputPathError`): a URDF not
    ``.urdf``, an MJCF not ``.xml``, a friction JSON named like another format (``.csv``, ``.md``…)."""
    check_urdf_path(urdf)
    check_mjcf_path(mjcf)
    if friction is not None:
        check_json_path(friction, "--friction")


def chosen_prior_weight(path: Path) -> str:
    """``"; this estimate was fitted at W"`` from a result's ``consistent.prior_weight``, or ``""`` when the file does not
    say (for the message refusing an implausible body: ``--prior-weight`` is an option of ``--consistent`` only)."""
    try:
        weight = json.loads(path.read_text(encoding="utf-8"))["consistent"]["prior_weight"]
    except (OSError, ValueError, KeyError, TypeError):
        return ""
    return f"; this estimate was fitted at {weight:g}" if isinstance(weight, (int, float)) else ""


def torques_scale(path: Path) -> float | None:
    """The scale at which the estimate's prior took the description's bodies, when it was the recorded torques'
    (a result's ``consistent.prior``, :func:`oed.workflows.consistent.scaled_prior_source`, written by ``oed
    identify`` and ``oed diagnose`` alike: a description in grams gives about 0.001); ``None`` otherwise, or when the
    file does not say."""
    try:
        return prior_source_scale(json.loads(path.read_text(encoding="utf-8"))["consistent"]["prior"])
    except (OSError, ValueError, KeyError, TypeError):
        return None


def prior_at_torques_scale(path: Path) -> str:
    """The sentence that the estimate's prior was the description's bodies at the recorded torques' scale (a
    result's ``consistent.prior``, :func:`oed.workflows.identify.torque_gains_selection`), for the message refusing
    an implausible body: the bodies were judged against the description's at that scale (:func:`torques_scale`);
    ``""`` when the file does not say so."""
    try:
        prior = json.loads(path.read_text(encoding="utf-8"))["consistent"]["prior"]
    except (OSError, ValueError, KeyError, TypeError):
        return ""
    if not isinstance(prior, str) or "torques' scale" not in prior:
        return ""
    return (f"\nits prior was the {prior}: the description's bodies are not in the log's units (masses in grams?); "
            "the bodies above were judged against the description's at that scale")


def scale_line(text: str, robot: Any, scale: float) -> str:
    """What ``oed export`` says when the description's bodies were read at the recorded torques' ``scale`` (a
    description in grams): the URDF ``text`` holds the identified bodies in the log's units, SI when its torques are
    N m (a URDF is SI by specification, ROS REP 103; were the torques in kN m or a motor's, the bodies are ``scale``
    times the robot's: said, as the scale alone does not tell the two apart), and the links it did not identify keep
    the description's ``<inertial>``, named."""
    root = ElementTree.fromstring(text)
    children = {joint.get("name"): joint.find("child").get("link") for joint in root.findall("joint")
                if joint.find("child") is not None}
    identified = {children.get(name) for name in robot.joint_names}
    kept = [str(link.get("name")) for link in root.findall("link")
            if link.find("inertial") is not None and link.get("name") not in identified]
    return (f"the description's bodies were read at the recorded torques' scale (x{scale:.4g}: the description's "
            "masses and inertias in other units, such as grams and g m^2, or the torques?): the URDF holds the "
            "identified bodies in the log's units, SI (kg, kg m^2) when the log's torques are N m, as URDF specifies, "
            "not in the description's units; were the torques in other units (kN m, a motor's before its gear), "
            f"these bodies would be {scale:.4g} times the robot's" + (
                "; the links not identified keep the description's <inertial> (" + ", ".join(kept) + "): mend their "
                "units" if kept else ""))


def export(*, model: str | Path, allow_implausible: bool = False, mjcf: bool = False,
           alternative: str | None = None) -> ExportRun:
    """``oed export``: the consistent estimate of ``model`` (a result.json of ``oed identify --consistent``) as the
    robot's URDF with every moving link's <inertial> replaced, and with ``mjcf`` as MuJoCo's MJCF (bodies, armature,
    damping, frictionloss, gravity; what MuJoCo cannot express listed in ``ExportRun.mjcf.notes`` and a comment). Raises ``ValueError`` when a body is not plausible
    (degenerate, a mass ten times the description's or a tenth of it, a centre of mass beyond twice the link's
    reach), unless ``allow_implausible``."""
    identified, note = exported_model(Path(model), alternative=alternative)  # refuses a model without bodies
    text = exported_urdf(identified)
    scale = torques_scale(Path(model))  # a description in grams: its bodies judged at the torques' scale
    findings = implausible_links(identified, scale=scale)
    if findings and not allow_implausible:
        raise ValueError("not exported: the consistent estimate holds bodies that are not plausible:\n  "
                         + "\n  ".join(findings) + "\nidentify again with `--consistent` and a larger --prior-weight "
                         f"(the weight toward the description's bodies where the data say little{chosen_prior_weight(Path(model))}) "
                         "or link bounds (--consistent --link-bounds FILE), or export them anyway with "
                         "--allow-implausible" + prior_at_torques_scale(Path(model)))
    masses = ", ".join(f"{link[0]:.4g}" for link in identified.file.consistent_links)
    line = f"{identified.robot.name}: {identified.robot.n_joints} bodies of the consistent estimate (masses {masses} kg)"
    mujoco = exported_mjcf(identified) if mjcf else None
    lines = (line, *(f"not expressed in MuJoCo (listed in the MJCF): {note}" for note in (mujoco.notes if mujoco else ())))
    if mujoco is not None and mujoco.source is not None:
        lines = (*lines, f"the MJCF is {mujoco.source} with these bodies and joint terms, everything else kept",
                 *(f"changed from that file (listed in the MJCF): {change}" for change in mujoco.changes))
    if scale is not None:  # the identified bodies are the log's units (SI): the URDF says SI whatever the description
        lines = (*lines, scale_line(text, identified.robot, scale))
    described = [name for name in urdf_dynamics_joints(text) if name in identified.robot.joint_names]
    if described:  # a simulator takes a URDF's <dynamics> for the joint's friction: the identified one written there
        lines = (*lines, "the joints' <dynamics damping friction> hold the identified viscous and Coulomb friction ("
                 + ", ".join(described) + "; 0 where the model holds no such law), not the description's")
    gains = (identified.file.torque_gains or {}).get("channels")
    if gains:  # a property of the log's sensors, not of the bodies: the URDF holds the description's units
        lines = (*lines, "the log's torques are these gains times the model's (torque_gains, not in the URDF): "
                 + ", ".join(f"{channel} {entry['value']:.4g}" for channel, entry in gains.items()))
    if identified.file.subtracted is not None:  # a property of the log, not of the bodies: the URDF holds the robot's
        lines = (*lines, f"the log's torques lack a load (subtracted, not in the URDF): "
                 f"{identified.file.subtracted.words()}; these bodies are the robot's, predict less that load to "
                 "compare with such a log")
    return ExportRun(text, identified, tuple(findings), lines, mujoco, note, gravity_note(identified))
