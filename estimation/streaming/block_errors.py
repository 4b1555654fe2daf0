"""Per-block squared-error sums of the streamed validation pass: the blocks memory cuts, from sums.

The default answer of ``oed identify`` reports whether the validation record tells the best-scoring candidate from
the consistent one (:func:`estimation.consistent.model_selection.paired_difference`): the difference of their
scores and its batch-means standard error over
:data:`~estimation.identification.preprocessing_on_validation.BLOCKS` contiguous blocks of the validation samples,
cut as :func:`numpy.array_split` cuts the samples memory holds
(:func:`~estimation.identification.preprocessing_on_validation.block_mse`). The streamed path holds no samples, but
it knows how many the validation record has once its sums are made, so each block's rows are known before the next
pass reads them:

* :class:`BlockSquares` sums the squared residuals of each block as the rows pass, in their order (the filter
  path's pass against the channels as recorded, :func:`estimation.streaming.recorded_errors.counted_predicted_errors`);
* :func:`block_normal_equations` sums each block's normal equations (``Y_cᵀY_c``, ``Y_cᵀy_c``, ``y_cᵀy_c`` and the
  factors) once, where the sums hold the recording: any parameter vector's block errors are then
  ``‖y_c − Y_c θ‖² / n_b`` without another pass (:func:`block_channel_mse`).

Memory: ``BLOCKS`` vectors of the channels, or ``BLOCKS`` normal equations (``m (k+1)²`` floats each), whatever the
record's length.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray

from dynamics.models import IdentificationModel
from estimation.data.channel_mask import masked_cells, valid_sum
from estimation.estimators.normal_equations import NormalEquations
from estimation.identification.preprocessing_on_validation import BLOCKS

__all__ = ["BlockSquares", "block_bounds", "block_channel_mse", "block_normal_equations", "block_sizes"]


def block_sizes(n_samples: int, blocks: int = BLOCKS) -> NDArray[np.intp]:
    """The sizes of the ``blocks`` contiguous blocks :func:`numpy.array_split` cuts ``n_samples`` rows into (the
    first ``n_samples % blocks`` one row longer)."""
    if n_samples < 0 or blocks < 1:
        raise ValueError(f"cannot cut {n_samples} samples into {blocks} blocks")
    size, extra = divmod(int(n_samples), int(blocks))
    return np.array([size + 1] * extra + [size] * (blocks - extra), dtype=np.intp)


def block_bounds(n_samples: int, blocks: int = BLOCKS) -> NDArray[np.intp]:
    """The row at which each block starts, and the end: ``(blocks + 1,)``."""
    return np.concatenate([[0], np.cumsum(block_sizes(n_samples, blocks))]).astype(np.intp)


def _pieces(bounds: NDArray[np.intp], start: int, rows: int) -> list[tuple[int, int, int]]:
    """``(block, first, stop)`` of the rows ``start .. start + rows`` (global) by block, ``first``/``stop`` local."""
    pieces = []
    for block in range(bounds.shape[0] - 1):
        low, high = max(bounds[block], start), min(bounds[block + 1], start + rows)
        if low < high:
            pieces.append((block, int(low - start), int(high - start)))
    return pieces


class BlockSquares:
    """The squared residuals of each channel summed over each block of a pass's rows, as they pass in order.

    ``n_samples``: the rows the pass will give (the validation sums' count); the blocks are those of
    :func:`block_sizes`. Rows past ``n_samples`` are counted, not summed: :meth:`block_mse` is then ``None``.
    """

    def __init__(self, n_samples: int, n_channels: int, blocks: int = BLOCKS) -> None:
        self.n_samples = int(n_samples)
        self.bounds = block_bounds(self.n_samples, blocks)
        self.squares = np.zeros((blocks, int(n_channels)))
        self.valid = np.zeros((blocks, int(n_channels)))  # each channel's valid samples per block
        self.count = 0
        self.spoiled = False

    def spoil(self) -> None:
        """Rows came out of their order: :meth:`block_mse` is ``None``."""
        self.spoiled = True

    def add(self, squares: NDArray[np.float64]) -> None:
        """The squared residuals ``(N, m)`` of the next ``N`` rows (NaN at a masked sample: left out of its
        channel's block, as memory's held-out blocks count each channel's valid samples)."""
        squares = np.asarray(squares, dtype=float)
        masked = masked_cells(squares)
        for block, first, stop in _pieces(self.bounds, self.count, squares.shape[0]):
            self.squares[block] += valid_sum(squares[first:stop], None if masked is None else masked[first:stop])
            self.valid[block] += stop - first if masked is None else np.sum(~masked[first:stop], axis=0)
        self.count += squares.shape[0]

    def block_mse(self, channels: Sequence[str]) -> dict[str, tuple[float, ...]] | None:
        """Per channel, each block's MSE; ``None`` when the pass gave another count of rows than announced or fewer
        rows than blocks (memory cuts no blocks then)."""
        sizes = np.diff(self.bounds)
        if self.spoiled or self.count != self.n_samples or np.any(sizes == 0):
            return None
        with np.errstate(invalid="ignore", divide="ignore"):
            mse = self.squares / self.valid
        return {channel: tuple(float(value) for value in mse[:, column]) for column, channel in enumerate(channels)}


def block_normal_equations(model: IdentificationModel, chunks: Any, n_samples: int, blocks: int = BLOCKS
                           ) -> list[NormalEquations] | None:
    """Each block's normal equations of ``model``'s base-parameter problem over the prepared ``chunks`` (an iterable
    of :class:`~dynamics.measurements.Measurements` with ``dq``, ``ddq``, in the order the sums took them), the
    blocks of ``n_samples`` rows (:func:`block_sizes`); ``None`` when the chunks hold another count of rows or fewer
    rows than blocks."""
    bounds = block_bounds(n_samples, blocks)
    if np.any(np.diff(bounds) == 0):
        return None
    sums = [NormalEquations.empty(model.channels, model.base.names, model.base.expressions) for _ in range(blocks)]
    count = 0
    for chunk in chunks:
        if chunk.n_samples == 0:
            continue
        Y = model.evaluate_base(chunk.q, chunk.dq, chunk.ddq)
        y = chunk.channels(model.channels)
        for block, first, stop in _pieces(bounds, count, chunk.n_samples):
            sums[block] = sums[block].add_block(Y[first:stop], y[first:stop])
        count += chunk.n_samples
    return sums if count == n_samples else None


def block_channel_mse(sums: Sequence[NormalEquations], theta: NDArray[np.float64]) -> dict[str, tuple[float, ...]]:
    """Per channel, the MSE of ``theta`` on each block of :func:`block_normal_equations` (from the factors)."""
    rss = np.array([part.channel_rss(theta) / part.samples for part in sums])  # (blocks, m): each channel's valid
    return {channel: tuple(float(value) for value in rss[:, column])
            for column, channel in enumerate(sums[0].channels)}

