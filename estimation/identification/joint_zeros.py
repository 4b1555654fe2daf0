"""Encoder zeros that differ from the robot description's: a constant position offset per joint, tested on held-out data.

A joint whose recorded position is ``q_j`` where the description's is ``q_j + δ_j`` (a calibration offset, an
encoder zeroed a quarter or half turn away from the URDF's zero) is not a change of base parameters: the
rigid-body columns of the regressor ``Y(q, q̇, q̈)`` describe another robot (a 225 mm upper arm a quarter turn
off moves the elbow), while friction and torque-offset columns do not depend on ``q``. The fit runs and predicts
worse (a Stäubli TX40 with joints 2 and 3 a quarter turn off: 1.1–2.3x the error of the same fit in the
description's zeros, ``benchmarks/README.md``).

:func:`check_joint_zeros` estimates ``δ`` on the training samples and tests it on held-out ones:

1. a scan over quarter and half turns (``δ_j ∈ {−π/2, +π/2, π}``), one joint at a time, greedily (the joint and
   turn that lower the training error most, then again from there);
2. Gauss–Newton on ``(θ, δ)`` together from the best scanned point: the residual ``τ − Y(q + δ) θ`` linearised
   with ``∂(Y θ)/∂q_j`` by forward differences (the nonlinear least squares of a constant offset per joint);
3. the held-out test: ``θ`` fitted by least squares on the training samples with and without ``δ``, each
   channel's error on the held-out samples (the validation record, or without one the second half of the
   training record, ``δ`` then chosen on the first half) compared.

Only joints whose offset the held-out samples, estimated alone (steps 1–2), confirm (:data:`AGREEMENT`) and that
matter by themselves (:data:`MIN_OFFSET`, and removing the offset alone raises the training error by
:data:`MIN_JOINT_GAIN`) are named, and only for a marked gain (:data:`MARKED_GAIN`: the mean over channels of the
held-out MSE ratio, and the total held-out MSE, both at most ``1 −`` it). A named joint's offset must also lower
by itself the held-out error, with and without a free gain on each joint's torque
(:func:`_apart_from_gains`): torques logged with an unknown gain per joint are otherwise read as joint zeros. When
such gains are in question (:func:`gains_in_question`: they lower the held-out error by a one-sided paired test over
blocks of the held-out samples at the level :data:`PAIRED_ALPHA`, :func:`paired_test`; asked at the directions the
scan found without them, and, when not in question there and the scan took a reversal, again at the recorded
directions with gains of either sign, a reversed torque being a negative gain: the directions are then scanned again
with the gains), steps 1–3 and the tests run with a gain on each joint's torque fitted beside ``θ`` (kept positive
when the directions are scanned: a reversed torque is theirs to say; scanned without the gains, a reversed torque among
gains is taken for the neighbouring joint's on some logs), so that a true offset is found where the records tell it from a gain, and nothing is said where they
do not; the gains must still pass the same test at the offsets and directions found, else they stood in for these and
the check runs without them. A correctly zeroed log whose model lacks
something (a spring, a cable, a joint's friction the laws miss) must not be told its zeros are wrong: on such logs
(the KUKA LWR4+, the Panda, the TX40 of ``benchmarks/bench_real_robots.py``) the steps find offsets up to a half turn
that lower the held-out error by up to 17 %, but they differ from one record to the other. When the training
error itself falls by less than half the marked gain, the held-out steps are skipped. The samples are thinned to
:data:`MAX_SAMPLES` evenly spaced rows of each record: the cost is one to two hundred evaluations of the regressor and
least-squares fits on them (1–3 s on the 7-joint real logs, one core). Joints no column depends on (a vertical first axis in the joint-torque model) and prismatic
joints beyond Gauss–Newton's reach are left as they are; only revolute joints are scanned for turns.
"""

from __future__ import annotations

import warnings
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import scipy.stats
from numpy.typing import NDArray

from dynamics.channels import is_joint_torque, torque_joint
from dynamics.measurements import Measurements
from dynamics.effects.linear import parse_effects
from dynamics.models import IdentificationModel, ModelKind, build_model
from dynamics.robot import JointType
from estimation.estimators.channel_gains import GainSign
from estimation.identification.channel_gains import ChannelGains, determined_channels, fit_channel_gains
from estimation.identification.preprocessing_on_validation import paired_difference

#: the held-out error must fall by at least this fraction (mean of the channels' ratios and total) to be reported
MARKED_GAIN = 0.10
#: a joint's offset smaller than this (rad, or m) is not named
MIN_OFFSET = np.deg2rad(2.0)
#: a joint is named only if zeroing its offset alone raises the training error by this fraction
MIN_JOINT_GAIN = 0.02
#: a revolute joint is named only if its offsets estimated on the training and on the held-out samples alone are
#: this close (rad), and within half the offset (a prismatic joint's within a quarter of it): a model that lacks
#: something finds offsets that differ from record to record (real logs zeroed as their URDF: large ones 0.7 rad apart
#: and more, small ones by more than half their size)
AGREEMENT = 0.4
#: evenly spaced rows of each record used by the check
MAX_SAMPLES = 1000
#: the turns scanned on a revolute joint (rad)
TURNS: tuple[float, ...] = (-np.pi / 2, np.pi / 2, np.pi)
#: a joint's reversal is taken by the scan of directions only if it lowers the training cost by this fraction
REVERSAL_GAIN = 0.10
#: a reversed revolute joint's zeros scanned with it (rad): as logged and the turns (a reversed encoder zeroed a
#: quarter turn away: at its logged zero alone the scan takes a parallel joint's reversal instead on a PUMA)
REVERSAL_TURNS: tuple[float, ...] = (0.0, *TURNS)
#: a reversal is said only if the held-out MSE with it falls to at most this fraction of that without (in total): a
#: joint reversed is a gross error, the torques of its gravity and inertia with the wrong sign (on simulated and real
#: logs with a joint reversed the held-out MSE falls to 0.005–0.32 of it), where a correctly signed log whose model
#: lacks something finds reversals that lower it by 7–15 % (the KUKA LWR4+ and TX40 logs)
REVERSAL_MARK = 0.5
#: Levenberg–Marquardt's steps of the fit with every joint's gain free that tells which gains the samples determine
SURVEY_ITERATIONS = 20
#: the level of the one-sided paired test by which the gains are in question (:func:`paired_test`)
PAIRED_ALPHA = 0.01
#: contiguous blocks of the held-out samples whose errors give the paired test's standard error (:func:`paired_test`)
PAIRED_BLOCKS = 10
#: Gauss–Newton iterations and the forward-difference step (rad, or m)
ITERATIONS = 8
STEP = 1e-5


class JointZeroWarning(UserWarning):
    """The recorded joint positions look offset from the robot description's zeros (by a constant per joint)."""


@dataclass(frozen=True)
class JointZeroCheck:
    """What :func:`check_joint_zeros` found.

    Attributes
    ----------
    offsets
        ``δ``, one per joint (rad, or m): the description's position is the recorded one plus ``δ``; zero on the
        joints not named.
    joints
        0-based indices of the joints named (offset at least :data:`MIN_OFFSET`, and needed by itself).
    mse_ratio
        Per channel, the held-out MSE with ``δ`` over that without.
    total_ratio
        The total held-out MSE with ``δ`` over that without.
    held_out
        What the held-out samples were (``"validation record"`` or ``"second half of the training record"``).
    held_out_offsets
        ``δ`` estimated on the held-out samples alone (a joint is named only where both estimates agree).
    prismatic
        Per joint, whether it is prismatic (its offset in m); empty: all revolute.
    signs, torque_signs
        Per joint, ``-1`` where the recorded ``q`` (with ``q̇``, ``q̈``), or the recorded torque, is reversed against
        the description's axis and both the training and the held-out samples say so (the description's ``q`` is
        ``sign · q_recorded + offset``); empty: none reversed.
    gains
        Whether each joint's torque was given a free gain (:func:`gains_in_question`): the offsets scanned, and the
        ratios taken, with the gains fitted on both sides.
    """

    offsets: NDArray[np.float64]
    joints: tuple[int, ...]
    mse_ratio: dict[str, float]
    total_ratio: float
    held_out: str
    held_out_offsets: NDArray[np.float64]
    prismatic: tuple[bool, ...] = ()
    signs: tuple[int, ...] = ()
    torque_signs: tuple[int, ...] = ()
    gains: bool = False

    @property
    def reversed_joints(self) -> tuple[int, ...]:
        """0-based indices of the joints whose recorded direction (``q`` or torque) is reversed."""
        signs = self.signs or (1,) * len(self.offsets)
        torque = self.torque_signs or (1,) * len(self.offsets)
        return tuple(index for index, (sign, other) in enumerate(zip(signs, torque)) if sign < 0 or other < 0)

    @property
    def mean_ratio(self) -> float:
        return float(np.mean(list(self.mse_ratio.values()))) if self.mse_ratio else 1.0

    @property
    def marked(self) -> bool:
        """Whether the offsets lower the held-out error markedly (the warning is said)."""
        return bool(self.joints or self.reversed_joints) and self.mean_ratio <= 1 - MARKED_GAIN and self.total_ratio <= 1 - MARKED_GAIN

    def message(self, joint_names: tuple[str, ...] | None = None) -> str:
        """The warning's text: the joints, their offsets in rad and degrees or their reversed directions, the gain,
        and how to declare them."""
        names = [f"q{index + 1}" if joint_names is None else joint_names[index] for index in range(len(self.offsets))]
        if not self.reversed_joints:
            listed = ", ".join(f"joint {index + 1} ({names[index]}) {self._amount(index)}" for index in self.joints)
            as_json = ", ".join(f'"{names[index]}": {self.offsets[index]:.4f}' for index in self.joints)
            return (f"the recorded joint positions look offset from the robot description's zeros: {listed}. With "
                    f"q + offset the {self.held_out} is predicted with {100 * (1 - self.total_ratio):.0f} % less "
                    f"error (mean of the channels' ratios {self.mean_ratio:.2f}{self._gains_said()}). If the encoders' zeros differ from "
                    f"the URDF's, declare them, \"offsets\": {{{as_json}}} in a transmission JSON (--transmission FILE) "
                    "for motor-side columns qm (q = R⁻¹ qm + offset), or the same object in a JSON file given to "
                    "--joint-offsets FILE (added to the recorded q), and run again")
        reversed_ = self.reversed_joints
        signs = self.signs or (1,) * len(self.offsets)
        torque = self.torque_signs or (1,) * len(self.offsets)
        what = {(True, True): "q, dq, ddq and its torque", (True, False): "q, dq and ddq (not its torque)",
                (False, True): "its torque (not q, dq, ddq)"}
        listed = ", ".join(f"joint {index + 1} ({names[index]}): {what[signs[index] < 0, torque[index] < 0]}"
                           for index in reversed_)
        entries = []
        kinematic = [index for index in reversed_ if signs[index] < 0]
        if kinematic:
            entries.append('"signs": {' + ", ".join(f'"{names[index]}": -1' for index in kinematic) + "}")
        torques = [index for index in reversed_ if torque[index] < 0]
        if torques:
            entries.append('"torque_signs": {' + ", ".join(f'"{names[index]}": -1' for index in torques) + "}")
        if self.joints:
            entries.append('"offsets": {' + ", ".join(f'"{names[index]}": {self.offsets[index]:.4f}'
                                                        for index in self.joints) + "}")
        offsets = (" and offset from its zeros: " + ", ".join(f"joint {index + 1} ({names[index]}) "
                                                              f"{self._amount(index)}" for index in self.joints)
                   if self.joints else "")
        axis = ("; a joint whose q and torque are both reversed is also the URDF's joint with its <axis> reversed "
                "(xyz to -xyz)" if any(signs[index] < 0 and torque[index] < 0 for index in reversed_) else "")
        return (f"the recorded joint directions look reversed against the robot description's axes: {listed} "
                f"(the log's positive direction is the URDF axis's opposite){offsets}. In the description's "
                f"directions the {self.held_out} is predicted with {100 * (1 - self.total_ratio):.0f} % less error "
                f"(mean of the channels' ratios {self.mean_ratio:.2f}{self._gains_said()}). If the log's conventions differ from the "
                f"URDF's, declare them in a JSON file given to --joint-offsets FILE, {{{', '.join(entries)}}} (the "
                "description's q = sign · recorded q + offset, dq and ddq times the sign, tau times the torque "
                f"sign; after a --transmission's conversion){axis}, and run again")

    def _gains_said(self) -> str:
        return ("; each joint's torque read with a free gain on both sides, as a log of currents with a torque "
                "constant per joint needs" if self.gains else "")

    def _amount(self, index: int) -> str:
        offset, again = self.offsets[index], self.held_out_offsets[index]
        if self.prismatic and self.prismatic[index]:
            return f"{offset:+.4f} m (the {self.held_out} alone: {again:+.4f} m)"
        return (f"{offset:+.4f} rad ({np.rad2deg(offset):+.1f}°{_turn(offset)}; the {self.held_out} alone: "
                f"{np.rad2deg(again):+.1f}°)")


def _turn(offset: float) -> str:
    """``", about a quarter turn"`` when ``offset`` is within 15° of a multiple of 90°."""
    quarters = int(np.round(offset / (np.pi / 2)))
    if quarters == 0 or abs(offset - quarters * np.pi / 2) > np.deg2rad(15):
        return ""
    return ", about " + {1: "a quarter turn", 2: "a half turn", 3: "three quarters of a turn"}.get(abs(quarters) % 4,
                                                                                                  "a whole turn")


def _thinned(measurements: Measurements, channels: tuple[str, ...], max_samples: int
             ) -> tuple[NDArray, NDArray, NDArray, NDArray] | None:
    if measurements.dq is None or measurements.ddq is None:
        return None
    try:
        target = measurements.channels(channels)
    except ValueError:
        return None
    q, dq, ddq = measurements.q, measurements.dq, measurements.ddq
    rows = np.flatnonzero(np.all(np.isfinite(np.hstack([q, dq, ddq, target])), axis=1))
    if rows.size > max_samples:
        rows = rows[np.round(np.linspace(0, rows.size - 1, max_samples)).astype(int)]
    if rows.size < 10:
        return None
    return q[rows], dq[rows], ddq[rows], target[rows]


class _Problem:
    """The weighted least squares of ``θ`` at given offsets, on thinned samples (weights fixed once: each
    channel's residual RMS of the fit without offsets, so that every candidate is scored alike).

    The regressor and the fit at the offsets last asked for are kept: Gauss–Newton asks again for those of the
    step it has just accepted (the same values: nothing is recomputed differently)."""

    def __init__(self, model: IdentificationModel, samples: tuple[NDArray, NDArray, NDArray, NDArray],
                 weights: NDArray | None = None, gained: NDArray | None = None, sign: GainSign = "held") -> None:
        self.model = model
        self.q, self.dq, self.ddq, self.target = samples
        self.weights = np.ones(model.n_channels)
        self.gained, self.sign = gained, sign
        self._last_regressor: tuple[bytes, NDArray] | None = None
        self._last_fit: tuple[bytes, tuple[NDArray, NDArray]] | None = None
        self._last_gains: tuple[bytes, ChannelGains] | None = None
        if weights is not None:
            self.weights = weights
            return
        _, residual = self.fit(np.zeros(self.q.shape[1]))
        rms = np.sqrt(np.mean(residual**2, axis=0))
        scale = np.sqrt(np.mean(self.target**2, axis=0))
        self.weights = 1.0 / np.maximum(rms, 1e-9 * np.maximum(scale, 1e-300) + 1e-300)
        self._last_fit = None  # the fit depends on the weights

    def regressor(self, offsets: NDArray) -> NDArray:
        key = np.asarray(offsets, dtype=float).tobytes()
        if self._last_regressor is None or self._last_regressor[0] != key:
            self._last_regressor = key, self.model.evaluate_base(self.q + offsets, self.dq, self.ddq)
        return self._last_regressor[1]

    def fit(self, offsets: NDArray, regressor: NDArray | None = None) -> tuple[NDArray, NDArray]:
        """``θ`` and the (unweighted) residual ``(N, channels)`` at ``offsets``."""
        key = np.asarray(offsets, dtype=float).tobytes()
        if regressor is None and self._last_fit is not None and self._last_fit[0] == key:
            return self._last_fit[1]
        Y = self.regressor(offsets) if regressor is None else regressor
        found = ((theta := _least_squares(Y * self.weights[None, :, None], self.target * self.weights)),
                 self.target - Y @ theta)
        if regressor is None:
            self._last_fit = key, found
        return found

    def cost(self, offsets: NDArray) -> float:
        """The mean weighted squared residual at ``offsets``: of the least-squares fit of ``θ``, or with a gain on each
        :attr:`gained` channel fitted too (:meth:`gains_fit`)."""
        if self.gained is not None:
            return self.gains_fit(offsets).cost
        _, residual = self.fit(offsets)
        return float(np.mean((residual * self.weights) ** 2))

    def gains_fit(self, offsets: NDArray) -> ChannelGains:
        """``θ`` and a gain on each :attr:`gained` channel at ``offsets`` (:func:`fit_channel_gains`, :attr:`sign`)."""
        key = np.asarray(offsets, dtype=float).tobytes()
        if self._last_gains is None or self._last_gains[0] != key:
            self._last_gains = key, fit_channel_gains(self.regressor(offsets), self.target, self.weights,
                                                      self.gained, sign=self.sign)
        return self._last_gains[1]

    def with_gains(self, gained: NDArray | None, sign: GainSign = "held") -> _Problem:
        """The same samples and weights scored with a gain on each ``gained`` channel (``None``: without)."""
        return _Problem(self.model, (self.q, self.dq, self.ddq, self.target), self.weights, gained, sign)

    def flipped(self, signs: NDArray, torque_signs: NDArray) -> _Problem:
        """The same samples in the description's directions: ``q``, ``q̇``, ``q̈`` of each joint times ``signs``, the
        joint's torque channel times ``torque_signs``; the weights and the gains kept (every convention scored
        alike)."""
        samples = (self.q * signs, self.dq * signs, self.ddq * signs,
                   self.target * channel_signs(self.model, torque_signs))
        return _Problem(self.model, samples, self.weights, self.gained, self.sign)

    def scored(self, Y: NDArray, signs: NDArray, normal: _Normal | None = None) -> float:
        """The cost of the fit of ``Y`` to the target times ``signs`` (one a channel); ``normal``: the normal equations
        of ``Y`` with these weights (:meth:`normal`), formed once for the targets of several signs. With a gain on
        each :attr:`gained` channel, the fit with the gains (:func:`fit_channel_gains`, :attr:`sign`; ``normal``
        unused)."""
        target = self.target * signs
        if self.gained is not None:
            return fit_channel_gains(Y, target, self.weights, self.gained, sign=self.sign).cost
        normal = self.normal(Y) if normal is None else normal
        theta = normal.solve(target * self.weights)
        return float(np.mean(((target - Y @ theta) * self.weights) ** 2))

    def normal(self, Y: NDArray) -> _Normal:
        """The normal equations of ``Y`` weighted as this problem weights its channels (:func:`_least_squares`)."""
        return _Normal(Y * self.weights[None, :, None])


def channel_signs(model: IdentificationModel, torque_signs: NDArray) -> NDArray:
    """One sign a channel of ``model``: joint ``j``'s in channel ``tau{j}``, 1 on the others (the base wrench)."""
    signs = np.ones(model.n_channels)
    for index, channel in enumerate(model.channels):
        if is_joint_torque(channel) and torque_joint(channel) < len(torque_signs):
            signs[index] = torque_signs[torque_joint(channel)]
    return signs


class _Normal:
    """The normal equations of the scaled columns of ``Y (N, channels, r)`` (:func:`_least_squares`), formed once
    and solved for any number of targets: each solution is the one :func:`_least_squares` gives, bit for bit."""

    def __init__(self, Y: NDArray) -> None:
        A = Y.reshape(-1, Y.shape[2])
        scale = np.linalg.norm(A, axis=0)
        scale[scale == 0] = 1.0
        self.A = A / scale
        self.scale = scale
        self.gram = self.A.T @ self.A

    def solve(self, target: NDArray) -> NDArray:
        """``argmin ‖target − Y θ‖`` for ``target (N, channels)``."""
        return np.linalg.lstsq(self.gram, self.A.T @ target.reshape(-1), rcond=1e-12)[0] / self.scale


def _least_squares(Y: NDArray, target: NDArray) -> NDArray:
    """``argmin ‖target − Y θ‖`` for ``Y (N, channels, r)`` through the normal equations of the scaled columns
    (``r x r``: an SVD of the tall matrix costs a hundred times more, and this check solves about a hundred)."""
    return _Normal(Y).solve(target)


def _wrapped(offsets: NDArray, revolute: NDArray) -> NDArray:
    wrapped = offsets.copy()
    wrapped[revolute] = (wrapped[revolute] + np.pi) % (2 * np.pi) - np.pi
    return wrapped


def _gauss_newton(problem: _Problem, offsets: NDArray, free: NDArray, revolute: NDArray) -> NDArray:
    """Gauss–Newton on ``(θ, δ_free)`` from ``offsets``: ``τ − Y(q + δ) θ`` linearised in both, the derivative of
    ``Y θ`` in ``q_j`` by forward differences; a step that does not lower the cost is halved (at most 4 times)."""
    cost = problem.cost(offsets)
    joints = np.flatnonzero(free)
    if joints.size == 0:
        return offsets
    for _ in range(ITERATIONS):
        theta, residual = problem.fit(offsets)  # those of the step just accepted (kept by the problem)
        Y = problem.regressor(offsets)
        predicted = Y @ theta
        columns = []
        for joint in joints:
            shifted = offsets.copy()
            shifted[joint] += STEP
            columns.append((problem.regressor(shifted) @ theta - predicted) / STEP)
        J = np.concatenate([Y, np.stack(columns, axis=2)], axis=2) * problem.weights[None, :, None]
        step = _least_squares(J, residual * problem.weights)
        searched = _line_search(offsets, joints, step[Y.shape[2]:], revolute, lambda trial: (problem.cost(trial),),
                                cost)
        if searched is None:
            break
        trial, (trial_cost,) = searched
        converged = np.max(np.abs(trial - offsets)) < 1e-6
        offsets, cost = trial, trial_cost
        if converged:
            break
    return offsets


def _line_search(offsets: NDArray, joints: NDArray, delta: NDArray, revolute: NDArray, evaluate: Callable,
                 cost: float) -> tuple[NDArray, tuple] | None:
    """The step ``delta`` on ``joints`` from ``offsets`` (wrapped), halved (at most 4 times) until the cost
    ``evaluate(trial)[0]`` falls below ``cost``: ``(trial, evaluate(trial))``, or ``None``."""
    for _ in range(5):
        trial = offsets.copy()
        trial[joints] += delta
        trial = _wrapped(trial, revolute)
        evaluated = evaluate(trial)
        if evaluated[0] < cost:
            return trial, evaluated
        delta = delta / 2
    return None


def estimate_offsets(model: IdentificationModel, problem: _Problem) -> NDArray[np.float64]:
    """``δ`` minimising the training cost: the scan over turns, then Gauss–Newton (the module docstring)."""
    robot = model.robot
    n = robot.n_joints
    revolute = np.array([joint.joint_type == JointType.REVOLUTE for joint in robot.joints])
    base = problem.regressor(np.zeros(n))
    scale = np.linalg.norm(base)
    free = np.zeros(n, dtype=bool)
    for joint in range(n):  # a joint no column depends on: its offset is not identifiable
        shifted = np.zeros(n)
        shifted[joint] = 0.5 if revolute[joint] else 0.05
        free[joint] = np.linalg.norm(problem.regressor(shifted) - base) > 1e-9 * max(scale, 1e-300)
    offsets, cost = np.zeros(n), problem.cost(np.zeros(n))
    scanned = np.flatnonzero(free & revolute)
    for _ in range(scanned.size):
        best = None
        for joint in scanned:
            for turn in TURNS:
                trial = offsets.copy()
                trial[joint] += turn
                trial = _wrapped(trial, revolute)
                trial_cost = problem.cost(trial)
                if trial_cost < cost * (1 - MIN_JOINT_GAIN) and (best is None or trial_cost < best[0]):
                    best = (trial_cost, trial)
        if best is None:
            break
        cost, offsets = best
    if problem.gained is not None:
        return _gained_offsets(problem, offsets, np.flatnonzero(free), problem.gained, problem.sign)
    return _gauss_newton(problem, offsets, free, revolute)


def estimate_signs(model: IdentificationModel, problem: _Problem) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The joints' directions minimising the training cost: a greedy scan, one joint at a time, of the conventions
    of :data:`SIGN_VARIANTS` (the joint's ``q``, ``q̇``, ``q̈`` reversed with its torque, without it, or its torque
    alone), a reversed joint's zero at ``0`` or one of :data:`TURNS` (a revolute joint). A convention is taken when
    it lowers the training cost by :data:`MIN_JOINT_GAIN`; returns ``(signs, torque_signs)``, one a joint."""
    robot = model.robot
    n = robot.n_joints
    revolute = np.array([joint.joint_type == JointType.REVOLUTE for joint in robot.joints])
    measured = np.array([f"tau{joint + 1}" in model.channels for joint in range(n)])
    signs, torque = np.ones(n), np.ones(n)
    cost = problem.cost(np.zeros(n))
    for _ in range(n):
        best = None
        base = problem.flipped(signs, torque) if np.any(signs < 0) or np.any(torque < 0) else problem
        unflipped = None  # the normal equations of base's regressor, for the torques reversed alone
        for joint in np.flatnonzero((signs > 0) & (torque > 0)):
            flipped_signs = signs.copy()
            flipped_signs[joint] = -1.0
            for turn in REVERSAL_TURNS if revolute[joint] else (0.0,):
                offsets = np.zeros(n)
                offsets[joint] = turn
                Y = model.evaluate_base(base.q * np.where(np.arange(n) == joint, -1.0, 1.0) + offsets,
                                        base.dq * np.where(np.arange(n) == joint, -1.0, 1.0),
                                        base.ddq * np.where(np.arange(n) == joint, -1.0, 1.0))
                normal = None if problem.gained is not None else problem.normal(Y)  # one for both torque signs
                for reversed_torque in (True, False) if measured[joint] else (False,):
                    flipped_torque = torque.copy()
                    if reversed_torque:
                        flipped_torque[joint] = -1.0
                    trial_cost = problem.scored(Y, channel_signs(model, flipped_torque), normal)
                    if trial_cost < cost * (1 - REVERSAL_GAIN) and (best is None or trial_cost < best[0]):
                        best = (trial_cost, flipped_signs, flipped_torque)
            if measured[joint]:  # the torque alone reversed
                flipped_torque = torque.copy()
                flipped_torque[joint] = -1.0
                Y = base.regressor(np.zeros(n))
                unflipped = problem.normal(Y) if unflipped is None and problem.gained is None else unflipped
                trial_cost = problem.scored(Y, channel_signs(model, flipped_torque), unflipped)
                if trial_cost < cost * (1 - REVERSAL_GAIN) and (best is None or trial_cost < best[0]):
                    best = (trial_cost, signs.copy(), flipped_torque)
        if best is None:
            break
        cost, signs, torque = best
    return signs, torque


#: the friction of the plain fit's class the check adds to a joint-torque model that lacks it
PLAIN_FRICTION: tuple[str, ...] = ("viscous", "coulomb", "offset")


def check_model(model: IdentificationModel) -> IdentificationModel:
    """The model the check refits: ``model`` with viscous and Coulomb friction and a torque offset on every joint
    where it lacks them (the plain fit's class; joint-torque models only). Friction a model lacks must not be taken
    up by a turn of a joint: with viscous friction alone (the verbs' default) the KUKA LWR4+'s log, zeroed as its
    URDF, finds joint 6 at +141° on both of its records, and 14 % less held-out error."""
    if model.kind == ModelKind.EXTERNAL:
        return model
    added = tuple(effect for effect in parse_effects(",".join(PLAIN_FRICTION)) if effect not in model.effects)
    if not added:
        return model
    try:
        return build_model(model.robot, model.kind, (*model.effects, *added))
    except (ValueError, TypeError):  # an effect that cannot be combined with these: the model as it is
        return model


def _held_out_mse(model: IdentificationModel, theta: NDArray, samples: tuple[NDArray, NDArray, NDArray, NDArray],
                  offsets: NDArray, signs: NDArray | None = None, torque_signs: NDArray | None = None,
                  gains: NDArray | None = None) -> NDArray:
    """Each channel's MSE of the prediction at ``signs q + offsets`` (times ``gains``, one a channel; its torque
    channels times ``torque_signs``: the errors are those against the recorded channels)."""
    return np.mean(_held_out_residual(model, theta, samples, offsets, signs, torque_signs, gains) ** 2, axis=0)


def _held_out_residual(model: IdentificationModel, theta: NDArray, samples: tuple[NDArray, NDArray, NDArray, NDArray],
                       offsets: NDArray, signs: NDArray | None = None, torque_signs: NDArray | None = None,
                       gains: NDArray | None = None) -> NDArray:
    """The residual ``(N, channels)`` of :func:`_held_out_mse`."""
    q, dq, ddq, target = samples
    signs = np.ones(q.shape[1]) if signs is None else signs
    predicted = model.evaluate_base(q * signs + offsets, dq * signs, ddq * signs) @ theta
    if gains is not None:
        predicted = predicted * gains
    if torque_signs is not None:
        predicted = predicted * channel_signs(model, torque_signs)
    return target - predicted


def _nominal_mse(model: IdentificationModel, nominal: NDArray, samples: tuple[NDArray, NDArray, NDArray, NDArray],
                 offsets: NDArray, signs: NDArray, torque_signs: NDArray, gained: NDArray | None = None) -> float:
    """The total MSE of the description's own bodies (its inertial values) on ``samples`` in the directions
    ``signs``, ``torque_signs`` at ``offsets``, the effects' parameters (friction, torque offsets) fitted by least
    squares to what the bodies leave: the errors against the recorded channels. With ``gained``, the bodies' torque
    of each ``gained`` channel times a positive gain fitted with the effects (:func:`_gained_bodies`)."""
    q, dq, ddq, target = samples
    target = target * channel_signs(model, torque_signs)
    Y = model.evaluate(q * signs + offsets, dq * signs, ddq * signs)
    bodies = len(nominal) - sum(len(effect.parameter_names(model.robot)) for effect in model.effects)
    if gained is not None:
        return _gained_bodies(Y[:, :, :bodies] @ nominal[:bodies], Y[:, :, bodies:], target, gained)
    residual = target - Y[:, :, :bodies] @ nominal[:bodies]
    if bodies < Y.shape[2]:
        residual = residual - Y[:, :, bodies:] @ _least_squares(Y[:, :, bodies:], residual)
    return float(np.sum(np.mean(residual ** 2, axis=0)))


def _gained_bodies(body: NDArray, effects: NDArray, target: NDArray, gained: NDArray) -> float:
    """The total MSE of ``target (N, m)`` fitted by ``body (N, m)``, the description's bodies' torque, times a gain on
    each ``gained`` channel (``1`` on the others) and the columns ``effects (N, m, k)``, by least squares; a gain
    that comes out negative or zero is held at zero (a reversed torque is the directions' to say, not a gain's)."""
    fixed = np.where(gained, 0.0, 1.0)
    channels = np.flatnonzero(gained)
    active = channels
    for _ in range(channels.size + 1):
        columns = np.zeros((*body.shape, active.size))
        columns[:, active, np.arange(active.size)] = body[:, active]
        A = np.concatenate([effects, columns], axis=2)
        residual = target - body * fixed
        coefficients = _least_squares(A, residual) if A.shape[2] else np.zeros(0)
        gains = coefficients[effects.shape[2]:]
        if np.all(gains > 0.0):
            break
        active = active[gains > 0.0]
    return float(np.sum(np.mean((residual - (A @ coefficients if A.shape[2] else 0.0)) ** 2, axis=0)))


def gains_in_question(model: IdentificationModel, found: _Problem, scored: tuple[NDArray, NDArray, NDArray, NDArray],
                      signs: NDArray, torque_signs: NDArray, sign: GainSign) -> NDArray | None:
    """The joint-torque channels to give a free gain, when a gain on each lowers the held-out error significantly.

    Torques logged with an unknown gain per joint (currents and a torque constant nobody gave) are a fault a linear
    fit of ``θ`` cannot take up, and a joint's zero moved takes part of it up (:func:`_apart_from_gains`); with the
    gains and a true offset together, a scan without the gains misses the offset or finds another (a 6-joint PUMA, 0.8
    rad on joint 2: found on 3 of 8 logs, one at −172°). The gains are in question when the fit with them, on the
    training samples ``found`` at the description's zeros in the directions ``signs``, ``torque_signs``, predicts the
    held-out samples ``scored`` better than the fit without, by the one-sided paired test of :func:`paired_test` at
    the level :data:`PAIRED_ALPHA`: then the scan of offsets, the held-out estimate and the tests run with them. The
    check asks at the directions its scan found without gains (``sign="held"``); when the scan took a reversal and the
    gains are not in question there, it asks again at the recorded directions with ``sign="free"`` (a reversed torque
    is a negative gain) and, when in question, scans the directions again with the gains kept positive: a 6-joint
    PUMA whose torques were logged with gains and joint 3's reversed took joint 2's reversal without the gains (its
    training cost 0.116 against 0.127), where the positive gains no longer lowered the held-out error (t = −1.0), and
    nothing was said, on 2 of 20 logs (``benchmarks/README.md``, h-gains3). Only the gains the
    training samples determine are freed (:func:`~estimation.identification.channel_gains.determined_channels`, after
    :data:`SURVEY_ITERATIONS` steps with every gain free): the others wander along a valley of the cost (a PUMA's
    wrist at the noise: gains of 100 and more for a fall of 2 %, as large as the offsets' tests). Returns the
    channels' mask, or ``None`` (fewer than two gains determined, or they do not lower the error significantly)."""
    gained = np.array([is_joint_torque(channel) for channel in model.channels])
    if gained.sum() < 2:
        return None
    q, dq, ddq, target = scored
    n = q.shape[1]
    Y = model.evaluate_base(q * signs, dq * signs, ddq * signs)
    target = target * channel_signs(model, torque_signs)
    theta, _ = found.fit(np.zeros(n))
    plain = target - Y @ theta
    at_zero = found.regressor(np.zeros(n))
    survey = fit_channel_gains(at_zero, found.target, found.weights, gained, sign=sign, max_iterations=SURVEY_ITERATIONS)
    if not np.mean(((target - survey.predicted(Y)) * found.weights) ** 2) < np.mean((plain * found.weights) ** 2):
        return None  # every gain free does not lower it at all (a log without gains: the real robots')
    gained = determined_channels(at_zero, found.target, found.weights, gained, survey)
    if gained.sum() < 2:
        return None
    test = paired_test(plain, target - found.with_gains(gained, sign).gains_fit(np.zeros(n)).predicted(Y),
                      found.weights)
    return gained if test.significant else None


@dataclass(frozen=True)
class PairedTest:
    """What :func:`paired_test` found: the score's fall (``without`` less ``with_``), its standard error, and the
    one-sided Student ``t`` limit at the level :data:`PAIRED_ALPHA` with ``PAIRED_BLOCKS − 1`` degrees of freedom."""

    difference: float
    standard_error: float
    limit: float

    @property
    def t(self) -> float:
        """``difference / standard_error``."""
        return self.difference / self.standard_error if self.standard_error > 0 else \
            (np.inf if self.difference > 0 else 0.0)

    @property
    def significant(self) -> bool:
        """Whether ``with_`` is smaller at the level: ``t`` above the limit."""
        return bool(self.t > self.limit)


def paired_test(without: NDArray, with_: NDArray, weights: NDArray) -> PairedTest:
    """Whether the residuals ``with_`` (``(N, channels)``, the samples in time order) are smaller than ``without`` on the
    same samples beyond the record's sampling error. The score is the mean over channels of the MSE times the
    channel's ``weights`` squared (the check's cost); its difference on :data:`PAIRED_BLOCKS` contiguous blocks has
    a mean and a standard error as a mean of batch means
    (:func:`~estimation.identification.preprocessing_on_validation.paired_difference`, the validation record's test
    of two preprocessing candidates, each channel's floor ``1 / weight²``). One sided: ``with_`` is smaller when
    ``t = mean / se`` exceeds Student's ``t`` quantile ``1 −`` :data:`PAIRED_ALPHA` with ``PAIRED_BLOCKS − 1``
    degrees of freedom (the blocks' means nearly independent where a record's samples are correlated in time; on
    draws of known law it rejects 2.1 % of white pairs and 1.1 % of strongly correlated ones at 1 %,
    ``tests/test_joint_zero_gains.py``)."""
    channels = [str(index) for index in range(without.shape[1])]
    parts = np.array_split(np.arange(without.shape[0]), PAIRED_BLOCKS)
    sizes = np.array([part.size for part in parts], dtype=float)

    def blocks(residual: NDArray) -> dict[str, tuple[float, ...]]:
        return {channel: tuple(float(np.mean(residual[part, index] ** 2)) for part in parts)
                for index, channel in enumerate(channels)}

    floors = 1.0 / np.asarray(weights, dtype=float) ** 2
    difference, error = paired_difference(blocks(without), blocks(with_), floors, channels, sizes)
    return PairedTest(difference, error, float(scipy.stats.t.ppf(1 - PAIRED_ALPHA, PAIRED_BLOCKS - 1)))


def check_joint_zeros(model: IdentificationModel, train: Measurements, held_out: Measurements | None = None, *,
                      max_samples: int = MAX_SAMPLES, warn: bool = True, directions: bool = True,
                      label: str = "validation record") -> JointZeroCheck | None:
    """Test whether a constant position offset per joint lowers the held-out error markedly (module docstring).

    Parameters
    ----------
    model
        The identification model fitted; the check refits its columns with the plain fit's friction added where it
        lacks it (:func:`check_model`; the offsets change only ``q``).
    train, held_out
        The training and held-out measurements with their derivatives (as prepared for the fit); without
        ``held_out``, ``δ`` is chosen on the first half of ``train`` and tested on the second.
    max_samples
        Evenly spaced rows of each record used.
    warn
        Issue a :class:`JointZeroWarning` when the gain is marked.
    directions
        Scan the joints' directions too (:func:`estimate_signs`): a joint whose recorded ``q`` (with ``q̇``, ``q̈``)
        or torque is reversed against the description's axis.
    label
        What ``held_out`` is (the check's ``held_out``; the streamed check gives the training record's second half,
        thinned, as ``held_out``: :mod:`estimation.streaming.joint_zeros`).

    Returns
    -------
    JointZeroCheck or None
        ``None`` when the check cannot run (no derivatives, no channel the model predicts, too few samples, no
        joint the regressor depends on).
    """
    check, scanned = _checked(model, train, held_out, max_samples, directions, label)
    if scanned and not (check is not None and check.reversed_joints and check.marked and
                        check.total_ratio <= REVERSAL_MARK):
        # reversals found on the training samples but not said: the offsets alone, as without the scan
        check, _ = _checked(model, train, held_out, max_samples, False, label)
    if warn and check is not None and check.marked:
        warnings.warn(JointZeroWarning(check.message(check_model(model).robot.joint_names)), stacklevel=2)
    return check


def _apart_from_gains(model: IdentificationModel, found: _Problem, held: _Problem, offsets: NDArray,
                      named: list[int], *, gains: bool = False, sign: GainSign = "free") -> list[int]:
    """The joints of ``named`` whose offset a free gain on each joint's torque cannot explain as well.

    Torques logged as currents with an unknown gain per joint are a fault a linear fit of ``θ`` cannot take up, and a
    joint's zero moved away from the description's takes part of it up, on every record alike (a 6-joint PUMA whose
    torques were logged with gains 0.3–1.8, one flipped: joint 2 found 38° off on the training record, 21° on the
    validation record alone, and the validation error 18 % lower with it; ``benchmarks/README.md``). A joint is kept
    when, by :data:`MIN_JOINT_GAIN` each:

    - its offset alone lowers the held-out error (``θ`` fitted on the training samples ``found`` at the named
      joints' ``offsets``, the others' zero, and at those less the joint's; the held-out samples ``held``, in the same
      directions, scored with the training's channel weights): an offset is the log's fault only if data its choice
      did not see confirm it;
    - with the gains free (:func:`~estimation.identification.channel_gains.fit_channel_gains`) and the named joints'
      offsets estimated again with them (:func:`_gained_offsets`), its offset alone lowers the held-out error: the
      gains alone do not explain what it does (the training error is no judge: on a 3-joint PUMA the gains' freedom
      takes up a quarter turn of joint 2 on the training samples, not on the held-out ones).

    With ``gains`` (:func:`gains_in_question`: the offsets were scanned with the gains), the second test alone (the
    fit without gains is not the model of such a log), the gains' ``sign`` as the scan's.
    """
    if not named:
        return named
    gained = np.array([is_joint_torque(channel) for channel in model.channels])
    weights = found.weights

    def plain_held(at: NDArray) -> float:
        theta, _ = found.fit(at)
        return _weighted_mse(model, held, at, lambda Y: Y @ theta, weights)

    def with_gains(at: NDArray) -> tuple[float, float]:
        fitted = fit_channel_gains(found.regressor(at), found.target, weights, gained, sign=sign)
        return fitted.cost, _weighted_mse(model, held, at, fitted.predicted, weights)

    said = np.zeros_like(offsets)  # the offsets said: the named joints' (the others' as recorded)
    said[named] = offsets[named]
    with np.errstate(all="ignore"):
        refitted = _gained_offsets(found, said, np.array(named), gained, sign)
        plain_at, gains_at = (np.inf if gains else plain_held(said)), with_gains(refitted)
        kept = []
        for joint in named:
            without, refitted_without = said.copy(), refitted.copy()
            without[joint] = refitted_without[joint] = 0.0
            if (gains or plain_held(without) > (1 + MIN_JOINT_GAIN) * plain_at) and \
                    with_gains(refitted_without)[1] > (1 + MIN_JOINT_GAIN) * gains_at[1]:
                kept.append(joint)
    return kept


def _weighted_mse(model: IdentificationModel, held: _Problem, offsets: NDArray, predict, weights: NDArray) -> float:
    """The mean weighted squared error of ``predict(Y)`` on ``held``'s samples at ``offsets``."""
    Y = model.evaluate_base(held.q + offsets, held.dq, held.ddq)
    return float(np.mean(((held.target - predict(Y)) * weights) ** 2))


def _gained_offsets(problem: _Problem, offsets: NDArray, joints: NDArray, gained: NDArray,
                    sign: GainSign = "free") -> NDArray:
    """The offsets of ``joints`` minimising the training cost with a free gain on each ``gained`` channel:
    Gauss–Newton on ``(θ, s, δ_joints)`` from ``offsets`` (:func:`_gauss_newton` with the gains), the residual
    ``τ_j − s_j Y_j(q + δ) θ`` linearised in all three, the first gained channel's gain held (the scale); ``sign``:
    whether the gains may change sign (:func:`fit_channel_gains`)."""
    if joints.size == 0:
        return offsets
    free = np.flatnonzero(gained)[1:]
    revolute = np.array([joint.joint_type == JointType.REVOLUTE for joint in problem.model.robot.joints])
    weights = problem.weights

    def scored(at: NDArray) -> tuple[float, ChannelGains]:
        fitted = fit_channel_gains(problem.regressor(at), problem.target, weights, gained, sign=sign)
        return fitted.cost, fitted

    _, current = scored(offsets)
    for _ in range(ITERATIONS):
        Y = problem.regressor(offsets)
        predicted = Y @ current.theta
        residual = problem.target - current.gains * predicted
        gain_columns = np.zeros((*predicted.shape, free.size))
        gain_columns[:, free, np.arange(free.size)] = predicted[:, free]
        columns = []
        for joint in joints:
            shifted = offsets.copy()
            shifted[joint] += STEP
            columns.append(current.gains * (problem.regressor(shifted) @ current.theta - predicted) / STEP)
        J = np.concatenate([Y * current.gains[None, :, None], gain_columns, np.stack(columns, axis=2)], axis=2)
        delta = _least_squares(J * weights[None, :, None], residual * weights)[-joints.size:]
        searched = _line_search(offsets, joints, delta, revolute, scored, current.cost)
        if searched is None:
            break
        trial, (_, trial_fit) = searched
        converged = np.max(np.abs(trial - offsets)) < 1e-6
        offsets, current = trial, trial_fit
        if converged:
            break
    return offsets


def _checked(model: IdentificationModel, train: Measurements, held_out: Measurements | None, max_samples: int,
             directions: bool, label: str, *, gains: bool = True) -> tuple[JointZeroCheck | None, bool]:
    """The check (:func:`check_joint_zeros`), and whether the scan of directions found a reversal on the training
    samples. ``gains``: whether the gains may be in question (:func:`gains_in_question`); when they are, they must
    still lower the held-out error significantly at the offsets and directions found (:func:`paired_test`), else the
    check runs again without them."""
    if held_out is None:
        half = train.n_samples // 2
        if half < 20:
            return None, False
        train, held_out = train.select(slice(0, half)), train.select(slice(half, None))
        label = "second half of the training record"
    model = check_model(model)
    fitted = _thinned(train, model.channels, max_samples)
    scored = _thinned(held_out, model.channels, max_samples)
    if fitted is None or scored is None:
        return None, False
    problem = _Problem(model, fitted)
    n = model.robot.n_joints
    # the gains kept positive when the directions are scanned (a reversed torque is theirs to say), else either sign
    sign: GainSign = "held" if directions else "free"
    ones = np.ones(n)
    with np.errstate(all="ignore"):
        signs, torque = estimate_signs(model, problem) if directions else (ones, ones)
        reversed_ = (signs < 0) | (torque < 0)
        found = problem.flipped(signs, torque) if np.any(reversed_) else problem
        gained = gains_in_question(model, found, scored, signs, torque, sign) if gains else None
        if gained is None and gains and np.any(reversed_):
            # the scan's reversal, taken without the gains, may be theirs (the neighbouring joint's torque reversed
            # in place of the true one's): the gains asked again at the recorded directions, of either sign (a
            # reversed torque is a negative gain), and when in question the directions scanned with them
            gained = gains_in_question(model, problem, scored, ones, ones, "free")
            if gained is not None:
                signs, torque = estimate_signs(model, problem.with_gains(gained, sign))
                reversed_ = (signs < 0) | (torque < 0)
                found = problem.flipped(signs, torque) if np.any(reversed_) else problem
        if gained is not None:  # every cost from here on with a gain on each joint's torque
            problem, found = problem.with_gains(gained, sign), found.with_gains(gained, sign)
        offsets = estimate_offsets(model, found)
    large = np.abs(offsets) >= MIN_OFFSET
    if not (np.any(large) or np.any(reversed_)) or \
            found.cost(offsets) > (1 - MARKED_GAIN / 2) * problem.cost(np.zeros(n)):
        # nothing large, or the training error itself hardly falls: no marked held-out gain to test
        return (JointZeroCheck(np.zeros(n), (), {channel: 1.0 for channel in model.channels}, 1.0, label, np.zeros(n)),
                bool(np.any(reversed_)))
    held = _Problem(model, scored)
    held = held if gained is None else held.with_gains(gained, sign)
    held_found = held.flipped(signs, torque) if np.any(reversed_) else held
    with np.errstate(all="ignore"):  # the held-out record's own estimate: a real offset is the same on both
        again = estimate_offsets(model, held_found)
    revolute = np.array([joint.joint_type == JointType.REVOLUTE for joint in model.robot.joints])
    apart = np.abs(np.where(revolute, _wrapped(offsets - again, revolute), offsets - again))
    agree = apart <= np.where(revolute, np.minimum(AGREEMENT, 0.5 * np.abs(offsets)), 0.25 * np.abs(offsets))
    cost, held_cost = found.cost(offsets), held_found.cost(again)
    kept_signs, kept_torque = np.ones(n), np.ones(n)
    for joint in np.flatnonzero(reversed_):  # a reversal both records need by itself (each fitted alone)
        undone_signs, undone_torque = signs.copy(), torque.copy()
        undone_signs[joint] = undone_torque[joint] = 1.0
        if problem.flipped(undone_signs, undone_torque).cost(offsets) > cost * (1 + MIN_JOINT_GAIN) and \
                held.flipped(undone_signs, undone_torque).cost(again) > held_cost * (1 + MIN_JOINT_GAIN):
            kept_signs[joint], kept_torque[joint] = signs[joint], torque[joint]
    named = []
    for joint in np.flatnonzero(large & agree):
        without = offsets.copy()
        without[joint] = 0.0
        if found.cost(without) > cost * (1 + MIN_JOINT_GAIN):
            named.append(int(joint))
    named = _apart_from_gains(model, found, held_found, offsets, named, gains=gained is not None, sign=sign)
    kept = np.zeros(n)
    kept[named] = offsets[named]
    if np.any(kept_signs < 0) or np.any(kept_torque < 0):  # the description's own bodies must confirm each joint
        nominal = model.nominal_parameters()
        with_all = _nominal_mse(model, nominal, fitted, kept, kept_signs, kept_torque, gained)
        confirmed = []
        for joint in np.flatnonzero((kept_signs < 0) | (kept_torque < 0) | (kept != 0)):
            signs_undone, torque_undone, kept_undone = kept_signs.copy(), kept_torque.copy(), kept.copy()
            signs_undone[joint] = torque_undone[joint] = 1.0
            kept_undone[joint] = 0.0
            if with_all <= (1 - MIN_JOINT_GAIN) * _nominal_mse(model, nominal, fitted, kept_undone, signs_undone,
                                                               torque_undone, gained):
                confirmed.append(joint)
        unconfirmed = np.setdiff1d(np.arange(n), confirmed)
        kept_signs[unconfirmed] = kept_torque[unconfirmed] = 1.0
        kept[unconfirmed] = 0.0
        named = [joint for joint in named if joint in confirmed]
        if not _nominal_mse(model, nominal, fitted, kept, kept_signs, kept_torque, gained) <= (1 - MARKED_GAIN) * \
                _nominal_mse(model, nominal, fitted, np.zeros(n), np.ones(n), np.ones(n), gained):
            kept_signs, kept_torque = np.ones(n), np.ones(n)
    flips = np.any(kept_signs < 0) or np.any(kept_torque < 0)
    if gained is None:
        theta_zero, _ = problem.fit(np.zeros(n))
        theta_offset, _ = (problem.flipped(kept_signs, kept_torque) if flips else problem).fit(kept)
        before = _held_out_mse(model, theta_zero, scored, np.zeros(n))
        after = _held_out_mse(model, theta_offset, scored, kept, kept_signs, kept_torque)
    else:  # both with the gains: what the offsets and directions do beside them
        zero_fit = problem.gains_fit(np.zeros(n))
        directed = problem.flipped(kept_signs, kept_torque) if flips else problem
        offset_fit = directed.gains_fit(kept)
        residual = _held_out_residual(model, offset_fit.theta, scored, kept, kept_signs, kept_torque,
                                      gains=offset_fit.gains)
        theta_plain, _ = directed.with_gains(None).fit(kept)
        if not paired_test(_held_out_residual(model, theta_plain, scored, kept, kept_signs, kept_torque), residual,
                          problem.weights).significant:
            # at the offsets and directions found, the gains no longer lower the held-out error: they stood in for
            # these (a true offset, no gains), and the check is the one without them
            return _checked(model, train, held_out, max_samples, directions, label, gains=False)
        before = _held_out_mse(model, zero_fit.theta, scored, np.zeros(n), gains=zero_fit.gains)
        after = np.mean(residual ** 2, axis=0)
    ratio = {channel: float(a / b) if b > 0 else 1.0 for channel, a, b in zip(model.channels, after, before)}
    total = float(after.sum() / before.sum()) if before.sum() > 0 else 1.0
    check = JointZeroCheck(kept, tuple(named), ratio, total, label, again, tuple(bool(value) for value in ~revolute),
                           tuple(int(value) for value in kept_signs) if flips else (),
                           tuple(int(value) for value in kept_torque) if flips else (), gained is not None)
    return check, bool(np.any(reversed_))
