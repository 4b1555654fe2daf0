"""Least squares from accumulated sums: per-channel Gram matrices and TSQR factors, summable.

Identification needs the regressor only through sums over samples (PUMA paper, eq. 20): per
channel ``c`` the Gram matrix ``Y_cᵀY_c``, the moment ``Y_cᵀy_c`` and the power ``y_cᵀy_c``. They
add over chunks of a record and over records, so a record of any length, or many records on a
cluster, reduce to ``m (r+1)²`` numbers without the ``(N, m, r)`` regressor in memory.

Accuracy. Solving the normal equations squares the condition number; a QR factorisation of the
stacked regressor does not. :class:`NormalEquations` therefore keeps, beside the Gram sums, the
triangular factor ``R_c`` of the augmented block ``[Y_c | y_c] = Q_c R_c`` of every channel,
accumulated as a TSQR: a chunk's rows are stacked under the current factor and re-factored
(``[R; A_chunk] = Q' R'``), and two partial sums combine by factoring ``[R_a; R_b]``. Then
``A_cᵀA_c = R_cᵀR_c`` exactly, and for channel weights ``w_c`` the weighted problem's factor is that
of ``[√w_1 R_1; …; √w_m R_m]`` (``m (r+1)`` rows):
:func:`estimation.estimators.summed_least_squares.solve_sums` solves it by back
substitution, as accurately as a QR of the full weighted ``(N m) x r`` regressor. Residual sums of
squares come from the factors too (``‖y_c − Y_c θ‖² = ‖R_c [θ; −1]‖²``), free of the cancellation
of ``yᵀy − 2θᵀYᵀy + θᵀYᵀYθ``. The Gram sums are kept for what is naturally a sum (sub-blocks of
candidate columns for F tests, :mod:`estimation.streaming.candidate_screening`) and as a cross-check.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass, replace

import numpy as np
import scipy.linalg
from numpy.typing import NDArray

from dynamics.runtime.memory import check_allocation
from dynamics.models import IdentificationModel
from dynamics.runtime.threads import single_threaded_blas
from dynamics.measurements import Measurements
from estimation.data.channel_mask import masked_equations
from estimation.estimators.identification_problem import in_band_blocks

__all__ = ["DEFAULT_CHUNK_SIZE", "NormalEquations", "accumulate", "check_chunk_size", "reduce_sums", "stacked_factor"]

#: samples a chunk. The regressor of a chunk is ``chunk x m x r`` floats: 10 000 samples of the
#: 7-joint KUKA internal model with viscous friction (m = 7, r = 50) is 28 MB, the QR work array
#: 4 MB, the overlap windows of the filter path a few MB. The fixed cost of a chunk (a compiled
#: CasADi call, m LAPACK calls on (r+1)² extra rows, the filter margins) is paid once per chunk:
#: ``benchmarks/bench_streaming.py --chunk-sizes`` measures the trade-off.
DEFAULT_CHUNK_SIZE = 10_000


#: rows of a block copied at a time into a channel's Fortran-ordered work array (a row-major block's channel
#: is strided: copied whole, each column's reads leave the cache; 512 rows at a time took half the time)
COPY_ROWS = 512


def _factor_in_place(work: NDArray[np.float64], width: int) -> NDArray[np.float64]:
    """``R`` (``width x width``) of a Fortran-ordered ``work`` (at least ``width`` rows), overwritten
    by LAPACK ``dgeqrf`` (no ``Q``, no full-height ``R`` allocated)."""
    qr, _, _, info = scipy.linalg.lapack.dgeqrf(work, overwrite_a=True)
    if info != 0:
        raise ValueError(f"QR factorisation failed (LAPACK info {info})")
    return np.triu(qr[:width])


def channel_columns(factor: NDArray[np.float64], support: NDArray[np.bool_]) -> NDArray[np.intp]:
    """The columns of ``[Y_c | y_c]`` a channel's TSQR step factors: those of the block that are not zero on it
    (``support``, ``(k,)``), those of its current factor ``R_c`` (``(k+1, k+1)``) with a non-zero row or column, and
    ``y_c`` (the last). The others are zero in ``[R_c; Y_c y_c]``: leaving them out is exact, and ``R_c`` on the
    columns kept, put back in place (zero elsewhere), is still upper-triangular with the same ``R_cᵀR_c``. A
    distal joint's torque reaches few base parameters: on a 7-joint arm the QR costs 2.6 times less."""
    nonzero = factor != 0
    keep = np.append(support, True) | np.any(nonzero, axis=0) | np.any(nonzero, axis=1)
    return np.flatnonzero(keep)


def stacked_factor(blocks: list[NDArray[np.float64]], width: int) -> NDArray[np.float64]:
    """Upper-triangular ``(width, width)`` factor ``R`` of the stacked ``blocks`` (zero rows padded)."""
    rows = sum(block.shape[0] for block in blocks)
    work = np.zeros((max(rows, width), width), order="F")
    start = 0
    for block in blocks:
        work[start:start + block.shape[0]] = block
        start += block.shape[0]
    return _factor_in_place(work, width)


@dataclass(frozen=True)
class NormalEquations:
    """Sums over samples of a linear problem ``y_c = Y_c θ + ε_c``, per channel ``c``.

    Attributes
    ----------
    gram
        ``(m, k, k)`` ``Y_cᵀY_c``.
    moment
        ``(m, k)`` ``Y_cᵀy_c``.
    power
        ``(m,)`` ``y_cᵀy_c``.
    factor
        ``(m, k+1, k+1)`` upper-triangular ``R_c`` of ``[Y_c | y_c]`` (TSQR; sign arbitrary).
    n_samples
        Samples summed.
    channels, names, expressions
        Channel names; column names and groupings (base parameters, then any candidate columns).
    sources
        What was summed (file names, chunks), for messages and the expected-count check.
    band
        The sums of the same problem in the motion's band, ``(F Y_c, F y_c)`` with ``F`` the zero-phase low-pass the
        motion was filtered with (:class:`estimation.estimators.identification_problem.ResidualBand`), when the
        torques were fitted as recorded: the channel weights of a weighted fit come from its residual
        (:func:`~estimation.estimators.identification_problem.in_band_variance`); ``None``: from the residual.
    channel_samples
        ``(m,)`` each channel's valid samples summed when some were masked (NaN in the block's target: a clipped
        sensor, a held channel's repeats; :mod:`estimation.data.channel_mask`), whose equations were left out (the
        regressor row and target zeroed, as :func:`~estimation.data.channel_mask.masked_equations` in memory);
        ``None``: every channel's ``n_samples``.
    """

    gram: NDArray[np.float64]
    moment: NDArray[np.float64]
    power: NDArray[np.float64]
    factor: NDArray[np.float64]
    n_samples: int
    channels: tuple[str, ...]
    names: tuple[str, ...]
    expressions: tuple[str, ...] = ()
    sources: tuple[str, ...] = ()
    band: NormalEquations | None = None
    channel_samples: tuple[int, ...] | None = None

    def __post_init__(self) -> None:
        m, k = len(self.channels), len(self.names)
        shapes = {"gram": (m, k, k), "moment": (m, k), "power": (m,), "factor": (m, k + 1, k + 1)}
        for name, shape in shapes.items():
            array = np.array(getattr(self, name), dtype=float)
            if array.shape != shape:
                raise ValueError(f"{name} has shape {array.shape}, expected {shape} for {m} channels and {k} columns")
            array.flags.writeable = False
            object.__setattr__(self, name, array)
        object.__setattr__(self, "expressions", tuple(self.expressions) or tuple(self.names))
        object.__setattr__(self, "sources", tuple(self.sources))
        if int(self.n_samples) != self.n_samples or self.n_samples < 0:
            raise ValueError(f"n_samples must be a non-negative integer, got {self.n_samples}")
        if self.band is not None and (not isinstance(self.band, NormalEquations) or self.band.band is not None
                                      or self.band.channels != self.channels or self.band.names != self.names
                                      or self.band.n_samples != self.n_samples):
            raise ValueError("the band's sums must be those of the same problem (channels, columns, samples)")
        if self.channel_samples is not None:
            counts = tuple(int(count) for count in self.channel_samples)
            if len(counts) != m or any(count < 0 or count > self.n_samples for count in counts):
                raise ValueError(f"channel_samples must be {m} counts within 0..{self.n_samples}, got "
                                 f"{self.channel_samples}")
            object.__setattr__(self, "channel_samples", None if all(c == self.n_samples for c in counts) else counts)

    @property
    def samples(self) -> NDArray[np.float64]:
        """``(m,)`` each channel's valid samples summed (``n_samples`` for every channel when nothing was masked)."""
        if self.channel_samples is None:
            return np.full(self.n_channels, float(self.n_samples))
        return np.array(self.channel_samples, dtype=float)

    @property
    def n_equations(self) -> int:
        """The equations summed: every channel's valid samples."""
        return int(self.n_samples * self.n_channels if self.channel_samples is None else sum(self.channel_samples))

    @property
    def n_channels(self) -> int:
        return len(self.channels)

    @property
    def n_columns(self) -> int:
        return len(self.names)

    @classmethod
    def empty(cls, channels: tuple[str, ...], names: tuple[str, ...], expressions: tuple[str, ...] = ()) -> NormalEquations:
        """Zero sums (the neutral element of ``+``)."""
        m, k = len(channels), len(names)
        return cls(np.zeros((m, k, k)), np.zeros((m, k)), np.zeros(m), np.zeros((m, k + 1, k + 1)), 0,
                   tuple(channels), tuple(names), expressions)

    @classmethod
    def from_arrays(cls, Y: NDArray[np.float64], y: NDArray[np.float64], channels: tuple[str, ...],
                    names: tuple[str, ...], expressions: tuple[str, ...] = (), source: str = "") -> NormalEquations:
        """Sums of one block: regressor ``Y (N, m, k)``, measured ``y (N, m)``."""
        Y, y = np.asarray(Y, dtype=float), np.asarray(y, dtype=float)
        if Y.ndim != 3 or y.shape != Y.shape[:2] or Y.shape[1:] != (len(channels), len(names)):
            raise ValueError(f"Y must be (N, {len(channels)}, {len(names)}) and y (N, {len(channels)}); "
                             f"got Y {Y.shape}, y {y.shape}")
        Y, y, valid = masked_equations(Y, y)
        by_channel = Y.transpose(1, 2, 0)  # (m, k, N)
        gram = np.matmul(by_channel, Y.transpose(1, 0, 2))
        moment = np.matmul(by_channel, y.T[:, :, None])[:, :, 0]
        power = np.einsum("nm,nm->m", y, y)
        k = Y.shape[2]
        factor = np.stack([stacked_factor([np.column_stack([Y[:, c, :], y[:, c]])], k + 1) for c in range(Y.shape[1])])
        return cls(gram, moment, power, factor, Y.shape[0], tuple(channels), tuple(names), expressions,
                   (source,) if source else (), None, None if valid is None else tuple(valid.sum(axis=0)))

    def _check_compatible(self, other: NormalEquations) -> None:
        if not isinstance(other, NormalEquations):
            raise TypeError(f"cannot add {type(other).__name__} to NormalEquations")
        if other.channels != self.channels or other.names != self.names:
            raise ValueError(f"sums of different problems: channels {self.channels} / {other.channels}, "
                             f"columns {self.names} / {other.names}")

    def __add__(self, other: NormalEquations) -> NormalEquations:
        self._check_compatible(other)
        width = self.n_columns + 1
        factor = np.stack([stacked_factor([a, b], width) for a, b in zip(self.factor, other.factor)])
        return NormalEquations(self.gram + other.gram, self.moment + other.moment, self.power + other.power,
                               factor, self.n_samples + other.n_samples, self.channels, self.names,
                               self.expressions, self.sources + other.sources, _added_bands(self, other),
                               _added_counts(self, other))

    def add_block(self, Y: NDArray[np.float64], y: NDArray[np.float64], source: str = "", *,
                  gram: bool = True) -> NormalEquations:
        """These sums plus a block's, re-factoring each channel's rows under its current factor
        (one QR of ``(k+1) + N`` rows a channel rather than two). ``gram=False``: the Gram sums and moments
        are not formed (left NaN: :func:`accumulate`), only the factors and powers. A masked sample of a channel
        (NaN in ``y``) leaves out that channel's equation (:attr:`channel_samples`)."""
        Y, y = np.asarray(Y, dtype=float), np.asarray(y, dtype=float)
        if Y.ndim != 3 or y.shape != Y.shape[:2] or Y.shape[1:] != (self.n_channels, self.n_columns):
            raise ValueError(f"block Y {Y.shape}, y {y.shape} does not fit {self.n_channels} channels, {self.n_columns} columns")
        Y, y, valid = masked_equations(Y, y)
        counts = None if valid is None and self.channel_samples is None else tuple(
            int(before) + int(added) for before, added in
            zip(self.samples, np.full(self.n_channels, Y.shape[0]) if valid is None else valid.sum(axis=0)))
        by_channel = Y.transpose(1, 2, 0)
        width = self.n_columns + 1
        # one work buffer for every channel: [R_c; Y_c y_c] on the channel's columns, Fortran-ordered, factored in
        # place (allocation churn made this 3x slower in dask workers, which return freed memory eagerly)
        buffer = np.empty((width + Y.shape[0]) * width)
        factor = np.zeros((self.n_channels, width, width))
        # (m, k): a distal joint's torque reaches few of the base parameters (``Y.any`` reads ``Y`` in place;
        # ``np.any(Y != 0)`` wrote a boolean copy of it first: the same booleans, NaN nonzero in both)
        support = Y.any(axis=0)
        for c in range(self.n_channels):
            columns = channel_columns(self.factor[c], support[c])
            narrow = columns.shape[0]
            work = buffer[:(narrow + Y.shape[0]) * narrow].reshape((narrow + Y.shape[0], narrow), order="F")
            work[:narrow] = self.factor[c][np.ix_(columns, columns)]
            kept = columns[:-1]
            for start in range(0, Y.shape[0], COPY_ROWS):  # a channel's rows of Y are strided: copied in blocks
                work[narrow + start:narrow + start + COPY_ROWS, :-1] = Y[start:start + COPY_ROWS, c, kept]
            work[narrow:, -1] = y[:, c]
            factor[c][np.ix_(columns, columns)] = _factor_in_place(work, narrow)
        return NormalEquations(
            self.gram + np.matmul(by_channel, Y.transpose(1, 0, 2)) if gram else np.full_like(self.gram, np.nan),
            self.moment + np.matmul(by_channel, y.T[:, :, None])[:, :, 0] if gram else np.full_like(self.moment, np.nan),
            self.power + np.einsum("nm,nm->m", y, y), factor, self.n_samples + Y.shape[0],
            self.channels, self.names, self.expressions, self.sources + ((source,) if source else ()), None, counts,
        )

    def select(self, columns: Iterable[int]) -> NormalEquations:
        """The sums of the problem restricted to some columns (the base block, a candidate added…):
        Gram sub-blocks, and factors re-triangularised from the kept columns of ``R_c``."""
        index = [int(i) for i in columns]
        keep = index + [self.n_columns]
        factor = np.stack([stacked_factor([R[:, keep]], len(keep)) for R in self.factor])
        return NormalEquations(self.gram[:, index][:, :, index], self.moment[:, index], self.power, factor,
                               self.n_samples, self.channels, tuple(self.names[i] for i in index),
                               tuple(self.expressions[i] for i in index), self.sources,
                               None if self.band is None else self.band.select(index), self.channel_samples)

    def in_band_rss(self, theta: NDArray[np.float64]) -> NDArray[np.float64]:
        """``‖F(y_c − Y_c θ)‖²`` per channel, the residual in the motion's band (:attr:`band`), or
        :meth:`channel_rss` when the sums have no band: what the channel weights are taken from."""
        return (self if self.band is None else self.band).channel_rss(theta)

    def channel_rss(self, theta: NDArray[np.float64]) -> NDArray[np.float64]:
        """``‖y_c − Y_c θ‖²`` per channel, ``(m,)``, from the factors."""
        augmented = np.append(np.asarray(theta, dtype=float).reshape(-1), -1.0)
        if augmented.shape[0] != self.n_columns + 1:
            raise ValueError(f"expected {self.n_columns} parameter values, got {augmented.shape[0] - 1}")
        return np.sum((self.factor @ augmented) ** 2, axis=1)

    def channel_mse(self, theta: NDArray[np.float64]) -> dict[str, float]:
        """Mean squared error per channel at ``θ`` (as :func:`estimation.identification.validation.channel_mse`)."""
        if self.n_samples == 0:
            raise ValueError("no samples summed")
        return dict(zip(self.channels, map(float, self.channel_rss(theta) / self.samples)))


def _added_counts(a: NormalEquations, b: NormalEquations) -> tuple[int, ...] | None:
    """The :attr:`NormalEquations.channel_samples` of ``a + b`` (``None`` when neither holds a masked sample)."""
    if a.channel_samples is None and b.channel_samples is None:
        return None
    return tuple(int(x) + int(y) for x, y in zip(a.samples, b.samples))


def _added_bands(a: NormalEquations, b: NormalEquations) -> NormalEquations | None:
    """The band sums of ``a + b``: their sum, the one side's when the other holds no samples, else ``None`` (a
    record without a band among them: the weights come from the residual, as in memory for records stacked so)."""
    if a.band is not None and b.band is not None:
        return a.band + b.band
    if b.n_samples == 0:
        return a.band
    if a.n_samples == 0:
        return b.band
    return None


def check_chunk_size(chunk_size: int, model: IdentificationModel, extra_columns: int = 0) -> int:
    """A positive integer whose chunk fits in memory (regressor, its QR copies, the evaluation's output)."""
    if isinstance(chunk_size, bool) or int(chunk_size) != chunk_size or chunk_size < 1:
        raise ValueError(f"chunk size must be a positive integer, got {chunk_size!r}")
    width = model.n_base + extra_columns + 1
    check_allocation(8.0 * chunk_size * (3 * model.n_channels * width + 8 * model.robot.n_joints),
                     f"a chunk of {chunk_size} samples")
    return int(chunk_size)


@single_threaded_blas()
def accumulate(model: IdentificationModel, measurements: Measurements, *, chunk_size: int = DEFAULT_CHUNK_SIZE,
               sums: NormalEquations | None = None, source: str = "", gram: bool = True,
               band: bool = True) -> NormalEquations:
    """Sums of ``model``'s base-parameter problem on ``measurements`` (with ``dq``, ``ddq``), the
    regressor evaluated ``chunk_size`` samples at a time, added to ``sums`` if given.

    When the measurements have a band (:func:`~estimation.estimators.identification_problem.in_band_blocks`: the
    torques kept as recorded, the motion low-passed), the sums of the problem in that band are summed too (:attr:`NormalEquations.band`; each block's regressor and
    target filtered in a window reaching the filter's margin beyond it, as the whole record is
    filtered), and added to the band of ``sums`` (given without one, the result has none); ``band=False``: not
    (ordinary least squares does not read them: they cost a second regressor and factor).

    ``gram=False``: only the TSQR factors and the powers are summed, the Gram matrices and moments are left NaN
    (not summed): enough for :class:`~estimation.estimators.summed_least_squares.SummedLeastSquares`, which
    solves and takes residuals from the factors, and a fifth less time a chunk (the fits of
    :mod:`estimation.identification.preprocessing_on_validation`, one per derivative candidate)."""
    if measurements.dq is None or measurements.ddq is None:
        raise ValueError("the measurements lack dq/ddq: derive them first (estimation.preprocessing.differentiation.fill_derivatives)")
    if measurements.n_joints != model.robot.n_joints:
        raise ValueError(f"the data have {measurements.n_joints} joints, the robot {model.robot.n_joints}")
    chunk_size = check_chunk_size(chunk_size, model)
    empty = NormalEquations.empty(model.channels, model.base.names, model.base.expressions)
    if sums is None:
        sums = empty
    measured = measurements.channels(model.channels)  # NaN: a masked sample (estimation.data.channel_mask)
    if np.any(np.isinf(measured)):
        raise ValueError(f"{source or 'the data'}: a measured channel holds inf")
    buffer = np.empty((min(chunk_size, measurements.n_samples), model.n_channels, model.n_base))
    blocks = in_band_blocks(measurements, chunk_size) if band else None
    given = sums  # its band (add_block sums the problem as it is)
    for start in range(0, measurements.n_samples, chunk_size):
        stop = min(start + chunk_size, measurements.n_samples)
        Y = model.evaluate_base(measurements.q[start:stop], measurements.dq[start:stop], measurements.ddq[start:stop],
                                out=buffer[: stop - start])
        if not np.all(np.isfinite(Y)):
            raise ValueError(f"{source or 'the data'}: the regressor holds NaN or inf near sample {start}: "
                             "check the measured q, dq, ddq")
        sums = sums.add_block(Y, measured[start:stop], gram=gram)
    in_band = None
    if blocks is not None and (given.band is not None or given.n_samples == 0):
        in_band = empty if given.band is None else given.band
        for band, window, kept in blocks:
            # the masked equations zeroed before the filter: the band of the residual that is 0 there, as in memory
            Y, y, _ = masked_equations(model.evaluate_base(window.q, window.dq, window.ddq),
                                       window.channels(model.channels))
            in_band = in_band.add_block(band.window(Y)[kept], band.window(y)[kept], gram=gram)
    if in_band is not None:  # the band's equations: those of the sums (its filtered target is no mask)
        in_band = replace(in_band, channel_samples=sums.channel_samples)
    return NormalEquations(sums.gram, sums.moment, sums.power, sums.factor, sums.n_samples, sums.channels,
                           sums.names, sums.expressions, sums.sources + ((source,) if source else ()), in_band,
                           sums.channel_samples)


def reduce_sums(parts: Iterable[NormalEquations]) -> NormalEquations:
    """The sum of several partial sums (a pairwise tree: each combination re-factors two ``R``)."""
    parts = list(parts)
    if not parts:
        raise ValueError("no sums to reduce")
    while len(parts) > 1:
        parts = [parts[i] + parts[i + 1] if i + 1 < len(parts) else parts[i] for i in range(0, len(parts), 2)]
    return parts[0]
