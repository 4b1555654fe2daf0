"""``oed payload`` as a library call: the mass, centre of mass and inertia of a payload from records made with it,
the robot's identified model held fixed (:func:`estimation.payload.identify_payload`).

:func:`payload` returns a :class:`PayloadRun`: ``to_dict()`` is ``payload.json`` (the payload and the model file with
it, so that ``oed predict --model payload.json`` includes it), ``write(out)`` writes it, ``summary()`` the lines
``oed payload`` prints.
"""

from __future__ import annotations

import copy
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from dynamics.runtime.output_files import OutputFiles, json_text
from estimation.identification.identified_model import IdentifiedModel
from estimation.payload import identify_payload
from oed.workflows.options import paths

__all__ = ["PayloadRun", "payload"]


@dataclass(frozen=True)
class PayloadRun:
    """What ``oed payload`` computed: ``payload.json``, the lines it prints and the
    :class:`~estimation.payload.PayloadResult` behind them."""

    document: dict[str, Any] = field(repr=False)
    lines: tuple[str, ...]
    result: Any = field(repr=False)
    warnings: tuple[str, ...] = ()

    def to_dict(self) -> dict[str, Any]:
        """``payload.json``."""
        return copy.deepcopy(self.document)

    def summary(self) -> list[str]:
        """The payload with its standard deviations and the validation error before and after."""
        return list(self.lines)

    def write(self, out: str | Path) -> None:
        """``payload.json`` at ``out``."""
        with OutputFiles() as outputs, outputs.open(out) as stream:
            stream.write(json_text(self.document))


def payload(*, model: str | Path, data: Any, validate: Any = None, link: str | None = None,
            mass: float | None = None) -> PayloadRun:
    """``oed payload``: the 10 inertial parameters of a rigid payload fixed to ``link`` (default the last) from the
    records ``data`` made with it (a path or a list), the robot's model of ``model`` (a result.json or report.json)
    held fixed; ``validate``: held-out records with the payload; ``mass``: its known (weighed) mass, kg."""
    identified = IdentifiedModel.load(Path(model))
    validation = paths(validate) or None
    result = identify_payload(identified, list(paths(data)), validate=None if validation is None else list(validation),
                              link=link, mass=mass)
    lines = [result.summary()]
    if result.validation_before is not None:
        lines.append("validation MSE    " + "  ".join(f"{channel:>10s}" for channel in result.validation_before))
        for label, values in (("robot model", result.validation_before), ("with payload", result.validation_after)):
            lines.append(f"  {label:<16s}" + "  ".join(f"{values[channel]:10.4g}" for channel in values))
    return PayloadRun(result.document(identified), tuple(lines), result)
