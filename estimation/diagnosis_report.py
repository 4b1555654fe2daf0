"""The figures and the Markdown report of a :class:`~estimation.diagnosis.Diagnosis`."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.figure import Figure  # no pyplot: no backend switch, no global figure registry

from estimation.diagnosis import Diagnosis
from estimation.measurements import Measurements
from estimation.output_files import save_figure


def plot_residuals(diagnosis: Diagnosis, train: Measurements, path: str | Path | None = None) -> Figure:
    """Training residuals of the declared model against q, dq, ddq of their joint, and time; saved to
    ``path`` when given."""
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
    figure.suptitle("Residuals of the declared model (training data)")
    figure.tight_layout()
    if path is not None:
        save_figure(figure, path, dpi=90)
    return figure


def markdown_report(diagnosis: Diagnosis, figure: str | None = None) -> str:
    """The report a person reads: effects found, rejected candidates, MSE before and after."""
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
    lines += ["", "## Validation error per channel (held-out data)", "", "| channel | MSE before | MSE after | ratio |", "|---|---|---|---|"]
    before, after = document["validation"]["before"]["mse"], document["validation"]["after"]["mse"]
    for channel, value in before.items():
        lines.append(f"| {channel} | {value:.5g} | {after[channel]:.5g} | {after[channel] / value if value else np.nan:.3f} |")
    lines += ["", "## Residual statistics of the declared model (training)", "", "| channel | mean | std | autocorrelation lag 1 / 10 / 100 |", "|---|---|---|---|"]
    for channel, stats in document["residuals"].items():
        autocorrelation = " / ".join(f"{stats[key]:.2f}" for key in stats if key.startswith("autocorrelation"))
        lines.append(f"| {channel} | {stats['mean']:.4g} | {stats['std']:.4g} | {autocorrelation} |")
    absorbed = [r for r in document["rejected"] if "absorb" in r["reason"]]
    if absorbed:
        lines += ["", "## Not identifiable here", ""]
        lines += [f"- {r['name']} on {', '.join(r['channels'])}: {r['reason']}" for r in absorbed]
    if figure:
        lines += ["", f"![residuals]({figure})"]
    return "\n".join(lines) + "\n"
