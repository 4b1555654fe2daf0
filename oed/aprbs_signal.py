"""Amplitude-modulated pseudo-random binary signals (APRBS) for the servo arm (servo paper section 4.1, eq. 15).

An APRBS holds a level ``d_s ∈ [u_min, u_max]`` for a random dwell time ``T_h`` (eq. 15). Here, per joint:

* levels are *stratified*: the range is cut into ``n_levels`` equal bins and the holds visit the bins in
  random permutations, each level drawn uniformly inside its bin — so the whole range is covered, not
  just two levels, and consecutive levels always differ;
* hold times are uniform in ``[hold_min, hold_max]``, rounded to whole samples, never below ``hold_min``
  (choose ``hold_min`` near the dominant time constant, :func:`hold_min_from_time_constant`; Nelles 2001);
* many candidates are drawn from a seeded generator and the best under a design *criterion* is kept.

Criteria are small objects with one method, ``score(signal) -> float`` (larger is better):
:class:`AmplitudeCoverage`, :class:`SpectralContent`, and :class:`WeightedSum` of those.

Examples
--------
>>> from oed.aprbs_signal import APRBSDesign, design_aprbs
>>> design = APRBSDesign(ranges=((-1.26, 1.20), (0.562, 1.972)), duration=20.0, dt=0.01, hold_min=0.2)
>>> result = design_aprbs(design, candidates=8, seed=3)
>>> result.u.shape, bool(result.score >= max(result.candidate_scores) - 1e-12)
((2000, 2), True)
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Protocol

import numpy as np
import scipy.signal

from dynamics.runtime.memory import check_allocation
from dynamics.robots.servo_arm import SERVO_ARM_RANGES


#: longest APRBS designed, in samples
MAX_APRBS_SAMPLES = 10_000_000


def _plain(value: object) -> str:
    """``value`` for an error message: numpy scalars as plain numbers (``nan``, not ``np.float64(nan)``)."""
    try:
        values = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        return repr(value)
    return str(values.tolist())


@dataclass(frozen=True)
class APRBSDesign:
    """What to design: per-joint ranges [rad], duration [s], sample time [s], hold-time bounds [s], levels.

    ``hold_max`` defaults to ``5 · hold_min``.
    """

    ranges: tuple[tuple[float, float], ...] = SERVO_ARM_RANGES
    duration: float = 60.0
    dt: float = 0.01
    hold_min: float = 0.2
    hold_max: float | None = None
    n_levels: int = 12

    def __post_init__(self) -> None:
        if not self.ranges:
            raise ValueError("ranges must hold at least one joint")
        for j, pair in enumerate(self.ranges, start=1):
            if len(pair) != 2 or not np.all(np.isfinite(pair)) or not pair[0] < pair[1]:
                raise ValueError(f"joint {j}: range must be (u_min, u_max) with u_min < u_max, got {_plain(pair)}")
        if not (np.isfinite(self.dt) and self.dt > 0):
            raise ValueError(f"dt must be positive, got {_plain(self.dt)}")
        for label in ("duration", "hold_min") + (("hold_max",) if self.hold_max is not None else ()):
            if not np.isfinite(getattr(self, label)):
                raise ValueError(f"{label} must be a finite time in seconds, got {_plain(getattr(self, label))}")
        if not self.hold_min >= self.dt * (1 - 1e-9):
            raise ValueError(f"hold_min = {self.hold_min} s is shorter than the sample time dt = {self.dt} s")
        if self.hold_max is not None and self.hold_max < self.hold_min:
            raise ValueError(f"hold_max = {self.hold_max} s is shorter than hold_min = {self.hold_min} s")
        if self.duration / self.dt > MAX_APRBS_SAMPLES:
            raise ValueError(f"duration {self.duration} s at dt = {self.dt} s is {self.duration / self.dt:.3g} samples, "
                             f"more than {MAX_APRBS_SAMPLES:.0e}: shorten it or raise dt")
        check_allocation(8.0 * 4 * (self.duration / self.dt) * len(self.ranges),
                         f"an APRBS of {self.duration} s at dt = {self.dt} s")
        if not self.duration >= 2 * self.hold_min:
            raise ValueError(f"duration = {self.duration} s must be at least two minimum holds (2 × {self.hold_min} s)")
        if not isinstance(self.n_levels, int) or self.n_levels < 3:
            raise ValueError(f"n_levels must be an integer >= 3 (an APRBS, not a PRBS), got {self.n_levels!r}")

    @property
    def n_samples(self) -> int:
        return int(round(self.duration / self.dt))

    @property
    def hold_bounds_samples(self) -> tuple[int, int]:
        low = int(np.ceil(self.hold_min / self.dt - 1e-9))
        high_s = 5 * self.hold_min if self.hold_max is None else self.hold_max
        return low, max(low, int(np.floor(high_s / self.dt + 1e-9)))


@dataclass(frozen=True)
class APRBSSignal:
    """A candidate signal: times ``t`` (N,), inputs ``u`` (N, joints) [rad], the design, and the hold lengths used."""

    t: np.ndarray
    u: np.ndarray
    design: APRBSDesign
    holds: tuple[np.ndarray, ...] = field(repr=False)


class SignalCriterion(Protocol):
    """A design criterion: larger is better."""

    def score(self, signal: APRBSSignal) -> float: ...


@dataclass(frozen=True)
class AmplitudeCoverage:
    """Normalised entropy of the amplitude histogram over each joint's range (1 = uniform), worst joint."""

    bins: int = 20

    def score(self, signal: APRBSSignal) -> float:
        values = []
        for j, (low, high) in enumerate(signal.design.ranges):
            counts, _ = np.histogram(signal.u[:, j], bins=self.bins, range=(low, high))
            p = counts[counts > 0] / counts.sum()
            values.append(float(-(p * np.log(p)).sum() / np.log(self.bins)))
        return min(values)


@dataclass(frozen=True)
class SpectralContent:
    """Fraction of the signal's power (mean removed, Welch estimate) inside ``band`` [Hz], worst joint."""

    band: tuple[float, float] = (0.05, 2.5)

    def score(self, signal: APRBSSignal) -> float:
        fs = 1.0 / signal.design.dt
        if not 0 <= self.band[0] < self.band[1] <= fs / 2:
            raise ValueError(f"band {self.band} Hz must lie in [0, {fs / 2}] Hz (Nyquist)")
        freq, psd = scipy.signal.welch(signal.u - signal.u.mean(axis=0), fs=fs, nperseg=min(1024, signal.u.shape[0]), axis=0)
        inside = (freq >= self.band[0]) & (freq <= self.band[1])
        return float(np.min(psd[inside].sum(axis=0) / psd.sum(axis=0)))


@dataclass(frozen=True)
class WeightedSum:
    """``Σ w_i · criterion_i.score`` over ``terms = ((criterion, weight), ...)``."""

    terms: tuple[tuple[SignalCriterion, float], ...] = ((AmplitudeCoverage(), 1.0), (SpectralContent(), 1.0))

    def score(self, signal: APRBSSignal) -> float:
        return float(sum(weight * criterion.score(signal) for criterion, weight in self.terms))


@dataclass(frozen=True)
class APRBSResult:
    """The chosen APRBS: ``t`` (N,), ``u`` (N, joints) [rad], its ``score``, all ``candidate_scores``, the seed."""

    t: np.ndarray
    u: np.ndarray
    score: float
    candidate_scores: tuple[float, ...]
    best_index: int
    seed: int | None
    design: APRBSDesign
    criterion: SignalCriterion


def hold_min_from_time_constant(time_constant: float, *, dt: float, factor: float = 1.0) -> float:
    """Minimum hold time ``factor · τ_dominant`` rounded up to whole samples (at least one sample).

    For a joint ``m q̈ + b q̇ + k q = σ u`` the dominant time constant is ``1/(ζ ω_n) = 2m/b`` when
    underdamped, and ``1/(ω_n (ζ − √(ζ² − 1)))`` otherwise.
    """
    if not (time_constant > 0 and dt > 0 and factor > 0):
        raise ValueError(f"time_constant, dt and factor must be positive, got {time_constant}, {dt}, {factor}")
    return max(dt, float(np.ceil(factor * time_constant / dt - 1e-9) * dt))


def random_aprbs(design: APRBSDesign, rng: np.random.Generator) -> APRBSSignal:
    """Draw one APRBS (eq. 15) for every joint of ``design`` from ``rng`` (stratified levels, bounded holds)."""
    n = design.n_samples
    low_h, high_h = design.hold_bounds_samples
    columns, holds_all = [], []
    for low, high in design.ranges:
        holds = []
        total = 0
        while total < n:
            hold = int(rng.integers(low_h, high_h + 1))
            holds.append(hold)
            total += hold
        holds[-1] -= total - n  # truncate the last hold at the end of the record
        if holds[-1] < low_h and len(holds) > 1:
            tail = holds.pop()
            holds[-1] += tail  # never a hold shorter than hold_min: merge a short tail into its predecessor
        n_holds = len(holds)
        bins = np.concatenate([rng.permutation(design.n_levels) for _ in range(-(-n_holds // design.n_levels) + 1)])
        bins = _no_repeats(bins, design.n_levels, rng)[:n_holds]
        width = (high - low) / design.n_levels
        levels = low + (bins + rng.uniform(0.0, 1.0, n_holds)) * width
        columns.append(np.repeat(levels, holds)[:n])
        holds_all.append(np.asarray(holds))
    t = np.arange(n) * design.dt
    return APRBSSignal(t=t, u=np.column_stack(columns), design=design, holds=tuple(holds_all))


def _no_repeats(bins: np.ndarray, n_levels: int, rng: np.random.Generator) -> np.ndarray:
    bins = bins.copy()
    for i in range(1, bins.size):
        while bins[i] == bins[i - 1]:
            bins[i] = rng.integers(n_levels)
    return bins


def design_aprbs(design: APRBSDesign, *, criterion: SignalCriterion | None = None, candidates: int = 64, seed: int | None = None) -> APRBSResult:
    """Best of ``candidates`` random APRBS under ``criterion`` (default: coverage + spectral content).

    Parameters
    ----------
    design
        Ranges, duration, sample time, hold bounds and levels.
    criterion
        Object with ``score(signal) -> float``; default ``WeightedSum()`` (amplitude coverage + band power).
    candidates
        Number of random signals drawn (independent streams of ``numpy.random.SeedSequence(seed)``).
    seed
        Seed; the same seed gives the same signal.
    """
    if not isinstance(candidates, int) or candidates < 1:
        raise ValueError(f"candidates must be a positive integer, got {candidates!r}")
    criterion = WeightedSum() if criterion is None else criterion
    streams = np.random.SeedSequence(seed).spawn(candidates)
    best, best_score, scores = None, -np.inf, []
    for stream in streams:
        signal = random_aprbs(design, np.random.default_rng(stream))
        value = float(criterion.score(signal))
        scores.append(value)
        if value > best_score:
            best, best_score = signal, value
    return APRBSResult(
        t=best.t, u=best.u, score=best_score, candidate_scores=tuple(scores), best_index=int(np.argmax(scores)),
        seed=seed, design=design, criterion=criterion,
    )
