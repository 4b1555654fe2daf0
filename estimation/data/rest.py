"""Rows at rest, handled deliberately: drop them, or smooth the Coulomb law below a speed.

Why: at rest the true velocity is zero and Coulomb friction is *any* torque in ``[−fc, fc]``
(static friction balances whatever else acts: gravity, the controller's integral action). The
velocity the identification sees there is the derivative of quantised, filtered encoder readings:
noise of zero mean whose sign flips from sample to sample. ``sign(dq)`` of that noise switches the
model's Coulomb term between ``+fc`` and ``−fc`` at random, an error of up to ``2 fc`` on rows
where the measured torque is the holding torque; in least squares it biases every parameter that
correlates with it and raises the validation error (a record with 1.5 s at rest raised joint 2's
validation MSE of a real arm from 30 to 43 N²m²). The same happens, briefly, at each velocity
reversal, and for longer when the joint sticks there under a PD controller.

Two remedies, chosen with ``--rest`` beside ``--min-speed V``:

* ``drop`` (default): samples where any joint moves slower than ``V`` are left out of the fit
  (:func:`drop_rest`), and the count is reported;
* ``smooth``: the Coulomb laws become ``fc · tanh(dq / V)`` (:func:`smooth_coulomb`), which
  predicts no friction at rest rather than a random sign.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from dynamics.measurements import Measurements

RestHandling = Literal["drop", "smooth"]


@dataclass(frozen=True)
class RestSelection:
    """The samples kept (:attr:`measurements`) and how many were dropped as at rest."""

    measurements: Measurements
    dropped: int
    total: int
    min_speed: float

    def to_dict(self) -> dict[str, Any]:
        return {"min_speed": self.min_speed, "dropped": self.dropped, "total": self.total,
                "kept": self.total - self.dropped}


def check_min_speed(min_speed: float) -> float:
    speed = float(min_speed)
    if not (np.isfinite(speed) and speed >= 0):
        raise ValueError(f"--min-speed must be a finite speed >= 0 (rad/s or m/s), got {min_speed}")
    return speed


def coulomb_combinations(effects: tuple[Any, ...]) -> NDArray[np.float64] | None:
    """The rows ``r`` (scaled to a largest ``|r|`` of 1) of the Coulomb laws on joint combinations or
    motors among ``effects`` (:class:`dynamics.effects.motor.CombinationEffect`), ``(k, n)``, or ``None``.

    A law whose smoothing is estimated (``coulomb:tanh[q5+q6]``,
    :class:`dynamics.effects.combination_shapes.TanhCombinationCoulomb`) is left out: its smoothing is
    given by the rows near the motor's rest, which dropping them would remove (the law the
    diagnosis found could then not be fitted again with the same ``--min-speed``)."""
    rows = [np.array(row) / np.max(np.abs(row)) for effect in effects
            if getattr(effect, "kind", None) == "coulomb" and not callable(getattr(effect, "shape_parameters", None))
            for row in getattr(effect, "weights", ())]
    return np.array(rows) if rows else None


def drop_rest(measurements: Measurements, min_speed: float, *, combinations: ArrayLike | None = None,
              source: str = "data") -> RestSelection:
    """Leave out the samples where any joint's ``|dq|`` is below ``min_speed``, or any combination
    ``|r dq|`` (a motor of a coupled wrist, ``q5 + q6``; rows of ``combinations``, see
    :func:`coulomb_combinations`): a motor can stand still while the joints it couples move.

    Raises ``ValueError`` when (almost) nothing is left: fewer than 10 % of the samples, or fewer
    than 2.
    """
    speed = check_min_speed(min_speed)
    if measurements.dq is None:
        raise ValueError(f"{source}: --min-speed needs joint velocities (derive them first)")
    moving = np.all(np.abs(measurements.dq) >= speed, axis=1)
    if combinations is not None:
        moving &= np.all(np.abs(measurements.dq @ np.atleast_2d(np.asarray(combinations, dtype=float)).T) >= speed, axis=1)
    kept = int(moving.sum())
    total = measurements.n_samples
    if kept < max(2, 0.1 * total):
        slowest = np.median(np.abs(measurements.dq), axis=0)
        raise ValueError(f"{source}: --min-speed {speed:g} leaves {kept} of {total} samples (the joints' median "
                         f"speeds are {np.array2string(slowest, precision=3)}): lower it")
    selected = measurements if kept == total else measurements.select(np.flatnonzero(moving))
    return RestSelection(selected, total - kept, total, speed)


def smooth_coulomb(effects: tuple[Any, ...], min_speed: float) -> tuple[Any, ...]:
    """The effects with each Coulomb law (``sign``) replaced by ``tanh(v / V)``; for a motor or a
    joint combination ``v = r q̇``, ``V`` is scaled by the largest ``|r|`` (a motor-side speed)."""
    speed = check_min_speed(min_speed)
    if speed == 0:
        return effects
    smoothed = []
    for effect in effects:
        fields = {field.name for field in dataclasses.fields(effect)} if dataclasses.is_dataclass(effect) else set()
        is_coulomb = getattr(effect, "kind", getattr(effect, "name", "")) == "coulomb"
        if "smoothing" in fields and is_coulomb and effect.smoothing is None:
            weights = getattr(effect, "weights", None)
            scale = 1.0 if weights is None else float(np.max(np.abs(np.array(weights))))
            effect = dataclasses.replace(effect, smoothing=speed * scale)
        smoothed.append(effect)
    return tuple(smoothed)


def holds(t: NDArray[np.float64], q: NDArray[np.float64], longer_than: float) -> list[tuple[int, int]]:
    """The holds of a record: row ranges ``[start, stop)`` over which every joint's position stays exactly what it
    was on the range's first row (the robot stopped: a brake, or a controller holding a pose), lasting more than
    ``longer_than`` seconds from the first row to the last.

    Why: at a hold the true velocity is zero and the torque holds whatever static friction or a brake takes, any
    share of ``[−fc, fc]``; the velocity derived from the held positions is the filter's transient and noise,
    whose sign switches the Coulomb columns between ``+fc`` and ``−fc`` on every row of the hold. A robot that
    moves, even slowly, changes some joint's position within ``longer_than`` (quantised encoders included): runs
    of a few repeated positions (the TX40's longest is 7.6 ms at 5 kHz) are not holds at the reader's
    ``max_gap`` of 50 ms.
    """
    if q.shape[0] < 2:
        return []
    return held_runs(t, np.r_[False, np.all(q[1:] == q[:-1], axis=1)], longer_than)


def held_runs(t: NDArray[np.float64], same: NDArray[np.bool_], longer_than: float) -> list[tuple[int, int]]:
    """:func:`holds` from ``same``: whether each row holds the position of the row before (the first row: ``False``),
    as a pass over a record too long for memory has them (:mod:`estimation.streaming.time_base`)."""
    edges = np.flatnonzero(np.diff(np.r_[0, np.asarray(same).astype(np.int8), 0]))
    found = []
    for first, last in zip(edges[::2], edges[1::2]):  # rows first..last-1 repeat row first-1's position
        start, stop = first - 1, last
        if t[stop - 1] - t[start] > longer_than:
            found.append((int(start), int(stop)))
    return found


def without_holds(segment: Measurements, longer_than: float) -> tuple[tuple[Measurements, ...], int]:
    """``segment`` cut at its :func:`holds`: the parts between them (of two rows or more), and the number of rows
    left out (the holds' and those of parts too short to keep)."""
    found = holds(segment.t, segment.q, longer_than)
    if not found:
        return (segment,), 0
    parts = [segment.select(rows) for rows in between_holds(segment.n_samples, found)]
    return tuple(parts), segment.n_samples - sum(part.n_samples for part in parts)


def between_holds(n_samples: int, found: list[tuple[int, int]]) -> list[slice]:
    """The row ranges of a record of ``n_samples`` rows between its holds ``found`` (:func:`holds`), each of two
    rows or more."""
    parts, begin = [], 0
    for start, stop in [*found, (n_samples, n_samples)]:
        if start - begin >= 2:
            parts.append(slice(begin, start))
        begin = stop
    return parts


def held_rows(t: NDArray[np.float64], q: NDArray[np.float64], longer_than: float) -> NDArray[np.bool_]:
    """Rows within the :func:`holds` of a record: the robot still, its velocity and acceleration exactly zero."""
    held = np.zeros(t.shape[0], dtype=bool)
    for start, stop in holds(t, q, longer_than):
        held[start:stop] = True
    return held
