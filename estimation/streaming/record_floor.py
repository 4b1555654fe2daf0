"""The noise floor of a record read in blocks, memory's to the last digits: exact order statistics in a few passes.

The in-memory floor of a record (:meth:`estimation.identification.identified_model.IdentifiedModel.floor`) is each
segment's :func:`~estimation.uncertainty.noise_floor.noise_floor` as recorded, pooled over the segments
(:func:`~estimation.uncertainty.noise_floor.pooled_floor`). Its difference estimator is no sum: it takes the median
of each channel's ``d``-th differences, then the median of their absolute deviations from it (the MAD), then a
whiteness check on the differences within five scaled MADs of the median. Here each median is found exactly by
selection over passes of the file (:func:`order_statistics`: the values gathered when they fit in
``capacity`` rows, else a histogram of the interval known to hold the rank, narrowed pass by pass to the values of
one bin until they fit; at most a few passes on any record), the differences made block by block with the last
``d`` rows carried over (each difference the same floating-point operations as ``numpy.diff`` of the whole), and
the whiteness check's sums gathered in one more pass. The variance, degrees of freedom and refusals are then the
in-memory estimator's own (:func:`~estimation.uncertainty.noise_floor.difference_scale`,
:func:`~estimation.uncertainty.noise_floor.difference_dof`, :func:`~estimation.uncertainty.noise_floor.check_white`):
the same floor, its lag-1 correlation to rounding (its sums taken in another order).

A periodic record (the Fourier path's model, its frequency known) takes the period-to-period or the Fourier-residual
estimate in memory; :func:`periodic_floor` reads such a segment whole when it fits in ``capacity`` rows (memory's own
call on it), else by passes: the stamps' median step by selection, then on a regular grid of a whole number of
samples a period each phase's mean and squared deviations summed period after period, as ``numpy.var`` sums the
folded periods (the same bits), or the Fourier residual with its normal equations summed chunk by chunk (each
chunk's chirp or block sums from the segment's mean stamp, memory's solver; the same floor to rounding, 1e-12).
"""

from __future__ import annotations

import warnings
from collections.abc import Callable, Iterable, Iterator, Sequence
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from dynamics.measurements import Measurements
from dynamics.models import IdentificationModel
from estimation.identification.subtracted_load import SubtractedLoad
from estimation.preprocessing.fourier_series import gram_solution
from estimation.preprocessing.fourier_sums import (BLOCK_ROWS, GRID_TOLERANCE, BlockFourierSums,
                                                    UniformFourierSums, fractional_turns)
from estimation.streaming.chunks import FileScans, logged_chunks
from estimation.streaming.diagnosis_sums import concatenate
from estimation.uncertainty.noise_floor import (DIFFERENCE_ORDER, MAX_HARMONICS, NoiseFloor, NoiseFloorError,
                                                check_difference_count, check_white, difference_dof, difference_scale,
                                                drift_free, kept_deviation, noise_floor, period_step_sums,
                                                pooled_floor)

__all__ = ["FLOOR_CAPACITY", "difference_floor", "order_statistics", "periodic_floor", "record_floor",
           "segment_floors"]

#: most rows of a channel block gathered at once by the selection (and a periodic segment read whole): 2^18 rows,
#: 2 MB a channel
FLOOR_CAPACITY = 1 << 18
#: bins of each pass's histogram when the values do not fit
BINS = 4096


def order_statistics(passes: Callable[[], Iterable[NDArray[np.float64]]], ranks: Sequence[int], *,
                     capacity: int = FLOOR_CAPACITY, bins: int = BINS) -> NDArray[np.float64]:
    """The values of rank ``ranks`` (0 the smallest) of each column of the blocks ``passes()`` yields (each call a
    new pass over the same ``(n, m)`` blocks, in any order), exactly: ``(len(ranks), m)``.

    First pass: the blocks gathered while they hold at most ``capacity`` rows (then ``numpy.partition``), each
    column's least and largest value. Then, for each rank and column not found, the interval ``[lo, hi]`` known to
    hold it and the count below it: a pass histograms the values inside into ``bins`` bins (each bin's count, least
    and largest value; a bin's values are contiguous in sorted order, the index being monotone in the value) and
    gathers them while they fit; the rank is then selected among those gathered, or the interval narrowed to its
    bin's least and largest values. The bin holding the rank never holds every value inside (the least falls in the
    first bin, the largest in the last), so each pass excludes some, and an interval of one value ends it.
    """
    ranks = [int(rank) for rank in ranks]
    gathered: list[NDArray[np.float64]] | None = []
    rows, low, high = 0, None, None
    for block in passes():
        block = np.asarray(block, dtype=float)
        if block.shape[0] == 0:
            continue
        low = block.min(axis=0) if low is None else np.minimum(low, block.min(axis=0))
        high = block.max(axis=0) if high is None else np.maximum(high, block.max(axis=0))
        rows += block.shape[0]
        if gathered is not None:
            gathered.append(np.array(block))
            if rows > capacity:
                gathered = None
    if low is None or high is None:
        raise ValueError("no values to select from")
    if any(rank < 0 or rank >= rows for rank in ranks):
        raise ValueError(f"ranks {ranks} outside the {rows} values")
    if gathered is not None:
        values = np.concatenate(gathered)
        return np.array([np.partition(values, rank, axis=0)[rank] for rank in ranks])
    m = low.shape[0]
    found = np.full((len(ranks), m), np.nan)
    state = {(index, column): [float(low[column]), float(high[column]), 0]
             for index in range(len(ranks)) for column in range(m)}
    while state:
        for key, (lo, hi, _) in list(state.items()):
            if lo == hi:
                found[key] = lo
                del state[key]
        if not state:
            break
        counts = {key: np.zeros(bins, dtype=np.int64) for key in state}
        least = {key: np.full(bins, np.inf) for key in state}
        largest = {key: np.full(bins, -np.inf) for key in state}
        inside: dict[tuple[int, int], list[NDArray[np.float64]] | None] = {key: [] for key in state}
        sizes = dict.fromkeys(state, 0)
        for block in passes():
            block = np.asarray(block, dtype=float)
            for key, (lo, hi, _) in state.items():
                column = block[:, key[1]]
                values = column[(column >= lo) & (column <= hi)]
                if values.shape[0] == 0:
                    continue
                index = np.minimum(((values - lo) / (hi - lo) * bins).astype(np.int64), bins - 1)
                counts[key] += np.bincount(index, minlength=bins)
                np.minimum.at(least[key], index, values)
                np.maximum.at(largest[key], index, values)
                sizes[key] += values.shape[0]
                kept = inside[key]
                if kept is not None:
                    kept.append(values)
                    if sizes[key] > capacity:
                        inside[key] = None
        for key in list(state):
            lo, hi, below = state[key]
            rank = ranks[key[0]] - below
            kept = inside[key]
            if kept is not None:
                found[key] = np.partition(np.concatenate(kept), rank)[rank]
                del state[key]
                continue
            cumulative = np.cumsum(counts[key])
            bin_ = int(np.searchsorted(cumulative, rank, side="right"))
            state[key] = [float(least[key][bin_]), float(largest[key][bin_]),
                          below + (int(cumulative[bin_ - 1]) if bin_ else 0)]
    return found


def _medians(passes: Callable[[], Iterable[NDArray[np.float64]]], count: int, *,
             capacity: int) -> NDArray[np.float64]:
    """Each column's median of ``count`` values, as ``numpy.median`` gives it (the middle value, or the mean of the
    two middle ones)."""
    middle = [count // 2] if count % 2 else [count // 2 - 1, count // 2]
    chosen = order_statistics(passes, middle, capacity=capacity)
    return np.mean(chosen, axis=0)


def _differences(blocks: Callable[[], Iterable[NDArray[np.float64]]], order: int
                 ) -> Callable[[], Iterator[NDArray[np.float64]]]:
    """A pass over the ``order``-th differences of the rows ``blocks()`` yields in order, the last ``order`` rows of
    each block carried to the next (the same operations as ``numpy.diff`` of the whole)."""
    def differences() -> Iterator[NDArray[np.float64]]:
        carried = None
        for block in blocks():
            rows = block if carried is None else np.concatenate([carried, block])
            if rows.shape[0] > order:
                yield np.diff(rows, n=order, axis=0)
            carried = rows[-order:]
    return differences


def difference_floor(blocks: Callable[[], Iterable[NDArray[np.float64]]], channels: Sequence[str], *,
                     order: int = DIFFERENCE_ORDER, capacity: int = FLOOR_CAPACITY) -> NoiseFloor:
    """:func:`~estimation.uncertainty.noise_floor.noise_floor`'s difference estimate of the channels whose rows
    ``blocks()`` yields in order (each call a new pass over one segment as recorded), by passes (module docstring).
    A channel's masked samples (NaN, :mod:`estimation.data.channel_mask`) leave out the differences that reach them,
    as memory's :func:`~estimation.uncertainty.noise_floor.difference_variance`: each channel's scale from its own
    valid differences, the degrees of freedom those of the channel with the fewest.

    Raises
    ------
    NoiseFloorError
        As memory: too few samples, a value not finite, a channel whose differences are not those of white noise.
    """
    channels = tuple(channels)
    rows, nonzero, masked = 0, np.zeros(len(channels), dtype=bool), False
    for block in blocks():
        if np.any(np.isinf(block)):
            raise NoiseFloorError("the channels hold NaN or inf: no noise floor")
        masked = masked or bool(np.isnan(np.sum(block)))
        rows += block.shape[0]
        nonzero |= np.any(block != 0, axis=0)
    order = check_difference_count(rows, order)
    differences = _differences(blocks, order)
    count = rows - order
    if not masked:
        deviation = _difference_deviation(differences, count, channels, nonzero, capacity, order)
        return NoiseFloor(channels, difference_scale(deviation, order), "differences", difference_dof(count, order),
                          rows, {"order": order})
    counts = np.zeros(len(channels), dtype=np.int64)
    for block in differences():
        counts += np.sum(~np.isnan(block), axis=0)
    if np.any(counts < 10):
        raise NoiseFloorError(f"{int(counts.min())} differences of a channel reach no masked sample: too few "
                              "for a difference estimate of the noise")
    deviation = np.empty(len(channels))
    for column, name in enumerate(channels):
        def valid(column: int = column) -> Iterator[NDArray[np.float64]]:
            for block in differences():
                values = block[:, column:column + 1]
                yield values[~np.isnan(values[:, 0])]
        deviation[column] = _difference_deviation(valid, int(counts[column]), (name,), nonzero[column:column + 1],
                                                  capacity, order)[0]
    return NoiseFloor(channels, difference_scale(deviation, order), "differences",
                      difference_dof(int(counts.min()), order), rows, {"order": order})


def _difference_deviation(differences: Callable[[], Iterator[NDArray[np.float64]]], count: int,
                          channels: tuple[str, ...], nonzero: NDArray[np.bool_], capacity: int, order: int
                          ) -> NDArray[np.float64]:
    """Each column's median absolute deviation of the ``count`` differences ``differences()`` yields, its whiteness
    checked on the differences within five scaled MADs of the median (:func:`difference_floor`)."""
    median = _medians(differences, count, capacity=capacity)

    def deviations() -> Iterator[NDArray[np.float64]]:
        for block in differences():
            yield np.abs(block - median)

    deviation = _medians(deviations, count, capacity=capacity)
    # the whiteness check's sums over the differences kept (within five scaled MADs of the median), in their order
    reach = np.array([kept_deviation(value) for value in deviation])
    kept_count = np.zeros(len(channels), dtype=np.int64)
    total, squares, products = (np.zeros(len(channels)) for _ in range(3))
    first, last = np.full(len(channels), np.nan), np.full(len(channels), np.nan)
    for block in differences():
        for column in range(len(channels)):
            kept = block[np.abs(block[:, column] - median[column]) <= reach[column], column]
            if kept.shape[0] == 0:
                continue
            if kept_count[column] == 0:
                first[column] = kept[0]
            else:
                products[column] += last[column] * kept[0]
            products[column] += float(kept[1:] @ kept[:-1])
            total[column] += kept.sum()
            squares[column] += float(kept @ kept)
            kept_count[column] += kept.shape[0]
            last[column] = kept[-1]
    for column, name in enumerate(channels):
        if not nonzero[column]:  # a channel of zeros (a passive joint's torque): no noise, floor 0
            continue
        n = int(kept_count[column])
        mean = total[column] / n
        energy = squares[column] - n * mean ** 2
        lagged = products[column] - mean * (2 * total[column] - first[column] - last[column]) + (n - 1) * mean ** 2
        check_white(lagged / energy if energy > 0 else 1.0, n, order, name)
    return deviation


def _logged(source: str | Path, model: IdentificationModel, chunk_size: int, load: SubtractedLoad | None = None
            ) -> Callable[[], Iterator[Measurements]]:
    """The source's samples as logged, read again at each call; the file scanned by the first call only (its scan
    handed to the later ones, :class:`~estimation.streaming.chunks.FileScans`)."""
    scans = FileScans()

    def chunks() -> Iterator[Measurements]:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # said when the source was read for its errors
            yield from logged_chunks(source, model, chunk_size=chunk_size, load=load, scans=scans)
    return chunks


def _channel_blocks(chunks: Callable[[], Iterator[Measurements]], channels: Sequence[str]
                    ) -> Callable[[], Iterator[NDArray[np.float64]]]:
    def blocks() -> Iterator[NDArray[np.float64]]:
        for chunk in chunks():
            yield chunk.channels(channels)
    return blocks


def segment_floors(sources: Sequence[str | Path], model: IdentificationModel, *, chunk_size: int,
                   frequency_hz: float | None = None, capacity: int = FLOOR_CAPACITY,
                   load: SubtractedLoad | None = None) -> tuple[list[NoiseFloor], list[str]]:
    """Each segment's noise floor as memory's :func:`~estimation.uncertainty.noise_floor.noise_floor` of it as
    recorded (the streamed reader's samples as logged, every row), and ``"source: why"`` for each that gives none.
    ``frequency_hz``: the periodic estimates (module docstring); ``load``: a load the logged torques lack, added back
    at the logged positions (:func:`~estimation.streaming.chunks.loaded_chunk`), as memory's floor of the records
    with the load added back takes them."""
    floors, failures = [], []
    for source in sources:
        chunks = _logged(source, model, chunk_size, load)
        try:
            if frequency_hz is not None:
                floors.append(periodic_floor(chunks, model.channels, frequency_hz, capacity=capacity))
            else:
                floors.append(difference_floor(_channel_blocks(chunks, model.channels), model.channels,
                                               capacity=capacity))
        except NoiseFloorError as error:
            failures.append(f"{source}: {error}")
    return floors, failures


def record_floor(sources: Sequence[str | Path], model: IdentificationModel, *, chunk_size: int,
                 frequency_hz: float | None = None, capacity: int = FLOOR_CAPACITY) -> dict[str, float] | None:
    """The noise floor per channel of the record whose segments are ``sources`` (the streamed reader's, each as
    recorded: a resampled one's logged samples), pooled over them as memory pools its segments; ``None`` when no
    segment gives one. A segment that gives none is said in a warning naming it, as memory says it.
    ``frequency_hz``: the Fourier path's fundamental (the periodic estimates, module docstring)."""
    floors, failures = segment_floors(sources, model, chunk_size=chunk_size, frequency_hz=frequency_hz,
                                      capacity=capacity)
    for failure in failures:
        warnings.warn(f"no noise floor from {failure}", stacklevel=2)
    pooled = pooled_floor(floors)
    return None if pooled is None else dict(pooled.mse())


def periodic_floor(chunks: Callable[[], Iterator[Measurements]], channels: Sequence[str], frequency_hz: float, *,
                   capacity: int = FLOOR_CAPACITY) -> NoiseFloor:
    """Memory's :func:`~estimation.uncertainty.noise_floor.noise_floor` at ``frequency_hz`` of the segment whose
    samples ``chunks()`` yields in order (each call a new pass): read whole when it holds at most ``capacity`` rows
    (memory's own call), else by passes. The median step of the stamps by selection (:func:`order_statistics`); on
    a regular grid of a whole number of samples a period, the period-to-period variance from each phase's sums,
    added period by period in memory's order (the same bits); else the Fourier residual, its normal equations summed
    chunk by chunk (:func:`~estimation.preprocessing.fourier_sums.fourier_sums` of each chunk's stamps from the
    segment's mean stamp: the same sums to rounding) and solved as memory solves them; fewer than two periods: the
    differences, as memory."""
    channels = tuple(channels)
    frequency_hz = float(frequency_hz)
    if not (np.isfinite(frequency_hz) and frequency_hz > 0):
        raise ValueError(f"frequency_hz must be positive, got {frequency_hz}")
    parts, rows = [], 0
    for chunk in chunks():
        rows += chunk.n_samples
        if parts is not None:
            parts.append(chunk)
            if rows > capacity:
                parts = None
    if rows == 0:
        raise NoiseFloorError("no samples")
    if parts is not None:
        return noise_floor(concatenate(parts), channels, frequency_hz=frequency_hz)
    return _periodic_by_passes(chunks, channels, frequency_hz, rows, capacity)


def _stamps(chunks: Callable[[], Iterator[Measurements]]) -> Callable[[], Iterator[NDArray[np.float64]]]:
    def stamps() -> Iterator[NDArray[np.float64]]:
        for chunk in chunks():
            yield chunk.t[:, None]
    return stamps


def _periodic_by_passes(chunks: Callable[[], Iterator[Measurements]], channels: tuple[str, ...],
                        frequency_hz: float, rows: int, capacity: int) -> NoiseFloor:
    """:func:`periodic_floor` of a segment over ``capacity`` rows."""
    steps = _differences(_stamps(chunks), 1)
    step = float(_medians(steps, rows - 1, capacity=capacity)[0])
    first = last = None
    largest = 0.0
    for block in steps():
        largest = max(largest, float(np.max(np.abs(block[:, 0] - step))))
    for chunk in chunks():
        first = chunk.t[0] if first is None else first
        last = chunk.t[-1]
    per_period = 1.0 / (frequency_hz * step)
    periods = (last - first + step) * frequency_hz
    if periods < 2 - 1e-9:  # memory's differences
        return difference_floor(_channel_blocks(chunks, channels), channels, capacity=capacity)
    whole = int(round(per_period))
    if largest <= 1e-6 * step and abs(per_period - whole) <= 1e-6 * per_period:
        variance, dof = _period_variance(_channel_blocks(chunks, channels), whole, rows)
        details = {"frequency_hz": frequency_hz, "samples_per_period": whole, "periods": rows // whole}
        if whole >= 10 * (DIFFERENCE_ORDER + 1):  # what drifts between the periods taken out, as memory does
            variance, dof, changed = drift_free(variance, dof, _period_step_sums(_channel_blocks(chunks, channels),
                                                                                 whole, rows), channels)
            if changed:
                details["drift"] = changed
        return NoiseFloor(channels, variance, "periods", dof, rows, details)
    variance, dof, harmonics = _fourier_residual_variance(chunks, channels, frequency_hz, rows, step)
    details = {"frequency_hz": frequency_hz, "samples_per_period": per_period, "periods": periods,
               "harmonics": harmonics}
    if harmonics == MAX_HARMONICS:
        details["note"] = (f"harmonics capped at {MAX_HARMONICS}: periodic content above "
                           f"{MAX_HARMONICS * frequency_hz:g} Hz counts as noise (floor too high)")
    return NoiseFloor(channels, variance, "fourier", dof, rows, details)


def _whole_periods(blocks: Callable[[], Iterable[NDArray[np.float64]]], samples_per_period: int, periods: int
                   ) -> Iterator[NDArray[np.float64]]:
    """The rows of ``blocks()`` period by period, ``(samples_per_period, m)`` each, the first ``periods`` only (the
    tail after the last whole period dropped, as memory drops it)."""
    pending: list[NDArray[np.float64]] = []
    held, done = 0, 0
    for block in blocks():
        pending.append(block)
        held += block.shape[0]
        if held < samples_per_period:
            continue
        rows = np.concatenate(pending)
        start = 0
        while rows.shape[0] - start >= samples_per_period and done < periods:
            yield rows[start:start + samples_per_period]
            start += samples_per_period
            done += 1
        if done == periods:
            return
        pending, held = [rows[start:]], rows.shape[0] - start


def _period_variance(blocks: Callable[[], Iterable[NDArray[np.float64]]], samples_per_period: int, rows: int
                     ) -> tuple[NDArray[np.float64], float]:
    """:func:`~estimation.uncertainty.noise_floor.period_variance` by two passes: each phase's mean, then each
    phase's squared deviations, summed period after period as ``numpy.var`` sums the folded periods (axis 0 of
    ``(periods, P, m)``, one period at a time), so the same bits."""
    P = int(samples_per_period)
    periods = rows // P
    if periods < 2:
        raise NoiseFloorError(f"{rows} samples hold {periods} whole period(s) of {P} samples: the "
                              "period-to-period variance needs at least two")
    total = None
    for period in _whole_periods(blocks, P, periods):
        total = np.array(period) if total is None else total + period
    mean = total / periods
    squares = None
    for period in _whole_periods(blocks, P, periods):
        deviation = period - mean
        deviation = deviation * deviation
        squares = deviation if squares is None else squares + deviation
    return np.mean(squares / (periods - 1), axis=0), float(P * (periods - 1))


def _period_step_sums(blocks: Callable[[], Iterable[NDArray[np.float64]]], samples_per_period: int, rows: int
                      ) -> tuple[NDArray[np.float64], ...]:
    """:func:`~estimation.uncertainty.noise_floor.period_step_sums` of each pair of consecutive whole periods, added
    in memory's order (one pass, two periods held)."""
    periods = rows // int(samples_per_period)
    previous, sums = None, None
    for period in _whole_periods(blocks, int(samples_per_period), periods):
        if previous is not None:
            step = period_step_sums(previous, period)
            sums = step if sums is None else tuple(total + part for total, part in zip(sums, step))
        previous = np.array(period)
    return sums


#: numpy's pairwise summation: blocks of at most this many values summed by its unrolled loop (numpy's
#: ``PW_BLOCKSIZE``), larger ones split in two halves (the first a multiple of 8)
PAIRWISE_BLOCK = 128


def _pairwise_leaves(start: int, count: int) -> Iterator[tuple[int, int]]:
    """The blocks ``(start, count)`` numpy's pairwise summation of ``count`` contiguous values adds by its loop, in
    order (``numpy/_core/src/umath/loops_utils.h.src``, ``pairwise_sum``)."""
    if count <= PAIRWISE_BLOCK:
        yield start, count
        return
    half = count // 2
    half -= half % 8
    yield from _pairwise_leaves(start, half)
    yield from _pairwise_leaves(start + half, count - half)


def _pairwise_total(leaves: dict[int, float], start: int, count: int) -> float:
    """``numpy.sum`` of ``count`` values from ``start`` from the sums of its blocks (:func:`_pairwise_leaves`)."""
    if count <= PAIRWISE_BLOCK:
        return leaves[start]
    half = count // 2
    half -= half % 8
    return _pairwise_total(leaves, start, half) + _pairwise_total(leaves, start + half, count - half)


def _stamp_mean(chunks: Callable[[], Iterator[Measurements]], rows: int,
                         bounds: list[tuple[int, int]]) -> float:
    """``numpy.mean`` of the stamps of every row, the same bits: numpy's pairwise blocks ``bounds``
    (:func:`_pairwise_leaves`) summed as they come, then combined as numpy combines them."""
    leaves: dict[int, float] = {}
    carried, first_row, index = np.empty(0), 0, 0  # carried: stamps from row first_row not yet summed
    for chunk in chunks():
        carried = np.concatenate([carried, chunk.t])
        while index < len(bounds) and bounds[index][0] + bounds[index][1] <= first_row + carried.shape[0]:
            start, count = bounds[index]
            leaves[start] = float(np.add.reduce(carried[start - first_row:start - first_row + count]))
            index += 1
        if index < len(bounds):
            cut = bounds[index][0] - first_row
            carried, first_row = carried[cut:], bounds[index][0]
    return _pairwise_total(leaves, 0, rows) / rows


def _sequential_sum(total: NDArray[np.float64] | None, block: NDArray[np.float64]) -> NDArray[np.float64]:
    """``total`` plus the rows of ``block`` added one after the other, as ``numpy.sum(axis=0)`` adds the rows of a
    C-ordered array (the same bits as the sum of the whole)."""
    if total is None:
        return np.sum(block, axis=0)
    return np.sum(np.vstack([total[None, :], block]), axis=0)


def _fourier_residual_variance(chunks: Callable[[], Iterator[Measurements]], channels: tuple[str, ...],
                               frequency_hz: float, rows: int, step: float
                               ) -> tuple[NDArray[np.float64], float, int]:
    """:func:`~estimation.uncertainty.noise_floor.fourier_residual_variance` by passes: the stamps' mean (numpy's
    pairwise sum, the same bits) and the channels' root mean square; then the normal equations and the residual sum
    of squares. Stamps off a regular grid: the design's blocks of
    :data:`~estimation.preprocessing.fourier_sums.BLOCK_ROWS` rows from the segment's first, as memory's
    :class:`~estimation.preprocessing.fourier_sums.BlockFourierSums` forms them (the same bits); on a grid, each
    chunk's chirp sums on memory's grid (its first stamp and step from the segment's ends), the same sums to
    rounding."""
    nyquist_harmonic = int(np.ceil(0.5 / (step * frequency_hz))) - 1
    H = min(nyquist_harmonic, MAX_HARMONICS)
    dof = rows - 2 * H - 1
    if H < 1 or dof < 1:
        raise NoiseFloorError(f"{rows} samples leave no degrees of freedom for {H} harmonics")
    origin = _stamp_mean(chunks, rows, list(_pairwise_leaves(0, rows)))
    power, first, last = None, None, None
    for chunk in chunks():
        power = _sequential_sum(power, chunk.channels(channels) ** 2)
        first = chunk.t[0] if first is None else first
        last = chunk.t[-1]
    scale = np.sqrt(power / rows) + np.finfo(float).tiny
    grid_step = (last - first) / (rows - 1)
    on_grid = grid_step > 0
    row = 0
    for chunk in chunks():  # memory's UniformFourierSums.of on the whole segment
        grid = first + grid_step * np.arange(row, row + chunk.n_samples)
        on_grid = on_grid and not np.max(np.abs(chunk.t - grid)) > GRID_TOLERANCE * grid_step
        row += chunk.n_samples
    parts = (_grid_parts(chunks, channels, frequency_hz, H, origin, first, grid_step) if on_grid else
             _block_parts(chunks, channels, frequency_hz, H, origin))
    normal, moment = None, None
    for sums, values in parts():
        part = sums.normal_equations(values / scale)
        normal, moment = part if normal is None else (normal + part[0], moment + part[1])
    coefficients = gram_solution(normal, moment)
    if coefficients is None:
        coefficients = np.linalg.lstsq(normal, moment, rcond=None)[0]
    rss = None
    for sums, values in parts():
        rss = _sequential_sum(rss, (values / scale - sums.fitted(coefficients)) ** 2)
    return rss / dof * scale**2, float(dof), H


def _block_parts(chunks: Callable[[], Iterator[Measurements]], channels: tuple[str, ...], frequency_hz: float,
                 harmonics: int, origin: float
                 ) -> Callable[[], Iterator[tuple[BlockFourierSums, NDArray[np.float64]]]]:
    """A pass over the segment in blocks of :data:`BLOCK_ROWS` rows from its first (the last one shorter), each with
    its design's sums (memory's blocks)."""
    def parts() -> Iterator[tuple[BlockFourierSums, NDArray[np.float64]]]:
        t_held: list[NDArray[np.float64]] = []
        values_held: list[NDArray[np.float64]] = []
        held = 0
        for chunk in chunks():
            t_held.append(chunk.t)
            values_held.append(chunk.channels(channels))
            held += chunk.n_samples
            if held < BLOCK_ROWS:
                continue
            t, values = np.concatenate(t_held), np.concatenate(values_held)
            whole = (held // BLOCK_ROWS) * BLOCK_ROWS
            for start in range(0, whole, BLOCK_ROWS):
                rows = slice(start, start + BLOCK_ROWS)
                yield BlockFourierSums(t[rows], frequency_hz, harmonics, origin), values[rows]
            t_held, values_held, held = [t[whole:]], [values[whole:]], held - whole
        if held:
            t, values = np.concatenate(t_held), np.concatenate(values_held)
            yield BlockFourierSums(t, frequency_hz, harmonics, origin), values
    return parts


def _grid_parts(chunks: Callable[[], Iterator[Measurements]], channels: tuple[str, ...], frequency_hz: float,
                harmonics: int, origin: float, first: float, step: float
                ) -> Callable[[], Iterator[tuple[UniformFourierSums, NDArray[np.float64]]]]:
    """A pass over the chunks, each with its chirp sums on memory's grid: its first sample's phase
    ``τ + r ν`` (``r`` its first row; the turns reduced exactly, :func:`fractional_turns`)."""
    start_turns = frequency_hz * (first - origin)
    per_sample = frequency_hz * step

    def parts() -> Iterator[tuple[UniformFourierSums, NDArray[np.float64]]]:
        row = 0
        for chunk in chunks():
            turns = (start_turns - np.floor(start_turns)) + float(fractional_turns(per_sample, np.array([row]))[0])
            yield (UniformFourierSums(turns - np.floor(turns), per_sample, chunk.n_samples, harmonics),
                   chunk.channels(channels))
            row += chunk.n_samples
    return parts
