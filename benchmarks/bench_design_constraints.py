"""Cost of a design a real robot can run (issue #36) against the unconstrained design, in the same run.

On the 6-joint arm ``dynamics/robots/arm6_collision.urdf`` (primitive collision geometry, effort limits,
declared friction), the same starts are solved

1. unconstrained (position, velocity and acceleration bounds only), and
2. with every constraint of issue #36: ``--torque-limits``, ``--start Q``, ``--floor 0`` and
   ``--self-collision`` (margin 0.02 m).

Both designs are then checked **independently** on the 1 kHz grid of the whole experiment (ramps in and
out, every period): torques by Pinocchio's RNEA plus the declared friction, the floor by the exact lowest
points of the shapes (Pinocchio placements), self-collision by coal signed distances
(``pinocchio.computeDistances``), the bounds, and rest at both ends. Printed: the wall time of each design,
the D-efficiency ``exp((L_u − L_c)/p)`` (``L = −log det`` of the information per sample of the period,
``p`` base parameters) and the worst margins of both designs.

    python benchmarks/bench_design_constraints.py [--starts 4] [--model internal] [--harmonics 5]
"""

from __future__ import annotations

import argparse
import os
import time
from importlib import resources
from pathlib import Path

import numpy as np
import pinocchio as pin

from dynamics.collision import read_collision_geometry
from dynamics.models import build_model
from dynamics.robots import load_robot
from oed.bounds import JointBounds
from oed.excitation import DesignSettings, design_excitation
from oed.design_constraints import constraints_from_options
from oed.criteria import information_matrix
from oed.rest_ramps import RestStart, experiment_samples, rest_of

URDF = Path(str(resources.files("dynamics.robots").joinpath("arm6_collision.urdf")))
START = np.array([0.0, 0.3, 0.6, 0.0, 0.5, 0.0])


def independent_check(trajectory, rest, periods, bounds, geometry) -> dict[str, float]:
    """Worst margins on the 1 kHz grid of the whole experiment, without the design's own code paths."""
    _, q, dq, ddq = experiment_samples(trajectory, rest, 1000.0, periods)
    model = pin.buildModelFromUrdf(str(URDF))
    data = model.createData()
    tau = np.array([pin.rnea(model, data, a, b, c) for a, b, c in zip(q, dq, ddq)])
    tau += np.asarray(model.damping) * dq + np.asarray(model.friction) * np.sign(dq)
    joints = np.array([primitive.joint for primitive in geometry.primitives])
    lowest = np.array([geometry.lowest_points(sample)[joints > 0].min() for sample in q])
    distances = geometry.pair_distances(q, geometry.non_adjacent_pairs())
    excess = bounds.excess(q, dq, ddq)
    return {
        "torque_margin_Nm": float((np.asarray(model.effortLimit) - np.abs(tau)).min()),
        "floor_margin_m": float(lowest.min()),
        "collision_distance_m": float(distances.min()),
        "bound_excess": float(max(value.max() for value in excess.values())),
        "rest_error": float(max(np.abs(dq[[0, -1]]).max(), np.abs(ddq[[0, -1]]).max(),
                                np.abs(q[[0, -1]] - START).max()) if rest is not None else np.nan),
        "samples": int(q.shape[0]),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--starts", type=int, default=4)
    parser.add_argument("--model", default="internal")
    parser.add_argument("--harmonics", type=int, default=5)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    robot = load_robot(urdf=URDF)
    bounds = JointBounds.from_robot(robot, ddq_max=8.0)
    geometry = read_collision_geometry(URDF, robot)
    settings = DesignSettings(harmonics=args.harmonics)
    common = dict(model=args.model, bounds=bounds, starts=args.starts, seed=args.seed, settings=settings)

    started, cpu = time.perf_counter(), time.process_time()
    free = design_excitation(robot, **common)
    free_time, free_cpu = time.perf_counter() - started, time.process_time() - cpu
    constraints = constraints_from_options(robot, URDF, torque_limits=True, floor=0.0, self_collision=True,
                                           collision_margin=0.02)
    rest = RestStart(START)
    started, cpu = time.perf_counter(), time.process_time()
    held = design_excitation(robot, constraints=constraints, rest=rest, **common)
    held_time, held_cpu = time.perf_counter() - started, time.process_time() - cpu

    model = build_model(robot, args.model, ("viscous",))
    p = model.n_base
    efficiency = float(np.exp((free.cost - held.cost) / p))
    rest, periods = rest_of(held.trajectory)  # the rest start as designed (its ramp resolved)

    def log_det_per_sample(trajectory, rest, periods) -> float:
        _, q, dq, ddq = experiment_samples(trajectory, rest, 1000.0, periods)
        return float(np.linalg.slogdet(information_matrix(model.evaluate_base(q, dq, ddq)) / q.shape[0])[1])

    whole = float(np.exp((log_det_per_sample(held.trajectory, rest, periods)
                          - log_det_per_sample(free.trajectory, None, 1)) / p))
    free_check = independent_check(free.trajectory, None, 1, bounds, geometry)
    held_check = independent_check(held.trajectory, rest, periods, bounds, geometry)
    print(f"arm6 ({robot.n_joints} joints), {args.model} model, p = {p} base parameters, {args.starts} starts, "
          f"{args.harmonics} harmonics")
    print(f"unconstrained: {free_time:6.1f} s wall, {free_cpu:6.1f} s CPU, cost {free.cost:.3f}, "
          f"successful starts {sum(s.success for s in free.starts)}/{args.starts}")
    print(f"constrained  : {held_time:6.1f} s wall, {held_cpu:6.1f} s CPU, cost {held.cost:.3f}, "
          f"successful starts {sum(s.success for s in held.starts)}/{args.starts}, "
          f"iterations {[s.iterations for s in held.starts]}, refinements {[s.refinements for s in held.starts]}")
    print(f"time ratio constrained/unconstrained: {held_time / free_time:.2f} wall, {held_cpu / free_cpu:.2f} CPU; "
          f"load average at the end {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores")
    print(f"D-efficiency exp((L_u - L_c)/p) of the period: {efficiency:.3f}; of the whole experiment (ramps "
          f"included, per sample) against the unconstrained period: {whole:.3f}")
    experiment = held.trajectory.metadata["experiment"]
    print(f"experiment: ramps of {experiment['ramp_s']} s around {periods} periods ({experiment['duration_s']} s); "
          f"D-efficiency per sample of the whole experiment against its period by periods: "
          f"{[round(value, 3) for value in experiment['d_efficiency_by_periods']]}")
    print("independent check on the 1 kHz grid (torque N·m, floor m, distance m; bounds excess; rest error):")
    for name, check in (("unconstrained (one period)", free_check), ("constrained (whole experiment)", held_check)):
        print(f"  {name:32s} " + ", ".join(f"{key} {value:.4g}" for key, value in check.items()))
    for entry in held.trajectory.metadata["constraints"]:
        print(f"  design file: {entry['name']:15s} worst margin {entry['worst_margin']:.4g} {entry['unit']} at "
              f"{entry['worst_at']} (t = {entry['worst_t_s']:.3f} s)")


if __name__ == "__main__":
    main()
