"""Validation: predicted against measured channels, mean squared error per channel, figures.

PUMA paper, section IV: identify on one trajectory, predict the torques and reaction wrench of
another with the estimates, and compare — MSE per channel (Tables VI–VIII) and measured vs
predicted curves (Figs. 7–9).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike, NDArray

from dynamics.models import IdentificationModel
from dynamics.measurements import Measurements
from dynamics.runtime.output_files import save_figure
from estimation.data.channel_mask import channel_counts, channel_mean
from estimation.data.segments import segment_slices


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
    filtered
        When ``measured`` is the recording and the estimation saw filtered or period-averaged
        channels: the same comparison on those (``mse_filtered``), else ``None``.
    segments
        Sample ranges of the segments stacked here (plots break their lines there).
    """

    t: NDArray[np.float64]
    measured: NDArray[np.float64]
    predicted: NDArray[np.float64]
    channels: tuple[str, ...]
    label: str = ""
    filtered: Comparison | None = None
    segments: tuple[slice, ...] = ()

    @property
    def residuals(self) -> NDArray[np.float64]:
        return self.measured - self.predicted

    @property
    def mse(self) -> dict[str, float]:
        """Mean squared error per channel (Tables VI–VIII of the PUMA paper)."""
        return channel_mse(self.measured, self.predicted, self.channels)

    @property
    def mse_filtered(self) -> dict[str, float] | None:
        """MSE against the filtered/averaged channels the estimation saw (``None`` when it saw the recording)."""
        return None if self.filtered is None else self.filtered.mse

    def to_dict(self) -> dict[str, dict[str, float]]:
        """``{mse}`` (against the recording) and, when there is one, ``{mse_filtered}``."""
        document = {"mse": self.mse}
        if self.filtered is not None:
            document["mse_filtered"] = self.filtered.mse
        return document

    @property
    def n_samples(self) -> int:
        return int(self.t.shape[0])

    @property
    def channel_samples(self) -> dict[str, int] | None:
        """The samples each channel's error is taken over where they differ by channel (a channel's masked samples
        left out: :mod:`estimation.data.channel_mask`), else ``None`` (every channel over :attr:`n_samples`)."""
        counts = channel_counts(self.measured)
        if np.all(counts == self.n_samples):
            return None
        return {channel: int(count) for channel, count in zip(self.channels, counts)}

    @property
    def relative_mse(self) -> dict[str, float]:
        """MSE divided by the measured channel's mean square (0 perfect, 1 no better than zero)."""
        power = channel_mean(self.measured**2)
        return {channel: value / power[index] if power[index] > 0 else float("inf")
                for index, (channel, value) in enumerate(self.mse.items())}


def channel_mse(measured: ArrayLike, predicted: ArrayLike, channels: Sequence[str]) -> dict[str, float]:
    """``mean((measured − predicted)²)`` per channel, over its valid samples (a masked sample of a channel, NaN in
    ``measured``, left out of that channel's mean only: :mod:`estimation.data.channel_mask`)."""
    measured, predicted = np.asarray(measured, dtype=float), np.asarray(predicted, dtype=float)
    if measured.shape != predicted.shape or measured.ndim != 2 or measured.shape[1] != len(channels):
        raise ValueError(f"measured {measured.shape} and predicted {predicted.shape} must be (N, {len(channels)})")
    return {channel: float(value) for channel, value in zip(channels, channel_mean((measured - predicted) ** 2, measured))}


def compare(model: IdentificationModel, theta: ArrayLike, measurements: Measurements, *, label: str = "",
            predicted: NDArray[np.float64] | None = None) -> Comparison:
    """Predict ``model``'s channels with parameters ``theta`` (base ``r`` or standard ``p`` values)
    along the measured (or derived) motion and pair them with the channels **as recorded**
    (``measurements.recorded`` when preprocessing filtered or averaged them; the comparison with
    the filtered channels is kept as ``filtered``). ``predicted``: ``model.predict(theta, …)`` along
    ``measurements`` itself when the caller has it (a fit's regressor times its estimate,
    :func:`estimation.identification.fit.identify`), not formed again; the recorded samples' is formed here."""
    if measurements.dq is None or measurements.ddq is None:
        raise ValueError("the measurements lack dq/ddq: derive them first (estimation.preprocessing.differentiation.fill_derivatives)")
    if predicted is not None and np.shape(predicted) != (measurements.n_samples, model.n_channels):
        raise ValueError(f"predicted has shape {np.shape(predicted)}, expected {(measurements.n_samples, model.n_channels)}")
    filtered = _compare_as_is(model, theta, measurements, label, predicted)
    if measurements.recorded is None:
        return filtered
    recorded = _compare_as_is(model, theta, measurements.recorded, label)
    return replace(recorded, filtered=filtered)


def compare_recorded(model: IdentificationModel, thetas: dict[str, ArrayLike], measurements: Measurements, *,
                     label: str = "", chunk_size: int = 10_000) -> dict[str, Comparison]:
    """:func:`compare` of several parameter vectors (each base ``r`` or standard ``p`` values) on the same
    measurements, against the channels **as recorded** only (no ``filtered`` comparison): the same predictions
    ``Y θ`` and errors as :func:`compare`'s, the regressor evaluated once for all the vectors, ``chunk_size``
    samples at a time, so that memory stays bounded by a chunk's regressor whatever the record's length (the
    derivative candidates' scoring, :mod:`estimation.identification.preprocessing_on_validation`)."""
    if measurements.dq is None or measurements.ddq is None:
        raise ValueError("the measurements lack dq/ddq: derive them first (estimation.preprocessing.differentiation.fill_derivatives)")
    if int(chunk_size) < 1:
        raise ValueError(f"chunk_size must be a positive integer, got {chunk_size!r}")
    recorded = measurements if measurements.recorded is None else measurements.recorded
    vectors = {name: np.asarray(theta, dtype=float).reshape(-1) for name, theta in thetas.items()}
    widths = {vector.shape[0] for vector in vectors.values()}
    if not widths <= {model.n_parameters, model.n_base}:
        raise ValueError(f"theta has {sorted(widths)} values; this model has {model.n_parameters} standard "
                         f"and {model.n_base} base parameters")
    n_samples = recorded.t.shape[0]
    predicted = {name: np.empty((n_samples, model.n_channels)) for name in vectors}
    for start in range(0, n_samples, int(chunk_size)):
        rows = slice(start, min(start + int(chunk_size), n_samples))
        states = (recorded.q[rows], recorded.dq[rows], recorded.ddq[rows])
        regressors = {width: (model.evaluate if width == model.n_parameters else model.evaluate_base)(*states)
                      for width in widths}
        for name, vector in vectors.items():
            predicted[name][rows] = regressors[vector.shape[0]] @ vector
        del regressors
    measured = recorded.channels(model.channels)
    segments = tuple(segment_slices(recorded))
    return {name: Comparison(recorded.t, measured, predicted[name], model.channels, label, segments=segments)
            for name in vectors}


def _compare_as_is(model: IdentificationModel, theta: ArrayLike, measurements: Measurements, label: str,
                   predicted: NDArray[np.float64] | None = None) -> Comparison:
    if predicted is None:
        predicted = model.predict(theta, measurements.q, measurements.dq, measurements.ddq)
    return Comparison(measurements.t, measurements.channels(model.channels), predicted, model.channels, label,
                      segments=tuple(segment_slices(measurements)))


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
            measured_label = "measured (as recorded)" if comparison.filtered is not None else "measured"
            for number, part in enumerate(comparison.segments or (slice(None),)):
                axis.plot(comparison.t[part], comparison.measured[part, row], color="0.55", linewidth=0.8,
                          label=measured_label if number == 0 else None)
                axis.plot(comparison.t[part], comparison.predicted[part, row], color="C3", linewidth=1.0,
                          label="predicted" if number == 0 else None)
            axis.set_ylabel(f"{channel} [{units[channel]}]")
            axis.text(0.99, 0.95, f"MSE vs recorded {mse[channel]:.3g}" if comparison.filtered is not None
                      else f"MSE {mse[channel]:.3g}", transform=axis.transAxes, ha="right", va="top", fontsize=8)
        segments = len(comparison.segments)
        axes[0, column].set_title(comparison.label + (f" ({segments} segments, t of each)" if segments > 1 else ""))
        axes[-1, column].set_xlabel("t [s]")
    axes[0, 0].legend(loc="upper left", fontsize=8)
    if title:
        figure.suptitle(title)
    figure.tight_layout()
    if path is not None:
        save_figure(figure, path)
    return figure


#: at most this many points of a time series drawn in a figure (every k-th sample beyond)
MAX_POINTS = 4000


def subsample_step(n_samples: int, max_points: int = MAX_POINTS) -> int:
    """The stride that draws at most ``max_points`` of ``n_samples``."""
    return max(1, -(-n_samples // max_points))


@dataclass(frozen=True)
class ChannelErrors:
    """The errors of a fit on a record whose samples are not held (read in blocks and summed): what a
    :class:`Comparison` gives, ``mse`` against the channels as recorded (``None`` when the sums hold filtered or
    period-averaged channels only) and ``mse_filtered`` against those (``None`` when the sums hold the recording);
    ``block_mse``: per channel, the MSE against the recording on each of the contiguous blocks
    :func:`estimation.identification.preprocessing_on_validation.block_mse` cuts a :class:`Comparison` of the same
    samples into (from per-block sums of the streamed validation pass, :mod:`estimation.streaming.block_errors`;
    ``None``: not summed by block), cut from ``block_samples`` samples (``None``: ``n_samples``; the recorded samples
    of a file the streamed path resampled onto a grid, whose sums count the grid's)."""

    mse: dict[str, float] | None
    n_samples: int | None = None
    mse_filtered: dict[str, float] | None = None
    block_mse: dict[str, tuple[float, ...]] | None = None
    block_samples: int | None = None

    def to_dict(self) -> dict[str, dict[str, float] | None]:
        """``{mse}`` and, when there is one, ``{mse_filtered}`` (:meth:`Comparison.to_dict`)."""
        document: dict[str, dict[str, float] | None] = {"mse": None if self.mse is None else dict(self.mse)}
        if self.mse_filtered is not None:
            document["mse_filtered"] = dict(self.mse_filtered)
        return document


def plot_channel(comparisons: dict[str, Comparison], row: int, step: int = 1, title: str = ""):
    """Channel ``row`` of one record: measured (as recorded) and each comparison's prediction (top), each one's
    residual (bottom), against time, every ``step``-th sample; lines break between segments. ``comparisons``:
    ``{label: Comparison}`` on the same samples (e.g. ``before`` and ``after``)."""
    from matplotlib.figure import Figure  # no pyplot

    figure = Figure(figsize=(11, 4.2))
    top, bottom = figure.subplots(2, 1, sharex=True, gridspec_kw={"height_ratios": (3, 2)})
    first = next(iter(comparisons.values()))
    colours = ("C0", "C3", "C2", "C1")
    for number, part in enumerate(first.segments or (slice(None),)):
        t = first.t[part][::step]
        top.plot(t, first.measured[part, row][::step], color="0.5", linewidth=0.8,
                 label="measured" if number == 0 else None)
        for colour, (label, comparison) in zip(colours, comparisons.items()):
            top.plot(t, comparison.predicted[part, row][::step], color=colour, linewidth=0.9,
                     label=label if number == 0 else None)
            bottom.plot(t, comparison.residuals[part, row][::step], color=colour, linewidth=0.7)
    channel = first.channels[row]
    for index, (colour, comparison) in enumerate(zip(colours, comparisons.values())):
        top.text(0.99, 0.95 - 0.15 * index, f"MSE {comparison.mse[channel]:.3g}", transform=top.transAxes, ha="right",
                 va="top", fontsize=8, color=colour)
    top.set_ylabel(channel)
    top.legend(loc="upper left", fontsize=8)
    bottom.set_ylabel("residual")
    bottom.set_xlabel("t [s]")
    if title:
        top.set_title(title)
    figure.tight_layout()
    return figure
