"""Speed of the mapped internal regressor against Pinocchio's regressor in a Python loop.

Issue 2's target: evaluating the internal regressor over 5 000 samples at least 10x faster than
``pinocchio.computeJointTorqueRegressor`` called in a Python loop (each result copied into the
stacked array, as an identification needs). All figures are measured in this run; the one-time
costs (graph build, C code generation and compilation) are reported apart.

Where the time goes, line by line: the CasADi virtual machine; the compiled code called through
CasADi's ``map`` over ``casadi.external`` (a mutex and sparsity checks at every sample); the C
sample loop alone (``<name>_samples`` into a preallocated output: the floor); the same through
:class:`SampleEvaluator` (adds the output allocation and the checks); and ``model.evaluate``
(adds the state checks and the reshape to ``(N, rows, p)``, a view; two threads above a work
threshold, which pays only when the second core is free).

Run: ``python benchmarks/bench_regressor.py`` (add ``--samples N``).
"""

from __future__ import annotations

import argparse
import ctypes
import time

import numpy as np
import pinocchio as pin

from dynamics.codegen.compiled import SampleEvaluator, cache_directory, compile_function
from dynamics.models import build_model
from dynamics.pinocchio_bridge import to_pinocchio
from dynamics.robots import load_robot


def best_time(function, repeats: int = 7) -> float:
    function()
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        function()
        times.append(time.perf_counter() - start)
    return min(times)


def run(joints: int, n_samples: int) -> None:
    robot = load_robot("puma560", joints=joints)
    start = time.perf_counter()
    model = build_model(robot, "internal", effects=None)
    build = time.perf_counter() - start
    generator = np.random.default_rng(0)
    q, dq, ddq = (generator.normal(size=(n_samples, joints)) for _ in range(3))

    pin_model = to_pinocchio(robot)
    pin_data = pin_model.createData()
    stacked = np.empty((n_samples, joints, 10 * joints))

    def pinocchio_loop():
        for index in range(n_samples):
            stacked[index] = pin.computeJointTorqueRegressor(pin_model, pin_data, q[index], dq[index], ddq[index])

    function = model._evaluators["full"].function
    mapped = function.map(n_samples)

    def vm_with_conversion():  # the naive way: DM in, DM out, np.asarray
        return np.asarray(mapped(q.T, dq.T, ddq.T))

    vm = SampleEvaluator(function, backend="vm")
    compiled = SampleEvaluator(function, backend="auto")
    # always split (model.evaluate splits only above a work threshold: 6 joints yes, 3 joints no)
    threaded = SampleEvaluator(
        function, backend="auto", threads=2, min_samples_per_thread=SampleEvaluator.MIN_SAMPLES_PER_THREAD
    )
    start = time.perf_counter()
    compiled(q[:1], dq[:1], ddq[:1])
    compile_time = time.perf_counter() - start

    output = np.empty((n_samples, function.numel_out(0)))
    buffer, trigger = compile_function(function).map(n_samples).buffer()
    for index, values in enumerate((q, dq, ddq)):
        buffer.set_arg(index, memoryview(values))
    buffer.set_res(0, memoryview(output))
    loop, pointers = compiled.sample_loop, (ctypes.c_void_p * 3)(q.ctypes.data, dq.ctypes.data, ddq.ctypes.data)

    reused = np.empty_like(model.evaluate(q, dq, ddq))
    reference = best_time(pinocchio_loop)
    timings = {
        "casadi VM, DM conversion": best_time(vm_with_conversion),
        "casadi VM, zero-copy buffers": best_time(lambda: vm(q, dq, ddq)),
        "compiled C, CasADi map over the external": best_time(trigger),
        "compiled C sample loop, output preallocated": best_time(lambda: loop(n_samples, pointers, output.ctypes.data)),
        "compiled C sample loop, SampleEvaluator": best_time(lambda: compiled(q, dq, ddq)),
        "compiled C sample loop, 2 threads": best_time(lambda: threaded(q, dq, ddq)),
        "model.evaluate (what users call)": best_time(lambda: model.evaluate(q, dq, ddq)),
        "model.evaluate(..., out=reused array)": best_time(lambda: model.evaluate(q, dq, ddq, out=reused)),
    }
    # Pinocchio's regressor takes the parameters in the joint frames, ours in the link (DH)
    # frames: the columns differ, the torques they predict must not.
    pinocchio_loop()
    theta_pinocchio = np.concatenate([pin_model.inertias[i].toDynamicParameters() for i in range(1, joints + 1)])
    error = np.abs(model.predict(robot.standard_parameters, q, dq, ddq) - stacked @ theta_pinocchio).max()
    print(f"\nPUMA 560, {joints} joints, internal regressor ({joints}x{10 * joints}), {n_samples} samples")
    print(f"  one-time: graph + base parameters {build * 1e3:.0f} ms; code generation + compile (or cache load) {compile_time * 1e3:.0f} ms")
    print(f"  max |tau CasADi - tau Pinocchio| = {error:.1e} N.m")
    print(f"  {'pinocchio.computeJointTorqueRegressor loop':<45s} {reference * 1e3:8.2f} ms  {reference / n_samples * 1e6:6.2f} us/sample  (baseline)")
    for label, seconds in timings.items():
        print(f"  {label:<45s} {seconds * 1e3:8.2f} ms  {seconds / n_samples * 1e6:6.2f} us/sample  {reference / seconds:6.1f}x")
    ratio = reference / timings["model.evaluate (what users call)"]
    print(f"  target >= 10x faster than the Pinocchio loop: {'met' if ratio >= 10 else 'NOT met'} ({ratio:.1f}x)")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--samples", type=int, default=5000)
    args = parser.parse_args()
    print(f"compiled-function cache: {cache_directory()}")
    for joints in (3, 6):
        run(joints, args.samples)


if __name__ == "__main__":
    main()
