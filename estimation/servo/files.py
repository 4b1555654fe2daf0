"""CSV files of the servo-arm workflow: ``t, u1..uJ`` (APRBS), ``t, u1..uJ, q1..qJ`` (+ raw sensor columns).

Writes are atomic (temporary file in the same folder, then ``os.replace``): a failed run leaves no
half-written output. Reads validate the columns and the time column (uniform sampling), naming the problem.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from dynamics.runtime.output_files import atomic_output
from dynamics.signal_checks import check_uniform_time


@dataclass(frozen=True)
class ServoTable:
    """A read CSV: ``t`` (N,), ``dt``, and the named columns (each (N,))."""

    t: np.ndarray
    dt: float
    columns: dict[str, np.ndarray]

    def stack(self, prefix: str) -> np.ndarray:
        """Columns ``prefix1, prefix2, …`` as an (N, J) array (J = how many consecutive ones exist)."""
        names = []
        while f"{prefix}{len(names) + 1}" in self.columns:
            names.append(f"{prefix}{len(names) + 1}")
        if not names:
            raise ValueError(f"no column {prefix}1 in the file (columns: {', '.join(self.columns)})")
        return np.column_stack([self.columns[name] for name in names])


def write_csv(path: str | Path, columns: dict[str, np.ndarray]) -> Path:
    """Write equal-length columns to ``path`` as CSV with a header, atomically."""

    path = Path(path)
    names = list(columns)
    data = np.column_stack([np.asarray(columns[name], dtype=float).reshape(-1) for name in names])
    with atomic_output(path) as stream:
        np.savetxt(stream, data, delimiter=",", header=",".join(names), comments="", fmt="%.10g")
    return path


def write_text_atomic(path: str | Path, text: str) -> Path:
    """Write ``text`` to ``path`` atomically."""

    path = Path(path)
    with atomic_output(path) as stream:
        stream.write(text)
    return path


def read_csv(path: str | Path, *, required: tuple[str, ...] = ("t",), dt: float | None = None) -> ServoTable:
    """Read a CSV with a header row; check ``required`` columns, finite values and a uniform ``t``.

    Parameters
    ----------
    dt
        Expected sample time [s]; the time column must match it (to 1e-6 relative).

    Raises
    ------
    OSError
        The file cannot be read.
    ValueError
        Missing column, non-numeric or NaN value, or a non-uniform time column (names the row).
    """
    path = Path(path)
    if not path.is_file():
        raise OSError(f"input file {str(path)!r} is a folder" if path.is_dir() else f"input file {str(path)!r} not found")
    with path.open(encoding="utf-8-sig") as stream:  # a spreadsheet's byte-order mark is not part of "t"
        header = [name.strip().strip('"').strip("'").strip() for name in stream.readline().strip().split(",")]
    missing = [name for name in required if name not in header]
    if missing:
        raise ValueError(f"{path.name}: missing column(s) {', '.join(missing)} (found {', '.join(header)})")
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", UserWarning)  # numpy's "input contained no data": said below
            data = np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2, encoding="utf-8-sig")
    except ValueError as error:
        raise ValueError(f"{path.name}: not a numeric CSV ({error})") from None
    if data.shape[0] == 0:
        raise ValueError(f"{path.name}: a header but no data rows")
    if data.shape[1] != len(header):
        raise ValueError(f"{path.name}: {len(header)} header names but {data.shape[1]} data columns")
    columns = {name: data[:, i] for i, name in enumerate(header)}
    for name, column in columns.items():
        if not np.all(np.isfinite(column)):
            raise ValueError(f"{path.name}: column {name} holds NaN/inf at row {int(np.flatnonzero(~np.isfinite(column))[0])}")
    step = check_uniform_time(columns["t"], dt=dt)
    return ServoTable(t=columns["t"], dt=step, columns=columns)
