"""Monte Carlo check of the model choice's paired difference (:func:`estimation.consistent.model_selection.
paired_difference`): when two candidates are equally good, does the one-sided 5 % test say "the validation record
tells them apart" about 5 % of the time?

A simulated 3-joint PUMA (viscous and Coulomb friction, offsets), a short validation record (``--seconds`` at
``--rate`` Hz, a random Fourier motion of 0.2 Hz, five harmonics, drawn anew each time) whose torques carry
noise correlated in time (first-order autoregressive, correlation time ``--correlation`` s) and, optionally, an
effect outside the model (``--mismatch``: a spring on each joint, its torque that fraction of the channel's
spread). Two candidates are exchangeable by construction: the true parameters plus and minus the same error
``delta`` (drawn each time, its prediction error about the noise's size), so neither is better on average. The
test is asked whether the candidate ``consistent`` is worse than ``ols`` beyond the record's sampling error; it
should say so in about :data:`~estimation.consistent.model_selection.NOISE_LEVEL` of the draws.

Rerun: ``PYTHONPATH=. python benchmarks/bench_paired_difference.py --draws 400 --correlation 0.02``
"""

from __future__ import annotations

import argparse
from types import SimpleNamespace

import numpy as np

from dynamics.models import build_model
from dynamics.robots import load_robot
from dynamics.simulation.synthetic import true_parameters
from estimation.consistent.model_selection import Candidate, paired_difference
from estimation.identification.validation import Comparison
from oed.fourier import random_fourier


def autoregressive(generator: np.random.Generator, shape: tuple[int, int], correlation: float, rate: float
                   ) -> np.ndarray:
    """Unit-variance noise, first-order autoregressive with correlation time ``correlation`` s."""
    rho = float(np.exp(-1.0 / (correlation * rate))) if correlation > 0 else 0.0
    white = generator.normal(size=shape)
    noise = np.empty(shape)
    noise[0] = white[0]
    scale = np.sqrt(1.0 - rho ** 2)
    for row in range(1, shape[0]):
        noise[row] = rho * noise[row - 1] + scale * white[row]
    return noise


def rejections(draws: int, *, seconds: float, rate: float, correlation: float, mismatch: float, seed: int
               ) -> tuple[float, float]:
    """The share of ``draws`` in which the test finds ``consistent`` worse beyond the sampling error, and the
    share in which it finds ``ols`` worse (both should be about the level)."""
    robot = load_robot("puma560", joints=3)
    model = build_model(robot, "internal", "viscous,coulomb,offset")
    theta = true_parameters(model, seed=1, coulomb=[3.0, 2.0, 1.0], offset=[0.5, -0.3, 0.2])
    generator = np.random.default_rng(seed)
    channels = tuple(model.channels)
    counts = np.zeros(2)
    for draw in range(draws):
        trajectory = random_fourier(robot, seed=10_000 * seed + draw)
        t, q, dq, ddq = trajectory.sample(rate, 1)
        keep = t < seconds
        t, q, dq, ddq = t[keep], q[keep], dq[keep], ddq[keep]
        truth = model.predict(theta, q, dq, ddq)
        spread = truth.std(axis=0)
        noise = 0.05 * spread * autoregressive(generator, truth.shape, correlation, rate)
        unmodelled = mismatch * spread * (q - q.mean(axis=0)) / np.maximum(q.std(axis=0), 1e-12)
        measured = truth + noise + unmodelled
        direction = generator.normal(size=theta.shape)
        error = model.predict(direction, q, dq, ddq)
        scale = 0.05 * np.mean(spread) / max(float(np.sqrt(np.mean(error ** 2))), 1e-12)
        candidates = [Candidate(name, SimpleNamespace(  # type: ignore[arg-type]
            validation=Comparison(t, measured, model.predict(theta + sign * scale * direction, q, dq, ddq), channels),
            train=None)) for name, sign in (("ols", 1.0), ("consistent", -1.0))]
        ahead = paired_difference(candidates, "ols")
        behind = paired_difference(candidates[::-1], "consistent", regularised="ols")
        counts += [ahead is not None and not ahead.within_noise, behind is not None and not behind.within_noise]
    return float(counts[0] / draws), float(counts[1] / draws)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--draws", type=int, default=400)
    parser.add_argument("--seconds", type=float, default=2.0)
    parser.add_argument("--rate", type=float, default=1000.0)
    parser.add_argument("--correlation", type=float, nargs="+", default=[0.0, 0.01, 0.02, 0.05, 0.1])
    parser.add_argument("--mismatch", type=float, nargs="+", default=[0.0, 0.05])
    parser.add_argument("--seed", type=int, default=1)
    args = parser.parse_args()
    print("| correlation time (s) | unmodelled spring (share of spread) | draws | consistent worse | ols worse |")
    print("|---|---|---|---|---|")
    for mismatch in args.mismatch:
        for correlation in args.correlation:
            first, second = rejections(args.draws, seconds=args.seconds, rate=args.rate, correlation=correlation,
                                       mismatch=mismatch, seed=args.seed)
            print(f"| {correlation:g} | {mismatch:g} | {args.draws} | {first:.3f} | {second:.3f} |", flush=True)


if __name__ == "__main__":
    main()
