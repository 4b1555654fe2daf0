"""Speed of the excitation design: IPOPT with exact AD gradients vs a SciPy SLSQP baseline.

The baseline is what a user would otherwise write: ``scipy.optimize.minimize(method="SLSQP")`` with
finite-difference gradients of the same cost (the same CasADi objective evaluated numerically),
the same linear bound constraints (also finite-differenced by SciPy) and the same starts.
All ratios are measured in this run.

    python benchmarks/bench_design.py [--starts 3] [--skip-5000] [--skip-kuka]
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np
import scipy.optimize

from dynamics.robots import load_robot
from oed.bounds import JointBounds
from oed.design import DesignSettings, ExcitationDesign

KUKA_URDF = Path(__file__).resolve().parents[1].parent / "shared" / "data" / "kuka_lwr4" / "kuka_lwr4.urdf"


def slsqp_start(problem: ExcitationDesign, x0: np.ndarray, max_iter: int = 500) -> tuple[float, float, int]:
    """One SLSQP start with finite-difference gradients; returns (seconds, cost at 1 kHz, iterations)."""
    objective = problem.cost_function()
    A, lower, upper = problem.constraint_matrix(problem.constraint_times())
    A = A.toarray()

    def cost(x):
        return float(objective(x))

    def margins(x):
        g = A @ x
        return np.concatenate([g - lower, upper - g])

    started = time.perf_counter()
    solution = scipy.optimize.minimize(cost, x0, method="SLSQP", constraints=[{"type": "ineq", "fun": margins}],
                                       options={"maxiter": max_iter, "ftol": 1e-9})
    elapsed = time.perf_counter() - started
    x = problem.shrink_to_bounds(solution.x)  # same 1 kHz guarantee as the IPOPT path
    return elapsed, problem.evaluate(x)["cost"], int(solution.nit)


def ipopt_starts(problem: ExcitationDesign, starts: list[np.ndarray]) -> tuple[list[float], list[float], list[int]]:
    times, costs, iterations = [], [], []
    for index, x0 in enumerate(starts):
        result = problem.solve(x0, index)
        times.append(result.time_s)
        costs.append(result.cost)
        iterations.append(result.iterations)
    return times, costs, iterations


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--starts", type=int, default=3)
    parser.add_argument("--skip-5000", action="store_true", help="skip the (slow) SLSQP run at 5 000 samples")
    parser.add_argument("--skip-kuka", action="store_true")
    args = parser.parse_args()

    robot = load_robot("puma560", joints=3)
    problem = ExcitationDesign(robot, "combined")
    started = time.perf_counter()
    build = problem.build()
    problem.solve(problem.random_start(np.random.default_rng(99)))  # first call: lazy derivative set-up
    warm = time.perf_counter() - started
    print(f"PUMA 560 (3 joints), combined model, {problem.identification_model.n_base} base parameters, "
          f"{problem.n_variables} variables")
    print(f"  one-time build: {build:.3f} s (solver construction), {warm:.3f} s including a first solve")
    generator = np.random.default_rng(0)
    starts = [problem.random_start(generator) for _ in range(args.starts)]

    ip_times, ip_costs, ip_iterations = ipopt_starts(problem, starts)
    print(f"  IPOPT, 250 cost samples: per start {np.mean(ip_times):.3f} s (max {np.max(ip_times):.3f} s), "
          f"iterations {ip_iterations}, costs {np.round(ip_costs, 3).tolist()}")

    sl = [slsqp_start(problem, x0) for x0 in starts]
    sl_times, sl_costs = [s[0] for s in sl], [s[1] for s in sl]
    print(f"  SLSQP-FD, 250 cost samples: per start {np.mean(sl_times):.3f} s, iterations {[s[2] for s in sl]}, "
          f"costs {np.round(sl_costs, 3).tolist()}")
    print(f"  ratio (same sample count): SLSQP-FD / IPOPT = {np.sum(sl_times) / np.sum(ip_times):.1f}x; "
          f"best cost IPOPT {min(ip_costs):.3f} vs SLSQP {min(sl_costs):.3f}; "
          f"per start IPOPT <= SLSQP + 0.01: {[i <= s + 1e-2 for i, s in zip(ip_costs, sl_costs)]}")

    if not args.skip_5000:
        fine = ExcitationDesign(robot, "combined", settings=DesignSettings(cost_samples=5000))
        fine.build()
        fine_ip = ipopt_starts(fine, starts[:1])
        print(f"  IPOPT, 5000 cost samples: {fine_ip[0][0]:.2f} s, cost {fine_ip[1][0]:.3f} "
              f"(250 samples gave {ip_costs[0]:.3f} from the same start)")
        time_5000, cost_5000, iterations_5000 = slsqp_start(fine, starts[0])
        print(f"  SLSQP-FD, 5000 cost samples: {time_5000:.1f} s, {iterations_5000} iterations, cost {cost_5000:.3f}")
        print(f"  ratio: SLSQP-FD at 5000 samples / IPOPT at 250 samples = {time_5000 / ip_times[0]:.0f}x; "
              f"/ IPOPT at 5000 samples = {time_5000 / fine_ip[0][0]:.1f}x")

    if not args.skip_kuka and KUKA_URDF.exists():
        kuka = load_robot(urdf=KUKA_URDF)
        # stated bounds: 90 % of the URDF position range, the URDF velocity limits, 10 rad/s² everywhere
        bounds = JointBounds.from_robot(kuka, ddq_max=10.0, scale=0.9)
        started = time.perf_counter()
        design = ExcitationDesign(kuka, "internal", bounds)
        build = design.build()
        result = design.solve(design.random_start(np.random.default_rng(0)))
        total = time.perf_counter() - started
        print(f"KUKA LWR4+ (7 joints, internal model, {design.identification_model.n_base} base parameters): "
              f"build {build:.2f} s, one start {result.time_s:.2f} s ({result.iterations} iterations, {result.status}), "
              f"total {total:.2f} s, cost {result.cost:.2f}, feasible at 1 kHz: {result.feasible}")


if __name__ == "__main__":
    main()
