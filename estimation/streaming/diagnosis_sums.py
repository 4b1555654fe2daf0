"""Per-channel sums of the diagnosis's columns ``[Y_base | C_1 | … | C_J]``, chunk by chunk.

The diagnosis (:func:`estimation.diagnosis.search.diagnose`) compares nested linear models with fixed
channel weights ``w_c`` through per-channel Gram matrices (:class:`estimation.estimators.separable_least_squares.FixedPart`):
channel ``c`` of the weighted problem on columns ``S`` contributes ``w_c X_c[S]ᵀX_c[S]`` to the
normal matrix and ``w_c X_c[S]ᵀy_c`` to its right side. A candidate's columns are zero off its
rows (one joint's torque for a per-joint law), so channel ``c`` needs only the columns that reach
it: the base regressor's and those of the candidates acting on ``c``. :class:`ChannelSums` holds,
per channel, the Gram matrix of those columns, their moments with two targets (the channels as
prepared, i.e. filtered, which the estimates are fitted to, and the channels **as recorded**,
which every reported error is measured against) and the powers ``yᵀy``. They add over chunks,
files and workers; a file of any length costs ``Σ_c (k_c + 2)²`` numbers.

Accuracy: the normal equations are solved as the in-memory loop solves them
(:func:`estimation.estimators.separable_least_squares.solve_linear`): equilibrated (unit diagonal), a rank test
on the eigenvalues (``λ_min < 1e-13 λ_max`` is rank-deficient) and a Cholesky solve; the weighted
RSS is ``wᵀ(yᵀy) − 2θᵀb + θᵀNθ``, the same formula. The sums themselves are exact up to the
summation's rounding (``≈ √N ε`` relative), so the streamed loop agrees with the in-memory one to
the rounding of the solve (checked in ``tests/test_streamed_diagnosis.py``: estimates and MSEs to
1e-8 relative). The final estimate is solved from a triangular factor of each channel's augmented
Gram matrix (:func:`normal_equations`), by :class:`estimation.estimators.summed_least_squares.SummedLeastSquares`.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import scipy.linalg
from numpy.typing import NDArray

from dynamics.models import IdentificationModel
from dynamics.measurements import Measurements
from estimation.estimators.identification_problem import in_band_blocks
from estimation.estimators.normal_equations import NormalEquations
from estimation.estimators.effect_blocks import Block, States
from estimation.estimators.separable_least_squares import solve_normal

__all__ = ["ChannelSums", "ColumnLayout", "EvenSubsample", "chunk_sums", "normal_equations"]


@dataclass(frozen=True)
class ColumnLayout:
    """Where each column lives: the base columns ``0 … p0−1``, then each candidate's, and the
    columns that reach each channel."""

    n_base: int
    names: tuple[str, ...]
    blocks: tuple[tuple[int, ...], ...]  # per candidate: its global column indices
    rows: tuple[tuple[int, ...], ...]  # per candidate: the channels it reaches
    channels: tuple[str, ...]

    @property
    def n_channels(self) -> int:
        return len(self.channels)

    @classmethod
    def build(cls, model: IdentificationModel, blocks: Sequence[Block]) -> ColumnLayout:
        names = list(model.base.names)
        columns = []
        for index, block in enumerate(blocks):
            columns.append(tuple(range(len(names), len(names) + block.n_linear)))
            names += [f"{name}#{index}" for name in block.names]
        return cls(model.n_base, tuple(names), tuple(columns), tuple(tuple(block.rows) for block in blocks),
                   tuple(model.channels))

    def channel_columns(self, channel: int) -> tuple[int, ...]:
        """Global indices of the columns that reach ``channel`` (base first, candidates in order)."""
        columns = list(range(self.n_base))
        for block, rows in zip(self.blocks, self.rows):
            if channel in rows:
                columns.extend(block)
        return tuple(columns)


@dataclass(frozen=True)
class ChannelSums:
    """Per channel ``c``: ``X_cᵀX_c``, ``X_cᵀ[y_c, y_c^rec]`` and ``[y_cᵀy_c, y_c^recᵀy_c^rec]`` over
    the columns :meth:`ColumnLayout.channel_columns` ``(c)``; target 0 is the prepared channel,
    target 1 the channel as recorded."""

    layout: ColumnLayout
    gram: tuple[NDArray[np.float64], ...]
    moment: tuple[NDArray[np.float64], ...]  # (k_c, 2)
    power: NDArray[np.float64]  # (m, 2)
    n_samples: int
    #: the same sums of the problem in the motion's band (the columns and the channels low-passed alike, both targets
    #: the channel as recorded), when the torques are fitted as recorded: the channel weights come from its residual
    #: (:attr:`estimation.estimators.normal_equations.NormalEquations.band`); ``None``: from the residual
    band: ChannelSums | None = None

    @classmethod
    def empty(cls, layout: ColumnLayout) -> ChannelSums:
        sizes = [len(layout.channel_columns(c)) for c in range(layout.n_channels)]
        return cls(layout, tuple(np.zeros((k, k)) for k in sizes), tuple(np.zeros((k, 2)) for k in sizes),
                   np.zeros((layout.n_channels, 2)), 0)

    def __add__(self, other: ChannelSums) -> ChannelSums:
        if not isinstance(other, ChannelSums) or other.layout != self.layout:
            raise ValueError("sums of different column layouts cannot be added")
        if self.band is not None and other.band is not None:
            band = self.band + other.band
        else:  # a side without samples takes the other's band; two records, one without a band: none
            band = self.band if other.n_samples == 0 else other.band if self.n_samples == 0 else None
        return ChannelSums(self.layout, tuple(a + b for a, b in zip(self.gram, other.gram)),
                           tuple(a + b for a, b in zip(self.moment, other.moment)), self.power + other.power,
                           self.n_samples + other.n_samples, band)

    def in_band_rss(self, selection: Sequence[int], theta: NDArray[np.float64]) -> NDArray[np.float64]:
        """``‖F(y_c − X_c[S] θ)‖²`` per channel, the residual in the motion's band (:attr:`band`), else the residual
        against the prepared channels: what the channel weights are taken from."""
        return self.channel_rss(selection, theta, target=0) if self.band is None else \
            self.band.channel_rss(selection, theta, target=0)

    def _positions(self, channel: int, selection: Sequence[int]) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
        """(positions in ``selection``, positions in the channel's columns) of the selected columns reaching it."""
        local = {column: position for position, column in enumerate(self.layout.channel_columns(channel))}
        pairs = [(i, local[column]) for i, column in enumerate(selection) if column in local]
        return np.array([p for p, _ in pairs], dtype=int), np.array([q for _, q in pairs], dtype=int)

    def normal_system(self, selection: Sequence[int], weights: NDArray[np.float64], target: int = 0
                      ) -> tuple[NDArray[np.float64], NDArray[np.float64], float]:
        """``(N, b, wᵀ(yᵀy))`` of the weighted problem on the columns ``selection`` (global indices)."""
        p = len(selection)
        normal, right = np.zeros((p, p)), np.zeros(p)
        for c, w in enumerate(np.asarray(weights, dtype=float)):
            outer, inner = self._positions(c, selection)
            normal[np.ix_(outer, outer)] += w * self.gram[c][np.ix_(inner, inner)]
            right[outer] += w * self.moment[c][inner, target]
        return normal, right, float(np.asarray(weights, dtype=float) @ self.power[:, target])

    def solve(self, selection: Sequence[int], weights: NDArray[np.float64]) -> tuple[NDArray[np.float64], float]:
        """``(θ, weighted RSS)`` on ``selection``, fitted to the prepared channels (as
        :func:`estimation.estimators.separable_least_squares.solve_linear`); raises ``LinAlgError`` when rank-deficient."""
        normal, right, power = self.normal_system(selection, weights)
        theta = solve_normal(normal, right)
        return theta, max(float(power - 2 * theta @ right + theta @ normal @ theta), 0.0)

    def channel_rss(self, selection: Sequence[int], theta: NDArray[np.float64], target: int = 1) -> NDArray[np.float64]:
        """``‖y_c − X_c[S] θ‖²`` per channel (default against the channels as recorded)."""
        theta = np.asarray(theta, dtype=float)
        values = np.empty(self.layout.n_channels)
        for c in range(self.layout.n_channels):
            outer, inner = self._positions(c, selection)
            part = theta[outer]
            values[c] = (self.power[c, target] - 2 * part @ self.moment[c][inner, target]
                         + part @ self.gram[c][np.ix_(inner, inner)] @ part)
        return np.maximum(values, 0.0)

    def channel_mse(self, selection: Sequence[int], theta: NDArray[np.float64], target: int = 1) -> NDArray[np.float64]:
        if self.n_samples == 0:
            raise ValueError("no samples summed")
        return self.channel_rss(selection, theta, target) / self.n_samples


def chunk_sums(model: IdentificationModel, layout: ColumnLayout, blocks: Sequence[Block],
               shapes: Sequence[NDArray[np.float64]], chunk: Measurements, sums: ChannelSums) -> ChannelSums:
    """``sums`` plus one preprocessed chunk's: base regressor and every candidate's columns (at its
    fixed shape) on each channel, against the prepared channels and the channels as recorded; and the sums of the
    problem in the motion's band when the chunk has one (:func:`~estimation.estimators.identification_problem.in_band_blocks`:
    a chunk of the streamed path carries its window) and ``sums`` hold it or no samples."""
    Y = model.evaluate_base(chunk.q, chunk.dq, chunk.ddq)
    if not np.all(np.isfinite(Y)):
        raise ValueError("the regressor holds NaN or inf: check the measured q, dq, ddq")
    states = States(chunk.q, chunk.dq, chunk.ddq)
    columns = [block.evaluate(states, shape) for block, shape in zip(blocks, shapes)]
    prepared = chunk.channels(model.channels)
    recorded = chunk.as_recorded.channels(model.channels)
    if not (np.all(np.isfinite(prepared)) and np.all(np.isfinite(recorded))):
        raise ValueError("a measured channel holds NaN or inf")
    added = _added(layout, Y, columns, prepared, recorded, sums)
    in_band = in_band_blocks(chunk, chunk.n_samples)
    band = None
    if in_band is not None and (sums.band is not None or sums.n_samples == 0):
        band = ChannelSums.empty(layout) if sums.band is None else sums.band
        for piece, window, kept in in_band:
            window_states = States(window.q, window.dq, window.ddq)
            Y_band = piece.window(model.evaluate_base(window.q, window.dq, window.ddq))[kept]
            columns_band = [piece.window(block.evaluate(window_states, shape))[kept]
                            for block, shape in zip(blocks, shapes)]
            target = piece.window(window.channels(model.channels))[kept]
            band = _added(layout, Y_band, columns_band, target, target, band)
    return ChannelSums(layout, added.gram, added.moment, added.power, added.n_samples, band)


def _added(layout: ColumnLayout, Y: NDArray[np.float64], columns: Sequence[NDArray[np.float64]],
           prepared: NDArray[np.float64], recorded: NDArray[np.float64], sums: ChannelSums) -> ChannelSums:
    """``sums`` (their band aside) plus a block's: regressor ``Y``, candidate ``columns``, the two targets."""
    gram, moment = [], []
    for c in range(layout.n_channels):
        parts = [Y[:, c, :]] + [values[:, rows.index(c), :] for values, rows in zip(columns, layout.rows) if c in rows]
        X = np.concatenate(parts, axis=1)
        targets = np.column_stack([prepared[:, c], recorded[:, c]])
        gram.append(sums.gram[c] + X.T @ X)
        moment.append(sums.moment[c] + X.T @ targets)
    power = sums.power + np.stack([np.einsum("nm,nm->m", prepared, prepared), np.einsum("nm,nm->m", recorded, recorded)],
                                  axis=1)
    if not all(np.all(np.isfinite(g)) for g in gram):
        raise ValueError("a candidate's columns hold NaN or inf at its shape")
    return ChannelSums(layout, tuple(gram), tuple(moment), power, sums.n_samples + Y.shape[0])


def _factor(augmented: NDArray[np.float64]) -> NDArray[np.float64]:
    """An upper-triangular ``R`` with ``RᵀR`` = the (semi-definite) ``augmented`` Gram matrix: the
    R of its symmetric square root (exact for a singular Gram, where Cholesky fails)."""
    values, vectors = np.linalg.eigh(0.5 * (augmented + augmented.T))
    root = np.sqrt(np.clip(values, 0.0, None))[:, None] * vectors.T
    return np.triu(scipy.linalg.qr(root, mode="r", check_finite=False)[0])


def normal_equations(sums: ChannelSums, selection: Sequence[int], names: Sequence[str],
                     expressions: Sequence[str] = ()) -> NormalEquations:
    """The problem on ``selection`` (prepared channels) as :class:`NormalEquations`, for
    :class:`~estimation.estimators.summed_least_squares.SummedLeastSquares` (the streamed identify's estimator):
    per-channel Gram matrices scattered on the selected columns, and factors of the augmented Gram."""
    m, k = sums.layout.n_channels, len(selection)
    gram, moment, factor = np.zeros((m, k, k)), np.zeros((m, k)), np.zeros((m, k + 1, k + 1))
    for c in range(m):
        outer, inner = sums._positions(c, selection)
        gram[c][np.ix_(outer, outer)] = sums.gram[c][np.ix_(inner, inner)]
        moment[c][outer] = sums.moment[c][inner, 0]
        augmented = np.zeros((k + 1, k + 1))
        augmented[:k, :k], augmented[:k, k], augmented[k, :k], augmented[k, k] = gram[c], moment[c], moment[c], sums.power[c, 0]
        factor[c] = _factor(augmented)
    return NormalEquations(gram, moment, sums.power[:, 0].copy(), factor, sums.n_samples, sums.layout.channels,
                           tuple(names), tuple(expressions),
                           band=None if sums.band is None else normal_equations(sums.band, selection, names, expressions))


class EvenSubsample:
    """At most ``2 cap`` samples spread evenly over a stream of chunks of unknown total length:
    every ``stride``-th sample is kept, and when ``2 cap`` are held every other one is dropped and
    the stride doubled (deterministic; at the end between ``cap`` and ``2 cap`` samples, or all)."""

    def __init__(self, cap: int) -> None:
        if cap < 1:
            raise ValueError(f"the subsample needs at least one sample, got {cap}")
        self.cap = int(cap)
        self.stride = 1
        self.seen = 0
        self.parts: list[Measurements] = []
        self.indices: list[NDArray[np.int64]] = []

    def add(self, chunk: Measurements) -> None:
        index = np.arange(self.seen, self.seen + chunk.n_samples)
        self.seen += chunk.n_samples
        keep = index % self.stride == 0
        if np.any(keep):
            self.parts.append(chunk.select(np.flatnonzero(keep)))
            self.indices.append(index[keep])
        while sum(part.n_samples for part in self.parts) > 2 * self.cap:
            self.stride *= 2
            parts, indices = [], []
            for part, where in zip(self.parts, self.indices):
                keep = where % self.stride == 0
                if np.any(keep):
                    parts.append(part.select(np.flatnonzero(keep)))
                    indices.append(where[keep])
            self.parts, self.indices = parts, indices

    def measurements(self) -> Measurements:
        return concatenate(self.parts)


def concatenate(parts: Sequence[Measurements]) -> Measurements:
    """Samples of several chunks (or files) as one :class:`Measurements`, the recorded channels too."""
    if len(parts) == 1:
        return parts[0]

    def join(items, name):
        values = [getattr(item, name) for item in items]
        return None if values[0] is None else np.concatenate(values)

    recorded = None
    if all(part.recorded is not None for part in parts):
        recorded = concatenate([part.recorded for part in parts])
    return Measurements(join(parts, "t"), join(parts, "q"), join(parts, "dq"), join(parts, "ddq"), join(parts, "tau"),
                        join(parts, "wrench"), dict(parts[0].metadata), recorded)
