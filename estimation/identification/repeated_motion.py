"""Does the validation record repeat the training motion?

A held-out record confirms an effect on another motion only if it holds another motion. A record of the
same trajectory again (a repeat run) differs from the training record by its noise alone: an effect
fitted to the trajectory's own features (a coupling of two joints that happen to move together, a
position ripple at the positions this trajectory visits) passes it as well as a physical one. Measured
on the real KUKA LWR4+: its run 2 repeats run 1 (positions within 0.4 % of their spread sample by
sample), and effects confirmed on it raised the error on run 3, a faster trajectory, above that of a
plain fit (``benchmarks/README.md``).

:func:`repeated_motion` compares the positions sample by sample from each record's start (a repeat
run is sampled alike), or, when the two records are sampled at different rates (a repeat logged at another
rate, or subsampled), at the training record's times from its start, the validation positions interpolated
there; :data:`REPEAT_FRACTION` of the training motion's spread on every joint makes a repeat. A repeat
shifted in time is not detected.
"""

from __future__ import annotations

import numpy as np

from dynamics.measurements import Measurements

__all__ = ["REPEAT_FRACTION", "STILL_SHARE", "repeated_motion", "repeat_note", "repeated_motion_note", "still_motion",
           "still_spans_note"]

#: two records whose median sampling steps differ by more than this fraction are compared in time, not sample by
#: sample
SAME_RATE = 1e-3

#: the validation positions within this fraction of the training motion's spread (root mean square, every
#: joint) sample by sample: the same motion again
REPEAT_FRACTION = 0.05


#: a validation record whose joints all span less than this share of the training motion's range hardly moves
STILL_SHARE = 0.05


def still_motion(train: Measurements, validation: Measurements) -> bool:
    """Whether every joint of ``validation`` spans less than :data:`STILL_SHARE` of its range in ``train`` (a robot
    holding a pose). Such a record measures little of the dynamics: the choices that read a validation record
    (derivatives, weighting, the default answer) treat it as no validation record, its errors still reported."""
    if validation.q.shape[0] == 0 or train.q.shape[0] == 0 or train.q.shape[1] != validation.q.shape[1]:
        return False
    return bool(np.all(np.ptp(validation.q, axis=0) < STILL_SHARE * np.ptp(train.q, axis=0)))


def still_spans_note(moved: np.ndarray, held: np.ndarray) -> str | None:
    """The warning of a validation record at rest (:func:`still_motion`), from each joint's span (max − min) in the
    training record (``moved``) and in the validation record (``held``), else ``None``: in memory
    (:func:`estimation.identification.prepared.still_record_note`) and from spans computed block by block
    (:func:`estimation.streaming.model_selection.streamed_spans`)."""
    if moved.shape != held.shape or not np.all(held < STILL_SHARE * moved):
        return None
    return ("the validation record hardly moves (its joints span " + ", ".join(f"{value:.3g}" for value in held)
            + f", each less than {100 * STILL_SHARE:g} % of its range in training): the robot holds a pose there, "
            "which measures little of the dynamics: the derivatives, the weighting and the default answer are chosen "
            "as without a validation record, its errors still reported; give a record of another motion")


def repeated_motion(train: Measurements, validation: Measurements) -> float:
    """The largest over the joints of ``rms(q_val − q_train) / rms(q_train − mean)`` over the samples both
    records have (from their starts; at the training record's times from its start when the records are sampled at
    different rates); ``inf`` for a joint that does not move in training but does in validation."""
    n = min(train.q.shape[0], validation.q.shape[0])
    if n == 0 or train.q.shape[1] != validation.q.shape[1]:
        return float("inf")
    q_train, q_validation = _aligned(train, validation, n)
    difference = np.sqrt(np.mean((q_validation - q_train) ** 2, axis=0))
    spread = np.sqrt(np.mean((q_train - q_train.mean(axis=0)) ** 2, axis=0))
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.where(spread > 0, difference / spread, np.where(difference > 0, np.inf, 0.0))
    return float(np.max(ratio))


def _aligned(train: Measurements, validation: Measurements, n: int) -> tuple[np.ndarray, np.ndarray]:
    """``(q_train, q_validation)`` on common instants: the first ``n`` samples of each when both are sampled at one
    rate (or a time base is not increasing: stacked segments), else the training samples within the validation
    record's duration and the validation positions interpolated at their times from each record's start."""
    t_train, t_validation = np.asarray(train.t, dtype=float), np.asarray(validation.t, dtype=float)
    increasing = t_train.shape[0] > 1 and t_validation.shape[0] > 1 and np.all(np.diff(t_train) > 0) \
        and np.all(np.diff(t_validation) > 0)
    if not increasing:
        return train.q[:n], validation.q[:n]
    step_train, step_validation = float(np.median(np.diff(t_train))), float(np.median(np.diff(t_validation)))
    if abs(step_train - step_validation) <= SAME_RATE * step_train:
        return train.q[:n], validation.q[:n]
    elapsed, elapsed_validation = t_train - t_train[0], t_validation - t_validation[0]
    inside = elapsed <= elapsed_validation[-1]
    q_validation = np.column_stack([np.interp(elapsed[inside], elapsed_validation, column)
                                    for column in validation.q.T])
    return train.q[inside], q_validation


def repeated_motion_note(train: Measurements, validation: Measurements, *, option: str = "--validate") -> str | None:
    """A warning when ``validation`` repeats ``train``'s motion (:func:`repeated_motion`), else ``None``."""
    return repeat_note(repeated_motion(train, validation), option=option)


def repeat_note(ratio: float, *, option: str = "--validate") -> str | None:
    """:func:`repeated_motion_note` of a validation record whose :func:`repeated_motion` is ``ratio`` (the streamed
    path computes it from sums: :func:`estimation.streaming.model_selection.streamed_repeated_motion`)."""
    if ratio > REPEAT_FRACTION:
        return None
    return (f"the {option} record repeats the training motion (its positions differ by at most {100 * ratio:.2g} % of "
            "their spread, sample by sample): it confirms what was fitted on this motion only, and an effect fitted to "
            f"this trajectory's own features passes it; give {option} a record of another trajectory")
