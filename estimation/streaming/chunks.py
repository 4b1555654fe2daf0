"""Records read and preprocessed chunk by chunk into :class:`~estimation.estimators.normal_equations.NormalEquations`.

A CSV file is read ``chunk_size`` rows at a time (``pandas.read_csv(chunksize=…)``), a Parquet
file batch by batch (``pyarrow`` row groups). Each chunk passes the checks of
:func:`estimation.data.records.measurements_from_frame` (columns, finiteness, time, units), and the
time base must run on across chunk boundaries. Peak memory depends on the chunk, the margin and
the parameter count, not on the record's length.

Preprocessing at chunk boundaries:

* ``dq`` and ``ddq`` in the file (the KUKA runs): nothing to derive, the chunks are independent.
* Butterworth path (:class:`estimation.preprocessing.differentiation.ButterworthDifferentiation`, and the
  decimation filter): **overlapping windows**. Each chunk is preprocessed in a window reaching
  ``margin`` samples beyond it on both sides (less at the ends of the record, where the in-memory
  path sees the same ends), and only the chunk's own samples are kept. ``margin`` is where the
  impulse responses of the zero-phase filters have decayed below :data:`MARGIN_TOLERANCE` of their
  peak (the derivative filter's plus the decimation filter's, plus the two samples central
  differences reach): the kept samples then equal the whole-record ones to about that relative
  accuracy. Overlap was chosen over carrying filter states because ``sosfiltfilt`` runs backwards
  too: a state-carrying forward pass cannot give the backward pass's state at a chunk's end.
  The cut-off must be one number for the whole set: given, or chosen by the caller once
  (:func:`automatic_cutoff` on the first chunk of the first file).
* Fourier path (period averaging): needs whole periods of the whole record; refused here
  (:class:`StreamingUnsupportedError`).

A logger's defects are handled as the loader handles them, with the same warnings, said once for the file:
re-sent rows and a few rows stamped with the previous row's time dropped, stalls bridged, irregular sampling
(jitter) resampled onto the grid of the whole file's median step (:mod:`estimation.streaming.time_base`: one extra
pass over the file keeps column ``t`` and a mask of the rows kept). A hole longer than ``max_gap`` is a
:class:`~estimation.data.loading.HoleError` here (the in-memory path splits the record there).
"""

from __future__ import annotations

import functools
import itertools
import re
import warnings
from collections.abc import Iterator
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
import pandas as pd
import scipy.signal
from numpy.typing import NDArray

from dynamics.models import IdentificationModel
from dynamics.runtime.threads import single_threaded_blas
from dynamics.channels import WRENCH_CHANNELS
from estimation.data.compressed_logs import csv_input, data_suffix, packed_format, packer_named
from estimation.data.log_formats import LogSource, is_log_file
from estimation.data.long_blocks import long_blocks
from estimation.data.reversed_csv import ReversedReadError, reversed_csv_frames
from estimation.data.unstarted_edges import started_blocks
from estimation.data.memory_budget import count_rows
from estimation.data.log_cleaning import DEFAULT_MAX_GAP
from estimation.data.loading import (
    HoldWarning,
    MeasurementError,
    NewestFirstWarning,
    MeasurementWarning,
    TimeBaseError,
    TooFewSamplesError,
    column_floats,
    in_si_units,
    without_repeated_headers,
    written_newest_first,
)
from estimation.data.log_cleaning import HeldExtremes
from estimation.data.date_times import INTEGER_CELL, counted_time, integers_of_text, seconds_of_date_times
from estimation.data.records import (AngleTurns, csv_options, dropouts, csv_units, in_the_format, measurements_from_frame,
                                     said_clipped,
                                     said_unwrapped, unwrap_angles)
from estimation.data.sampling_clock import ClockSums, clock_instants, said_receive_times
from dynamics.measurements import Measurements, joint_columns
from estimation.estimators.identification_problem import BandWindow, ResidualBand, decay_length
from estimation.estimators.normal_equations import DEFAULT_CHUNK_SIZE, NormalEquations, accumulate, check_chunk_size
from estimation.identification.subtracted_load import SubtractedLoad, added_back
from estimation.identification.training_range import TrainingRange
from estimation.preprocessing.differentiation import ButterworthDifferentiation, compensate_hold, decimate
from estimation.streaming.time_base import (Part, RegularClock, Resampler, TimeScan, file_parts, file_segments,
                                            scan_time)

__all__ = [
    "CLOCK_SUFFIX", "POSITIONS_SUFFIX", "FileSums", "from_positions", "positions_source", "MARGIN_TOLERANCE", "clock_source", "StreamingUnsupportedError", "automatic_cutoff", "file_sums", "filter_margin",
    "CellMask", "FileScans", "MaskedCells", "cell_mask", "masked_cells", "loaded_chunk", "logged_chunks", "preprocessed_chunks", "read_chunks", "receive_times_evidence_of", "segment_sources", "source_file", "source_files", "source_rows",
    "source_step",
]

#: relative size of the impulse response at which the overlap margin ends
MARGIN_TOLERANCE = 1e-13

_GROUPS = ("q", "dq", "ddq", "tau", "wrench")


def _group_columns(group: str, n_joints: int) -> list[str]:
    return list(WRENCH_CHANNELS) if group == "wrench" else joint_columns(group, n_joints)


class StreamingUnsupportedError(MeasurementError):
    """The preprocessing asked for needs the whole record at once (run without chunks)."""


@dataclass(frozen=True)
class FileSums:
    """The sums of one file with what a reducer checks: rows read, samples summed, columns; and each joint's range
    on the samples summed (:class:`~estimation.identification.training_range.TrainingRange`, taken in the same pass)."""

    path: str
    sums: NormalEquations
    rows: int
    columns: tuple[str, ...]
    metadata: dict
    joint_range: TrainingRange | None = None

    @property
    def expected_samples(self) -> int:
        """Samples a complete pass sums: every row, one in ``decimation`` after decimation."""
        if "expected_samples" in self.metadata:  # period averaging: one period
            return int(self.metadata["expected_samples"])
        return -(-self.rows // int(self.metadata.get("decimation", 1)))


def _raw_frames(path: Path, chunk_size: int, model: IdentificationModel | None = None, *,
                say: bool = True) -> Iterator[pd.DataFrame]:
    """The file's rows as frames of ``chunk_size``; with ``model``, each frame's columns under the format's names as
    the in-memory reader names the whole table's (:func:`_in_the_format`; ``say``: its reading said)."""
    frames = _file_frames(path, chunk_size)
    if model is None:
        yield from frames
        return
    formatted = _in_the_format(frames, path, model, say, chunk_size)
    first = next(formatted, None)
    if first is not None and _newest_first(first):  # read from the file's end, oldest row first, as memory reverses it
        formatted.close()
        if say:
            warnings.warn(NewestFirstWarning(
                f"{path}: column t decreases on every row of its first block: a log written newest first, read from "
                "its end (oldest first); the rows named in other messages count from the oldest"), stacklevel=2)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # the reading said with the first block
            formatted = _in_the_format(_file_frames(path, chunk_size, reverse=True), path, model, say=False,
                                       chunk_size=chunk_size)
            yield from started_blocks(formatted, model.robot.n_joints, str(path), say=say,
                                      dropouts=functools.partial(dropouts, n_joints=model.robot.n_joints))
        return
    # the rows before every channel has reported and after one has stopped left out, as in memory
    yield from started_blocks(itertools.chain([] if first is None else [first], formatted), model.robot.n_joints,
                              str(path), say=say, dropouts=functools.partial(dropouts, n_joints=model.robot.n_joints))


def _newest_first(frame: pd.DataFrame) -> bool:
    """Whether a file's first block (in the format's columns) is a newest-first log's
    (:func:`estimation.data.loading.written_newest_first`)."""
    if "t" not in frame.columns:
        return False
    t = column_floats(frame["t"])
    return written_newest_first(t[np.isfinite(t)])


def _in_the_format(frames: Iterator[pd.DataFrame], path: Path, model: IdentificationModel,
                   say: bool = True, chunk_size: int = DEFAULT_CHUNK_SIZE) -> Iterator[pd.DataFrame]:
    """``frames`` read as :func:`estimation.data.records.in_the_format` reads the whole table: a controller's or
    driver's log (``actual_q_0``, ``q[0]``, ``measured_torque`` with arrays in cells…), ``rostopic echo -p`` of
    ``JointState`` messages, the time or the joints under other names, each block by the same rule (the same
    refusals: commanded, external or estimated torques never read as measured). The first block's reading is said
    (the in-memory reader's warning); a later block read with other columns is an error naming the in-memory
    route (never met on a log whose header and cells keep their meaning)."""
    columns = None
    frames = long_blocks(frames, model.robot.joint_names, str(path), chunk_size=chunk_size, say=say)  # a long
    # table put side by side
    for index, frame in enumerate(frames):
        with warnings.catch_warnings():
            if index or not say:
                warnings.simplefilter("ignore")  # said once, with the first block (of the scan)
            formatted = in_the_format(frame, path, model, streamed=True)
        if columns is None:
            columns = list(formatted.columns)
        elif list(formatted.columns) != columns:
            raise MeasurementError(f"{path}: its rows {index * len(frame) + 1}.. are read with other columns than "
                                   "the first ones (a log whose cells change their layout): read it in memory (drop "
                                   "the streaming options)")
        yield formatted


def _file_frames(path: Path, chunk_size: int, only_time: bool = False, reverse: bool = False
                 ) -> Iterator[pd.DataFrame]:
    """The file's rows as frames of ``chunk_size`` (with ``only_time``: column ``t`` alone, if any; ``reverse``: the
    last row first, :func:`estimation.data.reversed_csv.reversed_csv_frames`)."""
    suffix = packed_format(path)  # a CSV file packed whole: read as the file it packs, decompressed block by block
    if is_log_file(path) or isinstance(path, LogSource):
        raise MeasurementError(f"{path}: the streamed path (chunks, workers, a cluster) reads .csv and .parquet files; "
                               "a ROS bag, an .npz or .mat file or a column map is read in memory (drop the streaming "
                               "options)")
    if path.is_dir():
        raise MeasurementError(f"data file {path} is a folder")
    if suffix not in (".csv", ".parquet"):
        raise MeasurementError(f"unknown data format {path.suffix!r} for {path}: use .csv or .parquet (either "
                               "packed by gzip, bzip2, xz, zstd or in a one-file ZIP archive)" + packer_named(path))
    if not path.is_file():
        raise MeasurementError(f"data file not found: {path}")
    origin = None  # the first stamp of a time column of date-times (estimation.data.date_times)
    try:
        if suffix == ".csv":
            usecols = (lambda name: str(name).strip() == "t") if only_time else None
            factors = csv_units(path)  # a units row's other units turned into SI, as in memory
            options = {**csv_options(path), "usecols": usecols}
            for frame in _counted_frames(path, chunk_size, options, reverse):  # date-times as seconds since the
                frame, origin = seconds_of_date_times(in_si_units(without_repeated_headers(frame, str(path)),
                                                                  factors), str(path), origin)  # first stamp
                yield frame
        else:
            try:
                import pyarrow.parquet
            except ImportError:
                raise MeasurementError(f"{path}: reading Parquet needs pyarrow (pip install pyarrow)") from None
            if reverse:
                raise ReversedReadError(f"{path}: a log written newest first in a Parquet file: the streamed reader "
                                        "reads a newest-first log from the end of a plain CSV file; read it in memory "
                                        "(drop the streaming options)")
            # without pre-buffering and threads: the default read grew by ~120 MB over a 1 M-sample file
            parquet = pyarrow.parquet.ParquetFile(path, pre_buffer=False, buffer_size=1 << 20)
            columns = [name for name in parquet.schema_arrow.names if name.strip() == "t"] if only_time else None
            for batch in parquet.iter_batches(batch_size=chunk_size, columns=columns, use_threads=False):
                frame, origin = seconds_of_date_times(batch.to_pandas(), str(path), origin)
                yield frame
    except (ValueError, OSError, pd.errors.ParserError, UnicodeDecodeError) as error:
        if isinstance(error, MeasurementError):
            raise
        raise MeasurementError(f"cannot read {path}: {error}") from None
    except Exception as error:  # pyarrow's own errors (ArrowInvalid…) on a corrupt file
        if type(error).__module__.startswith("pyarrow"):
            raise MeasurementError(f"cannot read {path}: {error}") from None
        raise


def _csv_blocks(path: Path, chunk_size: int, options: dict, reverse: bool) -> Iterator[pd.DataFrame]:
    """The CSV file's rows as parsed by ``pandas.read_csv`` with ``options``, ``chunk_size`` rows a block (``reverse``:
    the last row first)."""
    if reverse:
        yield from reversed_csv_frames(path, chunk_size, options)
        return
    with csv_input(path) as source, pd.read_csv(source, chunksize=chunk_size, **options) as reader:
        yield from reader


def _counted_frames(path: Path, chunk_size: int, options: dict, reverse: bool) -> Iterator[pd.DataFrame]:
    """:func:`_csv_blocks`, a time column of integer counts (:func:`~estimation.data.date_times.counted_time` on the
    first block) read as text and each block's cells as integers exactly
    (:func:`~estimation.data.date_times.integers_of_text`): a later block with a blank cell is not rounded, as the
    in-memory reader reads such a column (the first block read again: integer counts only).

    Raises
    ------
    TimeBaseError
        A later block's cell of such a column not written as an integer (a decimal): the row named."""
    blocks = _csv_blocks(path, chunk_size, options, reverse)
    first = next(blocks, None)
    counted = None if first is None else counted_time(first)
    if counted is None:
        yield from itertools.chain([] if first is None else [first], blocks)
        return
    blocks.close()
    blocks = _csv_blocks(path, chunk_size, {**options, "dtype": {counted: str}}, reverse)
    for index, frame in enumerate(blocks):
        integers = integers_of_text(frame[counted])
        if integers is None and index == 0:  # written as floats (1.0): read as parsed, as in memory
            blocks.close()
            yield from _csv_blocks(path, chunk_size, options, reverse)
            return
        if integers is None:
            cells = frame[counted].astype("string").str.strip()
            bad = cells.notna() & (cells != "") & ~cells.str.fullmatch(INTEGER_CELL).fillna(False)
            row = int(frame.index[int(np.flatnonzero(bad.to_numpy(dtype=bool))[0])])
            raise TimeBaseError(f"{path}: column {counted} holds integer counts in its first rows and "
                                f"{cells[bad].iloc[0]!r}, not an integer, at row {row}: a time column written one way "
                                "throughout is read")
        yield frame.assign(**{counted: integers})


#: a streamed source naming one segment of a file split at its holes, as the loader names it, or one part of a
#: training file cut at its holes and holds (:class:`~estimation.streaming.time_base.Part`)
_SEGMENT = re.compile(r"^(?P<file>.*) \((?P<kind>segment|part) (?P<index>[0-9]+)\)$")


#: the end of a streamed source read on the regular clock its stamps jitter around (:func:`clock_source`)
CLOCK_SUFFIX = " (regular clock)"


def clock_source(path):
    """The streamed source of ``path`` (a file or a segment's source) read on the regular clock its stamps jitter
    around (a :class:`~estimation.streaming.time_base.RegularClock`): ``run.csv (regular clock)``,
    ``run.csv (segment 2) (regular clock)``; of the same type as ``path``."""
    return type(path)(f"{path}{CLOCK_SUFFIX}") if isinstance(path, Path) else f"{path}{CLOCK_SUFFIX}"


#: the end of a streamed source whose logged velocities are left unread: ``dq`` made from the positions, as the
#: in-memory plan's ``velocity_from_positions`` makes it (:func:`positions_source`)
POSITIONS_SUFFIX = " (velocity from positions)"


def positions_source(path):
    """The streamed source of ``path`` (a file, a segment's or a clock's source) whose logged ``dq`` is left unread
    (each chunk read without it, :func:`read_chunks`): the filter then derives ``dq`` from the positions, bit for bit
    as memory's ``ButterworthDifferentiation(logged_velocity=False)`` (whose output ignores the logged ``dq``);
    ``run.csv (velocity from positions)``; of the same type as ``path``."""
    return type(path)(f"{path}{POSITIONS_SUFFIX}") if isinstance(path, Path) else f"{path}{POSITIONS_SUFFIX}"


def from_positions(path: str | Path) -> bool:
    """Whether the streamed source ``path`` is read without its logged velocities (:func:`positions_source`)."""
    return not Path(path).exists() and str(path).endswith(POSITIONS_SUFFIX)


def source_file(path: str | Path) -> tuple[Path, int | Part | RegularClock | None]:
    """The file and segment (1-based; ``None``: the whole file) of a streamed source: ``run.csv (segment 2)`` (the
    name the loader gives the second segment of a file split at a hole longer than ``max_gap``,
    :func:`segment_sources`) is the second segment of ``run.csv``; ``run.csv (part 2)`` its second part between its
    holes and holds (a :class:`~estimation.streaming.time_base.Part`, training files only); a source ending in
    :data:`CLOCK_SUFFIX` is the file or segment before it on its regular clock
    (:class:`~estimation.streaming.time_base.RegularClock`, :func:`clock_source`)."""
    file = Path(path)
    if from_positions(path):  # the velocities left unread: the same file and segment (read_chunks drops dq)
        return source_file(str(path)[:-len(POSITIONS_SUFFIX)])
    if not file.exists() and str(path).endswith(CLOCK_SUFFIX):
        inner, segment = source_file(str(path)[:-len(CLOCK_SUFFIX)])
        if inner.is_file() and not isinstance(segment, (Part, RegularClock)):
            return inner, RegularClock(segment)
    if not file.exists():
        match = _SEGMENT.match(str(path))
        if match is not None and Path(match["file"]).is_file():
            index = int(match["index"])
            return Path(match["file"]), Part(index) if match["kind"] == "part" else index
    return file, None


def segment_sources(paths, model: IdentificationModel, *, chunk_size: int = DEFAULT_CHUNK_SIZE,
                    holds_cut: bool = False) -> list:
    """``paths`` with each file the loader splits at its holes (longer than ``max_gap``,
    :func:`estimation.data.records.read_record`) replaced by its segments' sources (``run.csv (segment 1)``…,
    :func:`source_file`), in order, each read and preprocessed on its own as in memory; a source already a segment,
    or a file that is not a .csv or .parquet one, is kept (the reader names its fault). ``holds_cut`` (training
    files, rows at rest not handled by the user): a file with holds (every joint's position unchanged for longer
    than ``max_gap``) is replaced by its parts between its holes and holds instead (``run.csv (part 1)``…), said in
    a :class:`~estimation.data.loading.HoldWarning`, as the in-memory path cuts a training record
    (:func:`estimation.identification.prepared.training_without_holds`)."""
    sources = []
    for path in paths:
        file, segment = source_file(path)
        if segment is not None or not file.is_file() or data_suffix(file) not in (".csv", ".parquet"):
            sources.append(path)
            continue
        held = file_parts(_raw_frames(file, max(int(chunk_size), 1), model), file, model) if holds_cut else None
        if held is not None and held.parts:
            warnings.warn(HoldWarning(
                f"{path}: the robot is held still (every joint's position unchanged for more than "
                f"{DEFAULT_MAX_GAP:g} s) on {held.dropped} of {held.rows} rows: left out of the fit, the record split "
                "there (at rest the torque holds any share of the static friction, and the sign of the derived "
                "velocity is noise); --min-speed V drops rows slower than V instead"), stacklevel=2)
            sources.extend(type(path)(f"{path} (part {index})") if isinstance(path, Path) else f"{path} (part {index})"
                           for index in range(1, len(held.parts) + 1))
            continue
        count = file_segments(_raw_frames(file, max(int(chunk_size), 1), model), file, model)
        sources.extend([path] if count == 1 else [type(path)(f"{path} (segment {index})") if isinstance(path, Path)
                                                  else f"{path} (segment {index})" for index in range(1, count + 1)])
    return sources


def source_files(paths) -> list:
    """The files of streamed sources (:func:`source_file`), each once, in order: what the in-memory reader reads
    (it splits a file into the same segments)."""
    files: list = []
    for path in paths:
        file, segment = source_file(path)
        entry = path if segment is None else (file if isinstance(path, Path) else str(file))
        if entry not in files:
            files.append(entry)
    return files


def source_rows(path: str | Path, model: IdentificationModel) -> int:
    """The rows of a streamed source: a file's (:func:`estimation.data.memory_budget.count_rows`, without parsing),
    or those the loader keeps of a segment (one scan of the file)."""
    file, segment = source_file(path)
    if segment is None:
        return count_rows(file)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # said when the segment is read
        scan = scan_time(_raw_frames(file, DEFAULT_CHUNK_SIZE, model), file, model, segment=segment)
    return count_rows(file) if scan is None or scan.keep is None else int(np.count_nonzero(scan.keep))


def source_step(path: str | Path, model: IdentificationModel) -> float | None:
    """The sampling step of a streamed source as the in-memory reader has it: the median step of the rows kept, or
    the step of the uniform grid a resampled record is put on (one scan of the file's times; ``None``: no numeric
    column ``t``)."""
    file, segment = source_file(path)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # said when the file is read
        scan = scan_time(_raw_frames(file, DEFAULT_CHUNK_SIZE, model), file, model, segment=segment)
    return None if scan is None else float(scan.step)


def _kept_frames(path: Path, chunk_size: int, keep: NDArray[np.bool_] | None, model: IdentificationModel
                 ) -> Iterator[pd.DataFrame]:
    """The rows of the file the loader keeps (``keep``, by row; ``None``: every row), ``chunk_size`` at a time, in
    the format (:func:`_in_the_format`; its reading said by the scan of the file before)."""
    if keep is None:
        yield from _raw_frames(path, chunk_size, model, say=False)
        return
    row, held, count = 0, [], 0
    for frame in _raw_frames(path, chunk_size, model, say=False):
        part = frame[keep[row:row + len(frame)]]
        row += len(frame)
        if len(part):
            held.append(part)
            count += len(part)
        while count >= chunk_size:
            joined = pd.concat(held, ignore_index=True) if len(held) > 1 else held[0]
            yield joined.iloc[:chunk_size]
            rest = joined.iloc[chunk_size:]
            held, count = ([rest] if len(rest) else []), len(rest)
    if count:
        yield pd.concat(held, ignore_index=True) if len(held) > 1 else held[0]


def _unwrapped(frame: pd.DataFrame, model: IdentificationModel, source: str, before: AngleTurns, first_row: int
               ) -> tuple[pd.DataFrame, AngleTurns, NDArray[np.int_]]:
    """The chunk with the angles a logger wrapped unwrapped as the whole record is
    (:func:`estimation.data.records.unwrap_angles`, from where the chunk before left them)."""
    frame = frame.rename(columns=lambda name: str(name).strip())
    columns = _group_columns("q", model.robot.n_joints)
    if not set(columns) <= set(frame.columns):  # the chunk's checks name the missing column
        return frame, before, np.zeros(len(columns), dtype=np.int_)
    q = np.column_stack([column_floats(frame[column]) for column in columns])
    unwrapped, after, wraps = unwrap_angles(q, model, source, before, first_row=first_row)
    if unwrapped is not q:
        frame = frame.assign(**{column: unwrapped[:, j] for j, column in enumerate(columns)})
    return frame, after, wraps


class _ClockEvidence:
    """The whole record's :class:`~estimation.data.sampling_clock.ClockSums`, block by block (the rows kept, as
    logged; the last two rows of a block carried, so that each interior row is summed once, as in memory)."""

    def __init__(self, model: IdentificationModel, scan) -> None:
        self.columns = _group_columns("q", model.robot.n_joints)
        self.scan = scan
        self.sums: ClockSums | None = None
        self.carry: tuple[NDArray[np.float64], NDArray[np.float64]] | None = None
        self.samples = 0
        self.first = self.last = 0.0

    def add(self, frame: pd.DataFrame) -> None:
        frame = frame.rename(columns=lambda name: str(name).strip())
        if not set(self.columns) | {"t"} <= set(frame.columns) or not len(frame):
            return
        t = column_floats(frame["t"])
        q = np.column_stack([column_floats(frame[column]) for column in self.columns])
        if not self.samples:
            self.first = float(t[0])
        self.samples += t.shape[0]
        self.last = float(t[-1])
        if self.carry is not None:
            t, q = np.concatenate([self.carry[0], t]), np.vstack([self.carry[1], q])
        self.carry = (t[-2:], q[-2:])
        if t.shape[0] >= 3:
            sums = ClockSums.of(t, q, self.scan.step)
            self.sums = sums if self.sums is None else self.sums + sums

    def say(self, source: str) -> None:
        said_receive_times(None if self.sums is None else self.sums.ratio, self.first, self.last, self.samples,
                           source, stacklevel=5)


class _ClippedEvidence:
    """The whole record's clipped sensors (:class:`~estimation.data.log_cleaning.HeldExtremes`, torques and wrench),
    block by block over the rows the loader keeps (a measured channel's held repeats masked: ``held``, the
    :attr:`~estimation.streaming.time_base.TimeScan.held` of the file), as memory judges them on the whole record
    (:func:`estimation.data.records.clipped_torques`); said once the file is read. Their samples are masked in each
    chunk (:class:`CellMask`), as memory masks them."""

    def __init__(self, model: IdentificationModel, held: dict[str, NDArray[np.bool_]] | None = None) -> None:
        n_joints = model.robot.n_joints
        self.q = _group_columns("q", n_joints)
        self.groups = {name: _group_columns(name, n_joints) for name in ("tau", "wrench")}
        self.scans: dict[str, HeldExtremes] = {}
        self.held = held or {}
        self.row = 0

    def add(self, frame: pd.DataFrame) -> None:
        frame = frame.rename(columns=lambda name: str(name).strip())
        first, self.row = self.row, self.row + len(frame)
        if not set(self.q) | {"t"} <= set(frame.columns) or not len(frame):
            return
        q = np.column_stack([column_floats(frame[column]) for column in self.q])
        t = column_floats(frame["t"])
        for name, columns in self.groups.items():
            if not set(columns) <= set(frame.columns):
                continue
            if name not in self.scans:
                self.scans[name] = HeldExtremes(len(columns), len(self.q), wrench=name == "wrench")
            values = np.column_stack([column_floats(frame[column]) for column in columns])
            if name in self.held:  # the repeats masked, as memory judges the channel after masking them
                values[self.held[name][first:self.row]] = np.nan
            self.scans[name].add(values, q, t)

    def mask(self) -> CellMask:
        """The file's masked cells: the held repeats and the clipped samples."""
        return CellMask(self.held, {name: tuple(scan.clipped_rows()) for name, scan in self.scans.items()})

    def say(self, model: IdentificationModel, source: str) -> None:
        said = [(self.groups[name][channel], value, count, first, last) for name in ("tau", "wrench")
                if name in self.scans for channel, value, count, first, last in self.scans[name].described()]
        if said:
            said_clipped(said, model, source)


@dataclass(frozen=True)
class CellMask:
    """The masked cells of a file's kept rows (:mod:`estimation.data.channel_mask`, as memory's reader masks them):
    ``held``, per measured group (``tau``, ``wrench``), its held repeats ``(rows,)``; ``clipped``, per group and
    channel, the sorted rows of a clipped sensor's samples. The rows are the kept rows' indices from the file's
    first kept row."""

    held: dict[str, NDArray[np.bool_]]
    clipped: dict[str, tuple[NDArray[np.int64], ...]]

    @property
    def empty(self) -> bool:
        return not self.held and not any(rows.size for found in self.clipped.values() for rows in found)

    def cells(self, group: str, first: int, rows: int, width: int) -> NDArray[np.bool_] | None:
        """``(rows, width)`` the masked cells of ``group`` on the kept rows ``first .. first + rows``; ``None``:
        none."""
        found = None
        if group in self.held and self.held[group][first:first + rows].any():
            found = np.repeat(self.held[group][first:first + rows, None], width, axis=1)
        for channel, at in enumerate(self.clipped.get(group, ())):
            low, high = np.searchsorted(at, [first, first + rows])
            if high > low:
                found = np.zeros((rows, width), dtype=bool) if found is None else found
                found[at[low:high] - first, channel] = True
        return found

    def applied(self, arrays: dict[str, NDArray[np.float64] | None], first: int) -> dict:
        """``arrays`` (``tau``, ``wrench`` among them, on the kept rows from ``first``) with their masked cells
        NaN; the arrays without a masked cell as they are."""
        masked = dict(arrays)
        for group in ("tau", "wrench"):
            values = arrays.get(group)
            if values is None:
                continue
            found = self.cells(group, first, values.shape[0], values.shape[1])
            if found is not None:
                masked[group] = np.where(found, np.nan, values)
        return masked

    def on(self, measurements: Measurements, first: int) -> Measurements:
        """``measurements`` (the kept rows from ``first``, not resampled) with their masked cells NaN."""
        arrays = self.applied({"tau": measurements.tau, "wrench": measurements.wrench}, first)
        if arrays["tau"] is measurements.tau and arrays["wrench"] is measurements.wrench:
            return measurements
        return replace(measurements, tau=arrays["tau"], wrench=arrays["wrench"])


class FileScans:
    """The scans of the files one run reads, held by the run and handed to its passes (no process-wide store): the
    first :func:`read_chunks` of a file, block size, segment and model scans its rows
    (:func:`~estimation.streaming.time_base.scan_time`, its findings said there) and judges its clipped sensors
    (:class:`_ClippedEvidence`, one more pass); each later pass of the same file, block size, segment and model given
    the same object takes both instead of reading the file twice again (:func:`read_chunks`, :func:`logged_chunks`).
    A scan is a function of the file's bytes and those keys, so the one taken is the one that would be made anew,
    bit for bit; the time base's findings are said once, by the pass that scans. Memory: each file's ``keep`` and
    held-repeat masks (a byte a row) and its clipped rows, for the run's length."""

    def __init__(self) -> None:
        self._found: dict[tuple, tuple[IdentificationModel, bool, TimeScan | None, _ClippedEvidence]] = {}

    @staticmethod
    def _key(file: Path, chunk_size: int, segment, model: IdentificationModel) -> tuple:
        return str(file), int(chunk_size), segment, id(model)

    def taken(self, file: Path, chunk_size: int, segment, model: IdentificationModel, *, said: bool = False
              ) -> tuple[TimeScan | None, _ClippedEvidence] | None:
        """The scan and clipped sensors held for these keys; ``None``: not scanned yet in this run (``said``: or
        scanned by a pass that does not say the file's findings, :func:`logged_chunks`)."""
        found = self._found.get(self._key(file, chunk_size, segment, model))
        return None if found is None or found[0] is not model or (said and not found[1]) else found[2:]

    def hold(self, file: Path, chunk_size: int, segment, model: IdentificationModel, scan: TimeScan | None,
             clipped: _ClippedEvidence, *, said: bool = True) -> None:
        """Hold a file's scan and judged clipped sensors (the model kept, so that its id names it; ``said``: by a
        pass that says the file's findings)."""
        self._found[self._key(file, chunk_size, segment, model)] = (model, said, scan, clipped)


def cell_mask(path: str | Path, model: IdentificationModel, *, chunk_size: int = DEFAULT_CHUNK_SIZE,
              scan: TimeScan | None = None, say: bool = False) -> CellMask:
    """The masked cells of the rows of ``path`` the loader keeps (:class:`CellMask`): one pass over them
    (:class:`_ClippedEvidence`, the clipped sensors judged on the whole record block by block); ``scan``: the
    file's :func:`~estimation.streaming.time_base.scan_time` (made when not given). ``say``: the clipped sensors'
    warning."""
    clipped = _cell_evidence(path, model, chunk_size, scan)
    if say:
        clipped.say(model, str(path))
    return clipped.mask()


def _cell_evidence(path: str | Path, model: IdentificationModel, chunk_size: int,
                   scan: TimeScan | None = None) -> _ClippedEvidence:
    """:func:`cell_mask`'s pass: the clipped sensors of the rows of ``path`` the loader keeps, judged block by
    block (their held repeats masked first)."""
    file, segment = source_file(path)
    if scan is None:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # said when the file is read
            scan = scan_time(_raw_frames(file, chunk_size, model), file, model, segment=segment)
    clipped = _ClippedEvidence(model, None if scan is None or scan.held is None else dict(scan.held))
    for frame in _kept_frames(file, chunk_size, None if scan is None else scan.keep, model):
        clipped.add(frame)
    return clipped


@dataclass(frozen=True)
class MaskedCells:
    """The counts of a streamed source's masked cells, as memory's reader has them: ``rows``, the rows the loader
    keeps (the samples as recorded); ``clipped``, each clipped channel's samples left out (memory's
    ``metadata["saturated_samples"]``, :func:`estimation.data.records.clipped_torques`); ``channels``, each
    measured channel's valid samples (its held repeats and clipped samples out; memory's
    :func:`~estimation.data.channel_mask.channel_counts` of the record as recorded)."""

    rows: int
    clipped: dict[str, int]
    channels: dict[str, int]


def masked_cells(path: str | Path, model: IdentificationModel, *, chunk_size: int = DEFAULT_CHUNK_SIZE) -> MaskedCells:
    """The :class:`MaskedCells` of ``path`` (a file or one of its segments or parts): one scan of its time base and
    one pass over its kept rows (:func:`cell_mask`'s), nothing said."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # said when the file is read
        evidence = _cell_evidence(path, model, chunk_size)
    mask, rows = evidence.mask(), evidence.row
    clipped: dict[str, int] = {}
    channels: dict[str, int] = {}
    for group in ("tau", "wrench"):  # memory's order: the torques, then the wrench
        if group not in evidence.scans:
            continue
        names = evidence.groups[group]
        for name, at in zip(names, mask.clipped.get(group, ())):
            if at.size:
                clipped[name] = int(at.size)
        found = mask.cells(group, 0, rows, len(names))
        lost = np.zeros(len(names), dtype=int) if found is None else found.sum(axis=0)
        channels.update({name: int(rows - count) for name, count in zip(names, lost)})
    return MaskedCells(int(rows), clipped, channels)


def read_chunks(path: str | Path, model: IdentificationModel, *, chunk_size: int = DEFAULT_CHUNK_SIZE,
                scans: FileScans | None = None) -> Iterator[Measurements]:
    """The checked measurements of ``path``, ``chunk_size`` rows at a time (a short last chunk is
    joined to the one before, so that each has more samples than base parameters). Raises the
    errors of :func:`estimation.data.records.read_measurements`, naming the file and rows, and a
    :class:`~estimation.data.loading.TimeBaseError` when the time does not run on across chunks. ``scans``: the
    run's :class:`FileScans`, the file's scan taken from it when an earlier pass of the run made it (else made and
    held there)."""
    if from_positions(path):  # dq from the positions: the chunks read without the logged velocities
        for chunk in read_chunks(str(path)[:-len(POSITIONS_SUFFIX)], model, chunk_size=chunk_size, scans=scans):
            recorded = chunk.recorded
            yield replace(chunk, dq=None, recorded=None if recorded is None else replace(recorded, dq=None))
        return
    path = Path(path)
    least = model.n_base + 1
    if chunk_size < least:
        raise ValueError(f"a chunk of {chunk_size} samples is shorter than the {least} samples each chunk is checked "
                         f"with ({model.n_base} base parameters): give at least {least} (10 000 is a good size)")
    pending: pd.DataFrame | None = None
    file, segment = source_file(path)
    taken = None if scans is None else scans.taken(file, chunk_size, segment, model, said=True)
    if taken is None:
        scan = scan_time(_raw_frames(file, chunk_size, model), file, model, segment=segment)  # the loader's findings, said once
        clipped = _ClippedEvidence(model, None if scan is None or scan.held is None else dict(scan.held))
        for frame in _kept_frames(file, chunk_size, None if scan is None else scan.keep, model):
            clipped.add(frame)  # the whole record's clipped sensors, before the first chunk is masked
        if scans is not None:
            scans.hold(file, chunk_size, segment, model, scan, clipped)
    else:  # scanned and judged by an earlier pass of the run (its findings said there)
        scan, clipped = taken
    resampler = Resampler(scan) if scan is not None and scan.irregular else None
    mask = clipped.mask()
    checked = _ChunkChecks(path, model, scan, resampler, None if mask.empty else mask)
    emitted = 0
    clock = _ClockEvidence(model, scan) if resampler is not None else None
    for frame in _kept_frames(file, chunk_size, None if scan is None else scan.keep, model):
        if clock is not None:
            clock.add(frame)
        if pending is not None and len(frame) < least:
            pending = pd.concat([pending, frame], ignore_index=True)
            continue
        if pending is not None:
            chunk = checked(pending)
            emitted += chunk.n_samples
            if chunk.n_samples:
                yield chunk
        pending = frame
    if pending is None:
        raise TooFewSamplesError(f"{path}: no samples")
    chunk = checked(pending)
    emitted += chunk.n_samples
    said_unwrapped(checked.wraps, model, str(path))
    if clock is not None:
        clock.say(str(path))
    clipped.say(model, str(path))
    if resampler is not None and emitted != scan.grid_count:
        raise TimeBaseError(f"{path}: {emitted} samples resampled of the {scan.grid_count} of the grid (did the file "
                            "change while it was read?)")
    if chunk.n_samples:
        yield chunk


def logged_chunks(path: str | Path, model: IdentificationModel, *, chunk_size: int = DEFAULT_CHUNK_SIZE,
                  load: SubtractedLoad | None = None, scans: FileScans | None = None) -> Iterator[Measurements]:
    """The samples of ``path`` as logged, ``chunk_size`` rows at a time, before any resampling (rows repeating the
    previous one dropped, as the loader drops them): the recorded time stamps and channels a resampled file's errors
    are measured at (:func:`estimation.streaming.recorded_errors.streamed_errors_at_stamps`). ``load``: a load the
    logged torques lack, added back at the logged positions (:func:`loaded_chunk`). ``scans``: the run's
    :class:`FileScans`, the file's scan and masked cells taken from it when a :func:`read_chunks` of the run made
    them."""
    least = model.n_base + 1  # a short last block is joined to the one before, as read_chunks joins it
    pending: pd.DataFrame | None = None
    file, segment = source_file(path)
    taken = None if scans is None else scans.taken(file, chunk_size, segment, model)
    if taken is None:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # said when the file was read for its sums
            scan = scan_time(_raw_frames(file, chunk_size, model), file, model, segment=segment)
        if scans is None:
            mask = cell_mask(path, model, chunk_size=chunk_size, scan=scan)
        else:  # cell_mask's pass, its evidence held for the run's later passes (its findings not said here)
            clipped = _ClippedEvidence(model, None if scan is None or scan.held is None else dict(scan.held))
            for frame in _kept_frames(file, chunk_size, None if scan is None else scan.keep, model):
                clipped.add(frame)
            scans.hold(file, chunk_size, segment, model, scan, clipped, said=False)
            mask = clipped.mask()
    else:  # the scan and the clipped sensors judged by the run's read_chunks of the file
        scan, mask = taken[0], taken[1].mask()
    mask = None if mask.empty else mask
    turns, row = AngleTurns(), 0
    for frame in itertools.chain(_kept_frames(file, chunk_size, None if scan is None else scan.keep, model), [None]):
        if frame is not None and pending is not None and len(frame) < least:
            pending = pd.concat([pending, frame], ignore_index=True)
            continue
        if pending is not None:
            pending, turns, _ = _unwrapped(pending, model, f"{path} (rows {row + 1}-{row + len(pending)})", turns, row)
            if isinstance(segment, RegularClock) and scan is not None and scan.clock is not None \
                    and "t" in pending.columns:  # the rows' instants on the regular clock, as read_chunks has them
                pending = pending.assign(t=clock_instants(scan.clock[0], scan.clock[1], scan.clock[2] + row,
                                                          len(pending)))
            first, row = row, row + len(pending)
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")  # said when the file was read for its sums
                chunk = measurements_from_frame(pending, model=model, resample=True, source=str(path),
                                                glitches=False).as_recorded
            if mask is not None:  # the masked cells of the rows as logged, as memory's samples as recorded
                chunk = _masked_logged(chunk, mask, first, len(pending), str(path))
            if chunk.n_samples:  # the samples kept as logged, when the block was resampled
                yield chunk if load is None else loaded_chunk(chunk, load, model)
        pending = frame


def _masked_logged(chunk: Measurements, mask: CellMask, first: int, rows: int, source: str) -> Measurements:
    """The logged rows ``first .. first + rows`` (``chunk``) with their masked cells NaN."""
    if chunk.n_samples != rows:
        raise MeasurementError(f"{source}: {chunk.n_samples} samples read of the {rows} rows kept (did the file change "
                               "while it was read?)")
    return mask.on(chunk, first)


def receive_times_evidence_of(path: str | Path, model: IdentificationModel, *,
                               chunk_size: int = DEFAULT_CHUNK_SIZE) -> float | None:
    """How many times smoother the positions of a streamed source are on a regular clock than at its stamps (the
    :class:`~estimation.data.sampling_clock.ClockSums` ratio of its kept rows as logged, summed block by block as
    :func:`read_chunks` sums them for its :class:`~estimation.data.loading.ReceiveTimesWarning`), memory's
    :func:`~estimation.data.sampling_clock.receive_times_ratio` of the segment; ``None`` when the source is not
    resampled by its stamps or the evidence is too thin."""
    file, segment = source_file(path)
    if isinstance(segment, RegularClock):
        segment = segment.of
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # said when the source is read
        scan = scan_time(_raw_frames(file, chunk_size, model), file, model, segment=segment)
    if scan is None or not scan.irregular:
        return None
    evidence = _ClockEvidence(model, scan)
    for frame in _kept_frames(file, chunk_size, scan.keep, model):
        evidence.add(frame)
    return None if evidence.sums is None else evidence.sums.ratio


class _ChunkChecks:
    """The checks of one file's chunks, in order: each as the loader checks a file, and the time
    running on from the chunk before; on irregular sampling each put on the whole file's grid."""

    def __init__(self, path: Path, model: IdentificationModel, scan: TimeScan | None,
                 resampler: Resampler | None, mask: CellMask | None = None) -> None:
        self.path, self.model, self.scan, self.resampler = path, model, scan, resampler
        self.mask = mask  # the masked cells of the kept rows (held repeats, clipped samples), NaN in each chunk
        self.row = 0  # rows checked so far
        self.previous: tuple[float, float] | None = None  # last time and step of the chunk before
        self.turns = AngleTurns()  # where the unwrap of a wrapped angle stands after the chunk before
        self.wraps = np.zeros(model.robot.n_joints, dtype=np.int_)  # wraps undone so far, per joint

    def __call__(self, frame: pd.DataFrame) -> Measurements:
        """The next chunk, checked (the rows the loader keeps: the file's scan dropped the others)."""
        path, previous = self.path, self.previous
        source = f"{path} (rows {self.row + 1}-{self.row + len(frame)})"
        rows = len(frame)
        frame, self.turns, wraps = _unwrapped(frame, self.model, source, self.turns, self.row)
        self.wraps = self.wraps + wraps
        if self.scan is not None and self.scan.clock is not None and "t" in frame.columns:  # a quantised time
            t0, step, first = self.scan.clock  # column: the rows' instants on the whole record's regular clock
            frame = frame.assign(t=clock_instants(t0, step, first + self.row, rows))
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", MeasurementWarning)  # the time base's findings: said once for the file
            if self.resampler is not None:
                measurements = self.resampled(frame, source)
                self.row += rows
                return measurements
            measurements = measurements_from_frame(frame, model=self.model, resample=False, source=source,
                                                   glitches=False)
        if self.mask is not None:
            measurements = _masked_logged(measurements, self.mask, self.row, rows, str(path))
        step = float(np.median(np.diff(measurements.t)))
        if previous is not None:
            gap = measurements.t[0] - previous[0]
            if not abs(gap - previous[1]) <= 1e-3 * previous[1]:
                raise TimeBaseError(f"{path}: column t goes from {previous[0]:.9g} to {measurements.t[0]:.9g} s at row "
                                    f"{self.row + 1}, not one step of {previous[1]:.4g} s: a gap or a jump in the "
                                    "record (split the record there)")
        self.previous = (float(measurements.t[-1]), step)
        self.row += rows
        if self.scan is not None:  # the whole record's median step: its rate, as the in-memory filter takes it
            measurements = replace(measurements, metadata=dict(measurements.metadata, sampling_step=self.scan.step))
        return measurements

    def resampled(self, frame: pd.DataFrame, source: str) -> Measurements:
        """The chunk checked as the loader checks it, then put on the whole file's grid."""
        path, previous, scan, n_joints = self.path, self.previous, self.scan, self.model.robot.n_joints
        checked_chunk = measurements_from_frame(frame, model=self.model, resample=True, source=source,
                                                glitches=False)
        frame = frame.rename(columns=lambda name: str(name).strip())
        t = column_floats(frame["t"])
        if previous is not None:
            if not t[0] > previous[0]:
                raise TimeBaseError(f"{path}: column t does not increase at row {self.row + 1} ({previous[0]:.9g} -> "
                                    f"{t[0]:.9g}); sort the samples")
        groups = [name for name in _GROUPS if getattr(checked_chunk, name) is not None]
        columns = [column for name in groups for column in _group_columns(name, n_joints)]
        values = np.column_stack([column_floats(frame[column]) for column in columns])
        if self.mask is not None:  # the masked cells NaN before the resampling, as memory's
            start = 0
            for name in groups:
                width = len(_group_columns(name, n_joints))
                found = self.mask.cells(name, self.row, values.shape[0], width) if name in ("tau", "wrench") else None
                if found is not None:
                    values[:, start:start + width][found] = np.nan
                start += width
        grid, interpolated = self.resampler(t, values)
        arrays, start = {}, 0
        for name in groups:
            width = len(_group_columns(name, n_joints))
            arrays[name] = interpolated[:, start:start + width]
            start += width
        self.previous = (float(t[-1]), scan.step)
        metadata = dict(checked_chunk.metadata, resampled_from=scan.rows)
        return Measurements(grid, arrays["q"], arrays.get("dq"), arrays.get("ddq"), arrays.get("tau"),
                            arrays.get("wrench"), metadata)


def _decay_length(sos: NDArray[np.float64], tolerance: float) -> int:
    """Samples after which the impulse response of ``sos`` stays below ``tolerance`` of its peak."""
    return decay_length(sos, tolerance)


@functools.lru_cache(maxsize=32)
def filter_margin(rate_hz: float, cutoff_hz: float | None, order: int, decimation: int) -> int:
    """Overlap a chunk needs on each side (samples, a multiple of ``decimation``): the decay lengths
    of the derivative filter and of the decimation filter, plus the reach of the central
    differences and of the hold compensation."""
    margin = 4
    if cutoff_hz is not None:
        margin += _decay_length(scipy.signal.butter(order, cutoff_hz, btype="low", fs=rate_hz, output="sos"),
                                MARGIN_TOLERANCE)
    if decimation > 1:
        sos = scipy.signal.butter(8, 0.8 * 0.5 * rate_hz / decimation, btype="low", fs=rate_hz, output="sos")
        margin += _decay_length(sos, MARGIN_TOLERANCE)
    return -(-margin // decimation) * decimation


def automatic_cutoff(path: str | Path, model: IdentificationModel, *, chunk_size: int = DEFAULT_CHUNK_SIZE) -> float:
    """The automatic Butterworth cut-off (:meth:`ButterworthDifferentiation.cutoff`) of the first
    chunk of ``path``: one cut-off for every chunk and file of a streamed set."""
    first = next(read_chunks(path, model, chunk_size=chunk_size))
    return ButterworthDifferentiation().cutoff(first)


def _concatenate(parts: list[Measurements]) -> Measurements:
    if len(parts) == 1:
        return parts[0]

    def join(name):
        values = [getattr(part, name) for part in parts]
        return None if values[0] is None else np.concatenate(values)

    return Measurements(join("t"), join("q"), join("dq"), join("ddq"), join("tau"), join("wrench"), dict(parts[0].metadata))


def _preprocessed(window: Measurements, method: ButterworthDifferentiation | None, decimation: int,
                  held_torques: bool) -> Measurements:
    """The in-memory pipeline of :func:`estimation.preprocessing.differentiation.fill_derivatives` on one window."""
    derived = window if method is None else method.apply(window)
    if held_torques and method is not None:
        derived = compensate_hold(derived)
    return decimate(derived, decimation)


def loaded_chunk(chunk: Measurements, load: SubtractedLoad, model: IdentificationModel) -> Measurements:
    """A prepared chunk with ``load`` (a load of ``model``'s description the logged torques lack,
    :mod:`estimation.identification.subtracted_load`) added back as memory adds it to a prepared record
    (:func:`~estimation.identification.subtracted_load.added_back`): at the prepared positions to the prepared
    torques, at the recorded positions to the torques as recorded beside them, and to the samples of the chunk's
    in-band window (``metadata["band_window"]``) at theirs; never to the logged torques before the filter (that
    would filter the load, where memory adds it after)."""
    loaded = added_back(chunk, load, model.robot)
    window = chunk.metadata.get("band_window")
    if window is not None:
        window = replace(window, samples=added_back(window.samples, load, model.robot))
        loaded = replace(loaded, metadata=dict(loaded.metadata, band_window=window))
    return loaded


def preprocessed_chunks(path: str | Path, model: IdentificationModel, *, chunk_size: int = DEFAULT_CHUNK_SIZE,
                        cutoff_hz: float | None = None, order: int = 4, decimation: int = 1,
                        held_torques: bool = False, trim: bool = False, record: dict | None = None,
                        band: bool = False, load: SubtractedLoad | None = None, scans: FileScans | None = None
                        ) -> Iterator[Measurements]:
    """The preprocessed samples of one file, chunk by chunk (overlapping windows: module docstring).

    The arguments are those of :func:`file_sums`. ``trim``: on the filter path without decimation,
    the samples where the zero-phase filter settles are dropped at both ends of the record
    (:meth:`ButterworthDifferentiation.settling_samples`), as the in-memory preprocessing of the CLI
    does (``ButterworthDifferentiation(trim=True)``). ``record`` (a dict, optional) receives, once the
    file is read to its end, ``rows`` (samples read), ``columns`` (the column groups) and
    ``metadata`` (decimation, margin, differentiation…). Each chunk keeps the channels as recorded
    (``Measurements.recorded``) beside the filtered ones when the filter path runs. ``band``: when the torques are
    kept as recorded (``ButterworthDifferentiation(torques="recorded")``), each chunk carries its samples extended by
    the band filter's margin, ``metadata["band_window"]`` (:class:`~estimation.estimators.identification_problem.BandWindow`:
    the windows reach that much further), from which the in-band problem of the chunk equals the whole record's
    (:func:`~estimation.estimators.identification_problem.in_band_blocks`); without, or when there is no band, it is
    ``None`` on the filter path (no chunk is low-passed on its own). ``load``: a load of the description the logged
    torques lack (:class:`~estimation.identification.subtracted_load.SubtractedLoad`), added back to each prepared
    chunk as memory adds it to the prepared record (:func:`loaded_chunk`); ``None``: the torques as logged.
    ``scans``: the run's :class:`FileScans` (:func:`read_chunks`).
    """
    path = Path(path)
    chunk_size = check_chunk_size(chunk_size, model)
    if int(decimation) != decimation or decimation < 1:
        raise ValueError(f"decimation factor must be a positive integer, got {decimation}")
    chunk_size = -(-chunk_size // decimation) * decimation
    if record is not None:
        record["chunk_size"] = chunk_size
    chunks = read_chunks(path, model, chunk_size=chunk_size, scans=scans)
    first = next(chunks)  # here, so that a warning of read_chunks points at the caller
    windows = _OverlappingWindows(path, first, chunks, chunk_size, cutoff_hz, order, decimation, held_torques, trim,
                                  band)
    if load is None:
        yield from windows.kept_chunks()
    else:
        for kept in windows.kept_chunks():
            yield loaded_chunk(kept, load, model)
    if record is not None:
        record.update(rows=windows.rows, columns=windows.columns, metadata=windows.metadata())


class _OverlappingWindows:
    """One file preprocessed chunk by chunk in windows reaching ``margin`` samples beyond each chunk
    (module docstring): the raw samples held (``buffer``, from global index ``start``), and the
    samples whose preprocessed values are given out (``done``)."""

    def __init__(self, path: Path, first: Measurements, chunks: Iterator[Measurements], chunk_size: int,
                 cutoff_hz: float | None, order: int, decimation: int, held_torques: bool, trim: bool,
                 band: bool = False) -> None:
        derive = first.dq is None or first.ddq is None
        if derive and cutoff_hz is None:
            raise StreamingUnsupportedError(f"{path}: without dq/ddq the streamed path needs one Butterworth cut-off for "
                                            "every chunk: give it (--cutoff), or let the caller pick it once")
        step = first.metadata.get("sampling_step")  # the record's (a block's median differs where stamps are coarse)
        rate = 1.0 / float(np.median(np.diff(first.t)) if step is None else step)
        method = ButterworthDifferentiation(cutoff_hz, order, rate_hz=None if step is None else rate) if derive else None
        if held_torques and not derive:
            held_torques = False  # nothing to align (the in-memory path warns)
        self.path, self.chunks, self.chunk_size, self.method = path, chunks, chunk_size, method
        self.cutoff_hz, self.order, self.decimation, self.held_torques = cutoff_hz, order, decimation, held_torques
        self.first_metadata = first.metadata
        self.margin = (filter_margin(rate, cutoff_hz if derive else None, order, int(decimation))
                       if (derive or decimation > 1) else 0)
        self.columns = tuple(name for name in ("dq", "ddq", "tau", "wrench") if getattr(first, name) is not None)
        self.edge = method.settling_samples(rate, cutoff_hz) if trim and method is not None and decimation == 1 else 0
        # the band of the in-band problem (ResidualBand.of of the record prepared in memory) and the samples beyond
        # each chunk its filter reaches, on the prepared (decimated) samples; the windows reach that much further
        rate_prepared = float(f"{rate / int(decimation):.9g}")
        self.band = (ResidualBand(float(cutoff_hz), int(order), rate_prepared)
                     if band and method is not None and method.torques == "recorded"
                     and float(cutoff_hz) < 0.45 * rate_prepared else None)
        self.extra = 0 if self.band is None else self.band.margin * int(decimation)
        self.buffer: list[Measurements] = [first]
        self.start = 0  # global index of buffer[0]
        self.done = 0  # samples whose sums are taken
        self.rows = first.n_samples
        self.exhausted = False
        self.cutoff_checked = False

    def kept_chunks(self) -> Iterator[Measurements]:
        """The preprocessed samples, about ``chunk_size`` at a time (no short tail chunk)."""
        while True:
            available = self.read_ahead()
            if self.done >= available:
                break
            stop = min(self.done + self.chunk_size, available)
            if self.exhausted and available - stop < max(self.margin, 1) and stop < available:
                stop = available  # no short tail chunk
            raw = _concatenate(self.buffer)
            kept = self.kept(raw, stop, available)
            if kept.n_samples:
                yield kept
            self.done = stop
            keep_from = max(self.done - self.margin - self.extra, 0)
            if keep_from > self.start:
                raw = raw.select(slice(keep_from - self.start, None))
                self.buffer, self.start = [raw], keep_from
            else:
                self.buffer = [raw]

    def read_ahead(self) -> int:
        """Chunks read until the next chunk and its margins are held (or the file ends); the samples available."""
        available = self.start + sum(part.n_samples for part in self.buffer)
        while not self.exhausted and available < self.done + self.chunk_size + self.margin + self.extra + self.edge:
            try:
                part = next(self.chunks)
            except StopIteration:
                self.exhausted = True
                break
            present = tuple(name for name in ("dq", "ddq", "tau", "wrench") if getattr(part, name) is not None)
            if present != self.columns:
                raise MeasurementError(f"{self.path}: the column groups change within the file ({self.columns} then "
                                       f"{present})")
            self.buffer.append(part)
            self.rows += part.n_samples
            available += part.n_samples
        return available

    def kept(self, raw: Measurements, stop: int, available: int) -> Measurements:
        """Samples ``done`` to ``stop`` preprocessed in their window (the filter's settling at the
        record's ends dropped with ``trim``)."""
        done, start, margin, decimation, extra = self.done, self.start, self.margin, self.decimation, self.extra
        low, high = max(done - margin - extra, start), min(stop + margin + extra, available)
        window = raw.select(slice(low - start, high - start))
        if self.method is not None and not self.cutoff_checked:
            self.method.cutoff(window)  # the cut-off against Nyquist once
            self.cutoff_checked = True
        processed = _preprocessed(window, self.method, int(decimation), self.held_torques)
        first_kept = (-(-done // decimation) * decimation - low) // decimation
        last_kept = (-(-stop // decimation) * decimation - low) // decimation
        kept = processed.select(slice(first_kept, last_kept))
        low_kept = 0
        if self.edge:  # the filter's settling at the record's two ends (the end is known once the file is exhausted)
            low_kept = max(self.edge - done, 0)
            high_kept = kept.n_samples - max(stop - (available - self.edge), 0) if self.exhausted else kept.n_samples
            kept = kept.select(slice(low_kept, max(high_kept, low_kept)))
        if self.method is None:
            return kept
        window = None
        if self.band is not None:  # the chunk's samples and the band's margin beyond, within the (trimmed) record
            first = max(done - extra, self.edge)
            last = min(stop + extra, available - self.edge if self.exhausted else available)
            first_extended = (-(-first // decimation) * decimation - low) // decimation
            last_extended = (-(-last // decimation) * decimation - low) // decimation
            window = BandWindow(self.band, processed.select(slice(first_extended, last_extended)),
                                first_kept + low_kept - first_extended)
        return replace(kept, metadata=dict(kept.metadata, band_window=window))

    def metadata(self) -> dict:
        """What the preprocessing did: decimation, margin, samples trimmed, the filter."""
        metadata = {"decimation": int(self.decimation), "margin": self.margin, "trimmed_samples": self.edge}
        if "resampled_from" in self.first_metadata:
            metadata["resampled_from"] = int(self.first_metadata["resampled_from"])
        if self.method is not None:
            metadata.update(differentiation="butterworth", cutoff_hz=float(self.cutoff_hz), filter_order=self.order)
        return metadata


@single_threaded_blas()  # threaded OpenBLAS takes 30x longer on tall, thin QR (0.7 against 0.024 s, 10 051 x 51)
def file_sums(path: str | Path, model: IdentificationModel, *, chunk_size: int = DEFAULT_CHUNK_SIZE,
              cutoff_hz: float | None = None, order: int = 4, decimation: int = 1,
              held_torques: bool = False, load: SubtractedLoad | None = None,
              scans: FileScans | None = None) -> FileSums:
    """Read, preprocess and sum one file chunk by chunk.

    Parameters
    ----------
    path
        CSV or Parquet file (``t, q…, [dq…, ddq…], tau…/fx…``).
    model
        The identification model.
    chunk_size
        Samples a chunk (a multiple of ``decimation`` is used).
    cutoff_hz, order
        Butterworth cut-off and order, used when the file lacks ``dq``/``ddq`` (then ``cutoff_hz`` is
        required: see :func:`automatic_cutoff`). Ignored when the file holds both.
    decimation, held_torques
        As :func:`estimation.preprocessing.differentiation.fill_derivatives`.
    load
        A load of the description the logged torques lack, added back to each prepared chunk
        (:func:`loaded_chunk`); ``None``: the torques as logged.
    scans
        The run's :class:`FileScans` (:func:`read_chunks`): the file's scan made once a run.
    """
    sums = NormalEquations.empty(model.channels, model.base.names, model.base.expressions)
    record: dict = {}
    joint_range = None
    for kept in preprocessed_chunks(path, model, chunk_size=chunk_size, cutoff_hz=cutoff_hz, order=order,
                                    decimation=decimation, held_torques=held_torques, record=record, band=True,
                                    load=load, scans=scans):
        sums = accumulate(model, kept, chunk_size=record["chunk_size"], sums=sums)
        if kept.n_samples:  # the samples summed: the training range, in the same pass
            joint_range = TrainingRange.of(kept.q, kept.dq, model.robot.joint_names).merged(joint_range)
    sums = replace(sums, sources=(str(path),))
    return FileSums(str(path), sums, record["rows"], record["columns"], record["metadata"], joint_range)
