"""The error of a diagnosis on a record no choice saw (``oed diagnose --test FILE``).

A diagnosis uses its data in two roles: the training record fits every candidate, and the validation record
confirms what is adopted (and the derivative method was chosen on held-out blocks of the training record). The
validation error after the diagnosis is therefore optimistic: the effects were kept because they lowered it. A
third record, the *test* record, is never used for a decision; the declared model (``before``) and the diagnosed
one (``after``) predict it along its own motion (prepared like the others), and each channel's mean squared error
is taken against the channels **as recorded**, beside that record's own noise floor
(:mod:`estimation.uncertainty.noise_floor`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any


from dynamics.measurements import Measurements
from estimation.diagnosis.results import Diagnosis
from estimation.data.segments import segment_slices
from estimation.identification.fit import IdentificationResult
from estimation.identification.validation import Comparison, channel_mse
from estimation.uncertainty.noise_floor import NoiseFloor

__all__ = ["UntouchedErrors", "recorded_comparison", "recorded_mse", "untouched_errors"]


@dataclass(frozen=True)
class UntouchedErrors:
    """Per channel, the test record's MSE before and after the diagnosis, and over its noise floor.

    Attributes
    ----------
    before, after
        ``{channel: MSE}`` of the declared and the diagnosed model, against the channels as recorded.
    floor
        ``{channel: noise variance}`` of the test record as read, or ``None`` when it gives none.
    n_samples
        Samples compared.
    """

    before: dict[str, float]
    after: dict[str, float]
    floor: dict[str, float] | None
    n_samples: int

    def over_floor(self, which: str) -> dict[str, float] | None:
        """``{channel: MSE / floor}`` of ``before`` or ``after``, or ``None`` without a floor."""
        if self.floor is None:
            return None
        errors = self.before if which == "before" else self.after
        return {channel: value / self.floor[channel] for channel, value in errors.items() if self.floor.get(channel)}

    def to_dict(self) -> dict[str, Any]:
        """``{before: {mse, mse_over_floor}, after: {mse, mse_over_floor}, noise_floor, n_samples}``."""
        return {
            "before": {"mse": self.before, "mse_over_floor": self.over_floor("before")},
            "after": {"mse": self.after, "mse_over_floor": self.over_floor("after")},
            "noise_floor": self.floor,
            "n_samples": self.n_samples,
        }


def recorded_mse(result: IdentificationResult, measurements: Measurements) -> dict[str, float]:
    """``{channel: MSE}`` of ``result`` predicting ``measurements`` (prepared), against the channels as recorded."""
    recorded = measurements.as_recorded
    return channel_mse(recorded.channels(result.model.channels), result.predict(recorded), result.model.channels)


def recorded_comparison(result: IdentificationResult, measurements: Measurements, label: str = "") -> Comparison:
    """``result`` predicting ``measurements`` (prepared), paired with the channels as recorded at their time stamps
    (the residual of :func:`recorded_mse`)."""
    recorded = measurements.as_recorded
    return Comparison(recorded.t, recorded.channels(result.model.channels), result.predict(recorded),
                      result.model.channels, label, segments=tuple(segment_slices(recorded)))


def untouched_errors(diagnosis: Diagnosis, test: Measurements, floor: NoiseFloor | None) -> UntouchedErrors:
    """The declared and the diagnosed model on the prepared test record ``test`` (module docstring)."""
    return UntouchedErrors(recorded_mse(diagnosis.before, test), recorded_mse(diagnosis.after, test),
                           None if floor is None else floor.mse(), int(test.as_recorded.n_samples))
