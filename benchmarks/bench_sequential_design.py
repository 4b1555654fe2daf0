"""Monte Carlo of the sequential design on the simulated Stribeck case (:mod:`benchmarks.sequential_case`).

**Focus.** Realisation 0 of the first experiment is identified and the next experiment designed from it
(``design_next(..., focus="stribeck", starts=8)``, as long as the first, 10 s). Then, for ``--realisations``
fresh noise draws, the first experiment plus either the designed experiment or the first one repeated are
identified, and the spread of the estimates of ``fc2, fs2, vs2`` (the realised standard deviations) is
compared with the predicted ones and with each other: the worst relative standard deviation of the three,
now / after repeating / after the designed experiment.

**Discrimination.** With a weaker Stribeck bump (``--discrimination-fs``), the true law and the rival
``coulomb:tanh@2`` are identified on realisation 0 of the first experiment, the discriminating experiment is
designed from them (``design_discriminating``), and in each realisation the BIC of both laws
(``χ²/σ² + k ln(N m)``, the true noise ``σ``) is compared after the first experiment alone and after it plus the
discriminating one: the share of realisations with ΔBIC > 10 for the true law, among those within 2 after the first.

Run: ``python -m benchmarks.bench_sequential_design [--realisations 50] [--part focus|discrimination|both]``.
"""

from __future__ import annotations

import argparse
import time
import warnings
from dataclasses import replace

import numpy as np

from benchmarks.sequential_case import StribeckCase
from dynamics.models import build_model
from estimation.identification.fit import ImplausibleEstimateWarning, identify
from oed.bounds import PUMA_BOUNDS
from oed.sequential.discrimination import design_discriminating
from oed.sequential.next_experiment import design_next

FOCUS = ("fc2", "fs2", "vs2")


def estimates(case: StribeckCase, records, names=FOCUS) -> np.ndarray:
    with warnings.catch_warnings():  # a realisation's implausible estimate is part of the spread measured
        warnings.simplefilter("ignore", ImplausibleEstimateWarning)
        model = case.identified(records)
    values = dict(zip(model.file.names, model.theta))
    values.update(model.file.shape)
    return np.array([values[name] for name in names])


def focus_part(realisations: int) -> None:
    case = StribeckCase()
    first = case.first_trajectory()
    record = case.record(first, seed=1)
    model = case.identified([record])
    started = time.perf_counter()
    result = design_next(model, record, bounds=PUMA_BOUNDS, focus="stribeck", starts=8, seed=0)
    print(f"design: {time.perf_counter() - started:.1f} s (8 starts), {result.summary()}")
    predicted = result.predicted
    index = [predicted.names.index(name) for name in FOCUS]
    truth = np.array([case.fc, case.fs, case.vs])
    runs = {"now": [], "after_repeat": [], "after_designed": []}
    started = time.perf_counter()
    for i in range(realisations):
        one = case.record(first, seed=1000 + i)
        runs["now"].append(estimates(case, [one]))
        runs["after_repeat"].append(estimates(case, [one, case.record(first, seed=3000 + i)]))
        runs["after_designed"].append(estimates(case, [one, case.record(result.design.trajectory, seed=2000 + i)]))
    print(f"{realisations} realisations: {time.perf_counter() - started:.1f} s")
    worst = {}
    for key, values in runs.items():
        realised = np.std(np.array(values), axis=0, ddof=1)
        expected = getattr(predicted, key)[index]
        worst[key] = (np.max(realised / truth), np.max(expected / np.abs(predicted.value[index])))
        print(f"  {key:15s} realised sd " + ", ".join(f"{n} {v:.4g}" for n, v in zip(FOCUS, realised))
              + " | predicted " + ", ".join(f"{v:.4g}" for v in expected)
              + " | realised/predicted " + ", ".join(f"{r / e:.2f}" for r, e in zip(realised, expected)))
    print("  worst relative sd (realised, predicted): " + ", ".join(f"{k} {100 * v[0]:.3g} % / {100 * v[1]:.3g} %"
                                                                   for k, v in worst.items()))
    for which in (0, 1):
        label = ("realised", "predicted")[which]
        repeat = worst["now"][which] / worst["after_repeat"][which]
        designed = worst["now"][which] / worst["after_designed"][which]
        print(f"  {label}: shrink factor repeat {repeat:.2f}x, designed {designed:.2f}x, ratio {designed / repeat:.2f}")


def bic(case: StribeckCase, records, friction: str) -> float:
    model = build_model(case.robot, "internal", friction)
    with warnings.catch_warnings():  # the wrong law's implausible estimates are part of what is measured
        warnings.simplefilter("ignore", ImplausibleEstimateWarning)
        result = identify(model, list(records), covariance="classical")
    chi2 = sum(result.train.mse[c] for c in model.channels) * sum(r.n_samples for r in records) / case.noise**2
    k = model.n_base + len(result.shapes)
    n = sum(r.n_samples for r in records) * len(model.channels)
    return chi2 + k * np.log(n)


def discrimination_part(realisations: int, fs: float) -> None:
    case = replace(StribeckCase(), fs=fs)
    rival = "viscous,coulomb:tanh@2"
    first = case.first_trajectory()
    record = case.record(first, seed=1)
    model, other = case.identified([record]), case.identified([record], rival)
    started = time.perf_counter()
    result = design_discriminating(model, other, record, bounds=PUMA_BOUNDS, starts=8, seed=0)
    print(f"discriminating design: {time.perf_counter() - started:.1f} s (8 starts), {result.summary()}")
    close, told = 0, 0
    differences = []
    for i in range(realisations):
        one = case.record(first, seed=1000 + i)
        before = bic(case, [one], rival) - bic(case, [one], case.friction)
        second = case.record(result.design.trajectory, seed=2000 + i)
        after = bic(case, [one, second], rival) - bic(case, [one, second], case.friction)
        differences.append((before, after))
        if abs(before) < 2:
            close += 1
            told += after > 10
    array = np.array(differences)
    print(f"  ΔBIC (rival − true) after the first: median {np.median(array[:, 0]):.3g}; after the discriminating: "
          f"median {np.median(array[:, 1]):.3g}, > 10 in {np.mean(array[:, 1] > 10):.0%} of {realisations}; "
          f"of the {close} within 2 after the first, {told} told apart (> 10)")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--realisations", type=int, default=50)
    parser.add_argument("--part", choices=("focus", "discrimination", "both"), default="both")
    parser.add_argument("--discrimination-fs", type=float, default=0.4)
    args = parser.parse_args()
    if args.part in ("focus", "both"):
        focus_part(args.realisations)
    if args.part in ("discrimination", "both"):
        discrimination_part(args.realisations, args.discrimination_fs)


if __name__ == "__main__":
    main()
