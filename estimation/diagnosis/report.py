"""The figures and the Markdown report of a :class:`~estimation.diagnosis.search.Diagnosis`."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from estimation.diagnosis.search import Diagnosis
from dynamics.measurements import Measurements
from dynamics.runtime.output_files import save_figure
from estimation.uncertainty.residual_tracing import plot_residual_trace

if TYPE_CHECKING:
    from matplotlib.figure import Figure


def plot_residuals(diagnosis: Diagnosis, train: Measurements, path: str | Path | None = None) -> Figure:
    """Training residuals of the declared model against q, dq, ddq of their joint, and time; saved to
    ``path`` when given."""
    from matplotlib.figure import Figure  # no pyplot; here, not at the top: a run without figures skips matplotlib

    estimate = diagnosis.before.estimate
    channels = estimate.channels
    figure = Figure(figsize=(14, 2.2 * len(channels)))
    axes = figure.subplots(len(channels), 4, squeeze=False)
    for row, channel in enumerate(channels):
        residual = estimate.residuals[:, row]
        joint = int(channel[3:]) - 1 if channel.startswith("tau") else 0
        for column, (label, values) in enumerate(
            (("q", train.q[:, joint]), ("dq", train.dq[:, joint]), ("ddq", train.ddq[:, joint]), ("t", train.t))
        ):
            axis = axes[row, column]
            axis.plot(values, residual, ".", markersize=1.5, alpha=0.4)
            axis.set_xlabel(f"{label}{joint + 1}" if label != "t" else "t [s]")
            if column == 0:
                axis.set_ylabel(f"residual {channel}")
    seen = ", the filtered or period-averaged channels the estimation saw" if train.recorded is not None else ""
    figure.suptitle(f"Residuals of the declared model (training data{seen})")
    figure.tight_layout()
    if path is not None:
        save_figure(figure, path, dpi=90)
    return figure


def markdown_report(diagnosis: Diagnosis, figure: str | None = None, trace_figure: str | None = None) -> str:
    """The report a person reads: effects found, rejected candidates, MSE before and after, the
    noise floor, what the residual follows and its whiteness (``trace_figure``: the figure of
    :func:`plot_trace`)."""
    document = diagnosis.to_dict()
    lines = [
        f"# Diagnosis: {document['robot']}, {document['model']} model",
        "",
        f"Declared effects: {', '.join(document['declared_effects']) or 'none'}.",
        "",
        "## Effects found",
        "",
    ]
    if document["effects"]:
        lines += ["| effect | channels | parameter | value | std | p-value |", "|---|---|---|---|---|---|"]
        for effect in document["effects"]:
            label = effect.get("spec", effect["name"])
            shape = effect.get("shape", {})
            rows = list(zip(effect["parameters"], effect["values"], effect["std"]))
            rows += [(f"{name} (shape)", value, effect["shape_std"][name]) for name, value in shape.items()]
            for name, value, std in rows:
                lines.append(
                    f"| {label} | {', '.join(effect['channels'])} | {name} | {value:.5g} | {std:.2g} | {effect['p_value']:.2g} |"
                )
    else:
        lines.append("Nothing significant that also lowers the validation error: the declared model is enough.")
    if document.get("pinned"):
        lines += ["", "## Terms held at zero (a friction or inertia may not be negative)", ""]
        lines += [f"- {term['parameter']} ({term['effect']}{', found' if term['found'] else ''}): {term['reason']}"
                  for term in document["pinned"]]
    lines += ["", "## Validation error per channel (held-out data)", "", "| channel | MSE before | MSE after | ratio |", "|---|---|---|---|"]
    before, after = document["validation"]["before"]["mse"], document["validation"]["after"]["mse"]
    for channel, value in before.items():
        lines.append(f"| {channel} | {value:.5g} | {after[channel]:.5g} | {after[channel] / value if value else np.nan:.3f} |")
    lines += ["", "## Residual statistics of the declared model (training)", "", "| channel | mean | std | autocorrelation lag 1 / 10 / 100 |", "|---|---|---|---|"]
    for channel, stats in document["residuals"].items():
        autocorrelation = " / ".join(f"{stats[key]:.2f}" for key in stats if key.startswith("autocorrelation"))
        lines.append(f"| {channel} | {stats['mean']:.4g} | {stats['std']:.4g} | {autocorrelation} |")
    lines += statistics_lines(document)
    absorbed = [r for r in document["rejected"] if "absorb" in r["reason"]]
    if absorbed:
        lines += ["", "## Not identifiable here", ""]
        lines += [f"- {r['name']} on {', '.join(r['channels'])}: {r['reason']}" for r in absorbed]
    if figure:
        lines += ["", f"![residuals]({figure})"]
    if trace_figure:
        lines += ["", f"![residual against its strongest variables]({trace_figure})"]
    return "\n".join(lines) + "\n"


def statistics_lines(document: dict) -> list[str]:
    """Markdown of the noise floor, floor comparison, tracing and whiteness keys of a report."""
    if "noise_floor" not in document:
        return []
    floor = document["noise_floor"]
    lines = ["", "## Noise floor", "", f"Method: {floor.get('method', 'none')} ({floor['note']})."]
    if floor["mse"] is not None:
        lines += ["", "| channel | floor (MSE) | MSE / floor before | MSE / floor after | |", "|---|---|---|---|---|"]
        comparison = document["floor_comparison"]
        for channel, value in floor["mse"].items():
            before, after = comparison["before"][channel], comparison["after"][channel]
            verdict = f"{after['ratio']:.3g} x above" if after["above"] else "at its floor"
            lines.append(f"| {channel} | {value:.4g} | {before['ratio']:.3g} | {after['ratio']:.3g} | {verdict} |")
    if document.get("floor_statements"):
        lines += [""] + [f"- {text}" for text in document["floor_statements"].values()]
    lines += ["", "## What the residual follows (share of the validation variance explained by binned means "
              "fitted on training)", "", "| channel | before: strongest variables | after: strongest variables |",
              "|---|---|---|"]
    tracing = document["tracing"]

    def strongest(which: str, channel: str) -> str:
        rows = [row for row in tracing[which]["rows"] if row["channel"] == channel][:3]
        return ", ".join(f"{row['variable']} {max(100 * row['validation_share'], 0.0):.0f} %" for row in rows)

    channels = list(dict.fromkeys(row["channel"] for row in tracing["after"]["rows"]))
    lines += [f"| {channel} | {strongest('before', channel)} | {strongest('after', channel)} |" for channel in channels]
    whiteness = document["whiteness"]
    lines += ["", f"## Whiteness and input correlation of the validation residual ({100 * whiteness['after']['confidence']:g} % bands)",
              "", "| channel | lags outside (before) | lags outside (after) | lag-1 autocorrelation after | correlated with (after) |",
              "|---|---|---|---|---|"]
    for channel, check in whiteness["after"]["channels"].items():
        before = whiteness["before"]["channels"][channel]["whiteness"]
        correlated = [name for name, entry in check["inputs"].items() if not entry["passed"]]
        lines.append(f"| {channel} | {before['outside']}/{len(before['lags'])} | {check['whiteness']['outside']}/"
                     f"{len(check['whiteness']['lags'])} | {check['whiteness']['values'][0]:.2f} | "
                     f"{', '.join(correlated) or 'none'} |")
    return lines


def plot_trace(diagnosis: Diagnosis, validate: Measurements, path: str | Path | None = None) -> Figure | None:
    """The augmented model's validation residual against its strongest variables (``None`` without
    statistics)."""
    if diagnosis.statistics is None:
        return None
    channels = diagnosis.after.estimate.channels
    return plot_residual_trace(diagnosis.statistics.tracing["after"], diagnosis.after.validation.residuals, validate,
                               channels, path, title="Residual after the diagnosis (validation) against its "
                               "strongest variables")
