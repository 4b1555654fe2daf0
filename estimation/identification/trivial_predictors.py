"""Trivial predictors: is the identified model better than predicting nothing, or the nominal model?

Per channel of the validation data, two yardsticks beside the identified model's MSE:

* ``zero_mse``: the mean square of the measured channel, the MSE of a predictor that always says 0;
* ``nominal_mse``: the MSE of the nominal model: the robot's description as given (URDF or DH
  table inertial values) with every effect's parameter 0 (``model.nominal_parameters()``).

An identified model worse than either on a channel predicts that channel worse than a constant or
than the datasheet: a wrong sign or unit, a transmission not declared (friction on a motor that
turns with ``q5 + q6``, fitted per joint), or an effect the model lacks. :func:`trivial_warnings`
says so, once per channel.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any


from dynamics.models import IdentificationModel
from dynamics.measurements import Measurements
from estimation.data.channel_mask import channel_mean


class TrivialPredictorWarning(UserWarning):
    """The identified model predicts a channel worse than a zero or the nominal model."""


def trivial_mse(model: IdentificationModel, measurements: Measurements) -> dict[str, dict[str, float]]:
    """``{"zero_mse": {channel: value}, "nominal_mse": {channel: value}}`` on ``measurements``, against
    the channels as recorded (``measurements.recorded`` when preprocessing filtered or averaged them),
    as the identified model's validation MSE is."""
    measurements = measurements.as_recorded
    measured = measurements.channels(model.channels)
    zero = channel_mean(measured**2)  # each channel over its valid samples (estimation.data.channel_mask)
    predicted = model.predict(model.nominal_parameters(), measurements.q, measurements.dq, measurements.ddq)
    nominal = channel_mean((measured - predicted) ** 2, measured)
    return {
        "zero_mse": {channel: float(value) for channel, value in zip(model.channels, zero)},
        "nominal_mse": {channel: float(value) for channel, value in zip(model.channels, nominal)},
    }


def trivial_warnings(mse: Mapping[str, float], trivial: Mapping[str, Mapping[str, float]], *,
                     label: str = "identified model", record: str = "the validation data") -> tuple[str, ...]:
    """One message per channel where ``mse`` (the identified model's validation MSE, or its MSE on ``record``)
    exceeds the zero predictor's or the nominal model's."""
    messages = []
    for channel, value in mse.items():
        if trivial.get("zero_mse", {}).get(channel, None) == 0:  # a channel of zeros (a passive joint's): no
            continue  # prediction beats zero there, and the model's error on it is its equation's, reported as such
        worse = [(name, trivial[key][channel]) for key, name in (("zero_mse", "a zero prediction"),
                                                                 ("nominal_mse", "the nominal model"))
                 if channel in trivial.get(key, {}) and value > trivial[key][channel]]
        if worse:
            against = " and ".join(f"{name} ({reference:.4g})" for name, reference in worse)
            messages.append(
                f"{channel}: the {label} predicts {record} worse (MSE {value:.4g}) than {against}: "
                "a sign or unit, an undeclared transmission (friction on a coupled motor fitted per joint; "
                "try --transmission, or `oed diagnose`) or a missing effect")
    return tuple(messages)


def add_trivial_predictors(document: dict[str, Any], validation: Mapping[str, Any] | None,
                           trivial: Mapping[str, Mapping[str, float]] | None) -> None:
    """Put ``zero_mse`` and ``nominal_mse`` into ``document``'s ``validation`` mapping (in place)."""
    if validation is None or trivial is None:
        return
    validation = dict(validation)
    validation.update({key: dict(value) for key, value in trivial.items()})
    document["validation"] = validation
