"""Why IPOPT needs many iterations on the excitation design (the figures quoted for issue 3).

One PUMA combined start (the design's own objective, constraints and IPOPT settings), three ways:

1. IPOPT's L-BFGS, as the design runs it: how many curvature pairs IPOPT uses, skips (``sᵀy``
   not positive: −log det(M(x)) is not convex in the Fourier coefficients) and how often it
   resets its memory, read from IPOPT's own log (``file_print_level 7``).
2. A Powell-damped BFGS matrix handed to IPOPT as the exact Hessian (``hess_lag``).
3. The exact Hessian (finite differences of the AD gradient) with its negative eigenvalues
   clipped, handed to IPOPT the same way: about the fewest iterations a Newton-type IPOPT gets
   here, at 33 gradients an iteration.

    python benchmarks/design_curvature.py [--start 0]
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import casadi
import numpy as np

from dynamics.robots import load_robot
from dynamics.runtime.threads import single_threaded
from oed.excitation import ExcitationDesign
from oed.design_solver import ipopt_solver


class _HessianCallback(casadi.Callback):
    """``hess_lag`` for linear constraints: ``lam_f · H(x)``, with ``H`` from :meth:`matrix`."""

    def __init__(self, name: str, gradient: casadi.Function, n: int, m: int) -> None:
        casadi.Callback.__init__(self)
        self.gradient, self.n, self.m = gradient, n, m
        self.construct(name, {})

    def get_n_in(self) -> int:
        return 4

    def get_n_out(self) -> int:
        return 1

    def get_sparsity_in(self, index: int) -> casadi.Sparsity:
        return [casadi.Sparsity.dense(self.n, 1), casadi.Sparsity.dense(0, 1), casadi.Sparsity.dense(1, 1),
                casadi.Sparsity.dense(self.m, 1)][index]

    def get_sparsity_out(self, index: int) -> casadi.Sparsity:
        return casadi.Sparsity.upper(self.n)

    def eval(self, arguments):
        x, lam_f = np.asarray(arguments[0]).reshape(-1), float(arguments[2])
        return [casadi.triu(casadi.DM(lam_f * self.matrix(x)))]

    def grad(self, x: np.ndarray) -> np.ndarray:
        return np.asarray(self.gradient(x)).reshape(-1)


class DampedBFGS(_HessianCallback):
    """Powell-damped BFGS (as in SLSQP) updated from the gradients at successive iterates."""

    def __init__(self, *arguments) -> None:
        self.B, self.x, self.g, self.damped, self.updates = None, None, None, 0, 0
        super().__init__("damped_bfgs", *arguments)

    def matrix(self, x):
        if self.x is None or np.any(x != self.x):
            g = self.grad(x)
            if self.x is not None:
                s, y = x - self.x, g - self.g
                if self.B is None:
                    self.B = np.eye(self.n) * (y @ y / (s @ y) if s @ y > 0 else 1.0)
                Bs = self.B @ s
                sBs, sy = s @ Bs, s @ y
                if sBs > 1e-14:
                    theta = 1.0 if sy >= 0.2 * sBs else 0.8 * sBs / (sBs - sy)
                    self.damped += theta < 1.0
                    r = theta * y + (1 - theta) * Bs
                    self.B = self.B - np.outer(Bs, Bs) / sBs + np.outer(r, r) / (s @ r)
                    self.updates += 1
            self.x, self.g = x, g
        return self.B if self.B is not None else np.eye(self.n)


class ClippedHessian(_HessianCallback):
    """Finite differences of the exact gradient, symmetrised, eigenvalues clipped at ``floor``."""

    def __init__(self, *arguments, floor: float = 1e-3, step: float = 1e-6) -> None:
        self.floor, self.step = floor, step
        super().__init__("clipped_hessian", *arguments)

    def matrix(self, x):
        g = self.grad(x)
        H = np.array([(self.grad(x + self.step * e) - g) / self.step for e in np.eye(self.n)])
        values, vectors = np.linalg.eigh((H + H.T) / 2)
        return (vectors * np.maximum(values, self.floor)) @ vectors.T


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--start", type=int, default=0, help="which of the benchmark's random starts")
    args = parser.parse_args()
    problem = ExcitationDesign(load_robot("puma560", joints=3), "combined")
    problem.build()
    generator = np.random.default_rng(0)  # the starts of bench_design.py
    x0 = [problem.random_start(generator) for _ in range(args.start + 1)][-1]
    s = problem.settings
    A, lower, upper = problem.constraint_matrix(problem.constraint_times())
    objective = problem.cost_function()
    x = casadi.MX.sym("x", problem.n_variables)
    gradient = casadi.Function("gradient", [x], [casadi.gradient(objective(x), x)])
    common = dict(tol=s.tol, acceptable_tol=s.acceptable_tol, acceptable_iter=s.acceptable_iter, max_iter=s.max_iter,
                  lbfgs_memory=s.lbfgs_memory, verbose=False, warm=False)
    print(f"PUMA 560 combined, start {args.start}: {problem.n_variables} variables, {A.shape[0]} constraint rows")
    cost_and_gradient = casadi.Function("cost_and_gradient", [x], [objective(x), gradient(x)])
    for label, function in (("cost", objective), ("cost + gradient", cost_and_gradient)):
        function(x0)
        started = time.perf_counter()
        for _ in range(200):
            function(x0)
        print(f"  {label} at {s.cost_samples} samples: {(time.perf_counter() - started) / 200 * 1e3:.2f} ms")

    def run(label: str, solver: casadi.Function) -> None:
        started = time.perf_counter()
        solution = solver(x0=x0, lbg=lower, ubg=upper)
        elapsed = time.perf_counter() - started
        stats = solver.stats()
        cost = problem.evaluate(np.asarray(solution["x"]).reshape(-1))["cost"]
        evaluations = sum(value for key, value in stats.items() if key.startswith("t_wall_nlp_"))
        own = (elapsed - evaluations - stats.get("t_wall_callback_fun", 0.0)) / max(stats["iter_count"], 1)
        print(f"  {label:<34s} {stats['iter_count']:4d} iterations, {elapsed:6.2f} s, {stats['return_status']}, "
              f"cost at 1 kHz {cost:.2f}; function evaluations {evaluations:.3f} s, "
              f"IPOPT's own work {own * 1e3:.1f} ms an iteration")

    with single_threaded(), tempfile.TemporaryDirectory() as folder:
        log = Path(folder) / "ipopt.log"
        run("IPOPT L-BFGS (the design's)", ipopt_solver(objective, A, **common))
        logged = ipopt_solver(objective, A, **common, ipopt_options={"output_file": str(log), "file_print_level": 7})
        logged(x0=x0, lbg=lower, ubg=upper)  # the same run again, its detailed log to a file
        text = log.read_text()
        print(f"    L-BFGS pairs: {text.count('Perform the update.')} used, {text.count('Skip the update.')} skipped "
              f"(sᵀy not positive), memory reset {text.count('Resetting Limited-Memory Update.')} times")
        for callback in (DampedBFGS(gradient, problem.n_variables, A.shape[0]),
                         ClippedHessian(gradient, problem.n_variables, A.shape[0])):
            solver = ipopt_solver(objective, A, **common, ipopt_options={"hessian_approximation": "exact"},
                                  nlpsol_options={"hess_lag": callback})
            run(f"IPOPT + {callback.name()}", solver)
            if isinstance(callback, DampedBFGS) and callback.B is not None:
                print(f"    {callback.updates} updates, {callback.damped} damped; condition number of the "
                      f"final matrix {np.linalg.cond(callback.B):.1e}")


if __name__ == "__main__":
    main()
