"""The stacked linear identification problem ``y = Y θ + ε``, kept per sample and channel.

:class:`IdentificationProblem` holds the base regressor ``(N, m, r)`` and the measured channels
``(N, m)`` with the names of both, checked on creation; :func:`stack` builds it from a model and
measurements. The estimators of :mod:`estimation.estimators.least_squares` fit it.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace

import functools

import numpy as np
import scipy.signal
from numpy.typing import ArrayLike, NDArray

from dynamics.models import IdentificationModel
from dynamics.measurements import Measurements
from estimation.uncertainty.covariance import segment_bounds
from estimation.data.channel_mask import masked_equations
from estimation.data.passive import passive_channels
from estimation.data.segments import concatenate, segment_slices


@dataclass(frozen=True)
class ResidualBand:
    """The band the motion was low-passed to (a zero-phase Butterworth differentiation): the torques are fitted as
    recorded, but only their part in this band can be fitted by the motion's columns, so the channel weights of a
    weighted fit come from the residual filtered alike (:func:`in_band_variance`); out of band, the residual holds
    the recording's high-frequency noise, which no column fits and which differs by channel.

    Attributes
    ----------
    cutoff_hz, order
        The motion's zero-phase Butterworth filter (``filtfilt`` of this order).
    rate_hz
        The samples' rate.
    segments
        ``(start, stop)`` of each segment (filtered on its own); empty: one.
    rates
        The rate of each segment when they differ (segments resampled each onto its own grid, each filtered at its
        rate as the differentiation filtered it); empty: ``rate_hz`` for all.
    """

    cutoff_hz: float
    order: int
    rate_hz: float
    segments: tuple[tuple[int, int], ...] = ()
    rates: tuple[float, ...] = ()

    @classmethod
    def of(cls, measurements: Measurements) -> ResidualBand | None:
        """The band of prepared ``measurements``: ``None`` unless a Butterworth differentiation filtered their motion
        below their Nyquist frequency and kept the torques as recorded (``torques="recorded"``; filtered alike, they
        hold nothing the motion's columns cannot)."""
        metadata = measurements.metadata
        if "band_window" in metadata:  # a block of a record read in chunks: its band is its window's (BandWindow)
            return None
        if metadata.get("differentiation") != "butterworth" or metadata.get("cutoff_hz") is None:
            return None
        if metadata.get("torques") != "recorded":  # filtered alike, the target holds nothing out of band
            return None
        if measurements.n_samples < 2:
            return None
        step = float(np.median(np.diff(measurements.t)))
        if not step > 0:
            return None
        rate, cutoff = float(f"{1.0 / step:.9g}"), float(metadata["cutoff_hz"])  # as the differentiation rounds it
        if not cutoff < 0.45 * rate:
            return None
        pieces = segment_slices(measurements)
        bounds = tuple((piece.start, piece.stop) for piece in pieces) if len(pieces) > 1 else ()
        rates = tuple(_rate(measurements.t[piece]) for piece in pieces) if len(pieces) > 1 else ()
        if any(not (value is not None and cutoff < 0.45 * value) for value in rates):
            return None
        return cls(cutoff, int(metadata.get("filter_order") or 4), rate, bounds,
                   rates if len(set(rates)) > 1 else ())

    def pieces(self, n_samples: int) -> list[tuple[int, int, ResidualBand]]:
        """``(start, stop, band)`` of each segment of ``n_samples`` and the band of that segment alone (its rate)."""
        bounds = self.segments or ((0, n_samples),)
        rates = self.rates or (self.rate_hz,) * len(bounds)
        return [(start, stop, ResidualBand(self.cutoff_hz, self.order, rate)) for (start, stop), rate in zip(bounds, rates)]

    @property
    def margin(self) -> int:
        """Samples the filter reaches beyond a block (:func:`decay_length`): a block filtered in a window reaching
        this far beyond it on each side (or to its segment's ends) equals its segment filtered whole."""
        return _band_margin(self.cutoff_hz, self.order, self.rate_hz)

    def windows(self, n_samples: int, size: int) -> list[tuple[ResidualBand, int, int, int, int]]:
        """``(band, low, start, stop, high)`` of each block ``start:stop`` of at most ``size`` samples of
        ``n_samples`` and the window ``low:high`` it is filtered in (``band``'s :meth:`window`, then ``start − low``
        on): the blocks cover each segment in order, each window within its segment, ``band`` its segment's."""
        windows = []
        for first, last, band in self.pieces(n_samples):
            margin = band.margin
            for start in range(first, last, size):
                stop = min(start + size, last)
                windows.append((band, max(start - margin, first), start, stop, min(stop + margin, last)))
        return windows

    def window(self, values: NDArray[np.float64]) -> NDArray[np.float64]:
        """``values`` of one window of :meth:`windows` (samples along axis 0) low-passed as one segment."""
        return replace(self, segments=()).apply(values)

    def apply(self, values: NDArray[np.float64]) -> NDArray[np.float64]:
        """``values`` (samples along axis 0) low-passed by the same zero-phase filter, each segment on its own
        (a segment too short for the filter's padding is left as it is)."""
        values = np.asarray(values, dtype=float)
        filtered = values.copy()
        for start, stop, band in self.pieces(values.shape[0]):
            sos = _sos(self.order, self.cutoff_hz, band.rate_hz)
            if stop - start > 3 * (2 * len(sos) + 1):
                filtered[start:stop] = _filtfilt(sos, values[start:stop])
        return filtered


def _filtfilt(sos: NDArray[np.float64], values: NDArray[np.float64]) -> NDArray[np.float64]:
    """``scipy.signal.sosfiltfilt(sos, values, axis=0)`` (its odd extension, padding and initial states), computed
    on the samples as rows of one contiguous ``(columns, samples)`` array: equal to it, in half its time on a
    residual of a few channels (the in-band variances are taken at every reweighting)."""
    n_sections = sos.shape[0]
    taps = 2 * n_sections + 1 - min(int(np.sum(sos[:, 2] == 0)), int(np.sum(sos[:, 5] == 0)))
    padding = 3 * taps
    rows = values.reshape(values.shape[0], -1)
    first, last = rows[:1], rows[-1:]
    extended = np.concatenate([2 * first - rows[padding:0:-1], rows, 2 * last - rows[-2:-(padding + 2):-1]]).T.copy()
    zi = scipy.signal.sosfilt_zi(sos)[:, None, :]  # (sections, 1, 2)
    forward, _ = scipy.signal.sosfilt(sos, extended, axis=-1, zi=zi * extended[None, :, :1])
    backward = forward[:, ::-1].copy()
    backward, _ = scipy.signal.sosfilt(sos, backward, axis=-1, zi=zi * backward[None, :, :1])
    return backward[:, ::-1][:, padding:backward.shape[1] - padding].T.reshape(values.shape)


#: relative size of the impulse response at which a filter's reach ends (the streamed path's overlap margins)
DECAY_TOLERANCE = 1e-13


def decay_length(sos: NDArray[np.float64], tolerance: float = DECAY_TOLERANCE) -> int:
    """Samples after which the impulse response of ``sos`` stays below ``tolerance`` of its peak: how far beyond a
    block of samples a zero-phase filter reaches (a block filtered in a window this much wider on each side equals
    the whole record filtered, to about ``tolerance``)."""
    length = 1024
    while True:
        impulse = np.zeros(length)
        impulse[0] = 1.0
        response = np.abs(scipy.signal.sosfilt(sos, impulse))
        above = np.flatnonzero(response > tolerance * response.max())
        if above[-1] < length - length // 4 or length > 50_000_000:
            return int(above[-1]) + 1
        length *= 4


@functools.lru_cache(maxsize=32)
def _band_margin(cutoff_hz: float, order: int, rate_hz: float) -> int:
    return decay_length(_sos(order, cutoff_hz, rate_hz))


def _sos(order: int, cutoff_hz: float, rate_hz: float) -> NDArray[np.float64]:
    """The band's low-pass filter as second-order sections, designed once per band (a residual is filtered at every
    reweighting); a copy, the design stays as cached."""
    return np.array(_sections(order, cutoff_hz, rate_hz))


@functools.lru_cache(maxsize=32)
def _sections(order: int, cutoff_hz: float, rate_hz: float) -> tuple[tuple[float, ...], ...]:
    sos = scipy.signal.butter(order, cutoff_hz, btype="low", fs=rate_hz, output="sos")
    return tuple(tuple(float(value) for value in row) for row in sos)


@dataclass(frozen=True)
class BandWindow:
    """A block of a record prepared in chunks (``metadata["band_window"]``, the streamed path) with what its in-band
    problem needs: ``samples``, the block's prepared samples extended by the band's :attr:`~ResidualBand.margin`
    on each side (less at the record's ends), the block from ``offset`` on, and the record's ``band``."""

    band: ResidualBand
    samples: Measurements
    offset: int


def in_band_blocks(measurements: Measurements, size: int
                   ) -> list[tuple[ResidualBand, Measurements, slice]] | None:
    """The blocks of ``measurements`` (at most ``size`` samples) as their in-band problem is built: ``(band, window,
    kept)``, the block's columns evaluated on ``window``, low-passed (:meth:`ResidualBand.window`) and cut to
    ``kept``, equal to those of the whole record low-passed; ``None``: no band (:meth:`ResidualBand.of`; a chunk
    of a record read in chunks has its window's, :class:`BandWindow`)."""
    if "band_window" in measurements.metadata:
        window = measurements.metadata["band_window"]
        if window is None:
            return None
        return [(window.band, window.samples, slice(window.offset, window.offset + measurements.n_samples))]
    band = ResidualBand.of(measurements)
    if band is None:
        return None
    return [(piece, measurements.select(slice(low, high)), slice(start - low, stop - low))
            for piece, low, start, stop, high in band.windows(measurements.n_samples, size)]


def _rate(t: NDArray[np.float64]) -> float | None:
    """The rate of samples at times ``t`` as the differentiation takes it (the median step, rounded alike)."""
    if t.shape[0] < 2:
        return None
    step = float(np.median(np.diff(t)))
    return float(f"{1.0 / step:.9g}") if step > 0 else None


def in_band_variance(residuals: NDArray[np.float64], n_parameters: int,
                     band: ResidualBand | None, samples: NDArray[np.int_] | None = None) -> NDArray[np.float64]:
    """Per channel, the variance of the residuals ``(N, m)`` in ``band`` (as recorded when ``None``),
    ``‖ρ_c‖² / (N_c − r/m)``: the variance channel weights ``1/σ_c²`` are taken from. ``samples``: ``N_c``, each
    channel's valid samples when some are masked (:attr:`IdentificationProblem.channel_samples`; their residual
    is 0 there), else ``N`` for all."""
    n_samples, n_channels = residuals.shape
    dof = (n_samples if samples is None else np.asarray(samples, dtype=float)) - n_parameters / n_channels
    if np.any(dof <= 0):
        raise ValueError(f"{n_samples} samples leave no degrees of freedom for {n_parameters} parameters")
    values = residuals if band is None else band.apply(residuals)
    return np.sum(values**2, axis=0) / dof


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
    band
        The band the motion was low-passed to (:class:`ResidualBand`): a weighted fit's channel weights come from
        the residual in it; ``None``: from the residual as it is.
    passive
        The channels of passive (unactuated) joints (:mod:`estimation.data.passive`): their zero is a measurement
        (``0 = Y_j θ``), not a dead sensor; a weighted fit weights them by their residual.
    mask
        ``(N, m)`` true where the equation is a measurement, false where the channel's sample is masked
        (:mod:`estimation.data.channel_mask`: its row of ``Y`` and its ``y`` are zero, so it adds nothing to the fit);
        ``None``: every equation is.
    """

    Y: NDArray[np.float64]
    y: NDArray[np.float64]
    channels: tuple[str, ...]
    names: tuple[str, ...]
    expressions: tuple[str, ...] = ()
    segments: tuple[tuple[int, int], ...] = ()
    band: ResidualBand | None = None
    passive: tuple[str, ...] = ()
    mask: NDArray[np.bool_] | None = None

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
        if self.mask is not None:
            mask = np.asarray(self.mask, dtype=bool)
            if mask.shape != y.shape:
                raise ValueError(f"mask has shape {mask.shape}, expected {y.shape} (samples, channels)")
            object.__setattr__(self, "mask", None if mask.all() else mask)

    @property
    def channel_samples(self) -> NDArray[np.int_] | None:
        """``(m,)`` each channel's valid samples (equations) when some are masked, else ``None`` (``N`` each)."""
        return None if self.mask is None else np.sum(self.mask, axis=0)

    @property
    def n_samples(self) -> int:
        return self.Y.shape[0]

    @property
    def n_channels(self) -> int:
        return self.Y.shape[1]

    @property
    def n_parameters(self) -> int:
        return self.Y.shape[2]

    @property
    def n_equations(self) -> int:
        """The equations that are measurements: ``N m`` less the masked ones (:attr:`mask`)."""
        return self.Y.shape[0] * self.Y.shape[1] if self.mask is None else int(np.count_nonzero(self.mask))

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
            self.band, self.passive, self.mask,
        )

    def select_channels(self, channels: tuple[str, ...] | list[str]) -> IdentificationProblem:
        """The problem restricted to some channels (in the given order)."""
        missing = [channel for channel in channels if channel not in self.channels]
        if missing:
            raise ValueError(f"no channel(s) {missing} in this problem; it has {self.channels}")
        index = [self.channels.index(channel) for channel in channels]
        return replace(self, Y=self.Y[:, index], y=self.y[:, index], channels=tuple(channels),
                       passive=tuple(channel for channel in self.passive if channel in channels),
                       mask=None if self.mask is None else self.mask[:, index])


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
    Y, measured, mask = masked_equations(Y, measured)  # a masked channel's samples: out (nothing copied if none)
    segments = segment_slices(measurements)
    bounds = tuple((piece.start, piece.stop) for piece in segments) if len(segments) > 1 else ()
    return IdentificationProblem(Y, measured, model.channels, model.base.names, model.base.expressions, bounds,
                                 ResidualBand.of(measurements), passive_channels(model), mask)


def _check_theta(theta: ArrayLike, count: int) -> NDArray[np.float64]:
    theta = np.asarray(theta, dtype=float).reshape(-1)
    if theta.shape[0] != count:
        raise ValueError(f"expected {count} parameter values, got {theta.shape[0]}")
    return theta
