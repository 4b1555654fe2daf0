"""Benchmark: the diagnosis (``estimation.diagnosis.search.diagnose``) with every default candidate, plain
and shaped (``coulomb:tanh``, ``stribeck:velocity``, ``sigmoid``, ``ripple``).

1. PUMA 560, 3 joints, internal model, two simulated 10 000-sample records (1 kHz, 0.2 Hz Fourier
   motion) with undeclared tanh Coulomb friction (smoothing 0.03 rad/s) and offsets. Target < 10 s.
2. KUKA LWR4+, 7 joints: identify on run 1, validate on run 3 (``../shared/data/kuka_lwr4``;
   skipped when absent). Target < 30 s.

The time is that of ``diagnose`` alone (the records are made or loaded before), one run, with the
compiled column functions already in the cache (``~/.cache/robot-oed``; a first run compiles them
once, a few seconds more). Run: ``python benchmarks/bench_diagnose.py [--skip-kuka]``.
"""

from __future__ import annotations

import argparse
import dataclasses
import time
from pathlib import Path

from dynamics.effects.linear import CoulombFriction, JointOffset
from dynamics.models import build_model
from dynamics.robots import load_robot
from estimation.diagnosis.search import diagnose
from dynamics.simulation.synthetic import simulate, true_parameters
from oed.fourier import random_fourier

DATA = Path(__file__).resolve().parents[2] / "shared" / "data" / "kuka_lwr4"


def puma_records(n_samples: int = 10_000):
    robot = load_robot("puma560", joints=3)
    truth = build_model(robot, "internal", ("viscous", CoulombFriction(smoothing=0.03), JointOffset()))
    theta = true_parameters(truth, seed=0, coulomb=[8.0, 5.0, 3.0], offset=[1.0, -0.5, 0.3])
    records = []
    for seed in (3, 4):
        data = simulate(truth, theta, random_fourier(robot, seed=seed), rate_hz=1000.0, periods=2,
                        noise={"tau1": 0.2, "tau2": 0.2, "tau3": 0.1}, seed=seed)
        records.append(dataclasses.replace(data, t=data.t[:n_samples], q=data.q[:n_samples], dq=data.dq[:n_samples],
                                           ddq=data.ddq[:n_samples], tau=data.tau[:n_samples]))
    return build_model(robot, "internal", "viscous"), records


def run(label: str, model, train, validate, target_s: float) -> None:
    start = time.perf_counter()
    diagnosis = diagnose(model, train, validate)
    elapsed = time.perf_counter() - start
    print(f"{label}: diagnose {elapsed:.1f} s (target < {target_s:g} s), {train.n_samples} + {validate.n_samples} samples, "
          f"{len(diagnosis.effects)} effects added: "
          + ", ".join(f"{e.spec}@{'+'.join(e.channels)}" for e in diagnosis.effects))
    before, after = diagnosis.before.validation.mse, diagnosis.after.validation.mse
    print(f"   validation MSE total before {sum(before.values()):.4g}, after {sum(after.values()):.4g}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--skip-kuka", action="store_true")
    args = parser.parse_args()
    model, (train, validate) = puma_records()
    diagnose(model, train, validate)  # warm-up: compiled column functions into the cache
    run("PUMA 560, 3 joints", model, train, validate, 10.0)
    if args.skip_kuka or not DATA.is_dir():
        print("KUKA LWR4+: skipped (no ../shared/data/kuka_lwr4)" if not args.skip_kuka else "KUKA: skipped")
        return
    from estimation.datasets.kuka import load_kuka_run

    runs = [load_kuka_run(DATA / f"kuka_lwr4_HW_measurements_{index}.npz") for index in (1, 3)]
    robot = load_robot(urdf=DATA / "kuka_lwr4.urdf")
    run("KUKA LWR4+, 7 joints (train run 1, validate run 3)", build_model(robot, "internal", "viscous"), runs[0], runs[1], 30.0)


if __name__ == "__main__":
    main()
