"""Residual tracing: which state variable does each channel's residual follow?

For each channel ``c`` and each variable ``x`` (each joint's ``q``, ``dq``, ``ddq``, the sign of
``dq`` and ``|dq|`` — a velocity reversal is where both change — and the time within the record,
as a fraction of it) the residual's conditional mean ``m(x) = E[ε_c | x]`` is estimated by binned
means on the **training** residual (quantile bins of ``x``: equal counts, :data:`DEFAULT_BINS`;
two bins for the sign). The explained share of the variance

    share = 1 − Σ (ε − ε̄ − (m(x) − m̄))² / Σ (ε − ε̄)²

is reported on training (the bins' fit; about ``(B − 1)/N`` by chance) and, with the *training*
bins and means, on the **validation** residual: a dependence that the validation record confirms
is a property of the robot, one that it does not is noise or the training motion's accident. The
validation share can be negative (the training means predict worse than a constant).

Used to rank candidate effects by the variables they depend on (:func:`rank_candidates`), to say
which variable an unexplained residual follows (:func:`residual_statements`), and for the figure
of the residual against its strongest variables (:func:`plot_residual_trace`).
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from dynamics.measurements import Measurements
from dynamics.runtime.output_files import save_figure

if TYPE_CHECKING:
    from matplotlib.figure import Figure

DEFAULT_BINS = 20
#: a validation share above this is a dependence worth naming
MIN_SHARE = 0.05

#: the variables each library effect depends on (``{j}``: the effect's joint, 1-based)
EFFECT_VARIABLES: dict[str, tuple[str, ...]] = {
    "coulomb": ("sign_dq{j}", "dq{j}"),
    "viscous": ("dq{j}",),
    "viscous:direction": ("abs_dq{j}",),
    "stribeck": ("dq{j}", "abs_dq{j}", "sign_dq{j}"),
    "sigmoid": ("dq{j}", "sign_dq{j}"),
    "armature": ("ddq{j}",),
    "spring": ("q{j}",),
    "ripple": ("q{j}",),
    "offset": ("time",),  # a constant: no variable explains it better than time's mean
    "delay": ("ddq{j}", "dq{j}"),
}


@dataclass(frozen=True)
class TraceRow:
    """How much of one channel's residual variance follows one variable."""

    channel: str
    variable: str
    train_share: float
    validation_share: float

    def to_dict(self) -> dict[str, Any]:
        return {"channel": self.channel, "variable": self.variable, "train_share": self.train_share,
                "validation_share": self.validation_share}


@dataclass(frozen=True)
class ResidualTrace:
    """The tracing table: one row per channel and variable, strongest (on validation) first."""

    rows: tuple[TraceRow, ...]
    bins: int

    def channels(self) -> tuple[str, ...]:
        return tuple(dict.fromkeys(row.channel for row in self.rows))

    def strongest(self, channel: str, count: int = 3) -> tuple[TraceRow, ...]:
        """The ``count`` variables explaining most of ``channel``'s validation residual."""
        return tuple(row for row in self.rows if row.channel == channel)[:count]

    def share(self, channel: str, variable: str) -> float:
        """Validation share of ``variable`` on ``channel`` (``nan`` when not traced)."""
        for row in self.rows:
            if row.channel == channel and row.variable == variable:
                return row.validation_share
        return float("nan")

    def to_dict(self) -> dict[str, Any]:
        return {"bins": self.bins, "rows": [row.to_dict() for row in self.rows]}


def state_variables(measurements: Measurements) -> dict[str, NDArray[np.float64]]:
    """The variables traced: ``q{j}``, ``dq{j}``, ``ddq{j}``, ``sign_dq{j}``, ``abs_dq{j}``, ``time``."""
    if measurements.dq is None or measurements.ddq is None:
        raise ValueError("tracing needs dq and ddq: derive them first (estimation.preprocessing.differentiation.fill_derivatives)")
    variables: dict[str, NDArray[np.float64]] = {}
    for j in range(measurements.n_joints):
        variables[f"q{j + 1}"] = measurements.q[:, j]
        variables[f"dq{j + 1}"] = measurements.dq[:, j]
        variables[f"ddq{j + 1}"] = measurements.ddq[:, j]
        variables[f"sign_dq{j + 1}"] = np.sign(measurements.dq[:, j])
        variables[f"abs_dq{j + 1}"] = np.abs(measurements.dq[:, j])
    span = measurements.t[-1] - measurements.t[0]
    variables["time"] = (measurements.t - measurements.t[0]) / (span if span > 0 else 1.0)
    return variables


def _edges(values: NDArray[np.float64], bins: int, variable: str) -> NDArray[np.float64]:
    if variable.startswith("sign_"):
        return np.array([0.0])  # two bins: dq < 0, dq >= 0 (0 itself is rare)
    if variable == "time":
        return np.linspace(0, 1, bins + 1)[1:-1]
    return np.unique(np.quantile(values, np.linspace(0, 1, bins + 1)[1:-1]))


def _binned_means(x: NDArray[np.float64], residual: NDArray[np.float64], edges: NDArray[np.float64]):
    index = np.searchsorted(edges, x, side="right")
    counts = np.bincount(index, minlength=edges.shape[0] + 1)
    return _bin_means(index, residual, edges.shape[0] + 1), counts


def _bin_means(index: NDArray[np.intp], residual: NDArray[np.float64], n_bins: int,
               counts: NDArray[np.intp] | None = None) -> NDArray[np.float64]:
    """The mean of ``residual`` in each of ``n_bins`` bins (0 in an empty bin); ``index``: each sample's bin,
    ``counts``: the samples in each (counted here when not given)."""
    counts = np.bincount(index, minlength=n_bins) if counts is None else counts
    sums = np.bincount(index, weights=residual, minlength=n_bins)
    return np.where(counts > 0, sums / np.maximum(counts, 1), 0.0)


def _centred(residual: NDArray[np.float64]) -> tuple[NDArray[np.float64], float]:
    """The residual about its mean and its sum of squares there (what every variable's share divides by)."""
    centred = residual - residual.mean()
    return centred, float(centred @ centred)


def _share(centred: tuple[NDArray[np.float64], float], fitted: NDArray[np.float64]) -> float:
    """The share of a residual (:func:`_centred`) that the binned means ``fitted`` explain."""
    values, total = centred
    if total == 0:
        return 0.0
    explained = values - (fitted - fitted.mean())
    return float(1.0 - (explained @ explained) / total)


def trace_residuals(
    train_residuals: NDArray[np.float64],
    train: Measurements,
    validation_residuals: NDArray[np.float64],
    validate: Measurements,
    channels: Sequence[str],
    *,
    bins: int = DEFAULT_BINS,
) -> ResidualTrace:
    """The tracing table of residuals ``(N, m)`` on training and ``(N_v, m)`` on validation.

    Parameters
    ----------
    train_residuals, validation_residuals
        ``y − Y θ̂`` of one model on the training and validation records.
    train, validate
        The records (with ``q, dq, ddq``) the residuals belong to.
    channels
        Channel names of the residual columns.
    bins
        Quantile bins per variable (the sign has two).
    """
    train_residuals = np.asarray(train_residuals, dtype=float).reshape(train.n_samples, -1)
    validation_residuals = np.asarray(validation_residuals, dtype=float).reshape(validate.n_samples, -1)
    if train_residuals.shape[1] != len(channels) or validation_residuals.shape[1] != len(channels):
        raise ValueError(f"residuals of {train_residuals.shape[1]} and {validation_residuals.shape[1]} channels "
                         f"for {len(channels)} channel names")
    if isinstance(bins, bool) or int(bins) != bins or bins < 2:
        raise ValueError(f"bins must be an integer of at least 2, got {bins}")
    if train.n_samples < 5 * bins:
        raise ValueError(f"{train.n_samples} training samples are too few for {bins} bins")
    x_train, x_validate = state_variables(train), state_variables(validate)
    # the bins of a variable are the same for every channel: their edges, each sample's bin and the counts found once
    binned = {}
    for variable, values in x_train.items():
        edges = _edges(values, int(bins), variable)
        index_train = np.searchsorted(edges, values, side="right")
        binned[variable] = (index_train, np.searchsorted(edges, x_validate[variable], side="right"),
                            np.bincount(index_train, minlength=edges.shape[0] + 1))
    rows = []
    for column, channel in enumerate(channels):
        residual = train_residuals[:, column]
        train_centred, check_centred = _centred(residual), _centred(validation_residuals[:, column])
        channel_rows = []
        for variable, (index_train, index_validate, counts) in binned.items():
            means = _bin_means(index_train, residual, counts.shape[0], counts)
            channel_rows.append(TraceRow(channel, variable, _share(train_centred, means[index_train]),
                                         _share(check_centred, means[index_validate])))
        rows += sorted(channel_rows, key=lambda row: -row.validation_share)
    return ResidualTrace(tuple(rows), int(bins))


def effect_variables(effect: Any, n_joints: int, mapping: Mapping[str, Sequence[str]] | None = None) -> dict[str, tuple[str, ...]]:
    """``{channel: variables}`` a candidate effect depends on (its joints' torque channels)."""
    mapping = EFFECT_VARIABLES if mapping is None else mapping
    templates = mapping.get(getattr(effect, "name", ""), ())
    joints = getattr(effect, "joints", None)
    joints = range(n_joints) if joints is None else joints
    return {f"tau{j + 1}": tuple(template.format(j=j + 1) for template in templates) for j in joints}


def rank_candidates(trace: ResidualTrace, candidates: Iterable[Any], n_joints: int, *,
                    mapping: Mapping[str, Sequence[str]] | None = None) -> list[tuple[Any, float, str]]:
    """Candidates ordered by how much of their channel's validation residual their variables explain.

    Returns ``[(candidate, share, variable)]``, best first; a candidate whose variables are not
    traced (an unknown effect, a wrench channel) gets ``share = 0`` and keeps its order.
    """
    scored = []
    for order, candidate in enumerate(candidates):
        best, best_variable = 0.0, ""
        for channel, variables in effect_variables(candidate, n_joints, mapping).items():
            for variable in variables:
                share = trace.share(channel, variable)
                if np.isfinite(share) and share > best:
                    best, best_variable = share, variable
        scored.append((order, candidate, best, best_variable))
    scored.sort(key=lambda item: (-item[2], item[0]))
    return [(candidate, share, variable) for _, candidate, share, variable in scored]


def residual_statements(trace: ResidualTrace, channels: Iterable[str] | None = None, *,
                        min_share: float = MIN_SHARE) -> dict[str, str]:
    """Per channel, in words, which variable the residual still follows (confirmed on validation).

    Give ``channels`` (those still above their noise floor, say) to speak only of them.
    """
    statements = {}
    for channel in (trace.channels() if channels is None else channels):
        strongest = [row for row in trace.strongest(channel, 3) if row.validation_share >= min_share]
        if not strongest:
            statements[channel] = (f"{channel}: the residual follows none of the traced variables (each explains "
                                   f"less than {100 * min_share:g} % of its validation variance)")
            continue
        named = ", ".join(f"{row.variable} ({100 * row.validation_share:.0f} %)" for row in strongest)
        statements[channel] = f"{channel}: the remaining residual follows {named} of its validation variance"
    return statements


def plot_residual_trace(trace: ResidualTrace, residuals: NDArray[np.float64], measurements: Measurements,
                        channels: Sequence[str], path: str | Path | None = None, *, count: int = 3,
                        title: str = "Residual against its strongest variables") -> Figure:
    """Each channel's residual against its ``count`` strongest variables, with the binned means;
    saved to ``path`` when given."""
    from matplotlib.figure import Figure  # no pyplot; here, not at the top: a run without figures skips matplotlib

    residuals = np.asarray(residuals, dtype=float).reshape(measurements.n_samples, -1)
    variables = state_variables(measurements)
    figure = Figure(figsize=(4.2 * count, 2.4 * len(channels)))
    axes = figure.subplots(len(channels), count, squeeze=False)
    for row_index, channel in enumerate(channels):
        residual = residuals[:, list(channels).index(channel)]
        strongest = trace.strongest(channel, count)
        for column in range(count):
            axis = axes[row_index, column]
            if column >= len(strongest):
                axis.set_axis_off()
                continue
            row = strongest[column]
            x = variables[row.variable]
            axis.plot(x, residual, ".", markersize=1.2, alpha=0.3)
            edges = _edges(x, trace.bins, row.variable)
            means, counts = _binned_means(x, residual, edges)
            centres = [np.mean(x[np.searchsorted(edges, x, side="right") == b]) for b in range(means.shape[0]) if counts[b]]
            axis.plot(centres, means[counts > 0], "-o", color="C3", markersize=3)
            axis.set_xlabel(row.variable)
            axis.set_title(f"{channel}: {100 * row.validation_share:.0f} % (validation)", fontsize=9)
            if column == 0:
                axis.set_ylabel(f"residual {channel}")
    figure.suptitle(title)
    figure.tight_layout()
    if path is not None:
        save_figure(figure, path, dpi=90)
    return figure
