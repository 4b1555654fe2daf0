"""Does the validation record repeat the training motion?

A held-out record confirms an effect on another motion only if it holds another motion. A record of the
same trajectory again (a repeat run) differs from the training record by its noise alone: an effect
fitted to the trajectory's own features (a coupling of two joints that happen to move together, a
position ripple at the positions this trajectory visits) passes it as well as a physical one. Measured
on the real KUKA LWR4+: its run 2 repeats run 1 (positions within 0.4 % of their spread sample by
sample), and effects confirmed on it raised the error on run 3, a faster trajectory, above that of a
plain fit (``benchmarks/README.md``).

:func:`repeated_motion` compares the positions sample by sample from each record's start (a repeat
run is sampled alike); :data:`REPEAT_FRACTION` of the training motion's spread on every joint makes a
repeat. A repeat shifted in time, or resampled at another rate, is not detected.
"""

from __future__ import annotations

import numpy as np

from dynamics.measurements import Measurements

__all__ = ["REPEAT_FRACTION", "repeated_motion", "repeated_motion_note"]

#: the validation positions within this fraction of the training motion's spread (root mean square, every
#: joint) sample by sample: the same motion again
REPEAT_FRACTION = 0.05


def repeated_motion(train: Measurements, validation: Measurements) -> float:
    """The largest over the joints of ``rms(q_val − q_train) / rms(q_train − mean)`` over the samples both
    records have (from their starts); ``inf`` for a joint that does not move in training but does in validation."""
    n = min(train.q.shape[0], validation.q.shape[0])
    if n == 0 or train.q.shape[1] != validation.q.shape[1]:
        return float("inf")
    q_train, q_validation = train.q[:n], validation.q[:n]
    difference = np.sqrt(np.mean((q_validation - q_train) ** 2, axis=0))
    spread = np.sqrt(np.mean((q_train - q_train.mean(axis=0)) ** 2, axis=0))
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.where(spread > 0, difference / spread, np.where(difference > 0, np.inf, 0.0))
    return float(np.max(ratio))


def repeated_motion_note(train: Measurements, validation: Measurements, *, option: str = "--validate") -> str | None:
    """A warning when ``validation`` repeats ``train``'s motion (:func:`repeated_motion`), else ``None``."""
    ratio = repeated_motion(train, validation)
    if ratio > REPEAT_FRACTION:
        return None
    return (f"the {option} record repeats the training motion (its positions differ by at most {100 * ratio:.2g} % of "
            "their spread, sample by sample): it confirms what was fitted on this motion only, and an effect fitted to "
            f"this trajectory's own features passes it; give {option} a record of another trajectory")
