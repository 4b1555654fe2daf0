"""Residual whiteness and independence from the inputs, in the manner of MATLAB's ``resid``.

A model that explains everything but the sensor noise leaves a residual that is white (no
autocorrelation at any lag) and uncorrelated with the inputs at every lag (Ljung, *System
Identification*, 2nd ed., §16.6). Both are tested here with normalised correlation estimates

    r_ee(k) = Σ_t ẽ_t ẽ_{t+k} / Σ_t ẽ_t²,                         (ẽ: e minus its mean)
    r_eu(k) = Σ_t ẽ_t ũ_{t+k} / √(Σ ẽ_t² Σ ũ_t²),

which lie in ``[-1, 1]`` by the Cauchy–Schwarz inequality (the ``1/N`` "biased" estimator: a
mean over ``N − k`` products divided by the variance can exceed one). Confidence bands at level
``1 − α`` (99 % by default, as ``resid``):

* autocorrelation of a white residual: ``± z_{1−α/2} / √N`` at each lag ``k ≥ 1``;
* cross-correlation of a residual independent of the input: ``± z_{1−α/2} √(Σ_j w_j r_ee(j) r_uu(j)) / √N``
  (Bartlett's formula for two independent series, summed over ``|j| ≤ L = N/10`` with the
  Bartlett taper ``w_j = 1 − |j|/(L+1)`` that keeps the sum of noisy products stable), which
  reduces to ``z/√N`` for a white residual and widens for a coloured one, so that a smooth input
  and a smooth residual are not called correlated by chance.

About ``α`` of the lags fall outside by chance. A check fails when more than
:func:`allowed_outside` lags are outside, or when one lag lies outside the band widened for the
number of lags tested (Bonferroni: ``z_{1−α/(2L)}``), so that one strong lag (a delay) fails it too.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import scipy.stats
from numpy.typing import ArrayLike, NDArray

#: lags tested (``resid`` uses 25)
DEFAULT_LAGS = 25
#: confidence level of the bands (``resid`` uses 99 %)
DEFAULT_CONFIDENCE = 0.99


def autocorrelation(values: ArrayLike, max_lag: int) -> NDArray[np.float64]:
    """Normalised autocorrelation ``r(0..max_lag)`` of a 1-D signal (``r(0) = 1``; a constant gives zeros after it)."""
    centred = np.asarray(values, dtype=float) - np.mean(values)
    energy = float(centred @ centred)
    max_lag = min(int(max_lag), centred.shape[0] - 1)
    if energy == 0:
        return np.r_[1.0, np.zeros(max_lag)]
    return np.array([1.0] + [float(centred[:-k] @ centred[k:]) / energy for k in range(1, max_lag + 1)])


def cross_correlation(values: ArrayLike, inputs: ArrayLike, max_lag: int) -> NDArray[np.float64]:
    """Normalised ``r_eu(k)`` for ``k = −max_lag..max_lag`` (``k > 0``: the input ``k`` samples after the residual)."""
    e = np.asarray(values, dtype=float) - np.mean(values)
    u = np.asarray(inputs, dtype=float) - np.mean(inputs)
    norm = float(np.sqrt((e @ e) * (u @ u)))
    max_lag = min(int(max_lag), e.shape[0] - 1)
    if norm == 0:
        return np.zeros(2 * max_lag + 1)
    out = []
    for k in range(-max_lag, max_lag + 1):
        out.append(float(e[: e.shape[0] - k] @ u[k:]) if k >= 0 else float(e[-k:] @ u[: u.shape[0] + k]))
    return np.array(out) / norm


def allowed_outside(lags: int, confidence: float) -> int:
    """Most lags outside a band of level ``confidence`` still consistent with chance (binomial, 1 %)."""
    return int(scipy.stats.binom.ppf(0.99, lags, 1 - confidence))


@dataclass(frozen=True)
class CorrelationCheck:
    """One correlation sequence with its confidence band."""

    lags: tuple[int, ...]
    values: tuple[float, ...] = field(repr=False)
    band: float
    outside: int
    allowed: int
    peak_band: float

    @property
    def passed(self) -> bool:
        return self.outside <= self.allowed and max(map(abs, self.values), default=0.0) <= self.peak_band

    def to_dict(self) -> dict[str, Any]:
        return {"lags": list(self.lags), "values": list(self.values), "band": self.band, "outside": self.outside,
                "allowed": self.allowed, "peak_band": self.peak_band, "passed": self.passed}


@dataclass(frozen=True)
class ResidualCheck:
    """Whiteness and input correlation of one channel's residual."""

    channel: str
    whiteness: CorrelationCheck
    inputs: dict[str, CorrelationCheck]

    def statement(self) -> str:
        parts = [f"white ({self.whiteness.outside}/{len(self.whiteness.lags)} lags outside the band)"
                 if self.whiteness.passed else
                 f"not white ({self.whiteness.outside}/{len(self.whiteness.lags)} lags outside the "
                 f"{self.whiteness.band:.2g} band, lag-1 autocorrelation {self.whiteness.values[0]:.2f})"]
        correlated = [name for name, check in self.inputs.items() if not check.passed]
        parts.append(f"correlated with {', '.join(correlated)}" if correlated else "uncorrelated with the inputs")
        return f"{self.channel}: " + "; ".join(parts)

    def to_dict(self) -> dict[str, Any]:
        return {"whiteness": self.whiteness.to_dict(), "inputs": {k: v.to_dict() for k, v in self.inputs.items()},
                "statement": self.statement()}


@dataclass(frozen=True)
class ResidualChecks:
    """:class:`ResidualCheck` per channel (``resid``'s two panels for each)."""

    checks: dict[str, ResidualCheck]
    confidence: float

    def to_dict(self) -> dict[str, Any]:
        return {"confidence": self.confidence, "channels": {k: v.to_dict() for k, v in self.checks.items()}}


def residual_checks(
    residuals: ArrayLike,
    channels: Sequence[str],
    inputs: Mapping[str, ArrayLike],
    *,
    max_lag: int = DEFAULT_LAGS,
    confidence: float = DEFAULT_CONFIDENCE,
) -> ResidualChecks:
    """Whiteness of each channel's residual ``(N, m)`` and its cross-correlation with each input.

    Parameters
    ----------
    residuals
        ``(N, m)`` residuals (validation residuals: a fit makes its training residual orthogonal to
        its regressors).
    channels
        Channel names.
    inputs
        ``{name: (N,)}`` signals the residual should not follow (each joint's ``dq``, say).
    max_lag
        Lags ``1..max_lag`` for the autocorrelation, ``−max_lag..max_lag`` for the cross-correlation.
    confidence
        Level of the bands (``resid``: 0.99).
    """
    residuals = np.asarray(residuals, dtype=float)
    if residuals.ndim == 1:
        residuals = residuals[:, None]
    if residuals.ndim != 2 or residuals.shape[1] != len(channels):
        raise ValueError(f"residuals {residuals.shape} do not match {len(channels)} channel names")
    if not 0 < confidence < 1:
        raise ValueError(f"confidence must lie in (0, 1), got {confidence}")
    if isinstance(max_lag, bool) or int(max_lag) != max_lag or max_lag < 1:
        raise ValueError(f"max_lag must be a positive integer, got {max_lag}")
    n = residuals.shape[0]
    max_lag = min(int(max_lag), n - 2)
    if max_lag < 1:
        raise ValueError(f"{n} samples are too few for a correlation check")
    signals = {name: np.asarray(values, dtype=float).reshape(-1) for name, values in inputs.items()}
    for name, values in signals.items():
        if values.shape[0] != n:
            raise ValueError(f"input {name} has {values.shape[0]} samples, the residuals {n}")
    z = float(scipy.stats.norm.ppf(0.5 + confidence / 2))
    span = max(max_lag, n // 10)
    taper = 1 - np.arange(1, span + 1) / (span + 1)
    input_autocorrelation = {name: _long_autocorrelation(values, span) for name, values in signals.items()}
    checks = {}
    for channel, e in zip(channels, residuals.T):
        r_ee = autocorrelation(e, max_lag)
        r_ee_long = _long_autocorrelation(e, span)
        band = z / np.sqrt(n)
        lags = tuple(range(1, max_lag + 1))
        whiteness = CorrelationCheck(lags, tuple(map(float, r_ee[1:])), float(band),
                                     int(np.sum(np.abs(r_ee[1:]) > band)), allowed_outside(max_lag, confidence),
                                     float(band * _bonferroni(confidence, max_lag) / z))
        cross = {}
        for name, u in signals.items():
            r_uu = input_autocorrelation[name]
            variance = max(float(1 + 2 * np.sum(taper * r_ee_long[1:] * r_uu[1:])), 1.0 / n)  # Bartlett
            cross_band = z * np.sqrt(variance / n)
            r_eu = cross_correlation(e, u, max_lag)
            cross[name] = CorrelationCheck(tuple(range(-max_lag, max_lag + 1)), tuple(map(float, r_eu)),
                                           float(cross_band), int(np.sum(np.abs(r_eu) > cross_band)),
                                           allowed_outside(2 * max_lag + 1, confidence),
                                           float(cross_band * _bonferroni(confidence, 2 * max_lag + 1) / z))
        checks[channel] = ResidualCheck(channel, whiteness, cross)
    return ResidualChecks(checks, float(confidence))


def _long_autocorrelation(values: NDArray[np.float64], span: int) -> NDArray[np.float64]:
    """:func:`autocorrelation` to lag ``span`` by FFT."""
    centred = values - values.mean()
    energy = float(centred @ centred)
    if energy == 0:
        return np.r_[1.0, np.zeros(span)]
    size = 1 << int(np.ceil(np.log2(2 * centred.shape[0])))
    spectrum = np.fft.rfft(centred, size)
    return np.fft.irfft(np.abs(spectrum) ** 2, size)[: span + 1] / energy


def _bonferroni(confidence: float, lags: int) -> float:
    return float(scipy.stats.norm.ppf(1 - (1 - confidence) / (2 * lags)))
