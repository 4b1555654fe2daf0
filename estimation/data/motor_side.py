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
from dataclasses import replace
from pathlib import Path

import numpy as np
import pandas as pd
from numpy.typing import ArrayLike

from dynamics.models import IdentificationModel
from dynamics.transmission import JointDirections, Transmission, TransmissionError, check_power_signs
from estimation.data.loading import MeasurementError, MissingColumnError
from estimation.data.log_cleaning import DEFAULT_MAX_GAP
from estimation.data.log_formats import is_log_file
from estimation.data.records import read_parquet_frame, read_record, segments_from_frame
from dynamics.measurements import Measurements

#: motor-side column prefix -> the joint-side prefix it converts to
MOTOR_COLUMNS: dict[str, str] = {"qm": "q", "dqm": "dq", "ddqm": "ddq", "taum": "tau", "im": "tau"}
_MOTOR_COLUMN = re.compile(r"^(qm|dqm|ddqm|taum|im)(\d+)$")


def motor_columns(columns) -> list[str]:
    return [str(column).strip() for column in columns if _MOTOR_COLUMN.match(str(column).strip())]


def _read_frame(path: Path) -> pd.DataFrame:
    try:
        return read_parquet_frame(path) if path.suffix.lower() == ".parquet" else pd.read_csv(path)
    except (ValueError, OSError, pd.errors.ParserError) as error:
        raise MeasurementError(f"cannot read {path}: {error}") from None


def joint_side_frame(frame: pd.DataFrame, transmission: Transmission | None, n_joints: int,
                     source: str = "data") -> pd.DataFrame:
    """``frame`` with its motor-side columns converted to joint-side ones (see the module docstring)."""
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
        if not np.all(np.isfinite(values)):
            raise MeasurementError(f"{source}: motor columns {prefix}1..{prefix}{n_joints} hold NaN/inf or text")
        if prefix in ("taum", "im"):
            torque_m = values if prefix == "taum" else transmission.torques_from_currents(values)
            joint = transmission.joint_torques(torque_m)
            torque_source = prefix
        elif prefix == "qm":
            joint = transmission.joint_positions(values)  # with the joint offsets
        else:
            joint = transmission.joint_rates(values)
        converted = converted.drop(columns=columns)
        for index, column in enumerate(targets):
            converted[column] = joint[:, index]
    if torque_source is not None:
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
    if path.suffix.lower() not in (".csv", ".parquet") or not path.is_file() or is_log_file(source):
        return read_record(source, model=model, max_gap=max_gap, split=split)  # its messages for a folder, a format
    header = pd.read_csv(path, nrows=0).columns if path.suffix.lower() == ".csv" else _read_frame(path).columns
    if not motor_columns(header):
        return read_record(path, model=model, max_gap=max_gap, split=split)
    frame = joint_side_frame(_read_frame(path), transmission, model.robot.n_joints, source=str(path))
    return segments_from_frame(frame, model=model, source=str(path), max_gap=max_gap, split=split)
