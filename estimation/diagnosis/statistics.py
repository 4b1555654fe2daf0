"""What a diagnosis says about its residuals: distance to the noise floor, tracing, whiteness.

:func:`residual_report` gathers, for the declared model (``before``) and the augmented one
(``after``):

* each channel's validation MSE against its noise floor (:mod:`estimation.uncertainty.noise_floor`): the
  ratio ``MSE / floor``, an F test and a plain statement ("at its floor" / "N x above");
* the residual tracing table (:mod:`estimation.uncertainty.residual_tracing`) and, for each channel still
  above its floor, which variable the remaining residual follows;
* whiteness and input-correlation checks of the validation residual (:mod:`estimation.uncertainty.whiteness`,
  the inputs being each joint's ``dq``).

The floor is that of the validation record **as recorded** (before period averaging or
filtering), as the validation MSE is (:func:`estimation.identification.validation.compare` measures against
``Measurements.recorded``). Measurements without their recorded channels (built by hand) are
compared on their prepared channels: a given floor is then carried through the preprocessing
their metadata record (:func:`estimation.uncertainty.noise_floor.prepared_floor`). Without a floor given, it
is estimated from the recorded validation channels, or from prepared ones when they are
unprocessed, or period-averaged only (averaged noise stays white: the difference estimator then
measures it directly); after a low-pass filter no model-free floor can be had from them, and the
report says so (the CLI computes the floor from the file before preprocessing).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from estimation.identification.fit import IdentificationResult
from dynamics.measurements import Measurements
from estimation.uncertainty.noise_floor import NoiseFloor, NoiseFloorError, difference_variance, noise_floor, prepared_floor
from estimation.uncertainty.floor_comparison import FloorComparison, compare_with_floor
from estimation.uncertainty.residual_tracing import DEFAULT_BINS, ResidualTrace, residual_statements, trace_residuals
from estimation.uncertainty.whiteness import ResidualChecks, residual_checks

#: significance level of "above its floor"
FLOOR_ALPHA = 0.01


@dataclass(frozen=True)
class ResidualReport:
    """The residual statistics of a diagnosis (see the module docstring)."""

    floor: NoiseFloor | None
    floor_note: str
    comparison: dict[str, dict[str, FloorComparison]] = field(repr=False)
    #: ``None`` where the residuals are not held sample by sample (the streamed diagnosis)
    tracing: dict[str, ResidualTrace] | None = field(repr=False)
    checks: dict[str, ResidualChecks] | None = field(repr=False)
    statements: dict[str, str] = field(default_factory=dict)

    def ratios(self, which: str = "after") -> dict[str, float]:
        """``validation MSE / floor`` per channel (empty without a floor)."""
        return {channel: c.ratio for channel, c in self.comparison.get(which, {}).items()}

    def to_dict(self) -> dict[str, Any]:
        floor = {"mse": None, "note": self.floor_note} if self.floor is None else {**self.floor.to_dict(), "note": self.floor_note}
        return {
            "noise_floor": floor,
            "floor_comparison": {which: {channel: c.to_dict() for channel, c in comparisons.items()}
                                 for which, comparisons in self.comparison.items()},
            "floor_statements": dict(self.statements),
            "tracing": None if self.tracing is None else {which: trace.to_dict() for which, trace in self.tracing.items()},
            "whiteness": None if self.checks is None else {which: checks.to_dict() for which, checks in self.checks.items()},
        }


def validation_floor(validate: Measurements, channels: tuple[str, ...]) -> tuple[NoiseFloor | None, str]:
    """The floor of the prepared validation channels estimated from them, or ``None`` and why."""
    metadata = validate.metadata
    filtered = metadata.get("differentiation") == "butterworth" or int(metadata.get("decimation") or 1) > 1
    if filtered:
        return None, ("no noise floor: the validation channels were low-pass filtered, which removes the noise a "
                      "model-free estimate measures; give the floor of the record as recorded (noise_floor=...)")
    try:
        if metadata.get("periods_averaged"):
            variance, dof = difference_variance(validate.channels(channels), names=channels)
            floor = NoiseFloor(channels, variance, "differences", dof, validate.n_samples,
                               {"order": 4, "on": f"the average of {metadata['periods_averaged']} periods"})
            return floor, "estimated from the period-averaged validation channels"
        floor = noise_floor(validate, channels)
        return floor, "estimated from the validation record"
    except NoiseFloorError as error:
        return None, f"no noise floor: {error}"


def floor_for_validation(validate: Measurements, channels: tuple[str, ...],
                         floor: NoiseFloor | None = None) -> tuple[NoiseFloor | None, str]:
    """The floor the validation MSE on ``validate`` is compared with, and how it was had.

    ``floor`` (of the record as recorded) is carried through the preprocessing ``validate``
    records; without it, :func:`validation_floor`. What the diagnosis loop's stopping rule
    (:func:`estimation.uncertainty.floor_comparison.above_floor`) should be given.
    """
    if floor is None and validate.recorded is not None:
        try:
            return noise_floor(validate.recorded, tuple(channels)), "estimated from the validation channels as recorded"
        except NoiseFloorError as error:
            return None, f"no noise floor: {error}"
    if floor is None:
        return validation_floor(validate, tuple(channels))
    if not isinstance(floor, NoiseFloor):
        raise TypeError(f"noise_floor must be a NoiseFloor, got {type(floor).__name__}")
    if validate.recorded is None:  # API data without the recorded channels: the MSE is on the prepared ones
        used = prepared_floor(floor, validate)
        note = f"given ({floor.method})" + (f", scaled for {used.details['scalings'][-1]['why']}" if used is not floor else "")
        return used, note
    return floor, f"given ({floor.method})"


def residual_report(
    before: IdentificationResult,
    after: IdentificationResult,
    train: Measurements,
    validate: Measurements,
    floor: NoiseFloor | None = None,
    *,
    alpha: float = FLOOR_ALPHA,
) -> ResidualReport:
    """Floor comparison, tracing and whiteness of the declared and augmented models' residuals.

    ``floor``: the noise floor of the validation record as recorded (before preprocessing);
    ``None``: estimated here when the validation data allow (module docstring).
    """
    channels = tuple(before.estimate.channels)
    used, note = floor_for_validation(validate, channels, floor)
    validate = validate.as_recorded  # the validation MSE and residuals are against the channels as recorded
    comparison, statements = {}, {}
    results = {"before": before, "after": after}
    if used is not None:
        for which, result in results.items():
            comparison[which] = compare_with_floor(result.validation.mse, used, validate.n_samples, alpha=alpha)
        statements = {channel: c.statement() for channel, c in comparison["after"].items()}
    tracing, checks = {}, {}
    inputs = {f"dq{j + 1}": validate.dq[:, j] for j in range(validate.n_joints)}
    for which, result in results.items():
        bins = max(2, min(DEFAULT_BINS, train.n_samples // 5))  # short records: fewer bins
        tracing[which] = trace_residuals(result.estimate.residuals, train, result.validation.residuals, validate, channels,
                                         bins=bins)
        checks[which] = residual_checks(result.validation.residuals, channels, inputs)
    still = [channel for channel, c in comparison.get("after", {}).items() if c.above] if used is not None else list(channels)
    follows = residual_statements(tracing["after"], still)
    for channel, text in follows.items():
        statements[channel] = statements[channel] + "; " + text.split(": ", 1)[1] if channel in statements else text
    return ResidualReport(used, note, comparison, tracing, checks, statements)
