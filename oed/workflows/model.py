"""``oed model`` as a library call: the base parameters of the internal, external and combined models of a robot.

:func:`model` returns a :class:`ModelRun`: ``to_dict()`` is what ``oed model --json`` prints, ``summary()`` the
table ``oed model`` prints, ``write(path)`` the JSON to a file.
"""

from __future__ import annotations

import copy
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from dynamics.models import ModelKind, build_model
from dynamics.runtime.output_files import OutputFiles, json_text
from oed.workflows.options import RobotOptions, robot_of

__all__ = ["ModelRun", "model"]


@dataclass(frozen=True)
class ModelRun:
    """The base parameters of each model (``document``: per model ``n_base``, ``channels``, ``parameters``
    ``[{name, expression}]``, ``unidentifiable``) and the header line."""

    document: dict[str, dict] = field(repr=False)
    header: str

    def to_dict(self) -> dict[str, dict]:
        """What ``oed model --json`` prints."""
        return copy.deepcopy(self.document)

    def summary(self) -> list[str]:
        """The table ``oed model`` prints."""
        lines = [self.header]
        for kind, entry in self.document.items():
            lines.append(f"\n{kind} model: {entry['n_base']} base parameters (rows: {' '.join(entry['channels'])})")
            width = max(len(parameter["name"]) for parameter in entry["parameters"])
            lines += [f"  {index:3d}  {parameter['name']:<{width}}  = {parameter['expression']}"
                      for index, parameter in enumerate(entry["parameters"], start=1)]
        return lines

    def write(self, path: str | Path) -> None:
        """The JSON at ``path``."""
        with OutputFiles() as outputs, outputs.open(path) as stream:
            stream.write(json_text(self.document))


def model(*, friction: str = "viscous", **robot: Any) -> ModelRun:
    """``oed model``: the base parameters of the robot (``robot``, ``urdf``, ``joints``) with the effects
    ``friction``."""
    described = robot_of(RobotOptions(**robot))
    document = {}
    for kind in ModelKind:
        built = build_model(described, kind, friction)
        document[kind.value] = {
            "n_base": built.n_base,
            "channels": list(built.channels),
            "parameters": [{"name": name, "expression": expression}
                           for name, expression in zip(built.base.names, built.base.expressions)],
            "unidentifiable": list(built.base.unidentifiable),
        }
    header = f"{described.name}: {described.n_joints} joints ({', '.join(described.joint_names)}), effects: {friction}"
    return ModelRun(document, header)
