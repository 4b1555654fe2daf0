"""Whether a record is estimated in memory or streamed, decided by the memory it needs, before it is read.

The in-memory identification and diagnosis hold, at their peak, a stacked regressor and its companions: about
``bytes_per_value`` bytes a sample, channel and column (base parameters). A record of a million samples of a
7-joint arm (50 base parameters) asked 1.5 GB of the in-memory diagnosis just to be read and prepared, and its
estimation would have asked about 23 GB; the streamed path (:mod:`estimation.streaming.diagnosis`) diagnosed it
in 0.6 GB. So the path is chosen by an estimate made from the files' row counts (:func:`count_rows`: the Parquet
footer, or the line breaks of a CSV file, without parsing a value) against a budget, by default the fixed
:data:`DEFAULT_BUDGET` (1 GB), never the memory free at the moment: the same command takes the same path on every
machine, and a record whose in-memory peak would pass what the streamed path takes is streamed (bounded memory by
default). The hard limit of :func:`dynamics.runtime.memory.check_allocation` still refuses an in-memory run the
machine cannot hold::

    budget = parse_memory_size("2GB")                      # or default_budget()
    need = estimate_in_memory([count_rows(p) for p in paths], model, bytes_per_value=64, budget=budget)
    need.stream, need.describe("diagnosing")

Period averaging (a Fourier fit of whole periods) reduces a training file to one period before the estimation:
``reduced_rows`` says how many samples remain of each file; reading the file still costs :data:`READ_BYTES` a
value of its columns.
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from dynamics.models import IdentificationModel
from estimation.data.compressed_logs import open_binary, packed_format
from estimation.data.log_formats import is_log_file

__all__ = ["DEFAULT_BUDGET", "InMemoryNeed", "MemorySizeError", "READ_BYTES", "count_rows", "default_budget",
           "estimate_in_memory", "format_size", "parse_memory_size"]

#: bytes the in-memory path may take before streaming is chosen when ``--memory-budget`` is not given: fixed, so the
#: path depends on the record only (rows, channels, base parameters), not on the memory free at the moment; about
#: what the streamed path peaks at on a long record (0.6 GB for 1 M samples of a 7-joint arm), so a long record never
#: costs more in memory than streamed (``benchmarks/README.md``)
DEFAULT_BUDGET = 10**9
#: bytes a value of a file's columns costs while it is read and prepared in memory (the table, the arrays, the
#: recorded channels beside the derived ones; measured: 1.5 GB for 1.1 M rows of 15 columns, about 90)
READ_BYTES = 96
#: units of ``--memory-budget`` (decimal and binary prefixes; a bare number is bytes)
UNITS = {"": 1, "B": 1, "KB": 10**3, "MB": 10**6, "GB": 10**9, "TB": 10**12,
         "KIB": 2**10, "MIB": 2**20, "GIB": 2**30, "TIB": 2**40, "K": 2**10, "M": 2**20, "G": 2**30, "T": 2**40}


class MemorySizeError(ValueError):
    """A memory size that cannot be read (``--memory-budget``)."""


def parse_memory_size(text: str | int | float) -> int:
    """Bytes of a memory size: ``2GB``, ``500MB``, ``1.5GiB``, ``2G`` (binary), or a number of bytes.

    Raises
    ------
    MemorySizeError
        Anything else, or a size that is not positive.
    """
    if isinstance(text, bool):
        raise MemorySizeError(f"a memory size must be a number of bytes or a text such as 2GB, got {text!r}")
    if isinstance(text, (int, float)):
        value = float(text)
    else:
        found = re.fullmatch(r"\s*([0-9]*\.?[0-9]+(?:[eE][+-]?[0-9]+)?)\s*([A-Za-z]*)\s*", str(text))
        if found is None or found.group(2).upper() not in UNITS:
            raise MemorySizeError(f"cannot read the memory size {text!r}: give a number of bytes or a size such as "
                                  "500MB, 2GB or 1.5GiB")
        value = float(found.group(1)) * UNITS[found.group(2).upper()]
    if not (value >= 1 and value < float("inf")):
        raise MemorySizeError(f"a memory size must be at least one byte, got {text!r}")
    return int(value)


def format_size(n_bytes: float) -> str:
    """``1.2 GB``, ``350 MB``: a size for a message (decimal units, as ``--memory-budget`` reads them)."""
    for unit, scale in (("TB", 1e12), ("GB", 1e9), ("MB", 1e6), ("kB", 1e3)):
        if n_bytes >= scale:
            return f"{n_bytes / scale:.3g} {unit}"
    return f"{n_bytes:.0f} bytes"


def default_budget() -> int:
    """The budget when none is given, bytes: :data:`DEFAULT_BUDGET`, whatever the memory free now."""
    return DEFAULT_BUDGET


def count_rows(path: str | Path, *, block: int = 1 << 20) -> int:
    """Data rows of a ``.csv`` (line breaks counted in blocks of ``block`` bytes, the header and blank last line
    left out) or ``.parquet`` file (its footer), without parsing a value.

    Raises
    ------
    FileNotFoundError
        No such file.
    ValueError
        Another format.
    """
    if is_log_file(path):
        raise ValueError(f"{path}: the streamed path (chunks, workers, a cluster) reads .csv and .parquet files; a ROS "
                         "bag, an .npz or .mat file or a column map is read in memory (drop the streaming options)")
    path = Path(path)
    suffix = packed_format(path)  # a packed CSV file: its lines counted as they are decompressed
    if suffix not in (".csv", ".parquet"):
        raise ValueError(f"unknown data format {path.suffix!r} for {path}: use .csv or .parquet")
    if not path.is_file():
        raise FileNotFoundError(f"data file not found: {path}")
    if suffix == ".parquet":
        import pyarrow.parquet  # an optional dependency, as for reading (estimation.streaming.chunks)

        return int(pyarrow.parquet.ParquetFile(path).metadata.num_rows)
    lines, last = 0, b"\n"
    with open_binary(path) as stream:
        while chunk := stream.read(block):
            lines += chunk.count(b"\n")
            last = chunk[-1:]
    lines += last != b"\n"  # a last line without its line break
    return max(lines - 1, 0)


@dataclass(frozen=True)
class InMemoryNeed:
    """What the in-memory path would need, against the budget.

    Attributes
    ----------
    rows
        Rows of the files read.
    samples
        Samples the estimation holds (rows, or fewer after period averaging).
    n_bytes
        Estimated peak, bytes.
    budget
        Bytes the in-memory path may take.
    """

    rows: int
    samples: int
    n_bytes: float
    budget: int

    @property
    def stream(self) -> bool:
        """Whether the in-memory path would pass the budget (then the records are streamed)."""
        return not self.n_bytes <= self.budget

    def describe(self, task: str) -> str:
        """One line: the estimate, the budget and the path (``task``: ``"diagnosing"``)."""
        verdict = "streaming the files in bounded memory" if self.stream else "in memory"
        return (f"{task} {self.rows} rows in memory would need about {format_size(self.n_bytes)}, "
                f"{'over' if self.stream else 'within'} the budget of {format_size(self.budget)}: {verdict}")


def estimate_in_memory(rows: Sequence[int], model: IdentificationModel, *, bytes_per_value: float,
                       budget: int, columns: int | None = None, file_columns: int | None = None,
                       reduced_rows: Sequence[int] | None = None) -> InMemoryNeed:
    """The in-memory path's peak for files of ``rows`` rows (module docstring).

    Parameters
    ----------
    rows
        Rows of each file read (training, validation, test).
    model
        The model estimated (its channels).
    bytes_per_value
        Bytes a sample, channel and column the estimation holds.
    budget
        Bytes it may take.
    columns
        Columns of the regressor (default the model's base parameters).
    file_columns
        Columns of each file (default: time, positions and channels).
    reduced_rows
        Samples each file keeps for the estimation (default ``rows``; fewer after period averaging).
    """
    if reduced_rows is not None and len(reduced_rows) != len(rows):
        raise ValueError(f"reduced_rows has {len(reduced_rows)} entries for {len(rows)} files")
    if bytes_per_value <= 0:
        raise ValueError(f"bytes_per_value must be positive, got {bytes_per_value}")
    columns = model.n_base if columns is None else int(columns)
    file_columns = 1 + model.robot.n_joints + model.n_channels if file_columns is None else int(file_columns)
    kept = list(rows) if reduced_rows is None else list(reduced_rows)
    reading = READ_BYTES * float(sum(rows)) * file_columns
    estimation = float(bytes_per_value) * float(sum(kept)) * model.n_channels * columns
    return InMemoryNeed(int(sum(rows)), int(sum(kept)), reading + estimation, int(budget))
