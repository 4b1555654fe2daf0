"""Validation: predicted against measured channels, mean squared error per channel, figures.

PUMA paper, section IV: identify on one trajectory, predict the torques and reaction wrench of
another with the estimates, and compare — MSE per channel (Tables VI–VIII) and measured vs
predicted curves (Figs. 7–9).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike, NDArray

from dynamics.models import IdentificationModel
from estimation.measurements import Measurements
from estimation.output_files import save_figure


@dataclass(frozen=True)
class Comparison:
    """Measured and predicted channels of one experiment.

    Attributes
    ----------
    t
        ``(N,)`` time, s.
    measured, predicted
        ``(N, m)`` values per channel (N, N·m).
    channels
        Channel names, as the data columns.
    label
        What was compared (``train``, ``validation``, a file name…).
    """

    t: NDArray[np.float64]
    measured: NDArray[np.float64]
    predicted: NDArray[np.float64]
    channels: tuple[str, ...]
    label: str = ""

    @property
    def residuals(self) -> NDArray[np.float64]:
        return self.measured - self.predicted

    @property
    def mse(self) -> dict[str, float]:
        """Mean squared error per channel (Tables VI–VIII of the PUMA paper)."""
        return channel_mse(self.measured, self.predicted, self.channels)

    @property
    def relative_mse(self) -> dict[str, float]:
        """MSE divided by the measured channel's mean square (0 perfect, 1 no better than zero)."""
        power = np.mean(self.measured**2, axis=0)
        return {channel: value / power[index] if power[index] > 0 else float("inf")
                for index, (channel, value) in enumerate(self.mse.items())}


def channel_mse(measured: ArrayLike, predicted: ArrayLike, channels: Sequence[str]) -> dict[str, float]:
    """``mean((measured − predicted)²)`` per channel."""
    measured, predicted = np.asarray(measured, dtype=float), np.asarray(predicted, dtype=float)
    if measured.shape != predicted.shape or measured.ndim != 2 or measured.shape[1] != len(channels):
        raise ValueError(f"measured {measured.shape} and predicted {predicted.shape} must be (N, {len(channels)})")
    return {channel: float(value) for channel, value in zip(channels, np.mean((measured - predicted) ** 2, axis=0))}


def compare(model: IdentificationModel, theta: ArrayLike, measurements: Measurements, *, label: str = "") -> Comparison:
    """Predict ``model``'s channels with parameters ``theta`` (base ``r`` or standard ``p`` values)
    along the measured motion and pair them with the measured channels."""
    if measurements.dq is None or measurements.ddq is None:
        raise ValueError("the measurements lack dq/ddq: derive them first (estimation.preprocessing.fill_derivatives)")
    predicted = model.predict(theta, measurements.q, measurements.dq, measurements.ddq)
    return Comparison(measurements.t, measurements.channels(model.channels), predicted, model.channels, label)


def plot_comparison(comparisons: Comparison | Sequence[Comparison], path: str | Path | None = None, *, title: str = ""):
    """Measured vs predicted per channel, one row of axes per channel (like Figs. 7–9), written
    atomically to ``path`` when given (format from the suffix: ``.png``, ``.pdf``, ``.svg``).

    Returns
    -------
    matplotlib.figure.Figure
    """
    from matplotlib.figure import Figure  # no pyplot: no backend switch, no global figure registry


    if isinstance(comparisons, Comparison):
        comparisons = [comparisons]
    comparisons = list(comparisons)
    channels = comparisons[0].channels
    units = {channel: ("N" if channel in ("fx", "fy", "fz") else "N·m") for channel in channels}
    figure = Figure(figsize=(5.5 * len(comparisons), 1.9 * len(channels)))
    axes = figure.subplots(len(channels), len(comparisons), sharex="col", squeeze=False)
    for column, comparison in enumerate(comparisons):
        mse = comparison.mse
        for row, channel in enumerate(channels):
            axis = axes[row, column]
            axis.plot(comparison.t, comparison.measured[:, row], color="0.55", linewidth=0.8, label="measured")
            axis.plot(comparison.t, comparison.predicted[:, row], color="C3", linewidth=1.0, label="predicted")
            axis.set_ylabel(f"{channel} [{units[channel]}]")
            axis.text(0.99, 0.95, f"MSE {mse[channel]:.3g}", transform=axis.transAxes, ha="right", va="top", fontsize=8)
        axes[0, column].set_title(comparison.label)
        axes[-1, column].set_xlabel("t [s]")
    axes[0, 0].legend(loc="upper left", fontsize=8)
    if title:
        figure.suptitle(title)
    figure.tight_layout()
    if path is not None:
        save_figure(figure, path)
    return figure
