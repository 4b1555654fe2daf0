"""Is a record periodic, and with which fundamental? Detection and a check of a given frequency.

The measure is the normalised difference function of pitch detection (de Cheveigné & Kawahara,
"YIN, a fundamental frequency estimator", JASA 2002): for a lag of ``L`` samples,

.. math::
    ρ(L) = \\frac{\\sum_j \\frac{1}{N-L} \\sum_{i<N-L} (q_{i+L,j} - q_{i,j})^2}{2 \\sum_j \\operatorname{var} q_j}

0 when the positions repeat after ``L`` samples, about 1 for unrelated samples. The fundamental
period is the first lag (after ``ρ`` has risen) where ``ρ`` drops below :data:`REPEAT_THRESHOLD`;
its frequency is then refined by minimising the residual of a Fourier fit on the time stamps
(:func:`estimation.preprocessing.fourier_series.fit_series`). A record must span at least
:data:`MIN_PERIODS` periods for its period to be seen (the overlap of the record with itself
shifted by one period is then half a period).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.optimize
from numpy.typing import NDArray

from estimation.preprocessing.fourier_series import fit_series

#: ρ below this at a lag: the record repeats after it (positions differ by < 14 % of their RMS)
REPEAT_THRESHOLD = 0.01
#: ρ must first exceed this (the motion decorrelates) before a repetition counts
RISE_THRESHOLD = 0.5
#: periods a record must span for its period to be detected or checked
MIN_PERIODS = 1.5
#: harmonics of the Fourier fit that refines a detected frequency
REFINE_HARMONICS = 10
#: a detected frequency this close (relative) to a round value is that value
ROUND_TOLERANCE = 2e-5
#: two frequencies whose ratio is this close to a whole number ≥ 2 are harmonics of each other
HARMONIC_TOLERANCE = 0.02


@dataclass(frozen=True)
class Periodicity:
    """What a record shows.

    Attributes
    ----------
    frequency_hz
        Detected fundamental, Hz, or ``None`` when the record does not repeat within
        ``1 / MIN_PERIODS`` of its length.
    repeat_error
        ``ρ`` at the detected period (``nan`` when none).
    """

    frequency_hz: float | None
    repeat_error: float = float("nan")


def difference_function(q: NDArray[np.float64], max_lag: int) -> NDArray[np.float64]:
    """``ρ(L)`` for ``L = 0..max_lag`` (module docstring), by FFT autocorrelation."""
    q = np.asarray(q, dtype=float).reshape(q.shape[0], -1)
    n = q.shape[0]
    x = q - q.mean(axis=0)
    variance = float(np.sum(np.var(x, axis=0)))
    if variance == 0:
        return np.full(max_lag + 1, np.nan)
    size = 1 << int(np.ceil(np.log2(2 * n)))
    spectrum = np.fft.rfft(x, size, axis=0)
    correlation = np.fft.irfft(np.abs(spectrum) ** 2, size, axis=0)[: max_lag + 1].sum(axis=1)  # Σ_i x_i x_{i+L}
    squares = np.sum(x**2, axis=1)
    cumulative = np.concatenate([[0.0], np.cumsum(squares)])
    lags = np.arange(max_lag + 1)
    head = cumulative[n - lags]  # Σ_{i < N-L} x_i²
    tail = cumulative[n] - cumulative[lags]  # Σ_{i ≥ L} x_i²
    difference = np.maximum(head + tail - 2 * correlation, 0.0) / (n - lags)
    return difference / (2 * variance)


def repeat_error(q: NDArray[np.float64], lag: float) -> float:
    """``ρ`` at a (fractional) lag, interpolated; ``nan`` beyond ``N / MIN_PERIODS``."""
    n = q.shape[0]
    if lag < 1 or lag > n / MIN_PERIODS:
        return float("nan")
    rho = difference_function(q, int(np.ceil(lag)))
    low = int(np.floor(lag))
    weight = lag - low
    return float((1 - weight) * rho[low] + weight * rho[min(low + 1, rho.shape[0] - 1)])


def detect_fundamental(t: NDArray[np.float64], q: NDArray[np.float64]) -> Periodicity:
    """The fundamental of a uniformly sampled record of positions ``q (N, n)`` at times ``t``.

    Returns ``Periodicity(None)`` when the record does not repeat (or spans fewer than
    :data:`MIN_PERIODS` of its candidate periods)."""
    t = np.asarray(t, dtype=float)
    n = t.shape[0]
    max_lag = int(n / MIN_PERIODS)
    if max_lag < 4:
        return Periodicity(None)
    rho = difference_function(q, max_lag)
    if not np.all(np.isfinite(rho)):
        return Periodicity(None)
    risen = np.flatnonzero(rho > RISE_THRESHOLD)
    if risen.size == 0:
        return Periodicity(None)
    below = np.flatnonzero(rho[risen[0]:] < REPEAT_THRESHOLD)
    if below.size == 0:
        return Periodicity(None)
    lag = int(risen[0] + below[0])
    while lag + 1 <= max_lag and rho[lag + 1] < rho[lag]:  # down to the local minimum
        lag += 1
    if 0 < lag < max_lag:  # parabolic interpolation between samples
        left, middle, right = rho[lag - 1], rho[lag], rho[lag + 1]
        curvature = left - 2 * middle + right
        offset = 0.5 * (left - right) / curvature if curvature > 0 else 0.0
    else:
        offset = 0.0
    step = (t[-1] - t[0]) / (n - 1)
    frequency = 1.0 / ((lag + offset) * step)
    return Periodicity(rounded(refine_frequency(t, q, frequency, width=2.0 / lag)), float(rho[lag]))


def rounded(frequency_hz: float) -> float:
    """A detected frequency snapped to 3 or 4 significant digits when within :data:`ROUND_TOLERANCE`
    of it (designed excitations have round fundamentals: 0.075 Hz, not 0.0749999 Hz)."""
    for digits in (3, 4):
        candidate = float(f"{frequency_hz:.{digits}g}")
        if abs(candidate - frequency_hz) <= ROUND_TOLERANCE * frequency_hz:
            return candidate
    return frequency_hz


def refine_frequency(t: NDArray[np.float64], q: NDArray[np.float64], frequency_hz: float, *, width: float) -> float:
    """The frequency within ``frequency_hz · (1 ± width)`` whose Fourier fit leaves the least residual."""
    nyquist = 0.5 * (t.shape[0] - 1) / (t[-1] - t[0])
    harmonics = max(1, min(REFINE_HARMONICS, int(nyquist / frequency_hz / 1.1), (t.shape[0] - 1) // 2))

    def residual(f: float) -> float:
        return fit_series(t, q, f, harmonics)[1]

    result = scipy.optimize.minimize_scalar(residual, bounds=(frequency_hz * (1 - width), frequency_hz * (1 + width)),
                                            method="bounded", options={"xatol": 1e-7 * frequency_hz})
    return float(result.x)


def frequency_mismatch(t: NDArray[np.float64], q: NDArray[np.float64], frequency_hz: float,
                       detected: Periodicity | None = None) -> str | None:
    """Why the data disagree with a given fundamental, or ``None`` when they agree (or cannot tell).

    A given frequency that is a sub-harmonic of the one the data show (0.1 Hz for a 0.2 Hz record)
    fits fewer useful harmonics and, averaged, cuts the record to few periods; one that is a
    harmonic (or unrelated) leaves the motion between its periods unexplained."""
    detected = detect_fundamental(t, q) if detected is None else detected
    step = (t[-1] - t[0]) / (t.shape[0] - 1)
    repeats = repeat_error(q, 1.0 / (frequency_hz * step))
    if detected.frequency_hz is not None:
        ratio = detected.frequency_hz / frequency_hz
        whole = round(ratio)
        if whole >= 2 and abs(ratio - whole) < HARMONIC_TOLERANCE * whole:
            return (f"the data repeat every {1 / detected.frequency_hz:.6g} s ({detected.frequency_hz:.6g} Hz), "
                    f"{whole} times per period of the given {frequency_hz:g} Hz: it is a sub-harmonic; give "
                    f"--frequency {detected.frequency_hz:.6g} (with the harmonics scaled down by {whole})")
    if np.isfinite(repeats) and repeats > REPEAT_THRESHOLD:
        shown = "" if detected.frequency_hz is None else f" (they repeat at {detected.frequency_hz:.6g} Hz)"
        return (f"the data do not repeat after one period of the given {frequency_hz:g} Hz (difference "
                f"{np.sqrt(2 * repeats):.2g} of their RMS){shown}: check --frequency")
    return None
