"""Where the rival of a discriminating design comes from: a model file (``oed design --discriminate --rival FILE``),
or the runner-up a diagnosis kept in its report (``oed design --from report.json --discriminate``: the key
``runner_up.model_file``, :mod:`estimation.diagnosis.runner_up`).

::

    model = IdentifiedModel.load("report.json")
    rival = runner_up_model("report.json")          # the best rival model the diagnosis did not choose
    design_discriminating(model, rival, records, bounds=PUMA_BOUNDS)
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

from estimation.identification.identified_model import IdentifiedModel
from estimation.identification.model_file import ModelFile, ModelFileError, read_model_file
from oed.sequential.discrimination import check_rivals
from oed.sequential.jacobian import SequentialDesignError

__all__ = ["NoRunnerUpError", "Rival", "load_rival", "runner_up_file", "runner_up_model"]


class NoRunnerUpError(SequentialDesignError):
    """A file that holds no runner-up to discriminate against."""


def runner_up_file(path: str | Path) -> ModelFile:
    """The runner-up's model file in a ``report.json`` of ``oed diagnose``; :class:`NoRunnerUpError` (with the
    diagnosis's reason when it kept none) or :class:`ModelFileError` otherwise."""
    path = Path(path)
    read_model_file(path)  # the file, its JSON and its own model checked as --from reads them
    document = json.loads(path.read_text())
    advice = "give the rival model with --rival FILE"
    if "runner_up" not in document:
        raise NoRunnerUpError(f"{path} holds no runner-up (the key runner_up of a report.json written by `oed diagnose` "
                              f"from this release on; a result.json of `oed identify` has none): {advice}")
    entry = document["runner_up"]
    if entry is None:
        reason = document.get("runner_up_reason") or "no reason given"
        raise NoRunnerUpError(f"{path} holds no runner-up: the diagnosis kept none ({reason}); {advice}")
    if not isinstance(entry, dict) or not isinstance(entry.get("model_file"), dict):
        raise NoRunnerUpError(f"{path}: its runner_up holds no model_file; {advice}")
    try:
        return ModelFile.from_dict(entry["model_file"])
    except ModelFileError as error:
        raise ModelFileError(f"{path}, runner_up: {error}") from None


def runner_up_model(path: str | Path) -> IdentifiedModel:
    """The runner-up of a ``report.json`` as an identified model (:func:`runner_up_file`)."""
    return IdentifiedModel(runner_up_file(path))


@dataclass(frozen=True)
class Rival:
    """The rival model and where it was read: ``file`` and the key of its model file (``model_file`` of a
    ``--rival`` file, ``runner_up.model_file`` of the ``--from`` report)."""

    model: IdentifiedModel
    file: str
    key: str

    def to_dict(self) -> dict[str, str]:
        return {"file": self.file, "key": self.key}


def load_rival(model: IdentifiedModel, from_path: str | Path, rival_path: str | Path | None = None) -> Rival:
    """The rival of ``model`` (read from ``from_path``): the model file ``rival_path`` when given, else the
    runner-up of the ``from_path`` report; refused when it is the same model, or one of another robot or
    channels (:func:`oed.sequential.discrimination.check_rivals`)."""
    if rival_path is not None:
        rival = Rival(IdentifiedModel.load(rival_path), str(rival_path), "model_file")
    else:
        rival = Rival(runner_up_model(from_path), str(from_path), "runner_up.model_file")
    check_rivals(model, rival.model)
    return rival
