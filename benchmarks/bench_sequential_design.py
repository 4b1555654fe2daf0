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
from dataclasses import dataclass, replace

import numpy as np

from benchmarks.sequential_case import PERIODS, RATE_HZ, StribeckCase
from dynamics.models import build_model
from estimation.identification.fit import ImplausibleEstimateWarning, identify
from oed.bounds import PUMA_BOUNDS
from oed.sequential.discrimination import design_discriminating
from oed.sequential.criteria import SEQUENTIAL_CRITERIA
from oed.sequential.jacobian import model_jacobian
from oed.sequential.next_experiment import NextExperiment, PredictedStd, design_next, predicted_std
from oed.sequential.prior import prior_information

FOCUS = ("fc2", "fs2", "vs2")


def estimates(case: StribeckCase, records, names=FOCUS) -> np.ndarray:
    with warnings.catch_warnings():  # a realisation's implausible estimate is part of the spread measured
        warnings.simplefilter("ignore", ImplausibleEstimateWarning)
        model = case.identified(records)
    values = dict(zip(model.file.names, model.theta))
    values.update(model.file.shape)
    return np.array([values[name] for name in names])


@dataclass(frozen=True)
class FocusMonteCarlo:
    """The focus part's figures: per arm (``now``, ``after_repeat``, ``after_designed``) the realised standard
    deviations of :data:`FOCUS` over the realisations, those predicted at realisation 0's estimate (what
    ``next.json`` says) and those predicted linearised at the truth; the design and the estimates themselves."""

    next_experiment: NextExperiment
    estimates: dict[str, np.ndarray]
    predicted: dict[str, np.ndarray]
    at_truth: dict[str, np.ndarray]
    truth: np.ndarray

    @property
    def realised(self) -> dict[str, np.ndarray]:
        return {key: np.std(values, axis=0, ddof=1) for key, values in self.estimates.items()}

    def worst(self, which: str = "realised") -> dict[str, float]:
        """The worst relative standard deviation per arm: realised or at the truth (over the true values),
        ``predicted`` over realisation 0's estimate, as ``next.json``."""
        if which == "predicted":
            return self.next_experiment.predicted.worst_relative(FOCUS)
        table = self.realised if which == "realised" else self.at_truth
        return {key: float(np.max(values / self.truth)) for key, values in table.items()}

    def shrink_ratio(self, which: str = "realised") -> float:
        """``(now / after_designed) / (now / after_repeat)``, the worst relative standard deviation's."""
        worst = self.worst(which)
        return worst["after_repeat"] / worst["after_designed"]


def predicted_at_truth(case: StribeckCase, first, designed, duration_s: float) -> PredictedStd:
    """The standard deviations the design's prediction gives linearised at the true parameters and noise
    (the model identified on a noise-free record of the first experiment)."""
    clean = replace(case, noise=0.0)
    record = clean.record(first, seed=0)
    model = clean.identified([record])
    jacobian = model_jacobian(model, np.full(len(model.channels), case.noise))
    prior = prior_information(jacobian, record)
    _, q, dq, ddq = designed.sample(RATE_HZ)
    information = jacobian.information(q, dq, ddq) * prior.samples_in(duration_s) / q.shape[0]
    return predicted_std(jacobian, prior, information, duration_s)


def focus_monte_carlo(case: StribeckCase, realisations: int, *, criterion: str | None = None, starts: int = 8,
                      periods: int = PERIODS) -> FocusMonteCarlo:
    """Design from realisation 0 (``focus="stribeck"``, ``periods`` of the first experiment's frequency), then
    identify ``realisations`` fresh noise draws of the first experiment alone, plus it repeated, plus the design."""
    first = case.first_trajectory()
    record = case.record(first, seed=1)
    duration = periods / first.frequency_hz
    result = design_next(case.identified([record]), record, bounds=PUMA_BOUNDS, focus="stribeck",
                         criterion=criterion, starts=starts, seed=0, duration_s=duration)
    runs = {"now": [], "after_repeat": [], "after_designed": []}
    for i in range(realisations):
        one = case.record(first, seed=1000 + i)
        runs["now"].append(estimates(case, [one]))
        runs["after_repeat"].append(estimates(case, [one, case.record(first, seed=3000 + i, periods=periods)]))
        designed = case.record(result.design.trajectory, seed=2000 + i, periods=periods)
        runs["after_designed"].append(estimates(case, [one, designed]))
    index = [result.predicted.names.index(name) for name in FOCUS]
    truth = predicted_at_truth(case, first, result.design.trajectory, duration)
    truth_index = [truth.names.index(name) for name in FOCUS]
    keys = tuple(runs)
    return FocusMonteCarlo(result, {key: np.array(runs[key]) for key in keys},
                           {key: getattr(result.predicted, key)[index] for key in keys},
                           {key: getattr(truth, key)[truth_index] for key in keys}, np.array([case.fc, case.fs, case.vs]))


def focus_part(realisations: int, case: StribeckCase, criterion: str | None, starts: int, periods: int) -> None:
    started = time.perf_counter()
    run = focus_monte_carlo(case, realisations, criterion=criterion, starts=starts, periods=periods)
    design = run.next_experiment.design
    print(f"vs = {case.vs}, criterion {design.criterion}, {starts} starts, {periods} periods: "
          f"{time.perf_counter() - started:.1f} s with {realisations} realisations; {run.next_experiment.summary()}")
    for key in run.estimates:
        realised, expected, truth = run.realised[key], run.predicted[key], run.at_truth[key]
        print(f"  {key:15s} realised sd " + ", ".join(f"{n} {v:.4g}" for n, v in zip(FOCUS, realised))
              + " | predicted " + ", ".join(f"{v:.4g}" for v in expected)
              + " | realised/predicted " + ", ".join(f"{r / e:.2f}" for r, e in zip(realised, expected))
              + " | at the truth " + ", ".join(f"{v:.4g}" for v in truth)
              + " | realised/at truth " + ", ".join(f"{r / e:.2f}" for r, e in zip(realised, truth)))
    for which in ("realised", "predicted", "at the truth"):
        worst = run.worst(which.split()[-1])
        print(f"  {which:12s}: worst relative sd " + ", ".join(f"{k} {100 * v:.3g} %" for k, v in worst.items())
              + f"; shrink factor repeat {worst['now'] / worst['after_repeat']:.2f}x, designed "
              f"{worst['now'] / worst['after_designed']:.2f}x, ratio {run.shrink_ratio(which.split()[-1]):.2f}")


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
    parser.add_argument("--vs", type=float, default=StribeckCase.vs, help="the true Stribeck velocity (focus part)")
    parser.add_argument("--criterion", choices=SEQUENTIAL_CRITERIA, default=None,
                        help="the focus part's criterion (default: design_next's with a focus)")
    parser.add_argument("--starts", type=int, default=8)
    parser.add_argument("--periods", type=int, default=PERIODS, help="the new experiment's length (focus part)")
    args = parser.parse_args()
    if args.part in ("focus", "both"):
        focus_part(args.realisations, replace(StribeckCase(), vs=args.vs), args.criterion, args.starts, args.periods)
    if args.part in ("discrimination", "both"):
        discrimination_part(args.realisations, args.discrimination_fs)


if __name__ == "__main__":
    main()
