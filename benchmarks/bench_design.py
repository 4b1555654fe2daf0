"""Speed of the excitation design: IPOPT with exact AD gradients vs a SciPy SLSQP baseline.

The baseline is what a user would otherwise write: ``scipy.optimize.minimize(method="SLSQP")`` with
finite-difference gradients of the same cost (the same CasADi objective evaluated numerically),
the same linear bound constraints (also finite-differenced by SciPy), the same starts and the same
thread budget (one thread, :func:`dynamics.runtime.threads.single_threaded`). The issue's targets are
measured against it.

For context, the same SLSQP also runs on the cost written without this toolkit: the base regressor
by a Pinocchio loop (:mod:`pinocchio_baseline`, as in ``bench_identify.py``) and the criterion in
numpy; it agrees with the compiled cost to rounding (printed). That ratio shows what the toolkit
saves a user end to end, not the optimiser alone. All ratios are measured in this run.

The design's default solver runs IPOPT for ``DesignSettings.sqp_after`` iterations and an SQP method
from there; the same starts are also solved by IPOPT alone (``sqp_after=None``, the former default) in
the same run, and the whole design (:func:`oed.excitation.design_excitation` with these starts, its build
included) is timed end to end. For context, ``oed design`` with the same starts also runs in a new process
(imports, model build, compile cache, starts and the JSON file), with the compile cache as it is and with an
empty one (the first design on a machine).

    python benchmarks/bench_design.py [--starts 3] [--skip-5000] [--skip-pinocchio-5000] [--skip-kuka]
                                      [--skip-fresh] [--ipopt NAME=VALUE ...]
"""

from __future__ import annotations

import argparse
import os
import resource
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path

import numpy as np
import scipy.optimize

from dynamics.robots import load_robot
from dynamics.runtime.threads import single_threaded
from oed.bounds import JointBounds
from oed.excitation import DesignSettings, ExcitationDesign, design_excitation

from pinocchio_baseline import PinocchioRegressor

KUKA_URDF = Path(__file__).resolve().parents[1].parent / "shared" / "data" / "kuka_lwr4" / "kuka_lwr4.urdf"


def pinocchio_cost(problem: ExcitationDesign) -> Callable[[np.ndarray], float]:
    """The design objective as a user without this toolkit writes it: the trajectory sampled at the
    same cost samples, the base regressor by a Pinocchio loop (:mod:`pinocchio_baseline`), then
    the criterion of ``Y_bᵀY_b / N`` in numpy."""
    regressor = PinocchioRegressor(problem.identification_model)
    s = problem.settings
    t = np.arange(s.cost_samples) / s.cost_samples / s.frequency_hz
    columns = problem.identification_model.n_base

    def cost(x: np.ndarray) -> float:
        q, dq, ddq = problem.trajectory(x).evaluate(t)
        Y = regressor.base(q, dq, ddq).reshape(-1, columns)
        return problem.criterion.value(Y.T @ Y / s.cost_samples)

    return cost


def compiled_cost(problem: ExcitationDesign) -> Callable[[np.ndarray], float]:
    """The design's own compiled CasADi objective, evaluated numerically."""
    objective = problem.cost_function()
    return lambda x: float(objective(x))


def slsqp_start(problem: ExcitationDesign, x0: np.ndarray, cost: Callable[[np.ndarray], float] | None = None,
                max_iter: int = 500) -> tuple[float, float, int]:
    """One SLSQP start with finite-difference gradients of ``cost`` (default: the compiled
    objective); returns (seconds, cost at 1 kHz, iterations)."""
    cost = compiled_cost(problem) if cost is None else cost
    A, lower, upper = problem.constraint_matrix(problem.constraint_times())
    A = A.toarray()

    def margins(x):
        g = A @ x
        return np.concatenate([g - lower, upper - g])

    started = time.perf_counter()
    with single_threaded():  # the same thread budget as ExcitationDesign.solve
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


def ipopt_option(text: str) -> tuple[str, object]:
    """``NAME=VALUE`` with VALUE read as an int, a float or else a string (argparse type)."""
    name, separator, value = text.partition("=")
    if not separator or not name:
        raise argparse.ArgumentTypeError(f"expected NAME=VALUE, got {text!r}")
    for convert in (int, float):
        try:
            return name, convert(value)
        except ValueError:
            pass
    return name, value


def fresh_process(starts: int, empty_cache: bool) -> tuple[float, float]:
    """Wall and CPU seconds of ``oed design --robot puma560 --joints 3 --starts N`` in a new process (imports,
    model build, compile cache, the starts, the JSON file); ``empty_cache``: with ``$ROBOT_OED_CACHE`` an empty
    folder, so that the regressor and the information function are compiled as on a machine's first design."""
    with tempfile.TemporaryDirectory() as folder:
        environment = dict(os.environ, **({"ROBOT_OED_CACHE": folder} if empty_cache else {}))
        command = [sys.executable, "-m", "oed", "design", "--robot", "puma560", "--joints", "3", "--starts", str(starts),
                   "--seed", "0", "--quiet", "--out", str(Path(folder) / "design.json")]
        before = resource.getrusage(resource.RUSAGE_CHILDREN)
        started = time.perf_counter()
        subprocess.run(command, env=environment, check=True)
        wall = time.perf_counter() - started
        after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return wall, (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)


def verdict(value: float, target: float, larger_is_better: bool = True) -> str:
    met = value >= target if larger_is_better else value <= target
    return "met" if met else "NOT met"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--starts", type=int, default=3)
    parser.add_argument("--skip-5000", action="store_true", help="skip the SLSQP run at 5 000 samples")
    parser.add_argument("--skip-pinocchio-5000", action="store_true",
                        help="skip SLSQP on the Pinocchio cost at 5 000 samples (about 25 s)")
    parser.add_argument("--skip-kuka", action="store_true")
    parser.add_argument("--skip-fresh", action="store_true", help="skip `oed design` in a new process")
    parser.add_argument("--ipopt", action="append", default=[], metavar="NAME=VALUE", type=ipopt_option,
                        help="an IPOPT option for the IPOPT runs (repeatable), e.g. mu_strategy=monotone")
    args = parser.parse_args()
    options = DesignSettings(ipopt_options=tuple(args.ipopt))
    targets: list[str] = []

    robot = load_robot("puma560", joints=3)
    problem = ExcitationDesign(robot, "combined", settings=options)
    started = time.perf_counter()
    build = problem.build()
    problem.solve(problem.random_start(np.random.default_rng(99)))  # first call: lazy derivative set-up
    warm = time.perf_counter() - started
    print(f"PUMA 560 (3 joints), combined model, {problem.identification_model.n_base} base parameters, "
          f"{problem.n_variables} variables, {problem.settings.cost_samples} cost samples")
    print(f"  one-time build: {build:.3f} s (objective + solver construction, JIT), "
          f"{warm:.3f} s including a first solve (not counted below)")
    generator = np.random.default_rng(0)
    starts = [problem.random_start(generator) for _ in range(args.starts)]

    cpu = time.process_time()  # CPU time as well: the steadier figure when other jobs share the machine
    ip_times, ip_costs, ip_iterations = ipopt_starts(problem, starts)
    ip_cpu = time.process_time() - cpu
    print(f"  IPOPT -> SQP after {options.sqp_after} iterations (the default), 250 cost samples: per start "
          f"{np.mean(ip_times):.3f} s (max {np.max(ip_times):.3f} s), iterations {ip_iterations}, "
          f"costs {np.round(ip_costs, 3).tolist()}")
    alone = ExcitationDesign(robot, "combined", settings=replace(options, sqp_after=None))
    alone.build()
    alone.solve(alone.random_start(np.random.default_rng(99)))
    alone_times, alone_costs, alone_iterations = ipopt_starts(alone, starts)
    print(f"  IPOPT alone (sqp_after=None, the former default): per start {np.mean(alone_times):.3f} s, "
          f"iterations {alone_iterations}, costs {np.round(alone_costs, 3).tolist()}; best {min(alone_costs):.3f} "
          f"against {min(ip_costs):.3f}, {np.sum(alone_times) / np.sum(ip_times):.2f}x the time")

    sl = [slsqp_start(problem, x0) for x0 in starts]
    sl_times, sl_costs = [s[0] for s in sl], [s[1] for s in sl]
    print(f"  SLSQP-FD, 250 cost samples: per start {np.mean(sl_times):.3f} s, iterations {[s[2] for s in sl]}, "
          f"costs {np.round(sl_costs, 3).tolist()}")
    ratio = np.sum(sl_times) / np.sum(ip_times)
    not_worse = [i <= s + 1e-2 for i, s in zip(ip_costs, sl_costs)]
    print(f"  cost at 1 kHz per start, IPOPT - SLSQP: {np.round(np.subtract(ip_costs, sl_costs), 3).tolist()} "
          f"(negative: IPOPT better); best IPOPT {min(ip_costs):.3f} vs SLSQP {min(sl_costs):.3f}")
    targets.append(f"IPOPT >= 10x faster than SLSQP-FD at 250 samples: {ratio:.1f}x -> {verdict(ratio, 10)}")
    targets.append(f"IPOPT cost equal or better (within 0.01) on every start: {not_worse} -> "
                   f"{'met' if all(not_worse) else 'NOT met'}")
    user_cost, own_cost = pinocchio_cost(problem), compiled_cost(problem)
    agreement = max(abs(user_cost(x0) - own_cost(x0)) for x0 in starts)
    cpu = time.process_time()
    pin_runs = [slsqp_start(problem, x0, user_cost) for x0 in starts]
    pin_cpu = time.process_time() - cpu
    pin_ratio = np.sum([r[0] for r in pin_runs]) / np.sum(ip_times)
    print(f"  SLSQP-FD on a Pinocchio/numpy cost (what a user without this toolkit writes; agrees with the "
          f"compiled cost to {agreement:.1e}), 250 samples: per start {np.mean([r[0] for r in pin_runs]):.3f} s, "
          f"costs {np.round([r[1] for r in pin_runs], 3).tolist()}; IPOPT {pin_ratio:.1f}x faster")
    pin_total = np.sum([r[0] for r in pin_runs])
    targets.append(f"design >= 10x faster than SLSQP-FD on the Pinocchio/numpy cost, {len(starts)} starts, "
                   f"250 samples: {pin_ratio:.1f}x -> {verdict(pin_ratio, 10)} (IPOPT alone: "
                   f"{pin_total / np.sum(alone_times):.1f}x)")
    fresh = ExcitationDesign(robot, "combined", settings=options)
    started, cpu = time.perf_counter(), time.process_time()
    design = design_excitation(robot, problem=fresh, starts=len(starts), seed=0)
    end_to_end, end_to_end_cpu = time.perf_counter() - started, time.process_time() - cpu
    print(f"  the whole design (design_excitation, the same {len(starts)} starts, build and first-call set-up "
          f"included): {end_to_end:.2f} s, best cost {design.cost:.3f}; {pin_total / end_to_end:.1f}x faster than "
          f"SLSQP-FD on the Pinocchio/numpy cost")
    print(f"  in CPU time: the {len(starts)} starts {ip_cpu:.2f} s, the whole design {end_to_end_cpu:.2f} s, SLSQP-FD "
          f"on the Pinocchio/numpy cost {pin_cpu:.2f} s: {pin_cpu / ip_cpu:.1f}x and {pin_cpu / end_to_end_cpu:.1f}x")
    context = [f"context: the whole design including its build vs SLSQP-FD on the Pinocchio/numpy cost: "
               f"{pin_total / end_to_end:.1f}x (in CPU time {pin_cpu / end_to_end_cpu:.1f}x)"]
    if not args.skip_fresh:
        for empty_cache, label in ((False, "compile cache as it is"), (True, "empty compile cache")):
            wall, cpu = fresh_process(len(starts), empty_cache)
            print(f"  `oed design` in a new process ({label}; imports, build, {len(starts)} starts, JSON): {wall:.2f} s "
                  f"wall, {cpu:.2f} s CPU; {pin_total / wall:.1f}x faster than SLSQP-FD on the Pinocchio/numpy cost")
            context.append(f"context: `oed design` in a new process, {label}, vs SLSQP-FD on the Pinocchio/numpy "
                           f"cost: {pin_total / wall:.1f}x ({wall:.2f} s wall)")
    targets.append(f"one PUMA combined start < 1 s after the build: max {np.max(ip_times):.3f} s -> "
                   f"{verdict(np.max(ip_times), 1.0, larger_is_better=False)}")

    if not args.skip_5000:
        fine = ExcitationDesign(robot, "combined", settings=replace(options, cost_samples=5000))
        fine.build()
        fine_ip = ipopt_starts(fine, starts[:1])
        print(f"  IPOPT, 5000 cost samples: {fine_ip[0][0]:.2f} s, cost {fine_ip[1][0]:.3f} "
              f"(250 samples gave {ip_costs[0]:.3f} from the same start)")
        time_5000, cost_5000, iterations_5000 = slsqp_start(fine, starts[0])
        print(f"  SLSQP-FD, 5000 cost samples: {time_5000:.2f} s, {iterations_5000} iterations, cost {cost_5000:.3f}")
        ratio_5000 = time_5000 / ip_times[0]
        print(f"  ratio: SLSQP-FD at 5000 samples / IPOPT at 250 samples = {ratio_5000:.1f}x; "
              f"/ IPOPT at 5000 samples = {time_5000 / fine_ip[0][0]:.1f}x")
        targets.append(f"IPOPT (250) >= 100x faster than SLSQP-FD at 5000 samples: {ratio_5000:.1f}x -> "
                       f"{verdict(ratio_5000, 100)}")
        if not args.skip_pinocchio_5000:
            time_pin, cost_pin, iterations_pin = slsqp_start(fine, starts[0], pinocchio_cost(fine))
            print(f"  SLSQP-FD on the Pinocchio/numpy cost, 5000 samples: {time_pin:.1f} s, {iterations_pin} iterations, "
                  f"cost {cost_pin:.3f}")
            context.append(f"context: IPOPT (250) vs SLSQP-FD on a Pinocchio/numpy cost at 5000 samples: "
                           f"{time_pin / ip_times[0]:.0f}x")

    if not args.skip_kuka and KUKA_URDF.exists():
        kuka = load_robot(urdf=KUKA_URDF)
        # stated bounds: 90 % of the URDF position range, the URDF velocity limits, 10 rad/s² everywhere
        bounds = JointBounds.from_robot(kuka, ddq_max=10.0, scale=0.9)
        started = time.perf_counter()
        design = ExcitationDesign(kuka, "internal", bounds, settings=options)
        build = design.build()
        result = design.solve(design.random_start(np.random.default_rng(0)))
        total = time.perf_counter() - started
        print(f"KUKA LWR4+ (7 joints, internal model, {design.identification_model.n_base} base parameters): "
              f"build {build:.2f} s, one start {result.time_s:.2f} s ({result.iterations} iterations, {result.status}), "
              f"total {total:.2f} s, cost {result.cost:.2f}, feasible at 1 kHz: {result.feasible}")
        targets.append(f"7-DOF KUKA design < 30 s (build + one start): {total:.2f} s -> "
                       f"{verdict(total, 30.0, larger_is_better=False)}")

    print("Targets (issue 3, ratios from this run):")
    for line in targets:
        print(f"  {line}")
    for line in context:
        print(f"  {line}")


if __name__ == "__main__":
    main()
