"""Benchmark: ERLS (ARMAX, extended recursive least squares) compiled CasADi mapaccum vs a per-sample numpy loop.

Both back ends run on the same data in the same process; the script prints samples per second and the
ratio, and checks that the two agree. Usage: ``python benchmarks/bench_erls.py [--samples N]``.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from estimation.estimators.arx import ARXEstimator
from estimation.estimators.recursive import ExtendedRecursiveLeastSquares


def _best_of(repeats: int, run) -> float:
    best = np.inf
    for _ in range(repeats):
        start = time.perf_counter()
        run()
        best = min(best, time.perf_counter() - start)
    return best


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--samples", type=int, default=1_000_000, help="samples for the compiled recursion")
    parser.add_argument("--numpy-samples", type=int, default=50_000, help="samples for the numpy loop (it is slow)")
    args = parser.parse_args()
    rng = np.random.default_rng(0)
    n = args.samples
    u, e = rng.standard_normal(n), 0.1 * rng.standard_normal(n)
    y = ARXEstimator.simulate_structure(a=[-1.5, 0.7], b=[1.0], c=[0.5], nk=1, u=u, e=e)
    settings = dict(na=2, nb=1, nc=1, forgetting=0.999)

    start = time.perf_counter()
    ExtendedRecursiveLeastSquares(backend="compiled", **settings).fit(u[:1000], y[:1000])  # code generation + gcc (cached)
    setup = time.perf_counter() - start
    t_compiled = _best_of(3, lambda: ExtendedRecursiveLeastSquares(backend="compiled", **settings).fit(u, y))
    t_vm = _best_of(1, lambda: ExtendedRecursiveLeastSquares(backend="vm", **settings).fit(u[: args.numpy_samples], y[: args.numpy_samples]))
    m = args.numpy_samples
    t_numpy = _best_of(1, lambda: ExtendedRecursiveLeastSquares(backend="numpy", **settings).fit(u[:m], y[:m]))

    ref = ExtendedRecursiveLeastSquares(backend="numpy", **settings).fit(u[:m], y[:m])
    fast = ExtendedRecursiveLeastSquares(backend="compiled", **settings).fit(u[:m], y[:m])
    gap = float(np.max(np.abs(fast.theta_ - ref.theta_)))

    rate_compiled, rate_vm, rate_numpy = n / t_compiled, m / t_vm, m / t_numpy
    print(f"ERLS ARMAX(2,1,1), lambda=0.999; first compiled call incl. codegen/cache lookup: {setup:.2f} s")
    print(f"compiled CasADi mapaccum : {rate_compiled / 1e6:8.2f} M samples/s ({n} samples, best of 3)")
    print(f"CasADi virtual machine   : {rate_vm / 1e6:8.3f} M samples/s ({m} samples)")
    print(f"numpy per-sample loop    : {rate_numpy / 1e6:8.3f} M samples/s ({m} samples)")
    print(f"speed-up compiled/numpy  : {rate_compiled / rate_numpy:8.1f} x   (target >= 50 x)")
    print(f"max |theta_compiled - theta_numpy| on {m} samples: {gap:.2e}")
    return 0 if gap < 1e-9 else 1


if __name__ == "__main__":
    raise SystemExit(main())
