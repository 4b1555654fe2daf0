"""The measured-data container and its file format.

Columns (CSV or Parquet, SI units)::

    t, q1..qn                       always
    dq1..dqn, ddq1..ddqn            optional (derived by preprocessing when absent)
    tau1..taun                      joint torques/forces (internal model)
    fx fy fz mx my mz               reaction wrench on the robot from its base, in the base
                                    frame, moments about the base origin (external model)

Reading with checks (missing columns, NaN, time, degrees…) lives in :mod:`estimation.data.loading`.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
from numpy.typing import NDArray

from dynamics.channels import WRENCH_CHANNELS, is_joint_torque, torque_joint
from dynamics.runtime.output_files import atomic_output


def joint_columns(prefix: str, n_joints: int) -> list[str]:
    """``[prefix1, …, prefixn]``."""
    return [f"{prefix}{index}" for index in range(1, n_joints + 1)]


def _real_array(values: Any, name: str) -> NDArray[np.float64]:
    """``values`` as a float array, or a ``TypeError`` naming ``name``."""
    array = np.asarray(values)
    if np.iscomplexobj(array) or not (np.issubdtype(array.dtype, np.number) or array.dtype == bool):
        raise TypeError(f"{name} must hold real numbers, got dtype {array.dtype}")
    return array.astype(float, copy=False)


@dataclass(frozen=True)
class Measurements:
    """Samples of one experiment.

    Attributes
    ----------
    t
        ``(N,)`` time, s, strictly increasing.
    q, dq, ddq
        ``(N, n)`` joint positions, velocities, accelerations (``dq``/``ddq`` may be ``None``).
    tau
        ``(N, n)`` joint torques/forces or ``None``.
    wrench
        ``(N, 6)`` base reaction wrench ``fx fy fz mx my mz`` or ``None``.
    metadata
        Free-form provenance (robot, trajectory, seed, effects simulated…).
    recorded
        After preprocessing (filtered or period-averaged channels): the torques and wrench as
        recorded, on the samples kept, with the derived motion at their instants; ``None`` when
        these measurements are themselves as recorded. Errors are measured against it
        (:func:`estimation.identification.validation.compare`).
    recorded_rows
        ``(len(recorded),)`` for each sample of :attr:`recorded`, the sample of these measurements it stands
        beside (a recorded time stamp between two samples of a resampled grid: the nearest; a sample of an
        averaged period: that period's sample); ``None``: :attr:`recorded` holds these samples one by one, or
        whole periods of them one after the other. Selecting samples keeps the recorded ones beside them.
    """

    t: NDArray[np.float64]
    q: NDArray[np.float64]
    dq: NDArray[np.float64] | None = None
    ddq: NDArray[np.float64] | None = None
    tau: NDArray[np.float64] | None = None
    wrench: NDArray[np.float64] | None = None
    metadata: dict[str, Any] = field(default_factory=dict)
    recorded: Measurements | None = None
    recorded_rows: NDArray[np.int_] | None = None

    def __post_init__(self) -> None:
        t = _real_array(self.t, "t")
        if t.ndim != 1:
            raise ValueError(f"t must be 1-D (one time per sample), got shape {t.shape}")
        object.__setattr__(self, "t", t)
        q = _real_array(self.q, "q")
        if q.ndim == 1:  # one joint (e.g. a linear axis)
            q = q.reshape(-1, 1)
        if q.ndim != 2:
            raise ValueError(f"q must be (samples, joints), got shape {q.shape}")
        object.__setattr__(self, "q", q)
        expected = {"q": q.shape, "dq": q.shape, "ddq": q.shape, "tau": q.shape, "wrench": (q.shape[0], 6)}
        for name in ("dq", "ddq", "tau", "wrench"):
            values = getattr(self, name)
            if values is None:
                continue
            values = _real_array(values, name)
            if values.ndim == 1 and expected[name][1] == 1:
                values = values.reshape(-1, 1)
            if values.shape != expected[name]:
                raise ValueError(f"{name} has shape {values.shape}, expected {expected[name]} (samples, "
                                 f"{'channels fx..mz' if name == 'wrench' else 'joints'}) to match q")
            object.__setattr__(self, name, values)
        if q.shape[0] != t.shape[0]:
            raise ValueError(f"t has {t.shape[0]} samples, q {q.shape[0]}: they must match")
        if not isinstance(self.metadata, dict):
            raise TypeError(f"metadata must be a dict, got {type(self.metadata).__name__}")
        if self.recorded is not None:
            if not isinstance(self.recorded, Measurements):
                raise TypeError(f"recorded must be Measurements, got {type(self.recorded).__name__}")
            if self.recorded.n_joints != q.shape[1]:
                raise ValueError(f"recorded has {self.recorded.n_joints} joints, these measurements {q.shape[1]}")
        if self.recorded is None:
            object.__setattr__(self, "recorded_rows", None)
        elif self.recorded_rows is not None:
            rows = np.asarray(self.recorded_rows, dtype=np.int_)
            if rows.shape != (self.recorded.n_samples,) or (rows.size and (rows.min() < 0 or rows.max() >= t.shape[0])):
                raise ValueError(f"recorded_rows must give one of these {t.shape[0]} samples for each of the "
                                 f"{self.recorded.n_samples} recorded ones, got shape {rows.shape}")
            object.__setattr__(self, "recorded_rows", rows)

    @property
    def n_samples(self) -> int:
        return self.t.shape[0]

    @property
    def n_joints(self) -> int:
        return self.q.shape[1]

    def channels(self, names: tuple[str, ...] | list[str]) -> NDArray[np.float64]:
        """Measured values of the named channels (``tau2``, ``fz``…) as ``(N, len(names))``."""
        columns = []
        for name in names:
            if name in WRENCH_CHANNELS:
                if self.wrench is None:
                    raise ValueError(f"channel {name!r} needs the base wrench, which these measurements lack")
                columns.append(self.wrench[:, WRENCH_CHANNELS.index(name)])
            elif is_joint_torque(name):
                if self.tau is None:
                    raise ValueError(f"channel {name!r} needs joint torques, which these measurements lack")
                index = torque_joint(name)
                if not 0 <= index < self.n_joints:
                    raise ValueError(f"channel {name!r}: the data have {self.n_joints} joints")
                columns.append(self.tau[:, index])
            else:
                raise ValueError(f"unknown channel {name!r}")
        return np.column_stack(columns)

    def select(self, indices: slice | NDArray[np.int_]) -> Measurements:
        """A subset of the samples."""
        def take(values):
            return None if values is None else values[indices]
        recorded, rows = self.recorded, None
        if recorded is not None and self.recorded_rows is not None:  # the recorded samples beside those chosen
            chosen = np.arange(self.n_samples)[indices]
            renumbered = np.full(self.n_samples, -1)
            renumbered[chosen] = np.arange(chosen.shape[0])
            beside = renumbered[self.recorded_rows]
            kept = np.flatnonzero(beside >= 0)
            if np.any(np.diff(chosen) <= 0):  # reordered: the recorded samples in the order of those chosen
                kept = kept[np.argsort(beside[kept], kind="stable")]
            recorded, rows = recorded.select(kept), beside[kept]
        elif recorded is not None and recorded.n_samples == self.n_samples:  # the same grid: the same samples
            recorded = recorded.select(indices)
        elif recorded is not None and recorded.n_samples % self.n_samples == 0:
            # averaged periods: the recorded channels hold P periods of these samples, one after the other
            chosen = np.arange(self.n_samples)[indices]
            periods = recorded.n_samples // self.n_samples
            recorded = recorded.select(np.concatenate([chosen + k * self.n_samples for k in range(periods)]))
        else:
            recorded = None
        return replace(
            self, t=self.t[indices], q=self.q[indices], dq=take(self.dq), ddq=take(self.ddq),
            tau=take(self.tau), wrench=take(self.wrench), recorded=recorded, recorded_rows=rows,
            metadata=self._selected_segments(np.arange(self.n_samples)[indices]),
        )

    def _selected_segments(self, chosen: NDArray[np.int_]) -> dict[str, Any]:
        """The metadata with the segments of a concatenation (``metadata["segments"]``, ``start``/``stop``
        rows) renumbered for the samples ``chosen``; dropped when the selection reorders the samples."""
        bounds = self.metadata.get("segments")
        if not bounds or bounds[-1]["stop"] != self.n_samples:
            return self.metadata
        metadata = dict(self.metadata)
        if np.any(np.diff(chosen) <= 0):
            metadata.pop("segments")
            return metadata
        renumbered = []
        for entry in bounds:
            start, stop = np.searchsorted(chosen, [entry["start"], entry["stop"]])
            if stop > start:
                renumbered.append({**entry, "start": int(start), "stop": int(stop)})
        metadata["segments"] = renumbered
        return metadata

    def beside_recorded(self) -> NDArray[np.int_]:
        """For each sample of :attr:`as_recorded`, the sample of these measurements it stands beside
        (:attr:`recorded_rows` made explicit)."""
        if self.recorded_rows is not None:
            return self.recorded_rows
        recorded = self.as_recorded
        if recorded.n_samples % self.n_samples:
            raise ValueError(f"{recorded.n_samples} recorded samples beside {self.n_samples}: say which with recorded_rows")
        return np.arange(recorded.n_samples) % self.n_samples

    @property
    def as_recorded(self) -> Measurements:
        """The channels as recorded (with the derived motion): :attr:`recorded`, or these measurements."""
        return self if self.recorded is None else self.recorded

    def to_frame(self) -> pd.DataFrame:
        """The file format as a ``DataFrame``."""
        n = self.n_joints
        data: dict[str, NDArray[np.float64]] = {"t": self.t}
        for prefix, values in (("q", self.q), ("dq", self.dq), ("ddq", self.ddq), ("tau", self.tau)):
            if values is not None:
                data.update(zip(joint_columns(prefix, n), values.T))
        if self.wrench is not None:
            data.update(zip(WRENCH_CHANNELS, self.wrench.T))
        return pd.DataFrame(data)

    def write(self, path: str | Path, *, staged: bool = True) -> None:
        """Write CSV (``.csv``) or Parquet (``.parquet``), atomically (staged beside ``path`` and renamed).

        ``staged=False``: write ``path`` directly, for a path that is already a staged file
        (:meth:`dynamics.runtime.output_files.OutputFiles.stage`): staging it again would leave a nested
        temporary file behind a run killed in between.
        """

        path = Path(path)
        suffix = path.suffix.lower()
        if suffix not in (".parquet", ".csv"):
            raise ValueError(f"unknown data format {path.suffix!r} for {path}: use .csv or .parquet")
        mode = "wb" if suffix == ".parquet" else "w"
        with (atomic_output(path, mode) if staged else open(path, mode)) as stream:
            self._write_frame(stream, suffix)

    def _write_frame(self, stream: Any, suffix: str) -> None:
        frame = self.to_frame()
        if suffix == ".parquet":
            frame.to_parquet(stream, index=False)
        else:
            frame.to_csv(stream, index=False, float_format="%.10g")
