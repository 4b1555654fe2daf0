"""The stacked linear identification problem ``y = Y θ + ε``, kept per sample and channel.

:class:`IdentificationProblem` holds the base regressor ``(N, m, r)`` and the measured channels
``(N, m)`` with the names of both, checked on creation; :func:`stack` builds it from a model and
measurements. The estimators of :mod:`estimation.estimators.least_squares` fit it.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import ArrayLike, NDArray

from dynamics.models import IdentificationModel
from dynamics.measurements import Measurements
from estimation.uncertainty.covariance import segment_bounds
from estimation.data.segments import concatenate, segment_slices


@dataclass(frozen=True)
class IdentificationProblem:
    """A stacked linear identification problem ``y = Y θ + ε``, kept per sample and channel.

    Attributes
    ----------
    Y
        ``(N, m, r)`` regressor: sample, channel, parameter.
    y
        ``(N, m)`` measured values.
    channels
        Name of each channel (``tau1``, ``fx``…), as the data columns.
    names, expressions
        Name and grouping of each parameter (column).
    segments
        ``(start, stop)`` samples of each segment of a stacked record (:mod:`estimation.data.segments`;
        empty: one segment): the HAC covariance runs no lag across a boundary.
    """

    Y: NDArray[np.float64]
    y: NDArray[np.float64]
    channels: tuple[str, ...]
    names: tuple[str, ...]
    expressions: tuple[str, ...] = ()
    segments: tuple[tuple[int, int], ...] = ()

    def __post_init__(self) -> None:
        Y, y = np.asarray(self.Y, dtype=float), np.asarray(self.y, dtype=float)
        if Y.ndim != 3 or y.shape != Y.shape[:2]:
            raise ValueError(f"Y must be (N, m, r) and y (N, m); got Y {Y.shape}, y {y.shape}")
        if len(self.channels) != Y.shape[1] or len(self.names) != Y.shape[2]:
            raise ValueError(f"{len(self.channels)} channel and {len(self.names)} parameter names for Y {Y.shape}")
        if not np.all(np.isfinite(y)):
            bad = np.argwhere(~np.isfinite(y))[0]
            raise ValueError(f"measured channel {self.channels[bad[1]]} holds NaN or inf (sample {bad[0]})")
        with np.errstate(over="ignore"):
            overflowing = [c for c, value in zip(self.channels, np.sum(y**2, axis=0)) if not np.isfinite(value)]
        if overflowing:
            raise ValueError(f"measured channel(s) {', '.join(overflowing)} overflow when squared (values up to "
                             f"{np.max(np.abs(y)):.3g}): check their units")
        if not np.all(np.isfinite(Y)):
            bad = np.argwhere(~np.isfinite(Y))[0]
            raise ValueError(f"regressor column {self.names[bad[2]]} holds NaN or inf (sample {bad[0]}, channel "
                             f"{self.channels[bad[1]]}): check the measured q, dq, ddq")
        object.__setattr__(self, "Y", Y)
        object.__setattr__(self, "y", y)
        object.__setattr__(self, "channels", tuple(self.channels))
        object.__setattr__(self, "names", tuple(self.names))
        object.__setattr__(self, "expressions", tuple(self.expressions) or tuple(self.names))
        object.__setattr__(self, "segments", tuple(segment_bounds(Y.shape[0], self.segments)) if self.segments else ())

    @property
    def n_samples(self) -> int:
        return self.Y.shape[0]

    @property
    def n_channels(self) -> int:
        return self.Y.shape[1]

    @property
    def n_parameters(self) -> int:
        return self.Y.shape[2]

    def stacked(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """``Y (N·m, r)`` and ``y (N·m,)``, sample-major (views, no copy)."""
        return self.Y.reshape(-1, self.n_parameters), self.y.reshape(-1)

    def predict(self, theta: ArrayLike) -> NDArray[np.float64]:
        """``Y θ`` per sample and channel, ``(N, m)``."""
        return self.Y @ _check_theta(theta, self.n_parameters)

    def residuals(self, theta: ArrayLike) -> NDArray[np.float64]:
        """``y − Y θ``, ``(N, m)``."""
        return self.y - self.predict(theta)

    def with_columns(
        self, columns: ArrayLike, names: tuple[str, ...] | list[str], expressions: tuple[str, ...] | list[str] = ()
    ) -> IdentificationProblem:
        """The problem with extra regressor columns ``(N, m, k)`` (candidate effects, say)."""
        columns = np.asarray(columns, dtype=float)
        if columns.ndim == 2:
            columns = columns[:, :, None]
        if columns.shape[:2] != self.Y.shape[:2]:
            raise ValueError(f"extra columns {columns.shape} do not match the problem's samples and channels {self.Y.shape[:2]}")
        clash = set(names) & set(self.names)
        if clash:
            raise ValueError(f"parameter name(s) {sorted(clash)} already in the problem")
        return IdentificationProblem(
            np.concatenate([self.Y, columns], axis=2), self.y, self.channels,
            self.names + tuple(names), self.expressions + (tuple(expressions) or tuple(names)), self.segments,
        )

    def select_channels(self, channels: tuple[str, ...] | list[str]) -> IdentificationProblem:
        """The problem restricted to some channels (in the given order)."""
        missing = [channel for channel in channels if channel not in self.channels]
        if missing:
            raise ValueError(f"no channel(s) {missing} in this problem; it has {self.channels}")
        index = [self.channels.index(channel) for channel in channels]
        return replace(self, Y=self.Y[:, index], y=self.y[:, index], channels=tuple(channels))


def stack(model: IdentificationModel, measurements: Measurements | Sequence[Measurements]) -> IdentificationProblem:
    """The base-parameter problem of ``model`` on ``measurements`` (which need ``dq``, ``ddq``:
    see :func:`estimation.preprocessing.differentiation.fill_derivatives`), evaluated with the model's CasADi
    base regressor mapped over the samples. Several segments (each prepared on its own) are
    stacked sample by sample (:func:`estimation.data.segments.concatenate`)."""
    measurements = concatenate(measurements)
    if measurements.dq is None or measurements.ddq is None:
        raise ValueError("the measurements lack dq/ddq: derive them first (estimation.preprocessing.differentiation.fill_derivatives)")
    if measurements.n_joints != model.robot.n_joints:
        raise ValueError(f"the data have {measurements.n_joints} joints, the robot {model.robot.n_joints}")
    measured = measurements.channels(model.channels)
    Y = model.evaluate_base(measurements.q, measurements.dq, measurements.ddq)  # compiled, zero-copy
    segments = segment_slices(measurements)
    bounds = tuple((piece.start, piece.stop) for piece in segments) if len(segments) > 1 else ()
    return IdentificationProblem(Y, measured, model.channels, model.base.names, model.base.expressions, bounds)


def _check_theta(theta: ArrayLike, count: int) -> NDArray[np.float64]:
    theta = np.asarray(theta, dtype=float).reshape(-1)
    if theta.shape[0] != count:
        raise ValueError(f"expected {count} parameter values, got {theta.shape[0]}")
    return theta
