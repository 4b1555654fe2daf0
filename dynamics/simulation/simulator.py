"""The simulated robot: Pinocchio forward dynamics under a controller, sampled like the real set-up.

Plant (true parameters ``θ``, joint effects ``e``)::

    (M(q) + diag(Ia)) ddq + h(q, dq) + Σ_e τ_e(q, dq) = τ                   (pinocchio.aba)

integrated with classic **RK4 at the sampling rate (1 kHz) with a zero-order hold** on the
controller torque ``τ_k`` over each step ``[t_k, t_k+1)`` (optionally ``substeps`` RK4 steps per
sample). The controller sees the true state. At each sample ``k`` the record holds the true
``q_k, dq_k``, ``ddq_k = aba(q_k, dq_k, τ_k)`` (so ``τ_k`` equals the model's prediction at the
recorded true state to rounding, whatever the step size), the applied torque ``τ_k`` and the
base reaction wrench from Pinocchio (free-flyer RNEA at a still root; rigid body only: friction
is internal) plus the plate effects.

Measured channels (what :class:`dynamics.measurements.Measurements` holds):

* ``q``: true positions quantised to the encoder resolution (``round(q / res) · res``);
* ``dq``, ``ddq``: **absent** by default (a real robot measures positions only; preprocessing
  derives them); with ``with_derivatives=True`` the true, noiseless values;
* ``tau``: applied torques plus Gaussian noise; ``fx … mz``: wrench plus Gaussian noise.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from dynamics.simulation.controllers import Controller, PDController, pd_gains
from dynamics.simulation.plant import Plant
from dynamics.channels import WRENCH_CHANNELS
from dynamics.runtime.memory import check_allocation
from dynamics.pinocchio_bridge import to_pinocchio
from dynamics.robot import RobotModel
from dynamics.simulation.sensors import NoiseModel
from dynamics.simulation.effects import Viscous, describe, effects_from_names, is_plate_effect
from dynamics.measurements import Measurements

@dataclass(frozen=True)
class SimulationResult:
    """One simulated experiment: the measurements and the truth behind them.

    Attributes
    ----------
    measurements
        What the sensors recorded (quantised ``q``, noisy ``tau`` and wrench).
    t, q, dq, ddq
        Sample times and the true states, ``(N, n)``.
    q_desired, dq_desired, ddq_desired
        The reference at the same times.
    tau
        Applied torques (controller output, noiseless), ``(N, n)``.
    wrench
        True base reaction wrench including the plate effects (noiseless), ``(N, 6)``.
    wrench_rigid_body
        Its rigid-body part only.
    elapsed_s
        Wall time of the integration loop.
    """

    measurements: Measurements
    t: NDArray[np.float64]
    q: NDArray[np.float64]
    dq: NDArray[np.float64]
    ddq: NDArray[np.float64]
    q_desired: NDArray[np.float64]
    dq_desired: NDArray[np.float64]
    ddq_desired: NDArray[np.float64]
    tau: NDArray[np.float64]
    wrench: NDArray[np.float64]
    wrench_rigid_body: NDArray[np.float64]
    elapsed_s: float
    metadata: dict[str, Any] = field(default_factory=dict)

    @property
    def tracking_error(self) -> NDArray[np.float64]:
        """``q − q_d`` at the samples, ``(N, n)``."""
        return self.q - self.q_desired


def _reference(trajectory: Any, n_joints: int) -> tuple[Callable, float | None]:
    if hasattr(trajectory, "evaluate"):
        evaluate = trajectory.evaluate
    elif callable(trajectory):
        evaluate = trajectory
    else:
        raise TypeError("trajectory must be a FourierTrajectory or a callable t -> (q_d, dq_d, ddq_d)")
    count = getattr(trajectory, "n_joints", None)
    if count is not None and count != n_joints:
        raise ValueError(f"trajectory has {count} joints, the robot {n_joints}")
    return evaluate, getattr(trajectory, "period", None)


#: most samples one simulation records (about 1 GB of states and torques for a 6-joint robot)
MAX_SAMPLES = 20_000_000
#: most RK4 steps a sample (stiff friction on a light joint asks for more)
MAX_SUBSTEPS = 10_000


@dataclass(frozen=True, eq=False)
class Simulator:
    """A simulated robot with its true parameters, extra effects and sensors.

    Parameters
    ----------
    robot
        The chain.
    effects
        Simulated effects (:mod:`dynamics.simulation.effects`) or a comma-separated list of their
        names with default values; ``None``: viscous friction with its default values.
    theta
        True standard parameters (``10 n``); default the robot's own.
    noise
        Sensor model; default :class:`NoiseModel` ``()``.
    rate_hz
        Sampling and control rate (default 1 kHz).
    substeps
        Least number of RK4 steps per sample (the torque is held over the sample). It is raised
        automatically so that ``h · λ ≤ 0.5`` for the friction stiffness
        ``λ_i = (fv_i + fc_i / smoothing) / M_ii(0)`` (a light joint with Coulomb friction).
    """

    robot: RobotModel
    effects: tuple[Any, ...] | str | None = None
    theta: tuple[float, ...] | None = None
    noise: NoiseModel = field(default_factory=NoiseModel)
    rate_hz: float = 1000.0
    substeps: int = 1

    def __post_init__(self) -> None:
        robot = self.robot
        if self.effects is None:
            effects: tuple[Any, ...] = (Viscous.default(robot),)
        elif isinstance(self.effects, str):
            effects = effects_from_names(self.effects, robot)
        else:
            effects = tuple(self.effects)
        for effect in effects:
            effect.parameters(robot)  # checks sizes against the robot
        object.__setattr__(self, "effects", effects)
        theta = robot.standard_parameters if self.theta is None else np.asarray(self.theta, dtype=float).reshape(-1)
        if theta.shape != (10 * robot.n_joints,) or not np.all(np.isfinite(theta)):
            raise ValueError(f"theta must hold {10 * robot.n_joints} finite standard parameters")
        object.__setattr__(self, "theta", tuple(theta.tolist()))
        if not (np.isfinite(self.rate_hz) and self.rate_hz > 0) or int(self.substeps) < 1:
            raise ValueError(f"rate_hz must be a positive finite number (got {self.rate_hz}) and substeps at least 1")
        if not isinstance(self.noise, NoiseModel):
            raise TypeError("noise must be a NoiseModel")

    @property
    def joint_effects(self) -> tuple[Any, ...]:
        return tuple(effect for effect in self.effects if not is_plate_effect(effect))  # type: ignore[union-attr]

    @property
    def plate_effects(self) -> tuple[Any, ...]:
        return tuple(effect for effect in self.effects if is_plate_effect(effect))  # type: ignore[union-attr]

    def true_parameters(self) -> dict[str, float]:
        """Standard parameters and every effect's values, by name (``m1 … Izz_n, fv1, fc1, mz_off …``)."""
        named = dict(zip(self.robot.standard_parameter_names, self.theta))  # type: ignore[arg-type]
        for effect in self.effects:  # type: ignore[union-attr]
            named.update(effect.parameters(self.robot))
        return named

    def true_theta(self, model: Any) -> NDArray[np.float64]:
        """The true standard-parameter vector of an identification model (0 for effects not simulated)."""
        named = self.true_parameters()
        return np.array([named.get(name, 0.0) for name in model.parameter_names])

    def default_controller(self, bandwidth_hz: float = 4.0) -> PDController:
        """PD at ``bandwidth_hz``, critically damped, on the true joint inertias (with armature) at ``q = 0``."""
        kp, kd = pd_gains(self.robot, bandwidth_hz=bandwidth_hz, armature=self._armature())
        return PDController(kp, kd)

    def substeps_needed(self) -> int:
        """RK4 steps per sample: ``substeps``, or more when friction is stiff for the joint inertia."""
        from dynamics.simulation.controllers import joint_inertia
        from dynamics.simulation.effects import Coulomb

        damping = np.zeros(self.robot.n_joints)
        with np.errstate(over="ignore"):  # an absurd friction gives inf here, refused below
            for effect in self.joint_effects:
                if isinstance(effect, Viscous):
                    damping += np.abs(effect.values)
                elif isinstance(effect, Coulomb):
                    damping += np.abs(effect.values) / effect.smoothing
                elif hasattr(effect, "damping"):  # e.g. dynamics.simulation.motor_effects.MotorFriction
                    damping += effect.damping(self.robot)
        if not damping.any():
            return int(self.substeps)
        inertia = joint_inertia(self.robot, self._armature())
        inertia = np.where(inertia > 0, inertia, np.inf)
        stiffness = float(np.max(damping / inertia))
        needed = stiffness / self.rate_hz / 0.5
        if not needed <= MAX_SUBSTEPS:
            raise ValueError(f"the friction is too stiff for the joint inertia: {stiffness:.3g} 1/s would need more than "
                             f"{MAX_SUBSTEPS} integration steps a sample at {self.rate_hz:g} Hz (raise the Coulomb "
                             "smoothing or the rate, or lower the friction)")
        return max(int(self.substeps), int(np.ceil(needed)))

    def _armature(self) -> NDArray[np.float64]:
        return sum((effect.armature(self.robot) for effect in self.joint_effects), np.zeros(self.robot.n_joints))

    def run(
        self,
        trajectory: Any,
        controller: Controller | None = None,
        *,
        periods: int = 1,
        duration: float | None = None,
        warmup_periods: int = 0,
        with_derivatives: bool = False,
        initial_state: tuple[ArrayLike, ArrayLike] | None = None,
        seed: int | None = None,
    ) -> SimulationResult:
        """Simulate ``periods`` periods of ``trajectory`` (or ``duration`` s) under ``controller``.

        ``warmup_periods`` whole periods are simulated first and dropped, so that the record
        starts in the periodic steady state; the record's ``t`` starts at 0. The robot starts at
        the reference ``q_d(0), dq_d(0)`` unless ``initial_state`` is given.
        """
        robot, n = self.robot, self.robot.n_joints
        evaluate, period = _reference(trajectory, n)
        length = _RecordLength.of(period, periods, duration, warmup_periods, self.rate_hz, n)
        t_all = np.arange(length.skip + length.count) / self.rate_hz
        q_d, dq_d, ddq_d = (np.asarray(values, dtype=float) for values in evaluate(t_all))
        if q_d.shape != (length.skip + length.count, n):
            raise ValueError(f"the reference must give ({length.skip + length.count}, {n}) arrays, got {q_d.shape}")
        controller = self.default_controller() if controller is None else controller
        if not isinstance(controller, Controller):
            raise TypeError("controller needs torque(t, q, dq, q_d, dq_d, ddq_d) and describe()")

        plant = Plant(robot, self.theta, self.joint_effects, self.rate_hz)
        q = q_d[0].copy() if initial_state is None else np.asarray(initial_state[0], dtype=float).copy()
        dq = dq_d[0].copy() if initial_state is None else np.asarray(initial_state[1], dtype=float).copy()
        plant.check_mass_matrix(q)
        substeps = self.substeps_needed()
        started = time.perf_counter()
        Q, DQ, DDQ, TAU = plant.track(controller, t_all, (q_d, dq_d, ddq_d), (q, dq), substeps)
        elapsed = time.perf_counter() - started

        keep = slice(length.skip, length.skip + length.count)
        t = t_all[keep] - t_all[length.skip]
        Q, DQ, DDQ, TAU = Q[keep], DQ[keep], DDQ[keep], TAU[keep]
        rigid = base_wrench(robot, self.theta, Q, DQ, DDQ)
        plate = sum((effect.plate_wrench(robot, Q) for effect in self.plate_effects), np.zeros((length.count, 6)))
        wrench = rigid + plate
        q_measured, tau_measured, wrench_measured = self._sensed(Q, TAU, wrench, seed)
        metadata = self._metadata(trajectory, controller, length, periods, warmup_periods, substeps, seed,
                                  with_derivatives)
        measurements = Measurements(
            t=t,
            q=q_measured,
            dq=DQ.copy() if with_derivatives else None,
            ddq=DDQ.copy() if with_derivatives else None,
            tau=tau_measured,
            wrench=wrench_measured,
            metadata=metadata,
        )
        q_ref, dq_ref, ddq_ref = q_d[keep], dq_d[keep], ddq_d[keep]
        return SimulationResult(
            measurements, t, Q, DQ, DDQ, q_ref, dq_ref, ddq_ref, TAU, wrench, rigid, elapsed, metadata
        )

    def _sensed(self, Q: NDArray, TAU: NDArray, wrench: NDArray, seed: int | None
                ) -> tuple[NDArray, NDArray, NDArray]:
        """What the sensors read of the true ``q``, ``tau`` and wrench: quantised positions, noisy
        torques and wrench (the torque noise drawn first, then the wrench's, from ``seed``)."""
        robot = self.robot
        count, n = TAU.shape
        generator = np.random.default_rng(seed)
        tau_noise = generator.normal(size=(count, n)) * np.broadcast_to(self.noise.tau_std, (n,))
        wrench_noise = generator.normal(size=(count, 6)) * np.broadcast_to(self.noise.wrench_std, (6,))
        resolution = self.noise.resolution(robot)
        if resolution is not None:
            spans = np.ptp(Q, axis=0)
            coarse = np.flatnonzero((spans > 0) & (np.broadcast_to(resolution, spans.shape) >= spans))
            if coarse.size:
                joint = int(coarse[0])
                raise ValueError(f"position resolution {np.broadcast_to(resolution, spans.shape)[joint]:.3g} of joint "
                                 f"{joint + 1} is coarser than its motion (range {spans[joint]:.3g}): its positions "
                                 "would read almost constant")
        q_measured = Q.copy() if resolution is None else np.round(Q / resolution) * resolution
        return q_measured, TAU + tau_noise, wrench + wrench_noise

    def _metadata(self, trajectory: Any, controller: Controller, length: _RecordLength, periods: int,
                  warmup_periods: int, substeps: int, seed: int | None, with_derivatives: bool) -> dict[str, Any]:
        """The record's metadata: the robot, the sampling, the controller, effects, noise and truth."""
        robot = self.robot
        return {
            "source": "dynamics.simulation.simulator",
            "robot": robot.name,
            "joint_names": robot.joint_names,
            "rate_hz": self.rate_hz,
            "duration_s": length.duration,
            "periods": int(periods) if length.whole_periods else None,
            # whole periods of a periodic reference: estimation.preprocessing.differentiation.fill_derivatives fits them
            "frequency_hz": 1.0 / length.period if length.whole_periods else None,
            "harmonics": getattr(trajectory, "harmonics", None),
            "warmup_periods": int(warmup_periods),
            "integrator": f"rk4, zero-order-hold torque, {substeps} substep(s) per sample",
            "seed": seed,
            "with_derivatives": bool(with_derivatives),
            "controller": controller.describe(),
            "effects": [describe(effect, robot) for effect in self.effects],  # type: ignore[union-attr]
            "noise": self.noise.describe(robot),
            "true_parameters": self.true_parameters(),
            "wrench_channels": list(WRENCH_CHANNELS),
        }



@dataclass(frozen=True)
class _RecordLength:
    """The samples one run simulates: ``skip`` warm-up samples (dropped), then ``count`` recorded.

    Attributes
    ----------
    duration
        Recorded seconds.
    count, skip
        Recorded and warm-up samples.
    period
        The reference's period (``None``: not periodic).
    whole_periods
        Whether the record is whole periods of a periodic reference (no ``duration`` given).
    """

    duration: float
    count: int
    skip: int
    period: float | None
    whole_periods: bool

    @classmethod
    def of(cls, period: float | None, periods: int, duration: float | None, warmup_periods: int, rate_hz: float,
           n_joints: int) -> _RecordLength:
        """Checked: ``periods`` periods (or ``duration`` s) after ``warmup_periods`` at ``rate_hz``,
        within :data:`MAX_SAMPLES` and the memory the arrays of ``n_joints`` joints take."""
        whole_periods = duration is None and period is not None
        if duration is None:
            if period is None:
                raise ValueError("give duration for a trajectory without a period")
            if int(periods) < 1 or int(warmup_periods) < 0:
                raise ValueError("periods must be at least 1 and warmup_periods non-negative")
            duration = int(periods) * period
        if not duration > 0:
            raise ValueError(f"duration must be positive, got {duration}")
        warmup = int(warmup_periods) * (period or 0.0)
        if not np.isfinite(duration * rate_hz) or duration * rate_hz + warmup * rate_hz > MAX_SAMPLES:
            raise ValueError(f"{duration + warmup:.4g} s at {rate_hz:g} Hz is more than {MAX_SAMPLES:.0e} samples: "
                             "shorten the record or lower the rate")
        count, skip = int(round(duration * rate_hz)), int(round(warmup * rate_hz))
        # t, the reference (q, dq, ddq), the record (q, dq, ddq, tau) and the wrench and frame written from it
        check_allocation(8.0 * (skip + count) * (1 + 8 * n_joints + 12), f"{duration + warmup:.4g} s at {rate_hz:g} Hz")
        if count < 2:
            raise ValueError(f"{duration:.4g} s at {rate_hz:g} Hz gives {count} sample(s): need at least two")
        return cls(duration, count, skip, period, whole_periods)


def base_wrench(robot: RobotModel, theta: Sequence[float] | None, q: NDArray, dq: NDArray, ddq: NDArray) -> NDArray:
    """Rigid-body reaction wrench on the robot from its base, ``(N, 6)`` (Pinocchio free-flyer RNEA).

    Forces then moments about the base origin, base frame; a robot at rest reads ``fz = +m g``.
    """
    import pinocchio as pin

    model = to_pinocchio(robot, free_flyer=True, theta=theta)
    data = model.createData()
    root = np.array([0, 0, 0, 0, 0, 0, 1.0])
    zeros = np.zeros(6)
    wrench = np.empty((q.shape[0], 6))
    for k in range(q.shape[0]):
        wrench[k] = pin.rnea(
            model, data, np.concatenate([root, q[k]]), np.concatenate([zeros, dq[k]]), np.concatenate([zeros, ddq[k]])
        )[:6]
    return wrench


def simulate_controlled(
    robot: RobotModel,
    trajectory: Any,
    *,
    controller: Controller | None = None,
    effects: Sequence[Any] | str | None = None,
    noise: NoiseModel | None = None,
    theta: ArrayLike | None = None,
    rate_hz: float = 1000.0,
    periods: int = 1,
    warmup_periods: int = 0,
    with_derivatives: bool = False,
    seed: int | None = None,
) -> Measurements:
    """One-shot simulation returning the measurements (see :class:`Simulator` for the truth)."""
    simulator = Simulator(
        robot, effects, None if theta is None else tuple(np.asarray(theta, dtype=float).reshape(-1)),
        NoiseModel() if noise is None else noise, rate_hz,
    )
    return simulator.run(
        trajectory, controller, periods=periods, warmup_periods=warmup_periods,
        with_derivatives=with_derivatives, seed=seed,
    ).measurements
