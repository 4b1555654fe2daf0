"""``oed predict`` as a library call: an identified model (result.json or report.json) applied to another record.

:func:`predict` returns a :class:`PredictRun`: ``to_dict()`` is the metrics JSON (``--metrics``), ``write(out=...,
metrics=..., plot=...)`` writes the predictions CSV, the metrics and the figure, ``summary()`` the lines ``oed predict`` prints.
"""

from __future__ import annotations

import copy
import tempfile
import warnings
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import pandas as pd

from dynamics.runtime.output_files import OutputFiles, check_figure_path, json_text
from estimation.identification.identified_model import IdentifiedModel
from estimation.identification.training_range import UNKNOWN_RANGE
from estimation.identification.trivial_predictors import trivial_warnings
from estimation.data.input_findings import grouped_messages
from estimation.data.compressed_logs import data_suffix
from estimation.data.log_formats import DEFAULT_TOPIC
from estimation.data.motor_side import joint_side_copies
from estimation.data.memory_budget import count_rows, default_budget, estimate_in_memory, parse_memory_size
from estimation.estimators.normal_equations import DEFAULT_CHUNK_SIZE, check_chunk_size
from estimation.streaming.chunks import StreamingUnsupportedError, source_files
from estimation.streaming.prediction import check_streamable, needs_joint_side, streamed_evaluation
from oed.workflows.options import log_sources, paths

__all__ = ["PREDICT_BYTES_PER_VALUE", "PredictRun", "StreamedPredictRun", "predict", "streamed_predict",
           "streaming_decided"]


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


#: bytes a sample, channel and base parameter the in-memory prediction holds (its band's regressor and the product
#: with the covariance, as identify's estimate: :data:`oed.workflows.identify.IN_MEMORY`)
PREDICT_BYTES_PER_VALUE = 2 * 8


#: what the streamed ``oed predict`` says of the per-sample outputs
PER_SAMPLE_REFUSED = ("--out and --plot write every sample's prediction (the result's columns() and plot()): not kept "
                      "on the streamed path (--chunk-size, or a record past the memory budget); leave out --chunk-size "
                      "to predict the record in memory (in Python: predict(..., per_sample=True) without chunk_size)")


@dataclass(frozen=True)
class StreamedPredictRun(PredictRun):
    """What the streamed ``oed predict`` computed (:func:`estimation.streaming.prediction.streamed_evaluation`):
    the errors, the yardsticks, the training range, the record's noise floor and the record-change check, memory's;
    not the per-sample predictions (``not_computed``; the metrics JSON holds the in-memory keys)."""

    def columns(self) -> dict[str, Any]:
        raise ValueError(PER_SAMPLE_REFUSED)

    def plot(self, path: str | Path | None = None) -> Any:
        raise ValueError(PER_SAMPLE_REFUSED)

    def write(self, *, out: str | Path | None = None, metrics: str | Path | None = None,
              plot: str | Path | None = None) -> None:
        """The metrics JSON at ``metrics``; ``out`` and ``plot`` (every sample) are refused."""
        if out is not None or plot is not None:
            raise ValueError(PER_SAMPLE_REFUSED)
        if metrics is not None:
            with OutputFiles() as outputs, outputs.open(metrics) as stream:
                stream.write(json_text(self.to_dict()))


def predict(*, model: str | Path, data: Any, consistent: bool = False, alternative: str | None = None,
            topic: str = DEFAULT_TOPIC, columns: dict[str, str] | None = None, chunk_size: int | None = None,
            memory_budget: str | None = None, per_sample: bool = False,
            say: Callable[[str], None] | None = None) -> PredictRun:
    """``oed predict``: the model of ``model`` (a result.json or report.json) on the record ``data`` (a path or
    the list of its segments; a ROS bag read on ``topic``, an ``.npz`` or ``.mat`` file, any with the column map
    ``columns``): the model the verb chose, or the ``alternative`` the file holds beside it (``ols``, ``wls``,
    ``consistent``; ``unconstrained``: the unconstrained fit behind the choice); ``consistent``: the same as
    ``alternative="consistent"`` (the physically consistent estimate, what ``oed export`` writes).

    ``chunk_size``: the record read and predicted in chunks of that many rows
    (:func:`estimation.streaming.prediction.streamed_evaluation`: the errors, the yardsticks, the training range,
    the noise floor and the record-change check, memory's; not the per-sample predictions). Without it, a record of .csv or .parquet files whose in-memory
    prediction would pass ``memory_budget`` (default 1 GB, as identify's) is streamed too, said in one line
    (``say``), unless ``per_sample`` (the predictions CSV or the figure asked for)."""
    if consistent and alternative not in (None, "consistent"):
        raise ValueError(f"--consistent is --alternative consistent: not with --alternative {alternative}")
    identified = IdentifiedModel.load(Path(model), estimate="consistent" if consistent else alternative)
    if chunk_size is not None:
        check_chunk_size(chunk_size, identified.model)
        if per_sample:
            raise ValueError(PER_SAMPLE_REFUSED)
        return streamed_predict(identified, paths(data), chunk_size)
    streamed = streaming_decided(identified, data, memory_budget, per_sample)
    if streamed is not None:
        if say is not None:
            say(streamed)
        return streamed_predict(identified, paths(data), DEFAULT_CHUNK_SIZE)
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


def streaming_decided(identified: IdentifiedModel, data: Any, memory_budget: str | None,
                      per_sample: bool) -> str | None:
    """The line that says the record is streamed (its in-memory prediction past the budget, every file a .csv or
    .parquet one, the model file's reading one the streamed reader makes, no per-sample output asked for), else
    ``None``: in memory, as before."""
    budget = default_budget() if memory_budget is None else parse_memory_size(memory_budget)
    files = paths(data)
    if per_sample or not all(isinstance(path, (str, Path)) and Path(path).is_file()
                             and data_suffix(path) in (".csv", ".parquet") for path in files):
        return None
    try:
        rows = [count_rows(path) for path in files]
    except (OSError, ValueError, ImportError):  # the reader names the fault
        return None
    need = estimate_in_memory(rows, identified.model, bytes_per_value=PREDICT_BYTES_PER_VALUE, budget=budget)
    if not need.stream:
        return None
    try:
        check_streamable(identified)
    except StreamingUnsupportedError:
        return None
    return need.describe("predicting") + " (--memory-budget to change it, --chunk-size to set the chunks)"


def streamed_predict(identified: IdentifiedModel, files: list, chunk_size: int) -> StreamedPredictRun:
    """The streamed ``oed predict`` (:func:`estimation.streaming.prediction.streamed_evaluation`) and its lines."""
    check_streamable(identified)  # before any copy is made
    with warnings.catch_warnings(record=True) as caught, tempfile.TemporaryDirectory(prefix="oed-predict-") as folder:
        warnings.simplefilter("always")
        read = files
        if needs_joint_side(identified):  # motor-side columns, joint zeros, directions: joint-side copies, streamed
            file = identified.file
            read = joint_side_copies(files, folder, n_joints=identified.robot.n_joints,
                                     transmission=identified.transmission, joint_offsets=file.joint_offsets,
                                     joint_directions=file.joint_directions, chunk_size=chunk_size,
                                     model=identified.model)
        evaluation = streamed_evaluation(identified, read, chunk_size=chunk_size)
    notes = trivial_warnings(evaluation.mse, {"zero_mse": evaluation.zero_mse, "nominal_mse": evaluation.nominal_mse},
                             label="model", record="this record")
    messages = tuple(dict.fromkeys(grouped_messages(caught, source_files(files)) + list(notes)))
    lines = [f"{identified.robot.name}: {identified.file.model} model ({identified.file.effects}, {identified.estimate}"
             + ("" if identified.estimate == (identified.file.chosen or "unconstrained") else ": an alternative")
             + (f", delay {1e3 * identified.delay:.3g} ms" if identified.delay is not None else "")
             + ("" if identified.subtracted_words is None else f", {identified.subtracted_words}")
             + f"), {evaluation.n_samples} samples read in chunks of {chunk_size} rows; "
             f"{identified.preprocessing.describe(applied=True).removeprefix('preprocessing: ')}",
             *mse_table(evaluation.mse, [("model", evaluation.mse), ("zero", evaluation.zero_mse),
                                         ("nominal", evaluation.nominal_mse)]
                        + ([] if evaluation.floor_mse is None else [("noise floor", evaluation.floor_mse)])),
             range_line(evaluation)]
    if evaluation.changes is not None:  # a load or a mount changed since the training (the prediction unchanged)
        lines.append(evaluation.changes.line())
    lines.append("not computed on the streamed path: " + ", ".join(evaluation.not_computed))
    return StreamedPredictRun(evaluation, tuple(lines), messages)


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
    return mse_table(mse, rows)


def mse_table(mse: dict[str, float], rows: list[tuple[str, dict[str, float]]]) -> list[str]:
    """The table of :func:`table_lines`: a header of ``mse``'s channels, a line per ``(label, values)``."""
    return ["MSE vs recorded   " + "  ".join(f"{channel:>10s}" for channel in mse),
            *(f"  {label:<16s}" + "  ".join(f"{values[channel]:10.4g}" for channel in mse) for label, values in rows)]
