"""Input checks shared by the servo-arm workflow: one-channel signals, uniform time columns and
per-joint ranges.

They raise ``ValueError`` (``TypeError`` for complex values) with a message that names the signal,
the column, the row or the bound at fault.
"""

from __future__ import annotations

import numpy as np


def single_channel(values: np.ndarray, name: str) -> np.ndarray:
    """A real one-channel signal (``(N,)``, ``(N, 1)`` or ``(1, N)``) as a 1-D float array; several
    channels are an error (they would otherwise be interleaved into one signal)."""
    array = np.asarray(values)
    if np.iscomplexobj(array):
        raise TypeError(f"signal {name} must be real, got complex values")
    if array.ndim not in (1, 2) or sum(length > 1 for length in array.shape) > 1:  # (N,), (N, 1), (1, N)
        raise ValueError(f"signal {name} must be one channel, (N,), (N, 1) or (1, N), got shape {array.shape}: "
                         "use one channel at a time")
    return array.astype(float).reshape(-1)


def check_informative(u: np.ndarray, y: np.ndarray) -> None:
    """A constant input excites nothing and a constant output shows nothing: ``ValueError`` naming which."""
    for name, signal, meaning in (("u", u, "input"), ("y", y, "output")):
        if np.ptp(signal) == 0:
            raise ValueError(f"{meaning} {name} is constant ({signal[0]:g}) over the record: "
                             "there is nothing to identify from it")


def rank_deficiency_message(what: str) -> str:
    """The message for a regressor (``what``) that does not determine every coefficient."""
    return (f"{what} is rank deficient: the data do not determine every coefficient (the output a copy or "
            "a filtered copy of the input, or too little excitation for these orders)")


def check_uniform_time(t: np.ndarray, *, dt: float | None = None, name: str = "t") -> float:
    """Return the sample time of a uniform time column, or raise ``ValueError`` naming the first irregular sample."""
    t = np.asarray(t, dtype=float).reshape(-1)
    if t.size < 2:
        raise ValueError(f"time column {name!r} needs at least two samples")
    if not np.all(np.isfinite(t)):
        raise ValueError(f"time column {name!r} holds NaN/inf")
    if dt is not None and not (np.isfinite(dt) and dt > 0):
        raise ValueError(f"sample time dt must be positive and finite, got {dt!r}")
    steps = np.diff(t)
    step = float(np.median(steps)) if dt is None else float(dt)
    if step <= 0:
        raise ValueError(f"time column {name!r} is not increasing")
    bad = np.flatnonzero(np.abs(steps - step) > 1e-6 * max(step, 1.0) + 1e-9)
    if bad.size:
        i = int(bad[0])
        raise ValueError(
            f"time column {name!r} is not uniform: step {steps[i]:.6g} s between rows {i} and {i + 1} "
            f"(t = {t[i]:.6g} s), expected {step:.6g} s"
        )
    return step


def check_in_ranges(u: np.ndarray, ranges: tuple[tuple[float, float], ...], *, prefix: str = "u") -> None:
    """Raise ``ValueError`` naming the column, sample and bound of the first value outside its joint range."""
    if u.ndim != 2 or u.shape[1] != len(ranges):
        raise ValueError(f"input must have {len(ranges)} columns {prefix}1..{prefix}{len(ranges)}, got shape {u.shape}")
    tol = 1e-9
    for j, (low, high) in enumerate(ranges):
        column = u[:, j]
        if not np.all(np.isfinite(column)):
            raise ValueError(f"column {prefix}{j + 1} holds NaN/inf")
        below, above = np.flatnonzero(column < low - tol), np.flatnonzero(column > high + tol)
        if below.size or above.size:
            i = int(below[0]) if below.size else int(above[0])
            side, bound = ("below the lower", low) if below.size else ("above the upper", high)
            raise ValueError(f"column {prefix}{j + 1} = {column[i]:.6g} rad at row {i} is {side} joint-{j + 1} bound {bound} rad")
