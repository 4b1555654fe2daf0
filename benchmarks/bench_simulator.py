"""Simulator speed: steps per second at 1 kHz, PUMA 560 (3 joints), against a bare Pinocchio ABA loop.

Baseline, measured in the same run: the same number of RK4 steps calling only ``pinocchio.aba``
(no controller, effects or recording). Prints steps/s and the ratio simulator / baseline.
"""

from __future__ import annotations

import time

import numpy as np
import pinocchio as pin

from dynamics.simulation.controllers import ComputedTorqueController, computed_torque_gains
from dynamics.models import build_model
from dynamics.pinocchio_bridge import to_pinocchio
from dynamics.robots import load_robot
from dynamics.simulation.simulator import NoiseModel, Simulator
from oed.fourier import FourierTrajectory


def baseline_steps_per_second(robot, steps: int) -> float:
    model = to_pinocchio(robot)
    data = model.createData()
    q, dq, tau, h = np.zeros(3), np.zeros(3), np.ones(3), 1e-3
    started = time.perf_counter()
    for _ in range(steps):
        a1 = pin.aba(model, data, q, dq, tau).copy()
        a2 = pin.aba(model, data, q + h / 2 * dq, dq + h / 2 * a1, tau).copy()
        a3 = pin.aba(model, data, q + h / 2 * dq, dq + h / 2 * a2, tau).copy()
        a4 = pin.aba(model, data, q + h * dq, dq + h * a3, tau).copy()
        q, dq = q + h * dq, dq + h / 6 * (a1 + 2 * a2 + 2 * a3 + a4)
    return steps / (time.perf_counter() - started)


def main() -> None:
    robot = load_robot("puma560", joints=3)
    generator = np.random.default_rng(0)
    trajectory = FourierTrajectory(0.2, np.zeros(3), generator.uniform(-0.15, 0.15, (3, 5)),
                                   generator.uniform(-0.15, 0.15, (3, 5)))
    baseline = baseline_steps_per_second(robot, 5000)
    print(f"baseline (bare RK4 on pinocchio.aba): {baseline:10.0f} steps/s")
    model = build_model(robot, "internal")
    kp, kd = computed_torque_gains(n_joints=3)
    cases = {
        "PD, viscous": (Simulator(robot, noise=NoiseModel.none()), None),
        "PD, viscous+coulomb+offset+armature": (Simulator(robot, "coulomb,offset,armature"), None),
        "computed torque (base parameters)": (
            Simulator(robot),
            ComputedTorqueController.from_model(model, model.base.to_base(model.nominal_parameters()), kp=kp, kd=kd),
        ),
    }
    for label, (simulator, controller) in cases.items():
        result = simulator.run(trajectory, controller, seed=0)
        rate = result.t.shape[0] / result.elapsed_s
        print(f"{label:<40s} {rate:10.0f} steps/s  ratio to baseline {rate / baseline:5.2f}  "
              f"(5 s at 1 kHz in {result.elapsed_s:.2f} s)")


if __name__ == "__main__":
    main()
