"""Velocities and accelerations from measured positions; filtering and decimation.

Two differentiation methods, each a small frozen object with ``apply(measurements)``:

* :class:`FourierDifferentiation` — for periodic excitation (PUMA paper, section IV): average the
  measured periods when the record holds two or more whole periods of a whole number of samples
  (noise on every channel drops by ``√periods``), fit the finite Fourier series of eq. 18 to the
  positions by linear least squares on their time stamps (any fundamental, any record of at least
  one period), and take ``q, dq, ddq`` analytically from the fit. The recorded channels of every sample
  (the tail past the last whole period too) are kept beside the averaged ones.
* :class:`ButterworthDifferentiation` — for any motion: zero-phase Butterworth low-pass
  (``filtfilt``) of the positions, ``dq`` and ``ddq`` the derivatives of their quintic interpolating
  spline (:func:`spline_derivatives`); the torques and wrench stay as recorded, the fit's target (filtered
  alike, a Coulomb law's step would be smeared while the regressor's ``sign(dq)`` stays sharp, its friction fitted
  low), and a weighted fit's channel weights come from the residual in the motion's band
  (:class:`estimation.estimators.identification_problem.ResidualBand`). The filter covers the whole record: each end is extended by its odd reflection
  over the filter's settling time (:func:`settling_samples`), so no sample is dropped and every
  cut-off is judged on the same samples (trimming the settling instead is an option).

Both keep the torques and wrench as recorded beside the filtered or averaged ones
(``Measurements.recorded``, with the derived motion at the recorded instants): errors are
measured against the recording.

:func:`fill_derivatives` applies one of them when ``dq`` or ``ddq`` is missing; :func:`decimate`
low-passes every channel and keeps one sample in ``factor``; :func:`compensate_hold` aligns derived
motion with joint torques held over each sample (zero-order hold).
"""

from __future__ import annotations

import functools
import warnings
from dataclasses import dataclass, replace
from typing import Literal, Protocol

import numpy as np
import scipy.interpolate
import scipy.linalg.lapack
import scipy.signal
from numpy.typing import NDArray

from dynamics.measurements import Measurements
from estimation.data.log_cleaning import DEFAULT_MAX_GAP
from estimation.data.rest import held_rows
from estimation.preprocessing.fourier_series import FourierSeries, fit_series

#: period averaging: ``auto`` averages when there are two or more whole periods of a whole number of samples
AverageChoice = Literal["auto", "yes", "no"]
#: the edges trimmed after a zero-phase filter: its impulse response there is below this fraction of its peak
SETTLING_FRACTION = 1e-2


class Differentiation(Protocol):
    """How ``dq`` and ``ddq`` are obtained from ``q``."""

    def apply(self, measurements: Measurements) -> Measurements:
        """Measurements with ``q, dq, ddq`` filled in (and the other channels treated alike)."""
        ...


def sampling_rate(t: NDArray[np.float64]) -> float:
    """Rate of a uniform time base, Hz (the loader resamples irregular data)."""
    steps = np.diff(t)
    if steps.size == 0:
        raise ValueError("need at least two samples to know the sampling rate")
    step = float(np.median(steps))
    if np.max(np.abs(steps - step)) > 1e-3 * step:
        raise ValueError("irregular sampling: resample first (estimation.data.records.read_measurements does)")
    return 1.0 / step


def average_periods(measurements: Measurements, frequency_hz: float) -> Measurements:
    """Average the whole periods of a periodic experiment into one period (PUMA paper, section IV).

    Keeps ``floor(N / P)`` whole periods of ``P = rate / f`` samples (``P`` must be an integer:
    the sampling rate a multiple of the excitation frequency), drops the tail, and averages
    every channel sample by sample. The time base is that of the first period.
    """
    rate = sampling_rate(measurements.t)
    per_period = rate / frequency_hz
    samples = int(round(per_period))
    if abs(per_period - samples) > 1e-6 * per_period:
        raise ValueError(
            f"the sampling rate {rate:.6g} Hz is not a multiple of the excitation frequency {frequency_hz} Hz: "
            "periods cannot be averaged sample by sample"
        )
    periods = measurements.n_samples // samples
    if periods < 1:
        raise ValueError(
            f"{measurements.n_samples} samples hold less than one period ({samples} samples at {frequency_hz} Hz)"
        )

    def fold(values):
        if values is None:
            return None
        return values[: periods * samples].reshape(periods, samples, -1).mean(axis=0)

    metadata = dict(measurements.metadata, periods_averaged=periods)
    return Measurements(
        measurements.t[:samples], fold(measurements.q), fold(measurements.dq), fold(measurements.ddq),
        fold(measurements.tau), fold(measurements.wrench), metadata,
    )


def fit_fourier(t: NDArray[np.float64], q: NDArray[np.float64], frequency_hz: float, harmonics: int) -> FourierSeries:
    """Least-squares fit of the finite Fourier series of eq. 18 (PUMA paper) to positions ``q (T, n)``
    on their time stamps ``t`` (:func:`estimation.preprocessing.fourier_series.fit_series`, by its normal
    equations: a derivative candidate is fitted many times a run)."""
    return fit_series(t, q, frequency_hz, harmonics, solver="normal")[0]


def whole_periods(measurements: Measurements, frequency_hz: float) -> tuple[int, int] | None:
    """``(periods, samples per period)`` when a period is a whole number of samples (to 1e-6), else ``None``."""
    return periods_at_rate(sampling_rate(measurements.t), measurements.n_samples, frequency_hz)


def periods_at_rate(rate: float, n_samples: int, frequency_hz: float) -> tuple[int, int] | None:
    """:func:`whole_periods` of ``n_samples`` samples at ``rate`` Hz (a record read in chunks knows both without
    holding its stamps)."""
    per_period = rate / frequency_hz
    samples = int(round(per_period))
    if samples < 1 or abs(per_period - samples) > 1e-6 * per_period:
        return None
    return n_samples // samples, samples


def averages_periods(average: AverageChoice | bool, periods: tuple[int, int] | None) -> bool:
    """Whether a record whose :func:`whole_periods` are ``periods`` has them averaged under the choice ``average``
    (:class:`FourierDifferentiation`'s): ``auto`` when they are two or more whole periods of a whole number of
    samples, ``yes`` whenever a period is a whole number of samples, ``no`` never. ``ValueError`` for ``yes`` when
    a period is not a whole number of samples is the caller's (it names the rate)."""
    choice = {True: "yes", False: "no"}.get(average, average) if isinstance(average, bool) else average
    if choice == "no":
        return False
    if choice == "yes":
        return True
    return periods is not None and periods[0] >= 2


def repeats_exactly(t: NDArray[np.float64], periods: int, frequency_hz: float) -> bool:
    """Whether the time stamps ``t`` of ``periods`` whole periods are those of the first period shifted by whole
    periods ``j / f``, to ``1e-12`` of the record's last time (the rounding of the phases ``ω_l t`` themselves):
    a Fourier series' motion there is that of the first period, repeated."""
    samples = t.shape[0] // periods
    shifts = t.reshape(periods, samples) - t[:samples]
    tolerance = 1e-12 * (float(np.max(np.abs(t))) + 1.0 / frequency_hz)
    return bool(np.max(np.abs(shifts - np.arange(periods)[:, None] / frequency_hz)) <= tolerance)


@dataclass(frozen=True)
class FourierDifferentiation:
    """Analytic derivatives of a Fourier fit (periodic excitation), after period averaging if chosen.

    Attributes
    ----------
    frequency_hz
        Fundamental frequency of the excitation (0.2 Hz in the PUMA paper); any value.
    harmonics
        Harmonics of the fit (5 in the paper); more than the excitation's is harmless.
    average
        ``"auto"`` (default): average the whole periods first (the torques and wrench too) when
        there are two or more and a period is a whole number of samples, else fit every sample on
        its time stamp; ``"yes"`` (or ``True``): average, an error when it cannot; ``"no"``
        (``False``): fit every sample.
    """

    frequency_hz: float
    harmonics: int = 5
    average: AverageChoice | bool = "auto"

    def __post_init__(self) -> None:
        if not (np.isfinite(self.frequency_hz) and self.frequency_hz > 0):
            raise ValueError(f"frequency_hz must be positive, got {self.frequency_hz}")
        if int(self.harmonics) != self.harmonics or self.harmonics < 1:
            raise ValueError(f"harmonics must be a positive integer, got {self.harmonics}")
        if self.average not in ("auto", "yes", "no", True, False):
            raise ValueError(f"average must be 'auto', 'yes' or 'no', got {self.average!r}")

    def averages(self, measurements: Measurements) -> bool:
        """Whether the periods of ``measurements`` are averaged (``ValueError`` for ``yes`` when they cannot be)."""
        if self.average in ("no", False):
            return False
        periods = whole_periods(measurements, self.frequency_hz)
        if self.average in ("yes", True) and periods is None:
            average_periods(measurements, self.frequency_hz)  # raises, naming the rate
        return averages_periods(self.average, periods)

    def apply(self, measurements: Measurements) -> Measurements:
        duration = measurements.t[-1] - measurements.t[0] + (measurements.t[1] - measurements.t[0])
        if duration * self.frequency_hz < 1 - 1e-9:
            raise ValueError(f"{measurements.n_samples} samples ({duration:.4g} s) hold less than one period of "
                             f"{self.frequency_hz:g} Hz: the Fourier fit is not determined (use a cut-off instead)")
        raw = measurements
        averaged = self.averages(measurements)
        if averaged:
            measurements = average_periods(measurements, self.frequency_hz)
        nyquist = 0.5 * sampling_rate(measurements.t)
        if self.harmonics * self.frequency_hz >= nyquist:
            raise ValueError(f"{self.harmonics} harmonics of {self.frequency_hz:g} Hz reach the Nyquist frequency {nyquist:.6g} Hz")
        fit = fit_fourier(measurements.t, measurements.q, self.frequency_hz, self.harmonics)
        q, dq, ddq = fit.evaluate(measurements.t)
        rms = np.sqrt(np.mean((measurements.q - q) ** 2, axis=0))
        metadata = dict(measurements.metadata, differentiation="fourier", fourier_fit=fit.to_dict(), fit_rms=rms.tolist())
        if not averaged:
            metadata["periods_averaged"] = 0
        recorded, rows = None, None
        if averaged:  # every recorded sample (the tail past the last whole period too), the fit's motion at its instant
            periods, samples = measurements.metadata["periods_averaged"], measurements.n_samples
            whole = periods * samples
            if repeats_exactly(raw.t[:whole], periods, self.frequency_hz):  # the averaged period's motion, repeated
                q_raw, dq_raw, ddq_raw = (np.tile(values, (periods, 1)) for values in (q, dq, ddq))
                if raw.n_samples > whole:
                    tail = fit.evaluate(raw.t[whole:])
                    q_raw, dq_raw, ddq_raw = (np.vstack([head, rest]) for head, rest in zip((q_raw, dq_raw, ddq_raw), tail))
            else:
                q_raw, dq_raw, ddq_raw = fit.evaluate(raw.t)
            recorded = replace(raw, q=q_raw, dq=dq_raw, ddq=ddq_raw, metadata=dict(metadata), recorded=None)
            rows = np.arange(raw.n_samples) % samples
        return replace(measurements, q=q, dq=dq, ddq=ddq, metadata=metadata, recorded=recorded, recorded_rows=rows)


@dataclass(frozen=True)
class ButterworthDifferentiation:
    """Zero-phase Butterworth low-pass and spline derivatives (any motion; :func:`spline_derivatives`).

    Attributes
    ----------
    cutoff_hz
        Cut-off frequency; ``None`` picks five times the frequency below which 99.9 % of the
        positions' variance lies (a common rule: well above the motion's bandwidth, well below
        the noise), capped at 0.8 × Nyquist.
    order
        Filter order (``filtfilt`` doubles it and cancels the phase).
    trim
        Drop the edges where the filter has not settled (:meth:`settling_samples` at each end); by default
        the filter covers the record, its ends extended over that time (:func:`extend_edges`).
    logged_velocity
        A ``dq`` in the measurements is filtered (and ``ddq`` differentiated from it); ``False``: ``dq`` is
        differentiated from the positions whatever the record logs.
    rate_hz
        The record's sampling rate, when the samples given are a window of it (the streamed path's blocks: a
        window's median step differs from the record's where the stamps are coarse, epoch or float32 time);
        ``None``: the rate of the samples given.
    torques
        ``"filtered"``: the torques and wrench filtered alike (the fit's target); ``"recorded"``: kept as recorded,
        the fit's target (a filtered Coulomb step is smeared over a period of the cut-off while the regressor's
        ``sign(dq)`` stays sharp: friction fitted low, the more so the lower the cut-off), and a weighted fit's
        channel weights taken from the residual in the motion's band
        (:class:`estimation.estimators.identification_problem.ResidualBand`; the streamed path sums the in-band
        problem too, :attr:`estimation.estimators.normal_equations.NormalEquations.band`). The default
        (benchmarks/README.md, h-target, h-band).
    """

    cutoff_hz: float | None = None
    order: int = 4
    trim: bool = False
    logged_velocity: bool = True
    rate_hz: float | None = None
    torques: Literal["filtered", "recorded"] = "recorded"

    def __post_init__(self) -> None:
        if self.cutoff_hz is not None and not (np.isfinite(self.cutoff_hz) and self.cutoff_hz > 0):
            raise ValueError(f"cutoff_hz must be positive, got {self.cutoff_hz}")
        if int(self.order) != self.order or self.order < 1:
            raise ValueError(f"order must be a positive integer, got {self.order}")
        if self.torques not in ("filtered", "recorded"):
            raise ValueError(f"torques must be 'filtered' or 'recorded', got {self.torques!r}")

    def cutoff(self, measurements: Measurements) -> float:
        rate = sampling_rate(measurements.t) if self.rate_hz is None else float(self.rate_hz)
        nyquist = 0.5 * rate
        if self.cutoff_hz is not None:
            if self.cutoff_hz >= nyquist:
                raise ValueError(f"cutoff {self.cutoff_hz:g} Hz is not below the Nyquist frequency {nyquist:.6g} Hz")
            lowest = 1.0 / (measurements.t[-1] - measurements.t[0])
            if self.cutoff_hz < lowest:
                raise ValueError(f"cutoff {self.cutoff_hz:g} Hz is below 1/(record length) = {lowest:.3g} Hz: the "
                                 "filter would remove the motion itself")
            return float(self.cutoff_hz)
        return min(5.0 * motion_bandwidth(measurements.q, rate), 0.8 * nyquist)

    def settling_samples(self, rate: float, cutoff: float) -> int:
        """Samples after which the zero-phase (forward-backward) impulse response of the filter stays
        below :data:`SETTLING_FRACTION` of its peak: what ``filtfilt`` smears at each edge of a record
        (:func:`settling_samples`)."""
        return settling_samples(self.order, float(rate), float(cutoff))

    def apply(self, measurements: Measurements) -> Measurements:
        rate = sampling_rate(measurements.t) if self.rate_hz is None else float(self.rate_hz)
        given = self.cutoff_hz is not None and self.cutoff_hz < 0.5 * rate
        cutoff = float(self.cutoff_hz) if given else self.cutoff(measurements)  # the length check first
        settling = self.settling_samples(float(f"{rate:.9g}"), cutoff)  # one length for every window of a record
        trim = settling if self.trim else 0
        if self.trim and measurements.n_samples < 4 * trim:
            raise ValueError(f"{measurements.n_samples} samples ({measurements.n_samples / rate:.4g} s) are too few for "
                             f"the {cutoff:.4g} Hz filter: it settles in {trim / rate:.3g} s at each edge, trimmed; "
                             f"need at least {4 * trim} samples")
        if given:
            self.cutoff(measurements)  # the cut-off against the record's length
        sos = scipy.signal.butter(self.order, cutoff, btype="low", fs=rate, output="sos")
        # each end extended over the settling time (at least scipy's default reach), filtered and differentiated
        # on the extended record: the derivatives up to its edges (extend_edges)
        n = measurements.n_samples
        padding = min(n - 1, max(3 * (2 * len(sos) + 1) * 10, settling))
        # the step from the record's span: epoch stamps (1.7e9 s) would round each difference to 2.4e-7 s
        step = (measurements.t[-1] - measurements.t[0]) / (n - 1)
        inside = slice(padding, padding + n)
        window = int(round(rate / cutoff))  # one period of the cut-off (rounded: the same for every window of a record)

        def smooth(values):
            if values is None:
                return None
            return scipy.signal.sosfiltfilt(sos, extend_edges(values, padding, window), axis=0, padtype=None)

        q = smooth(measurements.q)
        logged = measurements.dq is not None and self.logged_velocity
        if logged:
            dq = smooth(measurements.dq)
            ddq = smooth(measurements.ddq) if measurements.ddq is not None else spline_derivatives(dq, step, 1)[0]
        elif measurements.ddq is not None:
            dq, ddq = spline_derivatives(q, step, 1)[0], smooth(measurements.ddq)
        else:
            dq, ddq = spline_derivatives(q, step, 2)  # one spline of the positions for both (its derivatives)
        q, dq, ddq = q[inside], dq[inside], ddq[inside]
        if not logged:  # a joint whose positions do not change: its velocity rounding, not the sign of a motion
            dq = below_resolution(measurements.q, step, dq, 1)
            ddq = ddq if measurements.ddq is not None else below_resolution(measurements.q, step, ddq, 2)
        held = held_rows(measurements.t, measurements.q, DEFAULT_MAX_GAP)
        if held.any():  # the robot held still: its velocity is zero, not the filter's transient (whose sign is noise)
            dq, ddq = np.where(held[:, None], 0.0, dq), np.where(held[:, None], 0.0, ddq)
        if self.torques == "recorded":
            tau, wrench = measurements.tau, measurements.wrench
        else:
            tau, wrench = (None if values is None else smooth(values)[inside] for values in (measurements.tau,
                                                                                            measurements.wrench))
        metadata = dict(measurements.metadata, differentiation="butterworth", cutoff_hz=cutoff, filter_order=self.order,
                        trimmed_s=trim / rate)
        if self.torques == "recorded":
            metadata["torques"] = "recorded"
        filtered = replace(measurements, q=q, dq=dq, ddq=ddq, tau=tau, wrench=wrench, metadata=metadata, recorded=None)
        recorded = replace(filtered, tau=measurements.tau, wrench=measurements.wrench)  # the recording, same motion
        filtered = replace(filtered, recorded=recorded)
        return filtered.select(slice(trim, measurements.n_samples - trim)) if trim else filtered


#: a derivative of the positions below this many times their floating-point resolution is rounding, not motion
#: (:func:`below_resolution`)
ROUNDING_FACTOR = 1e3


def below_resolution(q: NDArray[np.float64], step: float, derivative: NDArray[np.float64], order: int
                     ) -> NDArray[np.float64]:
    """``derivative`` (the ``order``-th of the positions ``q``, samples ``step`` apart) zeroed where it is below
    :data:`ROUNDING_FACTOR` times the positions' floating-point resolution (the spacing of float64 at each joint's
    largest ``|q|``) over ``step**order``.

    Why: a joint whose positions do not change (held by its controller while another joint moves, a locked joint)
    gets, filtered and spline-differentiated, a velocity of rounding noise (±6e-14 rad/s for a joint held at
    0.52 rad at 250 Hz) whose sign switches its Coulomb column between ``+fc`` and ``−fc`` on every row, where the
    true velocity, and the friction's sign, is zero. The rounding measured on held joints (0.5-300 rad, 100 Hz-5 kHz,
    cut-offs 1 Hz to 0.8 Nyquist) reaches 34 spacings over a step in ``dq`` and 27 over its square in ``ddq``: the
    factor leaves a 30x margin. Any motion a sensor resolves is orders of magnitude above the threshold (4e-10 rad/s
    at 3 rad and 1 kHz); on the real logs only velocities at the TX40's motor reversals fall below it (5 kHz, motor
    angles of hundreds of rad: 3e-7 rad/s)."""
    resolution = ROUNDING_FACTOR * np.spacing(np.max(np.abs(q), axis=0)) / step**order
    return np.where(np.abs(derivative) < resolution, 0.0, derivative)


#: degree of the interpolating spline whose derivatives are ``dq`` and ``ddq`` (:func:`spline_derivatives`)
SPLINE_DEGREE = 5


def spline_derivatives(values: NDArray[np.float64], step: float, orders: int) -> list[NDArray[np.float64]]:
    """The first ``orders`` derivatives of ``values`` (samples along axis 0, ``step`` apart): those of their
    quintic interpolating spline (not-a-knot ends).

    The derivatives must be those of the filtered positions, which the torques are filtered alike against:
    central differences are a further low-pass on ``dq`` alone (gain ``sin(ωh) / (ωh)`` at step ``h``) and, applied
    twice, on ``ddq`` (its square), which neither ``q`` nor the torques see. Negligible where the filter's cut-off
    is far below the sampling rate, it is not at low rates: at 50 Hz a 12.5 Hz component's ``ddq`` keeps 41 % of
    its amplitude, and the real EMPS logged at 50 Hz gave a mass 10 % high (104.5 kg against 94.9 at 1 kHz) and test
    errors 1.07 times the plain fit's instead of 1.23 (``benchmarks/bench_sweep.py --only emps-sub20``). A quintic
    spline's ``dq`` and ``ddq`` are within 0.5 % of a sinusoid's up to a fifth of the sampling rate, where
    central differences are 24 % and 43 % low (the quintic spline of biomechanics' differentiation, Woltring, "A Fortran
    package for generalized, cross-validatory spline smoothing and differentiation", Adv. Eng. Software 8,
    1986). Fewer samples than the spline needs: central differences. The spline is that of the filtered
    positions: differentiating first and filtering after (the two commute inside the record) starts the filter
    from a noisy derivative at the extended edges (a 3 Hz filter, positions with 1 mrad noise at 500 Hz: ddq 7
    times further from the truth over the first and last 2 s).
    """
    if values.shape[0] <= SPLINE_DEGREE:
        found, current = [], values
        for _ in range(orders):
            current = np.gradient(current, step, axis=0) if values.shape[0] > 1 else np.zeros_like(values)
            found.append(current)
        return found
    grid = step * np.arange(values.shape[0])
    spline = interpolating_spline(values, step)
    return [spline(grid, nu=order) for order in range(1, orders + 1)]


def interpolating_spline(values: NDArray[np.float64], step: float) -> scipy.interpolate.BSpline:
    """The quintic interpolating spline (not-a-knot ends) of ``values`` (samples along axis 0) at ``step * k``:
    ``scipy.interpolate.make_interp_spline(step * arange(N), values, k=5, axis=0)`` bit for bit, its banded
    collocation matrix factored once for every record of the same length and step (:func:`interpolation_factors`:
    a choice's candidates filter the same record alike), the coefficients by the same LAPACK solve (``dgbsv`` is
    ``dgbtrf`` then ``dgbtrs``)."""
    n = values.shape[0]
    if values.dtype != np.float64 or not np.all(np.isfinite(values)):  # scipy's own path and errors
        return scipy.interpolate.make_interp_spline(step * np.arange(n), values, k=SPLINE_DEGREE, axis=0)
    factors = interpolation_factors if n <= CACHED_SPLINE_SAMPLES else interpolation_factors.__wrapped__
    knots, lu, pivots = factors(n, float(step))
    coefficients, info = scipy.linalg.lapack.dgbtrs(lu, SPLINE_DEGREE, SPLINE_DEGREE, values.reshape(n, -1), pivots)
    if info != 0:
        raise ValueError(f"illegal value in {-info}-th argument of internal gbtrs")
    return scipy.interpolate.BSpline.construct_fast(knots, np.ascontiguousarray(coefficients.reshape(values.shape)),
                                                    SPLINE_DEGREE, axis=0)


#: records up to this many samples keep their spline's factors (:func:`interpolation_factors`, at most 4 lengths
#: held: 16 rows of 8 bytes a sample each, 51 MB at most); longer ones factor afresh, so what is held does not grow
#: with the record
CACHED_SPLINE_SAMPLES = 100_000


@functools.lru_cache(maxsize=4)
def interpolation_factors(n: int, step: float) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.int32]]:
    """The not-a-knot knots of the quintic spline through ``n > 5`` samples ``step`` apart and the banded LU factors
    (LAPACK ``dgbtrf``) of its collocation matrix, as ``make_interp_spline`` forms them (read-only arrays)."""
    k = SPLINE_DEGREE
    grid = step * np.arange(n)
    knots = np.r_[(grid[0],) * (k + 1), grid[(k + 1) // 2: -((k + 1) // 2)], (grid[-1],) * (k + 1)]
    collocation = scipy.interpolate.BSpline.design_matrix(grid, knots, k).tocoo()
    band = np.zeros((3 * k + 1, n), order="F")  # LAPACK band storage: row kl + ku + i - j, column j
    band[2 * k + collocation.row - collocation.col, collocation.col] = collocation.data
    lu, pivots, info = scipy.linalg.lapack.dgbtrf(band, k, k)
    if info > 0:
        raise np.linalg.LinAlgError("Colocation matrix is singular.")
    for array in (knots, lu, pivots):
        array.setflags(write=False)
    return knots, lu, pivots


def extend_edges(values: NDArray[np.float64], padding: int, window: int, *, degree: int = 3) -> NDArray[np.float64]:
    """``values (N, …)`` extended by ``padding < N`` samples at each end, for a zero-phase filter to cover the record.

    At each end a cubic (``degree``) is fitted by least squares to the first ``window`` samples (at least
    ``degree + 5``, at most ``N``), and the extension is that polynomial continued plus the odd reflection of the
    samples' departure from it: ``x(−k) = p(−k) − (x(k) − p(k))``. It keeps the record's value, slope and curvature
    at the edge, and the departure's odd part (a plain odd reflection, ``2 x(0) − x(k)``, flips the curvature: the
    acceleration derived where a record starts or stops mid-motion falls to zero there, 70 N of force error on the
    EMPS's first samples); a Butterworth low-pass, maximally flat at zero frequency, passes the polynomial unchanged.
    With ``window`` one period of the cut-off, a filter covering a simulated PUMA record (200 Hz, 4 to 25 Hz
    cut-offs) scored within 4 % of the same filter with its settling trimmed (a quadratic: within 25 %; a plain odd
    reflection: within 38 %).
    """
    n = values.shape[0]
    if padding <= 0:
        return values
    width = int(min(n, max(degree + 5, window)))
    flat = values.reshape(n, -1)

    def before(samples: NDArray[np.float64]) -> NDArray[np.float64]:
        """The extension before ``samples`` (in time order, ending next to ``samples[0]``)."""
        basis = np.vander(np.arange(width, dtype=float) / width, degree + 1, increasing=True)
        coefficients = np.linalg.lstsq(basis, samples[:width], rcond=None)[0]
        k = np.arange(1, padding + 1, dtype=float) / width

        def polynomial(x: NDArray[np.float64]) -> NDArray[np.float64]:
            return np.vander(x, degree + 1, increasing=True) @ coefficients

        return (polynomial(-k) - (samples[1:padding + 1] - polynomial(k)))[::-1]

    extended = np.concatenate([before(flat), flat, before(flat[::-1])[::-1]], axis=0)
    return extended.reshape((n + 2 * padding,) + values.shape[1:])


@functools.lru_cache(maxsize=64)
def settling_samples(order: int, rate: float, cutoff: float) -> int:
    """Samples after which the zero-phase (forward-backward) impulse response of an ``order`` Butterworth
    low-pass at ``cutoff`` Hz, sampled at ``rate`` Hz, stays below :data:`SETTLING_FRACTION` of its peak."""
    sos = scipy.signal.butter(order, cutoff, btype="low", fs=rate, output="sos")
    length = int(np.ceil(40 * rate / cutoff)) + 1
    impulse = np.zeros(length)
    impulse[0] = 1.0
    forward = scipy.signal.sosfilt(sos, impulse)
    # centred at lag 0; by FFT: the direct sum is O(length²), 1.2 s at a 1 Hz cut-off and 1 kHz
    response = np.abs(scipy.signal.correlate(forward, forward, mode="full", method="fft")[length - 1:])
    return int(np.flatnonzero(response > SETTLING_FRACTION * response.max())[-1]) + 1


def motion_bandwidth(q: NDArray[np.float64], rate: float, fraction: float = 0.999) -> float:
    """Frequency below which ``fraction`` of the positions' variance lies, Hz (detrended and
    Hann-windowed: a record that is not a whole period would otherwise leak power to high frequencies)."""
    detrended = scipy.signal.detrend(q, axis=0) * scipy.signal.get_window("hann", q.shape[0])[:, None]
    power = np.abs(np.fft.rfft(detrended, axis=0)) ** 2
    frequencies = np.fft.rfftfreq(q.shape[0], 1.0 / rate)
    cumulative = np.cumsum(power.sum(axis=1))
    if cumulative[-1] == 0:
        return frequencies[1]
    return float(frequencies[np.searchsorted(cumulative, fraction * cumulative[-1])])


def decimate(measurements: Measurements, factor: int, *, order: int = 8) -> Measurements:
    """Low-pass every channel (zero-phase Butterworth, cut-off 0.8 × the new Nyquist frequency) and
    keep one sample in ``factor`` — the parallel decimation of identification practice, applied to
    positions and torques alike."""
    if int(factor) != factor or factor < 1:
        raise ValueError(f"decimation factor must be a positive integer, got {factor}")
    if factor == 1:
        return measurements
    if measurements.n_samples < 30 * factor:
        raise ValueError(f"{measurements.n_samples} samples are too few to decimate by {factor}")
    rate = sampling_rate(measurements.t)
    sos = scipy.signal.butter(order, 0.8 * 0.5 * rate / factor, btype="low", fs=rate, output="sos")

    def reduce(values):
        return None if values is None else scipy.signal.sosfiltfilt(sos, values, axis=0)[::factor]

    metadata = dict(measurements.metadata, decimation=int(factor))
    recorded = measurements.recorded
    if recorded is not None:  # the motion decimated alike, the recorded channels sampled as they are
        motion = decimate(replace(recorded, recorded=None), factor, order=order)
        recorded = replace(motion, tau=None if recorded.tau is None else recorded.tau[::factor],
                           wrench=None if recorded.wrench is None else recorded.wrench[::factor])
    elif measurements.tau is not None or measurements.wrench is not None:
        recorded = replace(measurements, q=reduce(measurements.q), dq=reduce(measurements.dq), ddq=reduce(measurements.ddq),
                           t=measurements.t[::factor], tau=None if measurements.tau is None else measurements.tau[::factor],
                           wrench=None if measurements.wrench is None else measurements.wrench[::factor],
                           metadata=metadata, recorded=None)
    rows = None
    if measurements.recorded_rows is not None:  # the recorded samples kept beside the samples kept
        rows = np.minimum(measurements.recorded_rows[::factor] // factor, -(-measurements.n_samples // factor) - 1)
    return Measurements(
        measurements.t[::factor], reduce(measurements.q), reduce(measurements.dq), reduce(measurements.ddq),
        reduce(measurements.tau), reduce(measurements.wrench), metadata, recorded, rows,
    )


def compensate_hold(measurements: Measurements) -> Measurements:
    """Derived motion moved half a sample later, to match joint torques held over each sample.

    A torque command ``τ_k`` held over ``[t_k, t_{k+1})`` makes the acceleration jump at every
    sample. A smooth fit of the positions (Fourier series or low-pass) cannot follow the jumps: its
    ``ddq`` is that of the held torque half a sample late, so the motion that satisfies the
    dynamics with ``τ_k`` is the fit's in the middle of the hold, ``t_k + T/2``: here
    ``(x_k + x_{k+1}) / 2`` for ``x = q, dq, ddq`` (the last sample extrapolated). The torques are
    left as measured, so their noise stays white. Measured on ``oed simulate`` data (PUMA, 3 joints,
    1 kHz, three periods, 15-harmonic Fourier fit), internal model: the largest error of a base
    parameter fell from 28 standard deviations (viscous friction of joint 1, 0.8 % low) to 3.2.

    For the joint-torque rows only: a wrench sampled at ``t_k`` (a force plate) then lags the motion
    by half a sample (combined model on the same data: largest error 28 → 8 standard deviations).
    Not for torques sampled from a continuous sensor, nor when ``dq``/``ddq`` were measured.
    """
    if measurements.dq is None or measurements.ddq is None:
        raise ValueError("compensate_hold moves derived dq/ddq: derive them first")
    if measurements.n_samples < 2:
        raise ValueError("compensate_hold needs at least two samples")

    def later(values):
        following = np.vstack([values[1:], 2 * values[-1:] - values[-2:-1]])
        return (values + following) / 2

    metadata = dict(measurements.metadata, hold_compensated=True)
    recorded = None if measurements.recorded is None else compensate_hold(measurements.recorded)
    return replace(measurements, q=later(measurements.q), dq=later(measurements.dq), ddq=later(measurements.ddq),
                   metadata=metadata, recorded=recorded)


def fill_derivatives(
    measurements: Measurements, method: Differentiation | None = None, *, decimation: int = 1,
    held_torques: bool = False,
) -> Measurements:
    """Measurements with ``dq`` and ``ddq``, derived by ``method`` when missing, then decimated.

    Without a method: periodic data (``metadata["frequency_hz"]`` set, as the simulator records
    for whole periods) use :class:`FourierDifferentiation` with three times the reference's
    ``metadata["harmonics"]`` (15 if unknown): the tracking error of a controlled robot adds
    harmonics above the reference's. With ``held_torques``, a fit with the reference's own count
    left the largest base-parameter error at 10–20 standard deviations (the paper's 5-harmonic
    design; 3-harmonic references), three times as many at 2–3 (``tests/test_simulator.py``).
    Other data use :class:`ButterworthDifferentiation` with the automatic cut-off. Data that
    already hold both are left alone unless a method is given.
    ``held_torques``: the joint torques were held over each sample; when the derivatives are
    derived here, :func:`compensate_hold` aligns the motion with them (before decimation).
    """
    if method is None and measurements.dq is not None and measurements.ddq is not None:
        if held_torques:
            warnings.warn("held torques: nothing to align, the data hold measured dq and ddq", stacklevel=2)
        return decimate(measurements, decimation)
    if method is None:
        frequency = measurements.metadata.get("frequency_hz")
        harmonics = 3 * int(measurements.metadata.get("harmonics") or 5)
        if frequency and measurements.n_samples > 1:  # stay below Nyquist
            nyquist_harmonic = int(np.ceil(0.5 * sampling_rate(measurements.t) / float(frequency))) - 1
            harmonics = max(1, min(harmonics, nyquist_harmonic))
        method = FourierDifferentiation(float(frequency), harmonics) if frequency else ButterworthDifferentiation()
    derived = method.apply(measurements)
    return decimate(compensate_hold(derived) if held_torques else derived, decimation)
