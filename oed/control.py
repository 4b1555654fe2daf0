"""Inverse-dynamics control with an identified model, simulated (PUMA paper, section V, Figs. 10–12).

``tracking_experiment`` runs one controller on the simulated robot and measures the tracking
error per joint; ``compare_controllers`` runs PD alone, computed torque with the nominal model,
and computed torque with an identified parameter vector, on the same robot and trajectory::

    comparison = compare_controllers(simulator, trajectory, model, theta_hat)
    print(comparison.table())
    comparison.figure().savefig("tracking.png")     # like Figs. 11 (q vs q_d) and 12 (|error|)
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from dynamics.simulation.controllers import (
    ComputedTorqueController, Controller, PDController, computed_torque_gains, pd_gains,
)
from dynamics.models import IdentificationModel
from dynamics.simulation.simulator import SimulationResult, Simulator


@dataclass(frozen=True)
class TrackingResult:
    """Tracking of one controller.

    Attributes
    ----------
    label
        Name of the controller in tables and legends.
    t, q, q_desired
        Sample times, true and desired positions ``(N, n)``.
    error
        ``q − q_d``, ``(N, n)`` (rad or m).
    max_error, rms_error
        Per joint, ``(n,)``.
    simulation
        Everything the simulator recorded.
    """

    label: str
    t: NDArray[np.float64]
    q: NDArray[np.float64]
    q_desired: NDArray[np.float64]
    error: NDArray[np.float64]
    max_error: NDArray[np.float64]
    rms_error: NDArray[np.float64]
    simulation: SimulationResult

    def summary(self) -> dict[str, Any]:
        return {"label": self.label, "max_error": self.max_error.tolist(), "rms_error": self.rms_error.tolist()}


def tracking_experiment(
    simulator: Simulator,
    trajectory: Any,
    controller: Controller,
    *,
    label: str | None = None,
    periods: int = 1,
    warmup_periods: int = 0,
    seed: int | None = None,
) -> TrackingResult:
    """Simulate ``controller`` tracking ``trajectory`` on ``simulator``'s robot; errors per joint."""
    result = simulator.run(trajectory, controller, periods=periods, warmup_periods=warmup_periods, seed=seed)
    error = result.tracking_error
    return TrackingResult(
        label=label or controller.describe().get("label", controller.describe()["type"]),
        t=result.t,
        q=result.q,
        q_desired=result.q_desired,
        error=error,
        max_error=np.abs(error).max(axis=0),
        rms_error=np.sqrt(np.mean(error**2, axis=0)),
        simulation=result,
    )


@dataclass(frozen=True)
class TrackingComparison:
    """Several controllers on the same robot and trajectory."""

    results: tuple[TrackingResult, ...]

    def __getitem__(self, label: str) -> TrackingResult:
        for result in self.results:
            if result.label == label:
                return result
        raise KeyError(f"no controller {label!r}; have {[result.label for result in self.results]}")

    def table(self) -> str:
        """Max and RMS tracking error per joint, one line per controller (mrad or mm)."""
        n = self.results[0].error.shape[1]
        width = max(len(result.label) for result in self.results)
        header = f"{'controller':<{width}}  " + "  ".join(f"max{j:<2d}   rms{j:<2d}  " for j in range(1, n + 1))
        lines = [header + " (1e-3 rad or mm)"]
        for result in self.results:
            cells = "  ".join(f"{1e3 * m:7.3f} {1e3 * r:7.3f}" for m, r in zip(result.max_error, result.rms_error))
            lines.append(f"{result.label:<{width}}  {cells}")
        return "\n".join(lines)

    def figure(self):
        """Figure like Figs. 11–12: per joint, desired and real positions, and the absolute error."""
        from matplotlib.figure import Figure

        n = self.results[0].error.shape[1]
        figure = Figure(figsize=(10, 2.6 * n), layout="constrained")
        axes = figure.subplots(n, 2, squeeze=False)
        reference = self.results[0]
        for joint in range(n):
            left, right = axes[joint]
            left.plot(reference.t, reference.q_desired[:, joint], "k--", label="desired")
            for result in self.results:
                left.plot(result.t, result.q[:, joint], label=result.label)
                right.semilogy(result.t, np.abs(result.error[:, joint]), label=result.label)
            largest = max(float(np.abs(result.error[:, joint]).max()) for result in self.results)
            right.set_ylim(bottom=max(largest * 1e-5, 1e-9))
            left.set_ylabel(f"q{joint + 1}")
            right.set_ylabel(f"|q{joint + 1} − q{joint + 1}d|")
        for ax in axes[-1]:
            ax.set_xlabel("t (s)")
        axes[0, 0].set_title("desired and real trajectory (cf. Fig. 11)")
        axes[0, 1].set_title("tracking error (cf. Fig. 12)")
        axes[0, 0].legend(fontsize="small")
        return figure


def compare_controllers(
    simulator: Simulator,
    trajectory: Any,
    model: IdentificationModel,
    theta_identified: ArrayLike,
    *,
    nominal_theta: ArrayLike | None = None,
    bandwidth_hz: float = 4.0,
    damping: float = 1.0,
    periods: int = 1,
    warmup_periods: int = 0,
) -> TrackingComparison:
    """PD alone vs computed torque with the nominal model vs with the identified parameters.

    Parameters
    ----------
    simulator
        The "real" robot (true parameters and effects).
    model
        The internal (or combined) identification model ``θ̂`` belongs to.
    theta_identified
        Base (``r``) or standard (``p``) parameters of ``model``.
    nominal_theta
        The nominal model; default the robot description's standard parameters with the
        effects at zero (:meth:`IdentificationModel.nominal_parameters`).
    bandwidth_hz, damping
        The same closed-loop bandwidth for all three: PD gains scaled by the nominal joint
        inertias at ``q = 0``, computed-torque gains on accelerations.
    """
    robot = simulator.robot
    nominal = model.nominal_parameters() if nominal_theta is None else np.asarray(nominal_theta, dtype=float)
    kp, kd = pd_gains(robot, bandwidth_hz=bandwidth_hz, damping=damping)
    kp_a, kd_a = computed_torque_gains(bandwidth_hz=bandwidth_hz, damping=damping, n_joints=robot.n_joints)
    controllers = (
        ("PD", PDController(kp, kd)),
        ("computed torque, nominal", ComputedTorqueController.from_model(model, nominal, kp=kp_a, kd=kd_a)),
        ("computed torque, identified", ComputedTorqueController.from_model(model, theta_identified, kp=kp_a, kd=kd_a)),
    )
    return TrackingComparison(
        tuple(
            tracking_experiment(simulator, trajectory, controller, label=label, periods=periods, warmup_periods=warmup_periods)
            for label, controller in controllers
        )
    )


__all__ = ["TrackingResult", "TrackingComparison", "tracking_experiment", "compare_controllers"]
