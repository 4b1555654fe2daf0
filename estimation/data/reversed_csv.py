"""A log written newest first, read block by block oldest first: its CSV file's lines taken from the end.

The in-memory reader reverses a newest-first table whole (:func:`estimation.data.loading.newest_first`). A
streamed reader cannot: its blocks come from the file's start. :func:`reversed_csv_frames` reads a plain CSV file's
bytes backwards in blocks of :data:`BLOCK_BYTES` (a file supports seeking), splits them into lines, and parses each
``chunk_size`` of them, last line first, under the file's header with the same ``pandas.read_csv`` options, so each
row's values are the ones the forward read gives. Memory: one block of bytes and one chunk of rows. A packed file
(decompressed as it is read: no seeking back) and a Parquet file are refused, naming the in-memory route; a CSV field
holding a line break (quoted) is refused too (its lines cannot be told apart read backwards).
"""

from __future__ import annotations

import io
from collections.abc import Iterator
from pathlib import Path

import pandas as pd

from estimation.data.compressed_logs import is_packed
from estimation.data.loading import MeasurementError

#: bytes read at a time from the end of the file
BLOCK_BYTES = 1 << 20


class ReversedReadError(MeasurementError):
    """A newest-first log the streamed reader cannot read from its end (packed, Parquet, a quoted line break)."""


def _header_end(stream, lines: int) -> int:
    """The byte offset after the file's first ``lines`` lines (the header, and a units row beneath it)."""
    stream.seek(0)
    for _ in range(lines):
        stream.readline()
    return stream.tell()


def reversed_lines(path: Path, skip: int = 1) -> Iterator[bytes]:
    """The lines of the CSV file ``path`` after its first ``skip`` lines, last first (blank lines left out, line
    breaks ``\\n`` or ``\\r\\n``)."""
    with open(path, "rb") as stream:
        start = _header_end(stream, skip)
        stream.seek(0, io.SEEK_END)
        position, rest = stream.tell(), b""
        while position > start:
            begin = max(start, position - BLOCK_BYTES)
            stream.seek(begin)
            data = stream.read(position - begin) + rest
            position = begin
            lines = data.split(b"\n")
            rest, complete = (lines[0], lines[1:]) if position > start else (b"", lines)
            for line in reversed(complete):
                line = line.rstrip(b"\r")
                if line.strip():
                    yield line
        if rest.strip():
            yield rest.rstrip(b"\r")


def reversed_csv_frames(path: Path, chunk_size: int, options: dict) -> Iterator[pd.DataFrame]:
    """The rows of the CSV file ``path`` (a log written newest first) as frames of ``chunk_size`` rows, its last row
    first, each parsed under its header with ``pandas.read_csv``'s ``options`` (``skiprows``: comment lines above
    the header and a units row beneath it, left out; ``names``: a commented header's); the frames' index counts the rows so read (the oldest row 0), as the in-memory reader's reversed table.

    Raises
    ------
    ReversedReadError
        A packed file, or a line holding a quote (a field that may span lines)."""
    if is_packed(path):
        raise ReversedReadError(f"{path}: a log written newest first in a packed file: the streamed reader reads a "
                                "newest-first log from the end of a plain CSV file; read it in memory (drop the "
                                "streaming options), or unpack it")
    options = dict(options)
    skipped = set(options.pop("skiprows", None) or ())  # comment lines above the header, a units row beneath it
    named = "names" in options  # a header commented (savetxt): the names given, no header line to parse
    skip = len(skipped) + (0 if named else 1)
    with open(path, "rb") as stream:
        line = 0
        while line in skipped:
            stream.readline()
            line += 1
        header = b"" if named else stream.readline().rstrip(b"\r\n")
    batch: list[bytes] = []
    row = 0

    def parsed(lines: list[bytes]) -> pd.DataFrame:
        if any(b'"' in line for line in lines):
            raise ReversedReadError(f"{path}: a log written newest first whose rows hold quoted fields (a field may "
                                    "span lines, so its lines cannot be read from the end); read it in memory (drop "
                                    "the streaming options)")
        frame = pd.read_csv(io.BytesIO((header + b"\n" if header else b"") + b"\n".join(lines) + b"\n"), **options)
        frame.index = pd.RangeIndex(row, row + len(frame))
        return frame

    for line in reversed_lines(path, skip):
        batch.append(line)
        if len(batch) == chunk_size:
            frame = parsed(batch)
            row += len(frame)
            batch = []
            yield frame
    if batch:
        yield parsed(batch)
