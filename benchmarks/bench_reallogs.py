"""Benchmark: ``oed diagnose`` on a real-log-sized record (issue 14), and where its time goes.

A 7-joint KUKA LWR4+ (URDF of ``../shared/data/kuka_lwr4``, or ``--urdf``): 14 000 samples at
1 kHz of a 0.1 Hz Fourier excitation (1.4 periods, not whole: no period averaging), positions only,
torques ``Y θ`` of a model with viscous + Coulomb friction and offsets plus 0.2 N·m noise; the log
has 120 re-sent packets and four 8 ms stalls. Validation: another 14 000-sample trajectory.
``diagnose`` starts from viscous friction and searches the default candidates.

Timed (one run): reading and cleaning the two files, choosing and applying the preprocessing
(frequency check, Fourier fits, recorded channels), then the whole CLI run (which repeats them and
diagnoses; the truth has 14 effects the declared model lacks).

Measured 2026-11-23 on the 2-core machine, otherwise idle, after the diagnosis loop of issue 13 was
merged: read + clean 0.06 s, preprocessing 0.10 s, the whole CLI run 26.5 s (27.9–32.7 s in earlier
runs of the same day, before the search refined two screened candidates a round instead of four,
which gave the same effects); it finds Coulomb friction and the offset on all seven joints and ends
with every channel at its noise floor (validation MSE / floor 0.97–1.05).

Run: ``python benchmarks/bench_reallogs.py [--urdf FILE] [--samples N]``.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
import warnings
from pathlib import Path

import numpy as np

from dynamics.models import build_model
from dynamics.robots import load_robot
from estimation.data.records import read_record
from dynamics.measurements import Measurements
from estimation.preprocessing.plan import choose_preprocessing, prepare
import oed
from dynamics.simulation.synthetic import true_parameters
from oed.fourier import random_fourier

ROOT = Path(__file__).resolve().parents[1]
DEFAULT_URDF = ROOT.parent / "shared" / "data" / "kuka_lwr4" / "kuka_lwr4.urdf"


def write_log(model, theta, seed: int, samples: int, path: Path) -> None:
    robot = model.robot
    trajectory = random_fourier(robot, seed, frequency_hz=0.1, harmonics=5)
    t = np.arange(samples) / 1000.0
    q, dq, ddq = trajectory.evaluate(t)
    generator = np.random.default_rng(seed)
    tau = model.predict(theta, q, dq, ddq) + generator.normal(0.0, 0.2, (samples, robot.n_joints))
    q = np.round(q / 1e-5) * 1e-5  # an encoder
    frame = Measurements(t, q, tau=tau).to_frame()
    data = [column for column in frame.columns if column != "t"]
    stale = np.sort(generator.choice(np.arange(100, samples - 100), 120, replace=False))
    frame.loc[stale, data] = frame.loc[stale - 1, data].to_numpy()  # re-sent packets
    for start in (2000, 5000, 8000, 11000):  # four 8 ms stalls
        frame = frame.drop(index=range(start, start + 8))
    frame.to_csv(path, index=False, float_format="%.10g")


def main_benchmark() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--urdf", type=Path, default=DEFAULT_URDF)
    parser.add_argument("--samples", type=int, default=14_000)
    parser.add_argument("--skip-cli", action="store_true", help="time loading and preprocessing only")
    args = parser.parse_args()
    if not args.urdf.is_file():
        sys.exit(f"no URDF at {args.urdf} (give --urdf)")
    robot = load_robot(urdf=args.urdf)
    truth = build_model(robot, "internal", "viscous,coulomb,offset")
    n = robot.n_joints
    theta = true_parameters(truth, seed=1, coulomb=np.linspace(0.5, 2.0, n), offset=np.linspace(-0.5, 0.5, n))
    model = build_model(robot, "internal", "viscous")
    model.evaluate_base(np.zeros((2, n)), np.zeros((2, n)), np.zeros((2, n)))  # compile outside the timings
    with tempfile.TemporaryDirectory() as folder:
        train_path, validate_path = Path(folder) / "train.csv", Path(folder) / "validate.csv"
        write_log(truth, theta, 3, args.samples, train_path)
        write_log(truth, theta, 4, args.samples, validate_path)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            start = time.perf_counter()
            train = read_record(train_path, model=model)
            validate = read_record(validate_path, model=model, split=False)
            loaded = time.perf_counter()
            plan = choose_preprocessing(train, frequency_hz=0.1, harmonics=15, held_torques=False)
            prepare(train, plan), prepare(validate, plan)
            prepared = time.perf_counter()
        print(f"{robot.name}: {n} joints, {args.samples} samples at 1 kHz per file")
        print(f"  read + clean (2 files)        {loaded - start:6.2f} s")
        print(f"  preprocessing (choose, apply) {prepared - loaded:6.2f} s   [{plan.describe()}]")
        if args.skip_cli:
            return
        start = time.perf_counter()
        oed.diagnose(urdf=args.urdf, data=train_path, validate=validate_path, frequency=0.1,
                     harmonics=15).write(Path(folder) / "report.json")
        whole = time.perf_counter() - start
        print(f"  whole `oed.diagnose` run      {whole:6.2f} s   (target < 30 s)")


if __name__ == "__main__":
    main_benchmark()
