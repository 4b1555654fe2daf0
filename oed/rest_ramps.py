"""Start and end at rest: quintic ramps in and out around whole periods of a Fourier excitation (issue #36).

The experiment is ``ramp in | periods x one period | ramp out``. The ramp in goes from rest at ``Q``
(``q = Q``, ``dq = ddq = 0``) to the periodic trajectory's state at ``t = 0``; the ramp out from that
state (the end of the last period) back to rest at ``Q``. Each is the quintic Hermite polynomial with
those positions, velocities and accelerations at its ends, so its samples are **affine** in the Fourier
coefficients: ``q(τ) = H_0(τ) Q + H_q(τ) q_p(0) + H_dq(τ) dq_p(0) + H_ddq(τ) ddq_p(0)``. The design
problem bounds them with linear rows and checks its other constraints on them, like the period's samples.

Rest costs information: a single period forced to rest at its ends gives up part of its freedom, ramps
around several unconstrained periods only dilute the information by the ramps' share of the samples.
:func:`choose_periods` picks the fewest periods whose whole experiment keeps
:data:`KEPT_INFORMATION` of the periodic part's D-efficiency per sample.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from oed.bounds import JointBounds
from oed.fourier import FourierTrajectory

#: the whole experiment keeps at least this D-efficiency per sample of its periodic part (choose_periods)
KEPT_INFORMATION = 0.95
#: most periods choose_periods considers
MAX_PERIODS = 12

# quintic Hermite basis on s in [0, 1], coefficients of s^0..s^5: p0, v0 T, a0 T², a1 T², v1 T, p1
_HERMITE = np.array([
    [1, 0, 0, -10, 15, -6],
    [0, 1, 0, -6, 8, -3],
    [0, 0, 0.5, -1.5, 1.5, -0.5],
    [0, 0, 0, 0.5, -1, 0.5],
    [0, 0, 0, -4, 7, -3],
    [0, 0, 0, 10, -15, 6],
], dtype=float)


@dataclass(frozen=True)
class RestStart:
    """Start and end at rest at ``q`` (rad or m), ramps of ``ramp_s`` seconds around ``periods`` periods.

    ``ramp_s=None``: two periods of the trajectory's highest harmonic, ``2/(f N)`` (2 s for 5 harmonics of
    0.2 Hz; :meth:`with_ramp_for`), so that the ramps' accelerations stay on the scale of the trajectory's.
    On the 6-joint example arm under every constraint (4 starts, ``benchmarks/README.md``), 1 s ramps left
    the period a D-efficiency of 0.81 against the unconstrained design, 2 s ramps 0.90: a short ramp has to
    leave from a slow state of the period, which costs it more than the longer ramp dilutes.
    ``periods=None``: chosen by :func:`choose_periods` once the periodic part is designed.
    """

    q: NDArray[np.float64]
    ramp_s: float | None = None
    periods: int | None = None

    def __post_init__(self) -> None:
        q = np.asarray(self.q, dtype=float).reshape(-1)
        if q.size == 0 or not np.all(np.isfinite(q)):
            raise ValueError(f"--start must be finite joint positions, got {self.q!r}")
        object.__setattr__(self, "q", q)
        if self.ramp_s is not None and not (np.isfinite(self.ramp_s) and self.ramp_s > 0):
            raise ValueError(f"ramp_s must be a positive duration (s), got {self.ramp_s}")
        if self.periods is not None and (isinstance(self.periods, bool) or not isinstance(self.periods, (int, np.integer))
                                         or self.periods < 1):
            raise ValueError(f"periods must be a positive integer or None, got {self.periods!r}")

    def with_ramp_for(self, frequency_hz: float, harmonics: int, rate_hz: float) -> RestStart:
        """This start with ``ramp_s`` set (default: ``2/(f N)``, rounded to whole samples at ``rate_hz``)."""
        if self.ramp_s is not None:
            return self
        return RestStart(self.q, max(1, round(2 * rate_hz / (frequency_hz * harmonics))) / rate_hz, self.periods)

    def check(self, bounds: JointBounds, rate_hz: float) -> None:
        """Refuse a start outside the position bounds (named joint) or a ramp of no whole number of samples."""
        if self.q.size != bounds.n_joints:
            raise ValueError(f"--start has {self.q.size} values for {bounds.n_joints} joints")
        for joint, value in enumerate(self.q):
            if not bounds.q_min[joint] <= value <= bounds.q_max[joint]:
                raise ValueError(f"--start: joint {bounds.joint_names[joint]!r} at {value:g} is outside its bounds "
                                 f"[{bounds.q_min[joint]:g}, {bounds.q_max[joint]:g}]")
        samples = self.ramp_s * rate_hz
        if abs(samples - round(samples)) > 1e-6 * max(1.0, samples):
            raise ValueError(f"ramp of {self.ramp_s:g} s is not a whole number of samples at {rate_hz:g} Hz")

    def ramp_samples(self, rate_hz: float) -> int:
        """Samples of one ramp's interval at ``rate_hz`` (its end points: one more sample)."""
        return int(round(self.ramp_s * rate_hz))

    def to_dict(self) -> dict:
        return {"q": self.q.tolist(), "ramp_s": self.ramp_s, "periods": self.periods, "ramp": "quintic"}


def hermite_weights(tau: ArrayLike, duration: float) -> NDArray[np.float64]:
    """``(3, 6, T)``: weights of ``p0, v0, a0, a1, v1, p1`` in ``q, dq, ddq`` at times ``tau`` of a quintic
    ramp of ``duration`` seconds."""
    s = np.asarray(tau, dtype=float).reshape(-1) / duration
    powers = np.vander(s, 6, increasing=True)  # (T, 6)
    d1 = np.column_stack([np.zeros_like(s)] + [k * s ** (k - 1) for k in range(1, 6)]) / duration
    d2 = np.column_stack([np.zeros_like(s)] * 2 + [k * (k - 1) * s ** (k - 2) for k in range(2, 6)]) / duration**2
    scale = np.array([1, duration, duration**2, duration**2, duration, 1])[:, None]
    return np.stack([(_HERMITE @ matrix.T) * scale for matrix in (powers, d1, d2)])


def ramp_states(rest: RestStart, state: tuple[NDArray, NDArray, NDArray], tau: NDArray[np.float64],
                ramp_in: bool) -> tuple[NDArray[np.float64], ...]:
    """``q, dq, ddq`` ``(T, n)`` of the ramp in (rest -> ``state``) or out (``state`` -> rest) at ``tau``."""
    weights = hermite_weights(tau, rest.ramp_s)  # (3, 6, T)
    q0, dq0, ddq0 = (np.asarray(v, dtype=float).reshape(-1) for v in state)
    zeros = np.zeros_like(q0)
    ends = [rest.q, zeros, zeros, ddq0, dq0, q0] if ramp_in else [q0, dq0, ddq0, zeros, zeros, rest.q]
    ends_matrix = np.stack(ends)  # (6, n)
    return tuple(weights[k].T @ ends_matrix for k in range(3))


def experiment_samples(trajectory: FourierTrajectory, rest: RestStart | None, rate_hz: float,
                       periods: int | None = None) -> tuple[NDArray[np.float64], ...]:
    """``t, q, dq, ddq`` of the whole experiment at ``rate_hz``: without ``rest`` one period (end excluded);
    with it, the ramp in, ``periods`` (default ``rest.periods``, else 1) periods and the ramp out, the last
    sample (at rest) included."""
    if rest is None:
        return trajectory.sample(rate_hz, periods or 1)
    rest = rest.with_ramp_for(trajectory.frequency_hz, trajectory.harmonics, rate_hz)
    count = periods or rest.periods or 1
    _, q, dq, ddq = trajectory.sample(rate_hz, count)
    start = tuple(v[0] for v in trajectory.evaluate(np.zeros(1)))
    steps = rest.ramp_samples(rate_hz)
    tau_in = np.arange(steps) / rate_hz
    tau_out = np.arange(steps + 1) / rate_hz
    ramp_in, ramp_out = ramp_states(rest, start, tau_in, True), ramp_states(rest, start, tau_out, False)
    states = [np.vstack([ramp_in[k], (q, dq, ddq)[k], ramp_out[k]]) for k in range(3)]
    t = np.arange(states[0].shape[0]) / rate_hz
    return (t, *states)


@dataclass(frozen=True)
class Experiment:
    """The whole experiment of a design with a rest start, as a reference to play (``oed simulate``):
    ``evaluate(t)`` gives ``q, dq, ddq`` at any times of ``[0, duration_s]`` (ramp in, periods, ramp out;
    at rest before and after)."""

    trajectory: FourierTrajectory
    rest: RestStart
    periods: int

    @property
    def n_joints(self) -> int:
        return self.trajectory.n_joints

    @property
    def duration_s(self) -> float:
        return 2 * self.rest.ramp_s + self.periods * self.trajectory.period

    def evaluate(self, t: ArrayLike) -> tuple[NDArray[np.float64], ...]:
        t = np.asarray(t, dtype=float).reshape(-1)
        ramp, middle = self.rest.ramp_s, self.periods * self.trajectory.period
        start = tuple(v[0] for v in self.trajectory.evaluate(np.zeros(1)))
        states = [np.empty((t.size, self.n_joints)) for _ in range(3)]
        pieces = ((t < ramp, lambda s: ramp_states(self.rest, start, np.clip(s, 0, ramp), True)),
                  ((t >= ramp) & (t < ramp + middle), lambda s: self.trajectory.evaluate(s - ramp)),
                  (t >= ramp + middle, lambda s: ramp_states(self.rest, start, np.clip(s - ramp - middle, 0, ramp), False)))
        for mask, piece in pieces:
            if mask.any():
                for state, values in zip(states, piece(t[mask])):
                    state[mask] = values
        return tuple(states)


def rest_of(trajectory: FourierTrajectory) -> tuple[RestStart | None, int | None]:
    """The rest start and the periods a designed trajectory's metadata records (``experiment``), or ``None``."""
    experiment = trajectory.metadata.get("experiment")
    if not experiment:
        return None, None
    return RestStart(experiment["q"], experiment["ramp_s"], experiment.get("periods")), experiment.get("periods")


def playable(trajectory: FourierTrajectory, rate_hz: float, periods: int = 1,
             warmup_periods: int = 0) -> tuple[FourierTrajectory | Experiment, float | None]:
    """What ``oed simulate`` plays: a design with a rest start as its whole :class:`Experiment` (ramps included,
    the last sample at rest) and its duration; any other trajectory as it is (``None``: by periods).

    Raises
    ------
    ValueError
        ``periods`` or ``warmup_periods`` asked of a whole experiment.
    """
    rest, count = rest_of(trajectory)
    if rest is None:
        return trajectory, None
    if periods != 1 or warmup_periods:
        raise ValueError("the design holds a whole experiment (start and end at rest, experiment.periods periods): "
                         "--periods and --warmup-periods do not apply")
    experiment = Experiment(trajectory, rest, count or 1)
    return experiment, experiment.duration_s + 1.0 / rate_hz


def choose_periods(information, trajectory: FourierTrajectory, rest: RestStart, rate_hz: float) -> tuple[int, list[float]]:
    """The fewest periods (1..:data:`MAX_PERIODS`) whose whole experiment keeps :data:`KEPT_INFORMATION` of the
    periodic part's D-efficiency per sample, and the D-efficiency of each count tried.

    ``information(q, dq, ddq)`` returns the unscaled ``Y_bᵀY_b`` of samples; the D-efficiency of ``M/N``
    against the period's ``M_p/N_p`` is ``exp((log det(M/N) − log det(M_p/N_p))/p)``.
    """
    _, q, dq, ddq = trajectory.sample(rate_hz, 1)
    reference = np.linalg.slogdet(information(q, dq, ddq) / q.shape[0])[1]
    efficiencies = []
    for periods in range(1, MAX_PERIODS + 1):
        _, q, dq, ddq = experiment_samples(trajectory, rest, rate_hz, periods)
        M = information(q, dq, ddq) / q.shape[0]
        efficiencies.append(float(np.exp((np.linalg.slogdet(M)[1] - reference) / M.shape[0])))
        if efficiencies[-1] >= KEPT_INFORMATION:
            return periods, efficiencies
    return MAX_PERIODS, efficiencies
