"""``oed predict`` as a library call: an identified model (result.json or report.json) applied to another record.

:func:`predict` returns a :class:`PredictRun`: ``to_dict()`` is the metrics JSON (``--metrics``), ``write(out=...,
metrics=..., plot=...)`` writes the predictions CSV, the metrics and the figure, ``summary()`` the lines ``oed predict`` prints.
"""

from __future__ import annotations

import copy
import warnings
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import pandas as pd

from dynamics.runtime.output_files import OutputFiles, check_figure_path, json_text
from estimation.identification.identified_model import IdentifiedModel
from estimation.identification.training_range import UNKNOWN_RANGE
from estimation.identification.trivial_predictors import trivial_warnings
from estimation.data.input_findings import grouped_messages
from estimation.data.log_formats import DEFAULT_TOPIC
from oed.workflows.options import log_sources, paths

__all__ = ["PredictRun", "predict"]


@dataclass(frozen=True)
class PredictRun:
    """What ``oed predict`` computed: the evaluation
    (:meth:`estimation.identification.identified_model.IdentifiedModel.evaluate`), the lines it prints and the
    warnings."""

    evaluation: Any = field(repr=False)
    lines: tuple[str, ...]
    warnings: tuple[str, ...]

    def to_dict(self) -> dict[str, Any]:
        """The metrics JSON (``--metrics``)."""
        return copy.deepcopy(self.evaluation.to_dict())

    def summary(self) -> list[str]:
        """The model, the record and the MSE per channel beside the yardsticks."""
        return list(self.lines)

    def columns(self) -> dict[str, Any]:
        """The predictions CSV's columns: t, each channel, and its _lo/_hi 95 % band, then each channel's
        _measured (as recorded) and _residual (measured minus predicted)."""
        return self.evaluation.prediction.columns()

    def plot(self, path: str | Path | None = None) -> Any:
        """Measured against predicted per channel, with the band and the residual (a matplotlib figure, saved at
        ``path`` when given)."""
        return self.evaluation.prediction.plot(path, title=self.lines[0].split(";")[0])

    def write(self, *, out: str | Path | None = None, metrics: str | Path | None = None,
              plot: str | Path | None = None) -> None:
        """The predictions CSV at ``out``, the metrics JSON at ``metrics`` and the figure at ``plot`` (each may be
        left out): all or none."""
        check_figure_path(plot)
        with OutputFiles() as outputs:  # all files or none
            if plot is not None:
                self.plot(outputs.stage_figure(plot))
            if out is not None:
                with outputs.open(out) as stream:
                    pd.DataFrame(self.columns()).to_csv(stream, index=False)
            if metrics is not None:
                with outputs.open(metrics) as stream:
                    stream.write(json_text(self.evaluation.to_dict()))


def predict(*, model: str | Path, data: Any, consistent: bool = False, alternative: str | None = None,
            topic: str = DEFAULT_TOPIC, columns: dict[str, str] | None = None) -> PredictRun:
    """``oed predict``: the model of ``model`` (a result.json or report.json) on the record ``data`` (a path or
    the list of its segments; a ROS bag read on ``topic``, an ``.npz`` or ``.mat`` file, any with the column map
    ``columns``): the model the verb chose, or the ``alternative`` the file holds beside it (``ols``, ``wls``,
    ``consistent``; ``unconstrained``: the unconstrained fit behind the choice); ``consistent``: the same as
    ``alternative="consistent"`` (the physically consistent estimate, what ``oed export`` writes)."""
    if consistent and alternative not in (None, "consistent"):
        raise ValueError(f"--consistent is --alternative consistent: not with --alternative {alternative}")
    identified = IdentifiedModel.load(Path(model), estimate="consistent" if consistent else alternative)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        evaluation = identified.evaluate(list(log_sources(paths(data), topic, columns)))
    prediction = evaluation.prediction
    notes = trivial_warnings(prediction.mse, {"zero_mse": evaluation.zero_mse, "nominal_mse": evaluation.nominal_mse},
                             label="model", record="this record")
    messages = tuple(dict.fromkeys(grouped_messages(caught, paths(data)) + list(notes)))  # a line per finding
    lines = [f"{identified.robot.name}: {identified.file.model} model ({identified.file.effects}, {identified.estimate}"
             + ("" if identified.estimate == (identified.file.chosen or "unconstrained") else ": an alternative")
             + (f", delay {1e3 * identified.delay:.3g} ms" if identified.delay is not None else "")
             + ("" if identified.fitted_gravity is None else f", {identified.fitted_gravity}")
             + ("" if identified.subtracted_words is None else f", {identified.subtracted_words}")
             + f"), {prediction.t.shape[0]} samples; "
             f"{identified.preprocessing.describe(applied=True).removeprefix('preprocessing: ')}",
             *table_lines(evaluation), range_line(evaluation)]
    if evaluation.changes is not None:  # a load or a mount changed since the training (the prediction unchanged)
        lines.append(evaluation.changes.line())
    return PredictRun(evaluation, tuple(lines), messages)


def range_line(evaluation: Any) -> str:
    """The record against each joint's training range (:mod:`estimation.identification.training_range`)."""
    check = evaluation.range_check
    if check is None:
        return f"training range: {UNKNOWN_RANGE}"
    if not check.outside:
        return "training range: the record stays within every joint's training positions and speeds"
    return "training range: outside on " + "; ".join(joint.statement() for joint in check.outside)


def table_lines(evaluation: Any) -> list[str]:
    """MSE per channel against the record as recorded, beside the yardsticks."""
    mse = evaluation.prediction.mse
    rows = [("model", mse), ("zero", evaluation.zero_mse), ("nominal", evaluation.nominal_mse)]
    if evaluation.floor_mse is not None:
        rows.append(("noise floor", evaluation.floor_mse))
    return ["MSE vs recorded   " + "  ".join(f"{channel:>10s}" for channel in mse),
            *(f"  {label:<16s}" + "  ".join(f"{values[channel]:10.4g}" for channel in mse) for label, values in rows)]
