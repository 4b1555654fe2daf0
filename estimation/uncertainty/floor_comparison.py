"""A model's validation error against the noise floor (:mod:`estimation.uncertainty.noise_floor`), and the stopping
rule.

Under "the model is exact" the validation MSE over ``N`` samples of a model fitted on other data and the floor
``σ̂²`` with ``ν`` degrees of freedom give ``MSE / σ̂² ~ F(N, ν)``: :func:`compare_with_floor` tests each channel one
sided, :func:`above_floor` is the stopping rule (a channel is above its floor while that test rejects), and
:func:`floor_ratios` gives ``MSE / σ̂² = 1 + (model error)/σ²``.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
import scipy.stats

from estimation.uncertainty.noise_floor import NoiseFloor

__all__ = ["FloorComparison", "above_floor", "compare_with_floor", "floor_ratios", "mse_over_floor"]


@dataclass(frozen=True)
class FloorComparison:
    """A channel's validation MSE against its noise floor."""

    channel: str
    mse: float
    floor: float
    ratio: float
    p_value: float
    above: bool

    def statement(self) -> str:
        """``"at its floor"`` or ``"N x above its floor"`` in plain words."""
        if self.floor == 0 and not self.above:
            return (f"{self.channel}: reads zero in every sample (a passive joint's torque): no noise, no floor; its "
                    f"error (MSE {self.mse:.3g}) is the model's on the joint's equation 0 = Y_j θ")
        if not self.above:
            return f"{self.channel}: at its floor (validation MSE / floor = {self.ratio:.3g})"
        return f"{self.channel}: {self.ratio:.3g} x above its floor (p = {self.p_value:.2g})"

    def to_dict(self) -> dict[str, Any]:
        return {"mse": self.mse, "floor": self.floor, "ratio": self.ratio, "p_value": self.p_value,
                "above": self.above, "statement": self.statement()}


def compare_with_floor(mse: Mapping[str, float], floor: NoiseFloor, n_samples: int, *,
                       alpha: float = 0.01) -> dict[str, FloorComparison]:
    """Per channel: is the validation MSE (over ``n_samples``) significantly above the floor?

    Under "the model is exact", ``N·MSE/σ² ~ χ²_N`` (the model was fitted on other data) and
    ``ν σ̂²/σ² ~ χ²_ν``, so ``MSE / σ̂² ~ F(N, ν)``; the channel is above its floor when the
    one-sided p-value is below ``alpha``. When the floor comes from the validation record itself
    the two are positively correlated, which makes the test conservative (fewer channels called
    above). The ratio ``MSE / σ̂²`` is ``1 + (model error)/σ²``. A floor of zero (a channel of zeros: a passive joint's
    torque) is not tested: the channel is not called above, and its statement says why.
    """
    if not 0 < alpha < 1:
        raise ValueError(f"alpha must lie in (0, 1), got {alpha}")
    if isinstance(n_samples, bool) or int(n_samples) != n_samples or n_samples < 1:
        raise ValueError(f"n_samples must be a positive integer, got {n_samples}")
    floors = floor.mse()
    missing = [channel for channel in mse if channel not in floors]
    if missing:
        raise ValueError(f"no noise floor for channel(s) {missing}; the floor has {list(floor.channels)}")
    comparisons = {}
    for channel, value in mse.items():
        value, reference = float(value), floors[channel]
        if reference == 0:  # a channel of zeros (a passive joint's torque, estimation.data.passive): no noise to
            # test against; not "above" (the stopping rule would never stop), its error said as the model's
            ratio, p_value = (np.inf if value > 0 else 1.0), 1.0
        else:
            ratio = value / reference
            p_value = float(scipy.stats.f.sf(ratio, int(n_samples), floor.dof))
        comparisons[channel] = FloorComparison(channel, value, reference, float(ratio), p_value, p_value < alpha)
    return comparisons


def above_floor(mse: Mapping[str, float], floor: NoiseFloor, n_samples: int, *, alpha: float = 0.01) -> dict[str, bool]:
    """The stopping rule: ``{channel: True}`` while a channel's validation MSE is significantly
    above its noise floor (see :func:`compare_with_floor`)."""
    return {channel: c.above for channel, c in compare_with_floor(mse, floor, n_samples, alpha=alpha).items()}


def floor_ratios(mse: Mapping[str, float], floor: NoiseFloor) -> dict[str, float]:
    """``validation MSE / floor`` per channel."""
    floors = floor.mse()
    return {channel: float(value) / floors[channel] if floors[channel] > 0 else float("inf")
            for channel, value in mse.items()}


def mse_over_floor(mse: Mapping[str, float], floor_mse: Mapping[str, float] | None) -> dict[str, float] | None:
    """``MSE / floor`` per channel of ``mse`` against each channel's floor MSE (infinite over a floor of zero: a
    channel of zeros), ``None`` without a floor (the ``mse_over_floor`` of ``oed predict``'s metrics)."""
    if floor_mse is None:
        return None
    return {channel: value / floor_mse[channel] if floor_mse[channel] > 0 else float("inf")
            for channel, value in mse.items()}
