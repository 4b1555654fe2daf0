"""Each joint's training range, and whether another record leaves it: extrapolation said, not silent.

A model identified on one motion is used on others. Its rigid-body parameters hold wherever the description does,
but what the training record measured of them (and of the friction laws and other velocity-dependent terms, which
extrapolate worse) is measured only where the record went. The range of a joint is that of the samples the fit
used (after holds, trims and rows at rest were dropped)::

    q_min_j = min_t q_j(t),   q_max_j = max_t q_j(t),   dq_max_j = max_t |q̇_j(t)|

stored in the model file (``model_file["training_range"]``). A record leaves joint ``j``'s range where
``q_j < q_min_j − ε_q`` or ``q_j > q_max_j + ε_q`` or ``|q̇_j| > dq_max_j + ε_v`` with the tolerances
``ε_q = max(2 % (q_max_j − q_min_j), 10⁻³)`` and ``ε_v = max(5 % dq_max_j, 10⁻³)`` (a repeat of the training motion,
its noise and filter edges, stays inside). The check reports, per joint, how far beyond the range (position below,
above; speed above) and on what fraction of the samples it is beyond the range and its tolerance; :class:`ExtrapolationWarning` names each joint that leaves it.

::

    ranges = TrainingRange.of(train.q, train.dq, robot.joint_names)
    check = ranges.check(test.q, test.dq)          # RangeCheck
    check.to_dict()                                  # {"joint2": {"outside": True, "fraction": 0.12, …}, …}
    for line in check.messages("the test record"):
        warnings.warn(line, ExtrapolationWarning)

The streamed path accumulates the same minima and maxima chunk by chunk (:meth:`TrainingRange.merged`): min and max
are exact under any split, so memory and streamed agree on the same samples.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = ["POSITION_TOLERANCE", "SPEED_TOLERANCE", "UNKNOWN_RANGE", "ExtrapolationWarning", "JointExcursion",
           "RangeCheck", "TrainingRange", "merged_ranges"]

#: the position tolerance, a fraction of the joint's training span (at least :data:`ABSOLUTE_TOLERANCE`)
POSITION_TOLERANCE = 0.02
#: the speed tolerance, a fraction of the joint's largest training speed (at least :data:`ABSOLUTE_TOLERANCE`)
SPEED_TOLERANCE = 0.05
#: the least tolerance, in the joint's units (rad, m; per s)
ABSOLUTE_TOLERANCE = 1e-3
#: what is said of a model file that holds no training range (written before ranges were stored)
UNKNOWN_RANGE = ("the model file holds no training range (written by an earlier release): cannot tell whether the "
                 "record leaves the joints' training range; identify again to store it")


class ExtrapolationWarning(UserWarning):
    """A record takes a joint outside the positions or speeds the model's training record measured: the model
    extrapolates there."""


def _joint_arrays(q: ArrayLike, dq: ArrayLike | None, n_joints: int) -> tuple[NDArray[np.float64], NDArray | None]:
    q = np.asarray(q, dtype=float)
    if q.ndim != 2 or q.shape[1] != n_joints:
        raise ValueError(f"q must be (N, {n_joints}), got shape {q.shape}")
    if dq is None:
        return q, None
    dq = np.asarray(dq, dtype=float)
    if dq.shape != q.shape:
        raise ValueError(f"dq must be shaped as q {q.shape}, got {dq.shape}")
    return q, dq


@dataclass(frozen=True)
class JointExcursion:
    """How a record stands against one joint's training range.

    Attributes
    ----------
    joint
        The joint's name.
    below, above
        How far the record's position goes below ``q_min`` and above ``q_max`` (``0``: not).
    speed_above
        How far the record's ``|q̇|`` goes above ``dq_max`` (``0``: not; ``None``: the record holds no speed).
    fraction
        The fraction of the record's samples beyond the range and its tolerance (position or speed); ``None`` when
        the record's own range alone was compared (:meth:`TrainingRange.check_range`: the streamed path, which
        holds no samples).
    outside
        Whether the record leaves the range beyond the tolerances (module docstring).
    training, tolerance
        The joint's training range (``q_min``, ``q_max``, ``dq_max``) and the tolerances (``position``,
        ``speed``) the check allowed beyond it.
    """

    joint: str
    below: float
    above: float
    speed_above: float | None
    fraction: float | None
    outside: bool
    training: Mapping[str, float]
    tolerance: Mapping[str, float]

    def to_dict(self) -> dict[str, Any]:
        return {"outside": self.outside, "fraction": self.fraction, "position_below": self.below,
                "position_above": self.above, "speed_above": self.speed_above, "training": dict(self.training),
                "tolerance": dict(self.tolerance)}

    def statement(self, *, fraction: bool = True) -> str:
        """The joint, by how much (each excursion beyond its tolerance) and on what fraction of the samples (with
        ``fraction`` and when known)."""
        beyond = []
        low, high = self.training["q_min"], self.training["q_max"]
        if self.below > self.tolerance["position"]:
            beyond.append(f"positions down to {low - self.below:.4g} (training {low:.4g}, {self.below:.3g} below)")
        if self.above > self.tolerance["position"]:
            beyond.append(f"positions up to {high + self.above:.4g} (training {high:.4g}, {self.above:.3g} above)")
        if self.speed_above is not None and self.speed_above > self.tolerance.get("speed", np.inf):
            top = self.training["dq_max"]
            beyond.append(f"speeds up to {top + self.speed_above:.4g}/s (training {top:.4g}/s)")
        share = "" if self.fraction is None or not fraction else f", on {100 * self.fraction:.3g} % of the samples"
        return f"{self.joint}: {'; '.join(beyond)}{share}"


@dataclass(frozen=True)
class RangeCheck:
    """A record against the training range, joint by joint (:meth:`TrainingRange.check`)."""

    joints: tuple[JointExcursion, ...]
    n_samples: int

    @property
    def outside(self) -> tuple[JointExcursion, ...]:
        """The joints the record takes outside their range."""
        return tuple(joint for joint in self.joints if joint.outside)

    def to_dict(self) -> dict[str, dict[str, Any]]:
        """``{joint: {outside, fraction, position_below, position_above, speed_above, training}}``."""
        return {joint.joint: joint.to_dict() for joint in self.joints}

    def messages(self, record: str = "the record", *, fraction: bool = True) -> list[str]:
        """One line naming the joints that leave the range (none when the record stays inside); ``fraction``: with
        the fraction of the samples beyond it."""
        if not self.outside:
            return []
        return [f"{record} leaves the training range of {len(self.outside)} joint(s), where the model extrapolates "
                f"(the friction and velocity terms most): "
                + "; ".join(joint.statement(fraction=fraction) for joint in self.outside)]


@dataclass(frozen=True)
class TrainingRange:
    """Each joint's position range and largest speed on the samples a fit used (module docstring)."""

    joint_names: tuple[str, ...]
    q_min: NDArray[np.float64]
    q_max: NDArray[np.float64]
    dq_max: NDArray[np.float64] | None
    n_samples: int

    @classmethod
    def of(cls, q: ArrayLike, dq: ArrayLike | None, joint_names: Sequence[str]) -> TrainingRange:
        """The range of the samples ``q`` (and ``dq``, ``None``: no speeds), ``(N, n)`` each."""
        names = tuple(str(name) for name in joint_names)
        q, dq = _joint_arrays(q, dq, len(names))
        if q.shape[0] == 0:
            raise ValueError("no samples to take a training range from")
        return cls(names, np.nanmin(q, axis=0), np.nanmax(q, axis=0),
                   None if dq is None else np.nanmax(np.abs(dq), axis=0), int(q.shape[0]))

    def merged(self, other: TrainingRange | None) -> TrainingRange:
        """The range of both sets of samples (exact: the minimum of minima, the maximum of maxima)."""
        if other is None:
            return self
        if other.joint_names != self.joint_names:
            raise ValueError(f"ranges of other joints: {other.joint_names} against {self.joint_names}")
        dq_max = None if self.dq_max is None or other.dq_max is None else np.maximum(self.dq_max, other.dq_max)
        return TrainingRange(self.joint_names, np.minimum(self.q_min, other.q_min), np.maximum(self.q_max, other.q_max),
                             dq_max, self.n_samples + other.n_samples)

    def to_dict(self) -> dict[str, Any]:
        """``{"joints": {name: {q_min, q_max, dq_max}}, "n_samples", "tolerance"}`` (the model file's key)."""
        return {"joints": {name: {"q_min": float(self.q_min[j]), "q_max": float(self.q_max[j]),
                                  "dq_max": None if self.dq_max is None else float(self.dq_max[j])}
                           for j, name in enumerate(self.joint_names)},
                "n_samples": self.n_samples,
                "tolerance": {"position": POSITION_TOLERANCE, "speed": SPEED_TOLERANCE, "absolute": ABSOLUTE_TOLERANCE}}

    @classmethod
    def from_dict(cls, document: Mapping[str, Any]) -> TrainingRange:
        """The range :meth:`to_dict` wrote; ``ValueError`` naming what is missing or garbled."""
        try:
            joints = document["joints"]
            names = tuple(joints)
            q_min = np.array([float(joints[name]["q_min"]) for name in names])
            q_max = np.array([float(joints[name]["q_max"]) for name in names])
            speeds = [joints[name].get("dq_max") for name in names]
            dq_max = None if any(value is None for value in speeds) else np.array(speeds, dtype=float)
            n_samples = int(document.get("n_samples") or 0)
        except (KeyError, TypeError, ValueError, AttributeError) as error:
            raise ValueError(f"the training range lacks or garbles {error}") from None
        if not names or not (np.all(np.isfinite(q_min)) and np.all(np.isfinite(q_max))) or np.any(q_min > q_max):
            raise ValueError("the training range must hold finite q_min <= q_max for each joint")
        return cls(names, q_min, q_max, dq_max, n_samples)

    def check_range(self, record: TrainingRange) -> RangeCheck:
        """Another record's own range (its minima and maxima, :meth:`of`) against this one: how far beyond, joint by
        joint, as :meth:`check` says it, without the fraction of samples (``None``)."""
        if record.joint_names != self.joint_names:
            raise ValueError(f"ranges of other joints: {record.joint_names} against {self.joint_names}")
        q = np.vstack([record.q_min, record.q_max])
        dq = None if record.dq_max is None else np.vstack([record.dq_max, record.dq_max])
        check = self.check(q, dq)
        return RangeCheck(tuple(replace(joint, fraction=None) for joint in check.joints), record.n_samples)

    def check(self, q: ArrayLike, dq: ArrayLike | None = None) -> RangeCheck:
        """The record's samples ``q`` (and ``dq``) against the range, joint by joint (module docstring)."""
        q, dq = _joint_arrays(q, dq, len(self.joint_names))
        n = q.shape[0]
        span = self.q_max - self.q_min
        position_tolerance = np.maximum(POSITION_TOLERANCE * span, ABSOLUTE_TOLERANCE)
        below = np.clip(self.q_min[None, :] - q, 0.0, None)
        above = np.clip(q - self.q_max[None, :], 0.0, None)
        beyond = (below > position_tolerance[None, :]) | (above > position_tolerance[None, :])
        faster, speed_tolerance = None, None
        if dq is not None and self.dq_max is not None:
            speed_tolerance = np.maximum(SPEED_TOLERANCE * self.dq_max, ABSOLUTE_TOLERANCE)
            faster = np.clip(np.abs(dq) - self.dq_max[None, :], 0.0, None)
            beyond = beyond | (faster > speed_tolerance[None, :])
        joints = []
        for j, name in enumerate(self.joint_names):
            low = float(below[:, j].max()) if n else 0.0
            high = float(above[:, j].max()) if n else 0.0
            speed = None if faster is None else (float(faster[:, j].max()) if n else 0.0)
            outside = low > position_tolerance[j] or high > position_tolerance[j] or \
                (speed is not None and speed > speed_tolerance[j])
            training = {"q_min": float(self.q_min[j]), "q_max": float(self.q_max[j])}
            tolerance = {"position": float(position_tolerance[j])}
            if self.dq_max is not None:
                training["dq_max"] = float(self.dq_max[j])
            if speed_tolerance is not None:
                tolerance["speed"] = float(speed_tolerance[j])
            joints.append(JointExcursion(name, low, high, speed, float(beyond[:, j].mean()) if n else 0.0,
                                         bool(outside), training, tolerance))
        return RangeCheck(tuple(joints), int(n))


def merged_ranges(ranges: Sequence[TrainingRange | None]) -> TrainingRange | None:
    """The range of several parts' samples (``None`` when any part lacks one: the whole range is then unknown)."""
    if not ranges or any(part is None for part in ranges):
        return None
    merged = ranges[0]
    for part in ranges[1:]:
        merged = merged.merged(part)
    return merged
