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
from dynamics.effects.linear import WRENCH_CHANNELS
from dynamics.runtime.memory import check_allocation
from dynamics.pinocchio_bridge import to_pinocchio
from dynamics.robot import RobotModel
from dynamics.simulation.sensors import NoiseModel
from dynamics.simulation.effects import Armature, Viscous, describe, effects_from_names, is_plate_effect
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
        import pinocchio as pin

        robot, n = self.robot, self.robot.n_joints
        evaluate, period = _reference(trajectory, n)
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
        if not np.isfinite(duration * self.rate_hz) or duration * self.rate_hz + warmup * self.rate_hz > MAX_SAMPLES:
            raise ValueError(f"{duration + warmup:.4g} s at {self.rate_hz:g} Hz is more than {MAX_SAMPLES:.0e} samples: "
                             "shorten the record or lower the rate")
        count, skip = int(round(duration * self.rate_hz)), int(round(warmup * self.rate_hz))
        # t, the reference (q, dq, ddq), the record (q, dq, ddq, tau) and the wrench and frame written from it
        check_allocation(8.0 * (skip + count) * (1 + 8 * n + 12), f"{duration + warmup:.4g} s at {self.rate_hz:g} Hz")
        if count < 2:
            raise ValueError(f"{duration:.4g} s at {self.rate_hz:g} Hz gives {count} sample(s): need at least two")
        t_all = np.arange(skip + count) / self.rate_hz
        q_d, dq_d, ddq_d = (np.asarray(values, dtype=float) for values in evaluate(t_all))
        if q_d.shape != (skip + count, n):
            raise ValueError(f"the reference must give ({skip + count}, {n}) arrays, got {q_d.shape}")
        controller = self.default_controller() if controller is None else controller
        if not isinstance(controller, Controller):
            raise TypeError("controller needs torque(t, q, dq, q_d, dq_d, ddq_d) and describe()")

        model = to_pinocchio(robot, theta=self.theta)
        model.armature = self._armature()
        data = model.createData()
        joint_effects = [effect for effect in self.joint_effects if not isinstance(effect, Armature)]  # armature: in M

        def acceleration(q, dq, tau):
            for effect in joint_effects:
                tau = tau - effect.joint_torque(robot, q, dq)
            return pin.aba(model, data, q, dq, tau).copy()

        q = q_d[0].copy() if initial_state is None else np.asarray(initial_state[0], dtype=float).copy()
        dq = dq_d[0].copy() if initial_state is None else np.asarray(initial_state[1], dtype=float).copy()
        upper = np.triu(pin.crba(model, data, q))  # CRBA fills the upper triangle
        inertia = np.linalg.eigvalsh(upper + np.triu(upper, 1).T)
        if not inertia[0] > 1e-12 * max(inertia[-1], 1e-300):
            raise ValueError(f"the mass matrix is singular at the start (eigenvalues {inertia[0]:.3g} … {inertia[-1]:.3g}): "
                             "a joint moves no mass or inertia (a massless link in the description?); "
                             "the robot cannot be simulated")
        Q, DQ, DDQ, TAU = (np.empty((skip + count, n)) for _ in range(4))
        substeps = self.substeps_needed()
        h = 1.0 / (self.rate_hz * substeps)
        started = time.perf_counter()
        for k in range(skip + count):
            tau = np.asarray(controller.torque(t_all[k], q, dq, q_d[k], dq_d[k], ddq_d[k]), dtype=float).reshape(n)
            a1 = acceleration(q, dq, tau)
            Q[k], DQ[k], DDQ[k], TAU[k] = q, dq, a1, tau
            for step in range(substeps):
                if step:
                    a1 = acceleration(q, dq, tau)
                v2 = dq + 0.5 * h * a1
                a2 = acceleration(q + 0.5 * h * dq, v2, tau)
                v3 = dq + 0.5 * h * a2
                a3 = acceleration(q + 0.5 * h * v2, v3, tau)
                v4 = dq + h * a3
                a4 = acceleration(q + h * v3, v4, tau)
                q = q + h / 6 * (dq + 2 * v2 + 2 * v3 + v4)
                dq = dq + h / 6 * (a1 + 2 * a2 + 2 * a3 + a4)
            if not (np.all(np.isfinite(q)) and np.all(np.isfinite(dq)) and np.all(np.abs(dq) < 1e4)):
                with np.errstate(all="ignore"):
                    peak = np.max(np.abs(np.nan_to_num(dq_d, nan=np.inf)), axis=0)
                raise RuntimeError(
                    f"simulation diverged at t = {t_all[k]:.3f} s (joint velocities {np.array2string(dq, precision=3)}); "
                    f"lower the controller gains or raise rate_hz/substeps, or check the reference (its peak "
                    f"velocities {np.array2string(peak, precision=3)} rad/s)"
                )
        elapsed = time.perf_counter() - started

        keep = slice(skip, skip + count)
        t = t_all[keep] - t_all[skip]
        Q, DQ, DDQ, TAU = Q[keep], DQ[keep], DDQ[keep], TAU[keep]
        rigid = base_wrench(robot, self.theta, Q, DQ, DDQ)
        plate = sum((effect.plate_wrench(robot, Q) for effect in self.plate_effects), np.zeros((count, 6)))
        wrench = rigid + plate

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
        metadata = {
            "source": "dynamics.simulation.simulator",
            "robot": robot.name,
            "joint_names": robot.joint_names,
            "rate_hz": self.rate_hz,
            "duration_s": duration,
            "periods": int(periods) if whole_periods else None,
            # whole periods of a periodic reference: estimation.preprocessing.differentiation.fill_derivatives fits them
            "frequency_hz": 1.0 / period if whole_periods else None,
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
        measurements = Measurements(
            t=t,
            q=q_measured,
            dq=DQ.copy() if with_derivatives else None,
            ddq=DDQ.copy() if with_derivatives else None,
            tau=TAU + tau_noise,
            wrench=wrench + wrench_noise,
            metadata=metadata,
        )
        q_ref, dq_ref, ddq_ref = q_d[keep], dq_d[keep], ddq_d[keep]
        return SimulationResult(
            measurements, t, Q, DQ, DDQ, q_ref, dq_ref, ddq_ref, TAU, wrench, rigid, elapsed, metadata
        )


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


def simulate(
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
