"""The noise floor: each channel's noise variance estimated without the model, and the stopping rule.

A model can be no better than its data: against recorded torques the validation MSE of a model is
``σ² + (model error)``, where ``σ²`` is the variance of the sensor noise. ``σ²`` is estimated here
from the record alone, without any model, so that it can judge every model:

* **periodic records** (a known fundamental frequency ``f`` and at least two whole periods): the
  period-to-period variance (Pintelon & Schoukens, *System Identification: A Frequency Domain
  Approach*, 2nd ed., §2.4 and §6.3): with ``p`` periods of ``P`` samples, ``x_{k,j}`` the sample
  at phase ``j`` of period ``k``,

      σ̂² = 1/P Σ_j  1/(p − 1) Σ_k (x_{k,j} − x̄_j)²,      ν = P (p − 1) degrees of freedom.

  Any periodic signal, however rich in harmonics, cancels exactly. When the period is not a whole
  number of samples the same estimate is the residual of a linear least-squares fit of a Fourier
  series with every harmonic of ``f`` below the Nyquist frequency over the actual time stamps
  (for a whole ``P`` that fit spans exactly the ``P``-periodic sequences and gives the same
  number): ``σ̂² = RSS / (N − 2H − 1)``, ``ν = N − 2H − 1`` (``method="fourier"``). Harmonics are
  capped at :data:`MAX_HARMONICS` (a periodic signal with content above the cap leaves it in the
  residual: the floor is then too high, i.e. the stopping rule lenient; the details say so).
* **other records**: a difference-based estimator (Rice 1984; Gasser, Sroka & Jennen-Steinmetz
  1986; Hall, Kay & Titterington 1990): a smooth signal sampled fast has a vanishing ``d``-th
  difference, while white noise of variance ``σ²`` gives ``Δ^d e`` of variance ``σ² C(2d, d)``.
  The scale is taken robustly, ``σ̂ = 1.4826 MAD(Δ^d x) / √C(2d, d)`` (Gaussian noise), so that
  the few samples where the signal itself jumps (Coulomb friction at a velocity reversal, a
  contact) do not count: ``method="differences"``. Its degrees of freedom are those of the
  mean square of the (correlated) differences, ``N / Σ_k ρ_k²`` with ``ρ`` the autocorrelation of
  the difference filter, times the 0.37 efficiency of the MAD. It measures the *white* part of
  the noise: a torque filtered before it was recorded has little high-frequency noise, and this
  estimate would be too low: such channels are recognised by the lag-1 correlation of their
  differences (−0.8 for white noise at ``d = 4``) and refused (prefer periodic records).

:func:`estimation.uncertainty.floor_comparison.above_floor` is the stopping rule: a channel is above its floor
when its validation MSE is significantly larger (one-sided F test).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from math import comb
from typing import Any, Literal

import numpy as np
import scipy.signal
import scipy.stats
from numpy.typing import ArrayLike, NDArray

from dynamics.measurements import Measurements
from estimation.preprocessing.fourier_series import gram_solution
from estimation.preprocessing.fourier_sums import fourier_sums

#: most harmonics of the Fourier fit used when the period is not a whole number of samples
MAX_HARMONICS = 1000
#: order of the difference estimator for non-periodic records
DIFFERENCE_ORDER = 4
#: asymptotic efficiency of the median absolute deviation for Gaussian data
MAD_EFFICIENCY = 0.37
#: largest departure of the differences' lag-1 correlation from white noise's (long records)
WHITENESS_TOLERANCE = 0.15
#: significance of a drift between a periodic record's periods (:func:`without_drift`)
DRIFT_ALPHA = 1e-3
#: a channel within this factor of its floor is "at its floor" in the plain statements
AT_FLOOR_RATIO = 1.2

Method = Literal["periods", "fourier", "differences"]


class NoiseFloorError(ValueError):
    """The record cannot give a noise floor (too short, fewer than two periods, constant…)."""


@dataclass(frozen=True)
class NoiseFloor:
    """Noise variance of each channel, estimated from the record without a model.

    Attributes
    ----------
    channels
        Channel names (``tau1``…, ``fx``…).
    variance
        ``(m,)`` noise variance per channel, in the channel's unit squared.
    method
        ``"periods"``, ``"fourier"`` or ``"differences"`` (module docstring).
    dof
        Degrees of freedom of each estimate (``ν σ̂²/σ² ~ χ²_ν`` for Gaussian white noise).
    n_samples
        Samples the estimate used.
    details
        How it was obtained (periods, harmonics, order, scalings applied).
    """

    channels: tuple[str, ...]
    variance: NDArray[np.float64]
    method: Method
    dof: float
    n_samples: int
    details: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        variance = np.array(self.variance, dtype=float).reshape(-1)
        if variance.shape[0] != len(self.channels):
            raise ValueError(f"{variance.shape[0]} variances for {len(self.channels)} channels")
        if not np.all(np.isfinite(variance)) or np.any(variance < 0):
            raise ValueError(f"noise variances must be finite and non-negative, got {variance.tolist()}")
        if not self.dof > 0:
            raise ValueError(f"dof must be positive, got {self.dof}")
        variance.flags.writeable = False
        object.__setattr__(self, "variance", variance)
        object.__setattr__(self, "channels", tuple(self.channels))

    def mse(self) -> dict[str, float]:
        """``{channel: σ̂²}``: the MSE a perfect model reaches against the recorded channel."""
        return {channel: float(value) for channel, value in zip(self.channels, self.variance)}

    def scaled(self, gain: float, note: str) -> NoiseFloor:
        """The floor of the same noise after a linear operation of variance gain ``gain``
        (averaging ``P`` periods: ``1/P``)."""
        details = dict(self.details, scalings=[*self.details.get("scalings", []), {"gain": float(gain), "why": note}])
        return NoiseFloor(self.channels, self.variance * gain, self.method, self.dof, self.n_samples, details)

    def to_dict(self) -> dict[str, Any]:
        return {"mse": self.mse(), "method": self.method, "dof": float(self.dof), "n_samples": int(self.n_samples),
                "details": self.details}


# --------------------------------------------------------------------------------------------
# estimators


def period_variance(values: ArrayLike, samples_per_period: int) -> tuple[NDArray[np.float64], float]:
    """Period-to-period variance of ``values (N, m)`` with whole periods of ``samples_per_period``;
    ``(σ̂² (m,), ν)``. The tail after the last whole period is dropped."""
    values = _as_2d(values)
    P = int(samples_per_period)
    periods = values.shape[0] // P
    if periods < 2:
        raise NoiseFloorError(f"{values.shape[0]} samples hold {periods} whole period(s) of {P} samples: the "
                              "period-to-period variance needs at least two")
    folded = values[: periods * P].reshape(periods, P, -1)
    return np.mean(np.var(folded, axis=0, ddof=1), axis=0), float(P * (periods - 1))


def without_drift(values: ArrayLike, samples_per_period: int, variance: NDArray[np.float64], dof: float,
                  channels: Sequence[str]) -> tuple[NDArray[np.float64], float, dict[str, dict[str, float]]]:
    """The period-to-period variance (``variance``, ``dof``: :func:`period_variance`'s) with what drifts between the
    periods taken out: ``(variance, dof, changed)`` (:func:`drift_free` of the sums :func:`period_step_sums` gives
    for each pair of consecutive periods).

    The periods' differences ``d_j = x_{k+1,j} − x_{k,j}`` cancel every periodic signal; what they keep is the
    noise (``2σ²`` for white noise) and whatever changed from one period to the next: a friction warming, a
    sensor's bias drifting, wear. Such a change is slow along the phase ``j``, so the mean square of the
    ``d``-th differences of ``d`` along ``j`` (:data:`DIFFERENCE_ORDER`, ``C(2d, d) · 2σ²`` for white noise, the
    mean square and not the MAD: unbiased for any white noise) measures the noise without it. Before
    (h-plants19), a Coulomb level warming over a periodic record's two periods made its floor 54x the noise's
    variance, and a residual 38x the noise read "at its floor"."""
    values = _as_2d(values)
    P = int(samples_per_period)
    periods = values.shape[0] // P
    if P < 10 * (DIFFERENCE_ORDER + 1):
        return variance, dof, {}
    folded = values[: periods * P].reshape(periods, P, -1)
    sums = None
    for index in range(periods - 1):
        step = period_step_sums(folded[index], folded[index + 1])
        sums = step if sums is None else tuple(total + part for total, part in zip(sums, step))
    return drift_free(variance, dof, sums, channels)


def period_step_sums(previous: NDArray[np.float64], current: NDArray[np.float64]
                     ) -> tuple[NDArray[np.float64], ...]:
    """Of two consecutive periods ``(P, m)``: the sums, per channel, of the squares, of the lag-1 products, of the
    values and of the values ending and starting a lag-1 pair, of the :data:`DIFFERENCE_ORDER`-th differences along
    the phase of their difference, and their count (:func:`without_drift`; a record read in blocks adds them period
    by period)."""
    differences = np.diff(np.asarray(current, dtype=float) - np.asarray(previous, dtype=float), n=DIFFERENCE_ORDER,
                          axis=0)
    return (np.sum(differences**2, axis=0), np.sum(differences[1:] * differences[:-1], axis=0),
            np.sum(differences, axis=0), np.sum(differences[:-1], axis=0) + np.sum(differences[1:], axis=0),
            int(differences.shape[0]), int(differences.shape[0]) - 1)


def drift_free(variance: NDArray[np.float64], dof: float,
               sums: tuple[NDArray[np.float64], ...], channels: Sequence[str]
               ) -> tuple[NDArray[np.float64], float, dict[str, dict[str, float]]]:
    """:func:`without_drift`'s decision from the periods' sums (:func:`period_step_sums`, added over the pairs of
    consecutive periods): where the period variance exceeds the differences' estimate beyond its sampling spread
    (one-sided F test at :data:`DRIFT_ALPHA`, the estimate's degrees of freedom ``N / Σρ²``), the periods differ
    by more than noise, and the channel's floor is the differences' estimate (``changed[channel]`` gives both). A
    channel whose differences are not those of white noise (filtered before it was recorded: :func:`check_white`,
    the lag-1 correlation of the differences about their mean) keeps the period variance: a drift cannot be told from
    coloured noise there."""
    squares, lagged, total, ends, count, pairs = sums
    order = DIFFERENCE_ORDER
    estimate = squares / count / (2.0 * comb(2 * order, order))
    estimate_dof = count / _difference_correlation_sum(order)
    threshold = float(scipy.stats.f.ppf(1.0 - DRIFT_ALPHA, dof, estimate_dof))
    out, changed = np.array(variance, dtype=float), {}
    for column, channel in enumerate(channels):
        if not estimate[column] > 0.0 or variance[column] <= threshold * estimate[column]:
            continue
        try:
            mean = total[column] / count  # the lag-1 correlation of the differences about their mean
            energy = squares[column] - count * mean**2
            lag = lagged[column] - mean * ends[column] + pairs * mean**2
            check_white(float(lag / energy) if energy > 0.0 else 1.0, count, order, channel)
        except NoiseFloorError:
            continue
        out[column] = estimate[column]
        changed[channel] = {"periods": float(variance[column]), "within_periods": float(estimate[column])}
    return out, (min(dof, estimate_dof) if changed else dof), changed


def fourier_residual_variance(t: ArrayLike, values: ArrayLike, frequency_hz: float, *,
                              harmonics: int | None = None) -> tuple[NDArray[np.float64], float, int]:
    """Residual variance of a least-squares Fourier fit (harmonics of ``frequency_hz``) over the
    actual time stamps ``t``; ``(σ̂² (m,), ν = N − 2H − 1, H)``. ``harmonics=None``: every harmonic
    below the Nyquist frequency, at most :data:`MAX_HARMONICS`.

    The normal equations are those of the design ``[1, sin kθ, cos kθ]`` (``θ = 2π f (t − t̄)``), never formed
    whole (:func:`~estimation.preprocessing.fourier_sums.fourier_sums`): on a regular grid every sum is a chirp
    z-transform, ``O(N log N)``; otherwise they are summed over blocks of rows, ``O(N H²)``. They are solved by Cholesky when well
    conditioned, by the SVD otherwise (:func:`~estimation.preprocessing.fourier_series.gram_solution`)."""
    t = np.asarray(t, dtype=float)
    values = _as_2d(values)
    step = float(np.median(np.diff(t)))
    nyquist_harmonic = int(np.ceil(0.5 / (step * frequency_hz))) - 1
    H = min(nyquist_harmonic, MAX_HARMONICS) if harmonics is None else int(harmonics)
    dof = t.shape[0] - 2 * H - 1
    if H < 1 or dof < 1:
        raise NoiseFloorError(f"{t.shape[0]} samples leave no degrees of freedom for {H} harmonics")
    scale = np.sqrt(np.mean(values**2, axis=0)) + np.finfo(float).tiny
    scaled = values / scale
    sums = fourier_sums(t, frequency_hz, H, origin=float(t.mean()))
    normal, moment = sums.normal_equations(scaled)
    coefficients = gram_solution(normal, moment)
    if coefficients is None:
        coefficients = np.linalg.lstsq(normal, moment, rcond=None)[0]
    rss = np.sum((scaled - sums.fitted(coefficients)) ** 2, axis=0)
    return rss / dof * scale**2, float(dof), H


def difference_variance(values: ArrayLike, *, order: int = DIFFERENCE_ORDER,
                        names: Sequence[str] | None = None) -> tuple[NDArray[np.float64], float]:
    """Robust difference-based noise variance of ``values (N, m)`` (module docstring); ``(σ̂², ν)``. A channel's
    masked samples (NaN, :mod:`estimation.data.channel_mask`) leave out the differences that reach them: each
    channel's scale from its own valid differences, ``ν`` that of the channel with the fewest."""
    values = _as_2d(values, masked=True)
    order = check_difference_count(values.shape[0], order)
    differences = np.diff(values, n=order, axis=0)
    counts = None
    if np.isnan(np.sum(differences)):  # masked samples: each channel's valid differences alone
        counts = np.sum(~np.isnan(differences), axis=0)
        if np.any(counts < 10):
            raise NoiseFloorError(f"{int(counts.min())} differences of a channel reach no masked sample: too few "
                                  "for a difference estimate of the noise")
        deviation = np.nanmedian(np.abs(differences - np.nanmedian(differences, axis=0)), axis=0)
    else:
        deviation = np.median(np.abs(differences - np.median(differences, axis=0)), axis=0)
    # white noise gives differences whose lag-1 correlation is −C(2d, d−1)/C(2d, d) (−0.8 for d = 4);
    # a channel filtered or interpolated before it was recorded does not, and its differences then
    # measure the filter, not the noise: refuse rather than report a floor that is far too low
    for column in range(values.shape[1]):
        if not np.any(values[:, column]):  # a channel of zeros (a passive joint's torque): no noise, floor 0
            continue
        kept = differences[:, column]
        if counts is not None:
            kept = kept[~np.isnan(kept)]
        kept = kept[np.abs(kept - np.median(kept)) <= kept_deviation(deviation[column])]
        centred = kept - kept.mean()
        energy = float(centred @ centred)
        lag1 = float(centred[1:] @ centred[:-1]) / energy if energy > 0 else 1.0
        check_white(lag1, kept.shape[0], order, names[column] if names else column + 1)
    used = differences.shape[0] if counts is None else int(counts.min())
    return difference_scale(deviation, order), difference_dof(used, order)


def check_difference_count(n_samples: int, order: int) -> int:
    """``order`` as an integer, checked, and :class:`NoiseFloorError` when ``n_samples`` are too few for the
    difference estimate (:func:`difference_variance`)."""
    order = int(order)
    if order < 1:
        raise ValueError(f"the difference order must be at least 1, got {order}")
    if n_samples < 10 * (order + 1):
        raise NoiseFloorError(f"{n_samples} samples are too few for a difference estimate of the noise")
    return order


def kept_deviation(deviation: float) -> float:
    """The largest distance from their median of the differences the whiteness check keeps: 5 scaled MADs (a jump
    of the signal itself, a Coulomb reversal or a contact, left out)."""
    return 5 * 1.4826 * max(float(deviation), np.finfo(float).tiny)


def difference_scale(deviation: ArrayLike, order: int) -> NDArray[np.float64]:
    """The noise variance from the median absolute deviation of the ``order``-th differences:
    ``(1.4826 MAD)² / C(2d, d)`` (Gaussian noise; module docstring)."""
    return (1.482602218505602 * np.asarray(deviation, dtype=float)) ** 2 / comb(2 * order, order)


def difference_dof(n_differences: int, order: int) -> float:
    """The degrees of freedom of the difference estimate from ``n_differences`` differences (module docstring)."""
    return float(MAD_EFFICIENCY * n_differences / _difference_correlation_sum(order))


def check_white(lag1: float, n_kept: int, order: int, name: object) -> None:
    """:class:`NoiseFloorError` when the lag-1 correlation ``lag1`` of ``n_kept`` differences of channel ``name``
    departs from white noise's by more than its sampling spread (the channel was filtered before it was recorded)."""
    expected = -comb(2 * order, order - 1) / comb(2 * order, order)
    # sampling spread of a lag-1 correlation of the differences: about √(Σ ρ_k² / N) (Bartlett)
    tolerance = max(WHITENESS_TOLERANCE, 4 * np.sqrt(_difference_correlation_sum(order) / max(n_kept, 1)))
    if abs(lag1 - expected) > tolerance:
        raise NoiseFloorError(
            f"channel {name}: its {order}th differences are not those of white noise (lag-1 correlation "
            f"{lag1:.2f}, white noise {expected:.2f}): it was probably filtered, interpolated or resampled before "
            "it was recorded, and no model-free floor can be read from it (a periodic record can give one)")


def _difference_correlation_sum(order: int) -> float:
    """``Σ_k ρ_k²`` of the autocorrelation of the ``order``-th difference of white noise."""
    coefficients = np.array([(-1) ** j * comb(order, j) for j in range(order + 1)], dtype=float)
    autocovariance = np.correlate(coefficients, coefficients, mode="full")
    rho = autocovariance / autocovariance[order]
    return float(np.sum(rho**2))


def _as_2d(values: ArrayLike, *, masked: bool = False) -> NDArray[np.float64]:
    """``values`` as ``(samples, channels)``; NaN or inf refused, except NaN where ``masked`` (masked samples)."""
    values = np.asarray(values, dtype=float)
    if values.ndim == 1:
        values = values[:, None]
    if values.ndim != 2:
        raise ValueError(f"channel values must be (samples, channels), got shape {values.shape}")
    if not np.all(np.isfinite(values)) and not (masked and not np.any(np.isinf(values))):
        raise NoiseFloorError("the channels hold NaN or inf: no noise floor")
    return values


# --------------------------------------------------------------------------------------------
# the floor of a record


def noise_floor(
    measurements: Measurements,
    channels: Sequence[str],
    *,
    frequency_hz: float | None = None,
    method: Literal["auto", "periods", "differences"] = "auto",
) -> NoiseFloor:
    """The noise floor of the named channels of a record, as recorded.

    Parameters
    ----------
    measurements
        The record before any filtering or period averaging (a record whose metadata say it was
        averaged or filtered is refused: its floor is that of the recording scaled, see
        :func:`prepared_floor`).
    channels
        Channels to estimate (``model.channels``).
    frequency_hz
        Fundamental frequency of a periodic excitation; default ``metadata["frequency_hz"]``.
    method
        ``"auto"``: period-to-period when the record holds at least two periods of a known
        frequency, otherwise differences; ``"periods"`` insists on the periodic estimate.
    """
    if not isinstance(measurements, Measurements):
        raise TypeError(f"measurements must be Measurements, got {type(measurements).__name__}")
    if method not in ("auto", "periods", "differences"):
        raise ValueError(f"method must be 'auto', 'periods' or 'differences', got {method!r}")
    processed = [key for key in ("periods_averaged", "differentiation", "decimation") if key in measurements.metadata]
    if "periods_averaged" in processed or (measurements.metadata.get("differentiation") == "butterworth") \
            or "decimation" in processed:
        raise NoiseFloorError(f"these measurements were processed ({', '.join(processed)}): the noise floor is "
                              "estimated on the record as loaded, before averaging or filtering")
    channels = tuple(channels)
    values = measurements.channels(channels)
    if frequency_hz is None and method != "differences":
        frequency_hz = measurements.metadata.get("frequency_hz")
    t = measurements.t
    if frequency_hz is not None and method != "differences" and np.isnan(np.sum(values)):
        if method == "periods":  # a period's samples are compared phase by phase: a masked one breaks them
            raise NoiseFloorError("a channel holds masked samples (a clipped sensor's): the period-to-period "
                                  "variance needs every sample of every period; the differences can give a floor")
        frequency_hz = None  # masked samples (estimation.data.channel_mask): the differences, channel by channel
    if frequency_hz is not None and method != "differences":
        frequency_hz = float(frequency_hz)
        if not (np.isfinite(frequency_hz) and frequency_hz > 0):
            raise ValueError(f"frequency_hz must be positive, got {frequency_hz}")
        step = float(np.median(np.diff(t)))
        per_period = 1.0 / (frequency_hz * step)
        periods = (t[-1] - t[0] + step) * frequency_hz
        if periods >= 2 - 1e-9:
            whole = int(round(per_period))
            regular = np.max(np.abs(np.diff(t) - step)) <= 1e-6 * step
            if regular and abs(per_period - whole) <= 1e-6 * per_period:
                variance, dof = period_variance(values, whole)
                details: dict[str, Any] = {"frequency_hz": frequency_hz, "samples_per_period": whole,
                                           "periods": measurements.n_samples // whole}
                variance, dof, changed = without_drift(values, whole, variance, dof, channels)
                if changed:
                    details["drift"] = changed
                return NoiseFloor(channels, variance, "periods", dof, measurements.n_samples, details)
            variance, dof, harmonics = fourier_residual_variance(t, values, frequency_hz)
            details = {"frequency_hz": frequency_hz, "samples_per_period": per_period, "periods": periods,
                       "harmonics": harmonics}
            if harmonics == MAX_HARMONICS:
                details["note"] = (f"harmonics capped at {MAX_HARMONICS}: periodic content above "
                                   f"{MAX_HARMONICS * frequency_hz:g} Hz counts as noise (floor too high)")
            return NoiseFloor(channels, variance, "fourier", dof, measurements.n_samples, details)
        if method == "periods":
            raise NoiseFloorError(f"the record holds {periods:.3g} periods of {frequency_hz:g} Hz: the "
                                  "period-to-period variance needs at least two")
    elif method == "periods":
        raise NoiseFloorError("method 'periods' needs the excitation frequency (frequency_hz)")
    variance, dof = difference_variance(values, names=channels)
    return NoiseFloor(channels, variance, "differences", dof, measurements.n_samples, {"order": DIFFERENCE_ORDER})


def pooled_floor(floors: Sequence[NoiseFloor]) -> NoiseFloor | None:
    """One floor from those of several segments of a record: each channel's variances averaged with
    their degrees of freedom as weights (the pooled variance; its dof add up). ``None`` for none."""
    floors = list(floors)
    if not floors:
        return None
    if len(floors) == 1:
        return floors[0]
    channels = floors[0].channels
    if any(floor.channels != channels for floor in floors):
        raise ValueError("the segments' noise floors cover different channels")
    dof = np.array([floor.dof for floor in floors], dtype=float)
    variance = np.sum([floor.variance * weight for floor, weight in zip(floors, dof)], axis=0) / dof.sum()
    methods = {floor.method for floor in floors}
    details = {"pooled_segments": len(floors), "methods": sorted(methods)}
    return NoiseFloor(channels, variance, floors[0].method if len(methods) == 1 else "differences", float(dof.sum()),
                      sum(floor.n_samples for floor in floors), details)


def preprocessing_gain(measurements: Measurements) -> tuple[float, list[str]]:
    """Variance gain on white noise of the preprocessing recorded in ``metadata`` (period averaging,
    zero-phase Butterworth filtering of the torques, decimation), and what it was (a Butterworth differentiation that
    keeps the torques as recorded, ``torques="recorded"``: gain 1, the floor that of the recording)."""
    metadata = measurements.metadata
    gain, notes = 1.0, []
    periods = int(metadata.get("periods_averaged") or 1)
    if periods > 1:
        gain /= periods
        notes.append(f"average of {periods} periods (1/{periods})")
    step = float(np.median(np.diff(measurements.t))) if measurements.n_samples > 1 else 1.0
    decimation = int(metadata.get("decimation") or 1)
    original_rate = decimation / step  # the filters ran before the decimation
    if metadata.get("differentiation") == "butterworth" and metadata.get("torques") != "recorded":
        sos = scipy.signal.butter(int(metadata.get("filter_order", 4)), float(metadata["cutoff_hz"]), btype="low",
                                  fs=original_rate, output="sos")
        filter_gain = _filtfilt_gain(sos)
        gain *= filter_gain
        notes.append(f"zero-phase Butterworth at {float(metadata['cutoff_hz']):.4g} Hz ({filter_gain:.3g})")
    if decimation > 1:
        sos = scipy.signal.butter(8, 0.8 * 0.5 * original_rate / decimation, btype="low", fs=original_rate,
                                  output="sos")
        filter_gain = _filtfilt_gain(sos)
        gain *= filter_gain
        notes.append(f"decimation by {decimation} ({filter_gain:.3g})")
    return gain, notes


def _filtfilt_gain(sos: NDArray[np.float64]) -> float:
    """Variance gain of ``sosfiltfilt`` on white noise: the mean of ``|H|⁴`` over ``[0, π]``."""
    _, response = scipy.signal.sosfreqz(sos, worN=1 << 15)
    return float(np.mean(np.abs(response) ** 4))


def prepared_floor(floor: NoiseFloor, measurements: Measurements) -> NoiseFloor:
    """The floor of a recording carried through the preprocessing ``measurements`` record (the
    MSE against averaged or filtered channels is compared with this)."""
    gain, notes = preprocessing_gain(measurements)
    return floor if not notes else floor.scaled(gain, "; ".join(notes))
