"""The joint-zero check on torques logged with a gain per joint: Monte Carlo over seeds (h-gains2).

A 6-joint PUMA (viscous, Coulomb and offset per joint), a training and a validation record of other Fourier motions,
2 % white torque noise; each seed draws the parameters, the motions, the noise and the gains (0.3–1.8, joint 2's or
3's sign flipped: a true torque reversal), the logs of ``tests/test_joint_zero_gains.py``. Six logs a seed:

- ``gains``: the torques times the gains, the zeros as the description's;
- ``gains+offset``: the same with joint 2's zero 0.8 rad off;
- ``offset``: joint 2's zero 0.8 rad off, no gains;
- ``plain``: neither;
- ``positive-gains``: the same gains kept positive (no reversal), the zeros as the description's (h-gains3);
- ``reversal``: the flipped joint's torque reversed alone, no gains, the zeros as the description's (h-gains3).

For each, :func:`~estimation.identification.joint_zeros.check_joint_zeros` (the verbs' call, directions scanned) and
what it said: whether marked, the joints named and their offsets, the signs, whether it ran with the gains. A row is
``wrong`` when it names an offset other than joint 2's near 0.8 rad, or a reversal the truth lacks.

    PYTHONPATH=. .venv/bin/python benchmarks/bench_joint_zero_gains.py [--seeds 0-19] [--logs gains,gains+offset]
        [--jobs 2] [--out FILE.csv]
"""

from __future__ import annotations

import argparse
import time
from concurrent.futures import ProcessPoolExecutor
from dataclasses import replace

import numpy as np
import pandas as pd

from dynamics.models import build_model
from dynamics.robots import load_robot
from dynamics.simulation.synthetic import simulate, true_parameters
from estimation.identification.joint_zeros import check_joint_zeros
from oed.fourier import random_fourier

LOGS = ("gains", "gains+offset", "offset", "plain", "positive-gains", "reversal")
OFFSETS = np.array([0.0, 0.8, 0.0, 0.0, 0.0, 0.0])


def records(model, robot, seed: int):
    """The training and validation records and the gains of a seed (also those of ``tests/test_joint_zero_gains.py``)."""
    generator = np.random.default_rng(seed)
    gains = generator.uniform(0.3, 1.8, 6)
    gains[generator.integers(1, 3)] *= -1
    theta = true_parameters(model, seed=seed)
    made = []
    for k in range(2):
        record = simulate(model, theta, random_fourier(robot, 50 + 2 * seed + k), seed=500 + 2 * seed + k)
        made.append(replace(record, tau=record.tau + generator.normal(size=record.tau.shape) * 0.02
                            * record.tau.std(axis=0)))
    return made, gains


def one(task: tuple[int, str]) -> dict:
    seed, log = task
    robot = load_robot("puma560")
    model = build_model(robot, "internal", "viscous,coulomb,offset")
    (train, validate), gains = records(model, robot, seed)
    offsets = OFFSETS if "offset" in log else np.zeros(6)
    scale = {"positive-gains": np.abs(gains), "reversal": np.sign(gains)}.get(log, gains if "gains" in log else np.ones(6))
    started = time.process_time()
    check = check_joint_zeros(model, replace(train, q=train.q - offsets, tau=train.tau * scale),
                              replace(validate, q=validate.q - offsets, tau=validate.tau * scale), warn=False)
    seconds = time.process_time() - started
    marked = bool(check is not None and check.marked)
    joints = check.joints if marked else ()
    truly = tuple(int(j) for j in np.flatnonzero(scale < 0))
    said_reversed = check.reversed_joints if marked else ()
    found = joints == (1,) and abs(check.offsets[1] - 0.8) < 0.1
    wrong = (joints not in ((), (1,)) or (bool(joints) and not found)
             or (marked and any(sign < 0 for sign in check.signs)) or said_reversed not in ((), truly))
    return {"seed": seed, "log": log, "marked": marked, "joints": " ".join(str(j + 1) for j in joints),
            "offsets_deg": " ".join(f"{np.rad2deg(check.offsets[j]):.1f}" for j in joints),
            "reversed_said": " ".join(str(j + 1) for j in said_reversed), "reversed_true": " ".join(str(j + 1) for j in truly),
            "reversal_said": bool(truly) and said_reversed == truly, "offset_found": found, "wrong": wrong,
            "with_gains": bool(check is not None and check.gains),
            "total_ratio": float(check.total_ratio) if check is not None else np.nan, "cpu_s": round(seconds, 2)}


def seeds_of(text: str) -> list[int]:
    if "-" in text:
        first, last = text.split("-")
        return list(range(int(first), int(last) + 1))
    return [int(item) for item in text.split(",")]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", default="0-19")
    parser.add_argument("--logs", default=",".join(LOGS))
    parser.add_argument("--jobs", type=int, default=1)
    parser.add_argument("--out", default=None)
    arguments = parser.parse_args()
    tasks = [(seed, log) for log in arguments.logs.split(",") for seed in seeds_of(arguments.seeds)]
    if arguments.jobs > 1:
        with ProcessPoolExecutor(arguments.jobs) as pool:
            rows = []
            for row in pool.map(one, tasks):
                rows.append(row)
                print(row, flush=True)
    else:
        rows = []
        for task in tasks:
            rows.append(one(task))
            print(rows[-1], flush=True)
    table = pd.DataFrame(rows)
    pd.set_option("display.width", 200)
    print(table.to_string(index=False))
    for log, part in table.groupby("log", sort=False):
        print(f"{log}: marked {part.marked.sum()}/{len(part)}, offset found {part.offset_found.sum()}, "
              f"reversal said {part.reversal_said.sum()}, wrong {part.wrong.sum()}, with gains {part.with_gains.sum()}, "
              f"CPU {part.cpu_s.sum():.0f} s")
    if arguments.out:
        table.to_csv(arguments.out, index=False)


if __name__ == "__main__":
    main()
