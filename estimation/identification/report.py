"""The report of an identification (``oed identify --report``): one document (:mod:`dynamics.runtime.report_document`)
with the choices made, every warning, the parameters with their standard deviations, the errors against the
channels as recorded beside the noise floor, and measured against predicted per channel on the validation (else
the training) record."""

from __future__ import annotations

import functools
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from dynamics.runtime.report_document import Block, Bullets, Figure, Heading, Paragraph, Report, Table
from estimation.identification.fit import IdentificationResult
from estimation.identification.validation import plot_channel, subsample_step

__all__ = ["identification_report", "parameter_table"]


def parameter_table(result: IdentificationResult, records: Sequence[dict[str, Any]] | None = None,
                    shape_std: Mapping[str, float | None] | None = None) -> Table:
    """The base parameters (and shape parameters) with their standard deviations: ``records`` (those of the
    model the result chose: ``name, expression, value, std, relative_std``), by default ``result``'s;
    ``shape_std``: the chosen model's standard deviations of the shapes (``None`` each: held, not estimated, by
    the consistent fit), by default ``result``'s."""
    records = result.estimate.records() if records is None else records
    rows = tuple((record["name"], str(record.get("expression", "")), f"{record['value']:.5g}",
                  "n/a" if record["std"] is None else f"{record['std']:.2g}",
                  f"{record['relative_std']:.2g} %" if np.isfinite(_number(record.get("relative_std"))) else "n/a")
                 for record in records)
    stds = {value.name: value.std for value in result.shapes} if shape_std is None else shape_std
    shapes = tuple((value.name, f"shape of {value.effect}", f"{value.value:.5g}",
                    "n/a (held)" if stds.get(value.name) is None else f"{stds[value.name]:.2g}", "")
                   for value in result.shapes)
    return Table(("parameter", "expression", "value", "std", "relative std"), rows + shapes)


def _error(errors: Any, channel: str) -> str:
    """A channel's MSE against the recording, else against the filtered channels (marked), else ``n/a``."""
    if errors is None:
        return "n/a"
    if errors.mse is not None:
        return f"{errors.mse[channel]:.4g}"
    return "n/a" if errors.mse_filtered is None else f"{errors.mse_filtered[channel]:.4g} (filtered)"


def _number(value: Any) -> float:
    return np.nan if value is None else float(value)


def identification_report(result: IdentificationResult, document: dict[str, Any], *, preprocessing: str = "",
                          warnings: Sequence[str] = (), title: str = "", chosen: Any = None) -> Report:
    """The report of ``result`` (``document``: its ``result.json``, for the choices and the floor); ``chosen``:
    the model the result holds when it is not ``result`` itself (the consistent refit: its ``name``, ``train``,
    ``validation`` comparisons and ``records()``), whose parameters and errors the report gives."""
    estimate = result.estimate
    answer = result if chosen is None else chosen
    blocks: list[Block] = [
        Paragraph(f"Effects: {', '.join(f'`{e.name}`' for e in result.model.effects) or 'none'}; "
                  f"{result.train.n_samples} training samples. Errors are mean squared errors against the channels as recorded, at the recorded time "
                  "stamps" + ("" if result.path == "in-memory" else "; read in blocks and summed (the streamed path): "
                              "marked *filtered* where the sums hold the filtered or averaged channels only") + "."),
        Heading("Warnings"), Bullets(tuple(warnings)) if warnings else Paragraph("None.")]
    choices = [preprocessing] if preprocessing else []
    selection = document.get("method_selection")
    choices.append(f"estimator: {estimate.method}" + (" (chosen on held-out blocks of the training record)"
                                                       if selection else "") + f"; standard deviations: "
                   f"{estimate.cov_method}; condition number {float(estimate.cond):.3g}")
    if chosen is not None and chosen.name != estimate.method:
        reason = (document.get("model_selection") or {}).get("reason")
        choices.append(f"model: {chosen.name} (refitted from {estimate.method}; standard deviations: "
                       f"{chosen.cov_method})" + (f"; {reason}" if reason else ""))
    blocks += [Heading("Choices made"), Bullets(tuple(choices)),
               Heading("Parameters"), parameter_table(result, None if chosen is None else chosen.records(),
                                                      None if chosen is None else chosen.shape_std)]
    rows = []
    floor = (document.get("noise_floor") or {}).get("mse") or {}
    over = (document.get("validation") or {}).get("mse_over_floor") or {}
    for channel in result.model.channels:
        rows.append((channel, _error(answer.train, channel), _error(answer.validation, channel),
                     f"{floor[channel]:.4g}" if channel in floor else "n/a",
                     f"{over[channel]:.3g}" if channel in over else "n/a"))
    blocks += [Heading("Error per channel"),
               Table(("channel", "training MSE", "validation MSE", "noise floor", "validation / floor"), tuple(rows))]
    missing = document.get("not_computed") or {}
    if missing:
        blocks += [Heading("Not computed on this path"), Bullets(tuple(f"{key}: {why}" for key, why in missing.items()))]
    comparison, label = (answer.validation, "validation") if answer.validation is not None else (answer.train,
                                                                                                   "training")
    if not hasattr(comparison, "t"):  # streamed: errors from sums, no samples held
        blocks += [Heading(f"Measured against predicted ({label} record)"),
                   Paragraph("No figure: the streamed path holds no samples (its errors come from sums).")]
        return Report(title or f"Identification: {result.model.robot.name}, {result.model.kind.value} model",
                      tuple(blocks))
    n = comparison.t.shape[0]
    step = subsample_step(n)
    drawn = f"every {step}th of {n} samples" if step > 1 else f"all {n} samples"
    blocks += [Heading(f"Measured against predicted ({label} record)"),
               Paragraph(f"Channels as recorded, at the recorded time stamps ({drawn} drawn), and the model's "
                         "prediction; below, the residual.")]
    blocks += [Figure(f"{label}.{channel}", f"{channel} on the {label} record: measured, predicted, residual",
                      functools.partial(plot_channel, {"predicted": comparison}, row, step, f"{channel}, {label} record"))
               for row, channel in enumerate(comparison.channels)]
    return Report(title or f"Identification: {result.model.robot.name}, {result.model.kind.value} model", tuple(blocks))
