"""Motor-side data converted to joint space through a transmission, with units and signs checked.

Columns a record may hold instead of (or besides) the joint-side ones of
:mod:`dynamics.measurements` (SI: rad, rad/s, N·m, A)::

    qm1..qmn  [dqm1..dqmn, ddqm1..ddqmn]   motor (rotor) positions: q = R⁻¹ θ_m + q₀ (q₀: the joint offsets)
    taum1..taumn                            motor torques:           τ = Rᵀ τ_m
    im1..imn                                motor currents:          τ = Rᵀ (k_t i)   (torque_constants)

(:mod:`dynamics.transmission`). The converted columns replace ``q``/``dq``/``ddq``/``tau``, then
the checks of :func:`estimation.data.records.measurements_from_frame` run as for any record. A joint
column and its motor column together (``q3`` and ``qm3``) are refused (which one is meant?). When
torques come from the motor side, :func:`dynamics.transmission.check_power_signs` checks that each
joint's converted torque does not push against its motion on average (a ratio or torque constant of
the wrong sign: :class:`dynamics.transmission.TransmissionSignError`).
"""

from __future__ import annotations

import os
import re
import warnings
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
from numpy.typing import ArrayLike

from dynamics.models import IdentificationModel
from dynamics.transmission import (
    MIN_SWEEP,
    JointDirections,
    Transmission,
    TransmissionError,
    check_mean_power,
    check_power_signs,
)
from estimation.data.loading import (MeasurementError, MissingColumnError, in_si_units, other_delimiter,
                                     without_repeated_headers)
from estimation.data.compressed_logs import csv_input, data_suffix
from estimation.data.log_cleaning import DEFAULT_MAX_GAP
from estimation.data.log_formats import is_log_file, read_log_frame
from estimation.data.records import (csv_head, csv_options, csv_units, in_the_format, read_csv_frame, read_parquet_frame, read_record,
                                     segments_from_frame)
from dynamics.measurements import Measurements

#: motor-side column prefix -> the joint-side prefix it converts to
MOTOR_COLUMNS: dict[str, str] = {"qm": "q", "dqm": "dq", "ddqm": "ddq", "taum": "tau", "im": "tau"}
_MOTOR_COLUMN = re.compile(r"^(qm|dqm|ddqm|taum|im)(\d+)$")


def motor_columns(columns) -> list[str]:
    return [str(column).strip() for column in columns if _MOTOR_COLUMN.match(str(column).strip())]


def _csv_header(path: Path) -> list[str]:
    """The column names of a CSV file, split by its delimiter (a comma, or the other one a header without commas
    holds: :func:`estimation.data.loading.other_delimiter`), as :func:`read_csv_frame` reads them."""
    try:
        head = csv_head(path)  # comment lines above the header skipped, a commented header read
    except OSError as error:
        raise MeasurementError(f"cannot read {path}: {error}") from None
    header = head.header.lstrip("\ufeff \t")[1:] if head.commented_header else head.header
    return [name.strip().strip('"\'') for name in head.names(other_delimiter(header) or ",")]


def _read_frame(path: Path) -> pd.DataFrame:
    try:
        return read_parquet_frame(path) if data_suffix(path) == ".parquet" else read_csv_frame(path)
    except (ValueError, OSError, pd.errors.ParserError) as error:
        raise MeasurementError(f"cannot read {path}: {error}") from None


def joint_side_frame(frame: pd.DataFrame, transmission: Transmission | None, n_joints: int,
                     source: str = "data", *, check_signs: bool = True) -> pd.DataFrame:
    """``frame`` with its motor-side columns converted to joint-side ones (see the module docstring); ``check_signs``:
    the power-sign check on ``frame`` (a block of a record read in blocks: checked on the whole record instead,
    :func:`joint_side_copies`)."""
    frame = frame.rename(columns=lambda name: str(name).strip())
    present = motor_columns(frame.columns)
    if not present:
        return frame
    if transmission is None:
        raise TransmissionError(f"{source}: motor-side columns ({', '.join(present[:3])}…) need the transmission: "
                                "--transmission FILE, a URDF with <transmission> elements, or a built-in robot that has one")
    if transmission.n_motors != n_joints:
        raise TransmissionError(f"{source}: the transmission has {transmission.n_motors} motors for {n_joints} joints")
    converted = frame.copy()
    torque_source = None
    for prefix in ("qm", "dqm", "ddqm", "taum", "im"):
        columns = [f"{prefix}{index}" for index in range(1, n_joints + 1)]
        found = [column for column in columns if column in frame.columns]
        if not found:
            continue
        if len(found) != n_joints:
            missing = [column for column in columns if column not in frame.columns]
            raise MissingColumnError(f"{source}: motor column(s) {', '.join(missing)} missing (the others of {prefix} "
                                     "are present: a coupled transmission needs every motor)")
        target = MOTOR_COLUMNS[prefix]
        targets = [f"{target}{index}" for index in range(1, n_joints + 1)]
        clash = [column for column in targets if column in frame.columns]
        if clash or (prefix in ("taum", "im") and torque_source is not None):
            raise MeasurementError(f"{source}: both {prefix}1..{prefix}{n_joints} and "
                                   f"{(clash or [torque_source + '1'])[0]}…: give the joint-side or the motor-side "
                                   "columns, not both")
        values = frame[columns].apply(pd.to_numeric, errors="coerce").to_numpy(dtype=float)
        # a row whose motor cells are all empty stays empty on the joint side: a logger's dropout, dropped by the
        # reader as on the joint side (estimation.data.records.dropouts); an empty cell beside others, text or inf
        # stays an error
        empty = np.all(frame[columns].isna().to_numpy(), axis=1)
        if not np.all(np.isfinite(values[~empty])):
            raise MeasurementError(f"{source}: motor columns {prefix}1..{prefix}{n_joints} hold NaN/inf or text")
        values = np.where(empty[:, None], 0.0, values)
        if prefix in ("taum", "im"):
            torque_m = values if prefix == "taum" else transmission.torques_from_currents(values)
            joint = transmission.joint_torques(torque_m)
            torque_source = prefix
        elif prefix == "qm":
            joint = transmission.joint_positions(values)  # with the joint offsets
        else:
            joint = transmission.joint_rates(values)
        joint = np.where(empty[:, None], np.nan, joint)
        converted = converted.drop(columns=columns)
        for index, column in enumerate(targets):
            converted[column] = joint[:, index]
    if torque_source is not None and check_signs:
        velocity, tau, q = _velocities_and_torques(converted, n_joints)
        if velocity is not None:
            check_power_signs(transmission, velocity, tau, source=source, q=q)
    return converted


def _numeric(frame: pd.DataFrame, columns: list[str]) -> np.ndarray:
    return frame[columns].apply(pd.to_numeric, errors="coerce").to_numpy(dtype=float)


def _velocities_and_torques(frame: pd.DataFrame, n_joints: int
                            ) -> tuple[np.ndarray | None, np.ndarray, np.ndarray | None]:
    """Joint velocities, torques and positions (``None`` without ``q``) for the power-sign check, on the rows where
    all are finite.

    The recorded ``dq`` when present; else the derivative of ``q`` along the time stamps, the rows
    ordered by ``t`` and a repeated stamp kept once (a log that writes a sample twice must not skip
    the check), or along the row order without ``t`` (only the sign of the power matters). ``None``
    when neither ``dq`` nor ``q`` is there or fewer than 3 rows remain.
    """
    joints = range(1, n_joints + 1)
    tau = _numeric(frame, [f"tau{j}" for j in joints])
    q = _numeric(frame, [f"q{j}" for j in joints]) if all(f"q{j}" in frame.columns for j in joints) else None
    if all(f"dq{j}" in frame.columns for j in joints):
        velocity = _numeric(frame, [f"dq{j}" for j in joints])
    elif q is not None:
        t = _numeric(frame, ["t"])[:, 0] if "t" in frame.columns else np.arange(float(len(frame)))
        rows = np.flatnonzero(np.isfinite(t) & np.all(np.isfinite(q), axis=1))
        rows = rows[np.argsort(t[rows], kind="stable")]
        rows = rows[np.concatenate([[True], np.diff(t[rows]) > 0])] if rows.size else rows  # each stamp once
        if rows.size < 3:
            return None, tau, None
        velocity = np.full_like(q, np.nan)
        velocity[rows] = np.gradient(q[rows], t[rows], axis=0)
    else:
        return None, tau, None
    finite = np.all(np.isfinite(velocity), axis=1) & np.all(np.isfinite(tau), axis=1)
    if q is not None:
        finite &= np.all(np.isfinite(q), axis=1)
    if finite.sum() < 3:
        return None, tau, None
    return velocity[finite], tau[finite], None if q is None else q[finite]


def read_record_with_transmission(path: str | Path, *, model: IdentificationModel, transmission: Transmission | None,
                                  max_gap: float = DEFAULT_MAX_GAP, split: bool = True,
                                  joint_offsets: ArrayLike | None = None,
                                  joint_directions: JointDirections | None = None) -> tuple[Measurements, ...]:
    """:func:`estimation.data.records.read_record` (the segments of one file), motor-side columns converted first;
    ``joint_directions`` (``--joint-offsets``' signs: :class:`dynamics.transmission.JointDirections`) applied to
    the joint positions, rates and torques read, then ``joint_offsets`` (one a joint, rad or m: ``--joint-offsets``)
    added to the joint positions, after the transmission's conversion."""
    segments = _read_record(path, model=model, transmission=transmission, max_gap=max_gap, split=split)
    if joint_directions is not None and joint_directions.reversed:
        segments = tuple(directed(segment, joint_directions) for segment in segments)
    if joint_offsets is None:
        return segments
    offsets = np.asarray(joint_offsets, dtype=float).reshape(-1)
    if offsets.shape != (model.robot.n_joints,):
        raise ValueError(f"{offsets.size} joint offsets for the {model.robot.n_joints} joints of {model.robot.name}")
    return tuple(replace(segment, q=segment.q + offsets) for segment in segments)


def directed(segment: Measurements, directions: JointDirections) -> Measurements:
    """``segment`` in the description's directions: ``q``, ``dq``, ``ddq`` of each joint times its sign, its joint
    torque times its torque sign (the base wrench as it is)."""
    if len(directions.signs) != segment.n_joints:
        raise ValueError(f"{len(directions.signs)} joint signs for the {segment.n_joints} joints of the record")
    signs, torque = np.asarray(directions.signs), np.asarray(directions.torque_signs)

    def times(values, factor):
        return None if values is None else values * factor

    return replace(segment, q=segment.q * signs, dq=times(segment.dq, signs), ddq=times(segment.ddq, signs),
                   tau=times(segment.tau, torque))


def _read_record(path: str | Path, *, model: IdentificationModel, transmission: Transmission | None,
                 max_gap: float, split: bool) -> tuple[Measurements, ...]:
    source, path = path, Path(os.fspath(path))
    if data_suffix(path) not in (".csv", ".parquet") or not path.is_file():
        return read_record(source, model=model, max_gap=max_gap, split=split)  # its messages for a folder, a format
    if is_log_file(source):  # a table read through a column map: motor columns it maps (im1=...) converted too
        frame = read_log_frame(source, joint_names=model.robot.joint_names, n_joints=model.robot.n_joints)
        if motor_columns(frame.columns):
            frame = joint_side_frame(frame, transmission, model.robot.n_joints, source=str(path))
        return segments_from_frame(frame, model=model, source=str(path), max_gap=max_gap, split=split)
    header = _csv_header(path) if data_suffix(path) == ".csv" else _read_frame(path).columns
    if not motor_columns(header) and "q1" in {str(name).strip() for name in header}:
        return read_record(path, model=model, max_gap=max_gap, split=split)
    frame = _read_frame(path)
    if not motor_columns(header):  # a controller's log may hold motor currents (actual_current_0..: im1..)
        frame = in_the_format(frame, path, model, servos=None if transmission is None else transmission.servos)
        if not motor_columns(frame.columns):
            return segments_from_frame(frame, model=model, source=str(path), max_gap=max_gap, split=split)
    frame = joint_side_frame(frame, transmission, model.robot.n_joints, source=str(path))
    return segments_from_frame(frame, model=model, source=str(path), max_gap=max_gap, split=split)


# ---------------------------------------------------------------- joint-side copies for the streamed path
#
# The streamed path (records read in blocks: ``--chunk-size``, or past ``--memory-budget``) reads joint-side columns
# of .csv and .parquet files by path, in many passes and across process boundaries. A motor-side record
# (``--transmission``) or one whose joint zeros or directions are given (``--joint-offsets``) is converted once,
# block by block, into a joint-side copy holding what the in-memory reader makes of it row by row (the
# transmission's conversion, then the directions, then the offsets: :func:`read_record_with_transmission`), and
# the streamed path reads the copy. Memory: one block; disk: one copy of each converted file.


def _frames(path: Path, chunk_size: int) -> Iterator[pd.DataFrame]:
    """The rows of a .csv or .parquet file as frames of ``chunk_size`` rows."""
    try:
        if data_suffix(path) == ".csv":
            factors = csv_units(path)  # a units row (its units converted), ';' as the joint side
            options = csv_options(path)
            with csv_input(path) as source, pd.read_csv(source, chunksize=chunk_size, **options) as reader:
                for frame in reader:
                    yield in_si_units(without_repeated_headers(frame, str(path)), factors)
            return
        try:
            import pyarrow.parquet
        except ImportError:
            raise MeasurementError(f"{path}: reading Parquet needs pyarrow (pip install pyarrow)") from None
        for batch in pyarrow.parquet.ParquetFile(path).iter_batches(batch_size=chunk_size):
            yield batch.to_pandas()
    except (ValueError, OSError, pd.errors.ParserError) as error:
        raise MeasurementError(f"cannot read {path}: {error}") from None


class _PowerSums:
    """A record's mean power ``τ_j q̇_j``, mean absolute power and position span by joint, summed block by block
    (:func:`check_power_signs`' rule on the whole record: :func:`dynamics.transmission.check_mean_power`). A block's
    velocities derived from its positions differ from the whole record's at the block's two edge rows (one-sided
    differences): the means differ by about 2 rows a block, immaterial to a sign test at a 20 % tolerance."""

    def __init__(self, n_joints: int) -> None:
        self.power, self.absolute, self.count = np.zeros(n_joints), np.zeros(n_joints), 0
        self.low, self.high, self.positions = np.full(n_joints, np.inf), np.full(n_joints, -np.inf), True

    def add(self, frame: pd.DataFrame, n_joints: int) -> None:
        velocity, tau, q = _velocities_and_torques(frame, n_joints)
        if velocity is None:
            return
        power = tau * velocity
        self.power += power.sum(axis=0)
        self.absolute += np.abs(power).sum(axis=0)
        self.count += power.shape[0]
        if q is None:
            self.positions = False
        else:
            self.low, self.high = np.minimum(self.low, q.min(axis=0)), np.maximum(self.high, q.max(axis=0))

    def check(self, transmission: Transmission, source: str) -> None:
        if self.count < 3:
            return
        moves = (self.high - self.low >= MIN_SWEEP) if self.positions else np.ones(self.power.shape, dtype=bool)
        check_mean_power(transmission, self.power / self.count, self.absolute / self.count, moves, source=source)


def _directed_frame(frame: pd.DataFrame, n_joints: int, offsets: np.ndarray | None,
                    directions: JointDirections | None) -> pd.DataFrame:
    """``frame``'s joint-side columns in the description's directions, then its positions plus ``offsets``
    (:func:`read_record_with_transmission`'s order)."""
    frame = frame.copy()
    signs = None if directions is None or not directions.reversed else np.asarray(directions.signs, dtype=float)
    torque = None if signs is None else np.asarray(directions.torque_signs, dtype=float)
    for index in range(n_joints):
        for prefix, factor in (("q", signs), ("dq", signs), ("ddq", signs), ("tau", torque)):
            column = f"{prefix}{index + 1}"
            if factor is not None and column in frame.columns:
                frame[column] = pd.to_numeric(frame[column], errors="coerce") * factor[index]
        column = f"q{index + 1}"
        if offsets is not None and column in frame.columns:
            frame[column] = pd.to_numeric(frame[column], errors="coerce") + offsets[index]
    return frame


def joint_side_copies(paths: Sequence[str | Path], folder: str | Path, *, n_joints: int,
                      transmission: Transmission | None, joint_offsets: ArrayLike | None = None,
                      joint_directions: JointDirections | None = None, chunk_size: int = 100_000,
                      model: IdentificationModel | None = None) -> list[Path]:
    """Joint-side copies of ``paths`` in ``folder`` (section comment above), one a file, in order: each .csv or
    .parquet file with motor-side columns converted by ``transmission``, then ``joint_directions`` and
    ``joint_offsets`` applied to its joint-side columns, written as Parquet (float64: exact) under
    ``folder/<index>/<the file's name>.parquet``, read and written ``chunk_size`` rows at a time; the power-sign check
    of :func:`joint_side_frame` on each whole file (:class:`_PowerSums`). A file that needs nothing converted is
    returned as it is. ``model``: a file without the format's joint columns read as the in-memory reader reads it
    (:func:`~estimation.data.records.in_the_format`: a controller's log, whose motor currents are motor-side
    columns), block by block, said with its first block."""
    folder = Path(folder)
    offsets = None if joint_offsets is None else np.asarray(joint_offsets, dtype=float).reshape(-1)
    if offsets is not None and offsets.shape != (n_joints,):
        raise ValueError(f"{offsets.size} joint offsets for {n_joints} joints")
    directed = offsets is not None or (joint_directions is not None and joint_directions.reversed)
    copies: list[Path] = []
    for index, source in enumerate(paths):
        path = Path(os.fspath(source))
        if data_suffix(path) not in (".csv", ".parquet") or not path.is_file() or is_log_file(source):
            copies.append(source)  # the streamed reader names what it cannot read
            continue
        header = _csv_header(path) if data_suffix(path) == ".csv" else \
            next(_frames(path, 1)).columns
        formatted = model is not None and not motor_columns(header) and not _in_format(header)
        if formatted:  # a controller's log: its columns as the in-memory reader names them (currents: im1..)
            header = formatted_header(path, model)
        if not motor_columns(header) and not directed:
            copies.append(source)
            continue
        target = folder / str(index) / f"{path.stem}.parquet"
        target.parent.mkdir(parents=True, exist_ok=True)
        power, writer = _PowerSums(n_joints), None
        try:
            for block, frame in enumerate(_frames(path, chunk_size)):
                if formatted:
                    with warnings.catch_warnings():
                        if block:
                            warnings.simplefilter("ignore")  # said with the first block
                        frame = in_the_format(frame, path, model)
                frame = joint_side_frame(frame, transmission, n_joints, source=str(path), check_signs=False)
                if any(str(column).startswith(("taum", "im")) for column in motor_columns(header)):
                    power.add(frame, n_joints)
                if directed:
                    frame = _directed_frame(frame, n_joints, offsets, joint_directions)
                writer = _written(frame, target, writer)
        finally:
            if writer is not None:
                writer.close()
        power.check(transmission, str(path))
        copies.append(target)
    return copies


def _in_format(header: Sequence[Any]) -> bool:
    return bool({"q1", "qm1"} & {str(name).strip() for name in header})


#: the rows of a file read to name its columns as the in-memory reader names them (:func:`formatted_header`)
HEADER_ROWS = 200


def formatted_header(path: str | Path, model: IdentificationModel) -> list[str]:
    """The columns of the .csv or .parquet file ``path`` once named as the in-memory reader names the whole table
    (:func:`~estimation.data.records.in_the_format`, read from its first :data:`HEADER_ROWS` rows, nothing said):
    a controller's log's columns under the format's names (its motor currents as ``im1``..)."""
    path = Path(os.fspath(path))
    header = _csv_header(path) if data_suffix(path) == ".csv" else next(_frames(path, 1)).columns
    if _in_format(header):
        return [str(name) for name in header]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # said when the file is read
        try:
            return [str(name) for name in in_the_format(next(_frames(path, HEADER_ROWS)), path, model).columns]
        except (ValueError, KeyError, MeasurementError):
            return [str(name) for name in header]  # the reader names the fault


def divided_torque_copies(paths: Sequence[str | Path], folder: str | Path, gains: Mapping[str, float], *,
                          chunk_size: int = 100_000) -> list[Path]:
    """Copies of ``paths`` in ``folder``, one a file, in order, with each torque column named in ``gains``
    (``{"tau1": g_1, …}``) divided by its gain (the per-joint torque gains of :mod:`estimation.consistent.torque_gains`,
    which the in-memory diagnosis divides its records by): written as Parquet (float64: exact) under
    ``folder/<index>/<the file's name>.parquet``, read and written ``chunk_size`` rows at a time, so that the streamed
    diagnosis reads the divided torques in bounded memory. Every other column is copied as it is.

    Raises
    ------
    ValueError
        A file that is not a .csv or .parquet file, or lacks a torque column of ``gains``.
    """
    folder = Path(folder)
    copies: list[Path] = []
    for index, source in enumerate(paths):
        path = Path(os.fspath(source))
        if data_suffix(path) not in (".csv", ".parquet") or not path.is_file() or is_log_file(source):
            raise ValueError(f"{source}: only .csv and .parquet files are copied with their torques divided")
        target = folder / str(index) / f"{path.stem}.parquet"
        target.parent.mkdir(parents=True, exist_ok=True)
        writer = None
        try:
            for frame in _frames(path, chunk_size):
                missing = [column for column in gains if column not in frame.columns]
                if missing:
                    raise ValueError(f"{source}: no column {', '.join(missing)} to divide by its gain")
                frame = frame.copy()
                for column, gain in gains.items():
                    frame[column] = pd.to_numeric(frame[column], errors="coerce").astype("float64") / float(gain)
                writer = _written(frame, target, writer)
        finally:
            if writer is not None:
                writer.close()
        copies.append(target)
    return copies


def _written(frame: pd.DataFrame, target: Path, writer: Any) -> Any:
    """``frame`` appended to the Parquet file ``target`` (``writer``: its writer, ``None`` before the first block):
    numeric columns as float64 (exact), the others as text, the first block's columns the file's."""
    import pyarrow
    import pyarrow.parquet

    if writer is None:
        fields = [pyarrow.field(str(name), pyarrow.float64() if pd.api.types.is_numeric_dtype(dtype)
                                else pyarrow.string()) for name, dtype in frame.dtypes.items()]
        writer = pyarrow.parquet.ParquetWriter(target, pyarrow.schema(fields))
    columns = {}
    for field in writer.schema:
        values = frame[field.name]
        if pyarrow.types.is_floating(field.type):
            columns[field.name] = pd.to_numeric(values, errors="coerce").astype("float64")
        else:
            columns[field.name] = values.astype(object).where(values.notna(), None).map(
                lambda value: None if value is None else str(value))
    writer.write_table(pyarrow.Table.from_pandas(pd.DataFrame(columns), schema=writer.schema, preserve_index=False))
    return writer
