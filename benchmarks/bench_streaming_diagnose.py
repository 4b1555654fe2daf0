"""Benchmark: ``oed diagnose`` on long records in bounded memory (``--chunk-size``, issue 16).

KUKA LWR4+ (7 joints, URDF of ``../shared/data/kuka_lwr4``), internal model declared with viscous
friction, filter path (the files hold ``t, q1..q7, tau1..tau7`` only: Butterworth-filtered
derivatives on overlapping windows, cut-off 5 Hz). Synthetic records as in
``benchmarks/bench_streaming.py`` (random 5-harmonic Fourier motion at 1 kHz, white noise on the
positions, 1e-5 rad, and torques, 0.05 N m), whose torques hold effects the declared model lacks:
Coulomb friction on every joint (2.0, 2.5, 1.5, 1.8, 0.8, 0.6, 0.5 N m) and a torque offset on joint 6
(0.8 N m). (With Coulomb friction on two joints only, the other five channels sit at their noise
floor, get weights ``1/σ²`` some 400 times larger from the declared model's fit, and a Coulomb term
that brings its channel to the floor lowers the *weighted* validation error by under 1 %: not
confirmed, by the in-memory rule as by the streamed one.)
Training records of 100 k, 300 k and 1 M samples; one validation record of 100 000 samples (another
motion) for every length, so that the time measured grows with the training length alone.

Each ``oed diagnose --chunk-size C`` runs in a fresh process under ``/usr/bin/time -v`` (peak
resident memory, wall and CPU time). Targets (issue 16): peak < 1 GB at 1 M samples, time linear
from 100 k to 1 M, 1 M samples diagnosed in < 2 min. ``--in-memory N``: the in-memory path on a
record of N samples, for comparison (14 KB a sample before this path existed).

``--no-flag N ...``: ``oed diagnose`` with no flag at all (the path decided by the memory budget, the
derivatives chosen by held-out error) on N training samples, against ``--chunk-size C`` with the derivatives
chosen too. Targets: at 1 M samples, peak <= 1 GB, wall <= 60 s, the same effects and within 10 % of the streamed
answer.

``--files K --file-samples N``: K training records of N samples through
:func:`estimation.streaming.diagnosis.diagnose_files` serially, in a 2-process pool and on a 2-worker dask
``LocalCluster`` (wall times; the same effects and estimates as serial).

Run: ``python benchmarks/bench_streaming_diagnose.py [--lengths N ...] [--chunk-size C]
[--subsample S] [--in-memory N ...] [--no-flag N ...] [--files K --file-samples N] [--folder DIR]``; records are kept in ``--folder`` (default a
folder under /tmp) and reused.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from dynamics.effects.linear import CoulombFriction, JointOffset  # noqa: E402
from dynamics.models import build_model  # noqa: E402
from dynamics.robots import load_robot  # noqa: E402

sys.path.insert(0, str(ROOT / "benchmarks"))
from bench_streaming import URDF  # noqa: E402
from bench_streaming import record as streaming_record  # noqa: E402

RATE = 1000.0
CUTOFF = 5.0
VALIDATION_SAMPLES = 100_000
#: the effects the declared model (viscous friction) lacks
COULOMB = dict(enumerate([2.0, 2.5, 1.5, 1.8, 0.8, 0.6, 0.5]))
OFFSET = {5: 0.8}


def truth_model():
    robot = load_robot(urdf=URDF)
    effects = ("viscous", CoulombFriction(joints=tuple(COULOMB))) + tuple(
        JointOffset(joints=(j,)) for j in OFFSET)
    return robot, build_model(robot, "internal", effects)


def truth():
    """``(robot, model, theta)`` of the torques: the declared viscous friction and the missing effects."""
    robot, model = truth_model()
    return robot, model, model.nominal_parameters(viscous=0.5, coulomb=list(COULOMB.values()),
                                                  offset=list(OFFSET.values()))


def record(folder: Path, n_samples: int, seed: int) -> Path:
    """The record of ``bench_streaming`` (its writer) with this benchmark's torques."""
    return streaming_record(folder, n_samples, seed, truth(), prefix="kuka_effects")


def time_diagnose(train: Path, validate: Path, out: Path, chunk_size: int | None, subsample: int | None,
                  cutoff: float | None = CUTOFF, extra: tuple[str, ...] = ()) -> tuple[float, float, float, dict]:
    """Wall time (s), CPU time (s), peak resident memory (MB) and the report of ``oed diagnose``
    in a fresh process; without ``chunk_size`` the path is the CLI's choice (in memory unless the record
    passes the memory budget); without ``cutoff`` the derivatives are chosen by held-out error."""
    command = ["/usr/bin/time", "-v", sys.executable, "-m", "oed", "diagnose", "--urdf", str(URDF), "--model",
               "internal", "--friction", "viscous", "--data", str(train), "--validate", str(validate),
               "--out", str(out), *(("--cutoff", str(cutoff)) if cutoff is not None else ()), *extra]
    if chunk_size is not None:
        command += ["--chunk-size", str(chunk_size)]
        if subsample is not None:
            command += ["--subsample", str(subsample)]
    run = subprocess.run(command, capture_output=True, text=True, cwd=ROOT)
    if run.returncode != 0:
        raise RuntimeError(f"oed diagnose failed: {run.stderr[-3000:]}")
    peak = float(re.search(r"Maximum resident set size \(kbytes\): (\d+)", run.stderr).group(1)) / 1024
    wall = re.search(r"Elapsed \(wall clock\) time \(h:mm:ss or m:ss\): ([\d:.]+)", run.stderr).group(1)
    seconds = sum(float(part) * 60**index for index, part in enumerate(reversed(wall.split(":"))))
    cpu = sum(float(re.search(rf"{kind} time \(seconds\): ([\d.]+)", run.stderr).group(1)) for kind in ("User", "System"))
    return seconds, cpu, peak, json.loads(out.read_text())


def summary(document: dict) -> str:
    found = ", ".join(f"{effect['spec']}" + (f"@{effect['channels'][0]}" if "@" not in effect["spec"] else "")
                      for effect in document["effects"]) or "nothing"
    before = document["validation"]["before"]["mse"]
    after = document["validation"]["after"]["mse"]
    worst = max(after, key=lambda channel: after[channel] / before[channel])
    return f"found {found}; validation MSE {sum(before.values()):.4g} -> {sum(after.values()):.4g} (worst {worst})"


def bench_files(folder: Path, count: int, samples: int, chunk_size: int) -> None:
    """``count`` training records through :func:`estimation.streaming.diagnosis.diagnose_files` serially, in a
    2-process pool and on a 2-worker dask ``LocalCluster``: wall times and the estimates against serial."""
    from concurrent.futures import ProcessPoolExecutor

    from estimation.streaming.diagnosis import diagnose_files

    paths = [record(folder, samples, seed=10 + index) for index in range(count)]
    validate = [record(folder, VALIDATION_SAMPLES, seed=2)]
    robot = load_robot(urdf=URDF)
    model = build_model(robot, "internal", "viscous")
    options = dict(chunk_size=chunk_size, cutoff_hz=CUTOFF)
    results = {}
    started = time.perf_counter()
    result = diagnose_files(model, paths, validate, **options)
    results["serial"] = (time.perf_counter() - started, result)
    with ProcessPoolExecutor(2) as executor:
        started = time.perf_counter()
        result = diagnose_files(model, paths, validate, executor=executor, **options)
        results["process pool (2)"] = (time.perf_counter() - started, result)
    try:
        from dask.distributed import Client, LocalCluster
    except ImportError:
        print("  dask not installed (pip install 'robot-oed[cluster]'): no cluster run")
    else:
        with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as cluster, \
                Client(cluster) as client:
            started = time.perf_counter()
            result = diagnose_files(model, paths, validate, executor=client.get_executor(pure=False), **options)
            results["dask LocalCluster (2 workers)"] = (time.perf_counter() - started, result)
    reference = results["serial"][1]
    print(f"{count} training files of {samples} samples, diagnose, filter path, chunks of {chunk_size}:")
    for label, (seconds, result) in results.items():
        same = [e.spec + str(e.channels) for e in result.effects] == [e.spec + str(e.channels) for e in reference.effects]
        values, expected = result.after.estimate.values, reference.after.estimate.values
        difference = np.linalg.norm(values - expected) / np.linalg.norm(expected)
        print(f"  {label:<32} {seconds:7.1f} s  ({len(result.effects)} effects, same as serial: {same}; "
              f"estimate vs serial {difference:.1e})", flush=True)
    print(f"  load average {os.getloadavg()[0]:.1f}")


def agreement(document: dict, reference: dict) -> tuple[bool, float, float]:
    """Whether two reports found the same effects (name and channels, in any order), the largest relative
    difference of their effects' values (relative to the largest value of each effect), and of the validation
    MSE after, per channel."""
    def effects(report):
        return {(effect["spec"], tuple(effect["channels"])): np.asarray(effect["values"]) for effect in report["effects"]}

    found, expected = effects(document), effects(reference)
    same = set(found) == set(expected)
    values = max((float(np.max(np.abs(found[key] - expected[key])) / max(np.max(np.abs(expected[key])), 1e-12))
                  for key in set(found) & set(expected)), default=float("nan"))
    after, after_ref = document["validation"]["after"]["mse"], reference["validation"]["after"]["mse"]
    mse = max(abs(after[channel] - after_ref[channel]) / after_ref[channel] for channel in after_ref)
    return same, values, mse


def bench_no_flag(folder: Path, length: int, chunk_size: int) -> None:
    """``oed diagnose`` with no flag (no --chunk-size, no derivative option) on ``length`` training samples against
    the streamed run (--chunk-size, derivatives chosen too): targets peak <= 1 GB, wall <= 60 s, the same effects
    and within 10 % of the streamed answer."""
    train, validate = record(folder, length, seed=1), record(folder, VALIDATION_SAMPLES, seed=2)
    runs = {}
    for label, chunk in (("no flag", None), (f"--chunk-size {chunk_size}", chunk_size)):
        out = folder / f"diagnose_noflag_{length}_{chunk or 0}.json"
        started_load = os.getloadavg()[0]
        seconds, cpu, peak, document = time_diagnose(train, validate, out, chunk, None, cutoff=None)
        runs[label] = document
        print(f"  {label:<20} {length:>9} samples: wall {seconds:7.1f} s, CPU {cpu:7.1f} s, peak {peak:7.0f} MB "
              f"(load average {started_load:.1f} -> {os.getloadavg()[0]:.1f}); path {document['diagnosis_path']}, "
              f"{document['preprocessing']['method']} {document['preprocessing'].get('cutoff_hz') or ''}; "
              f"{summary(document)}", flush=True)
        if document.get("streaming"):
            print("             wall by part: " + ", ".join(f"{name} {value:.1f} s" for name, value in
                                                            document["streaming"]["seconds"].items()), flush=True)
    same, values, mse = agreement(runs["no flag"], runs[f"--chunk-size {chunk_size}"])
    print(f"  no flag against --chunk-size: same effects {same}, effects' values within {100 * values:.2g} %, "
          f"validation MSE after within {100 * mse:.2g} %")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--lengths", type=int, nargs="*",
                        help="training lengths streamed with --cutoff (default 100000 300000 1000000, none with --no-flag)")
    parser.add_argument("--chunk-size", type=int, default=10_000)
    parser.add_argument("--subsample", type=int, help="streamed path's subsample (default: the CLI's)")
    parser.add_argument("--in-memory", type=int, nargs="*", default=[], help="lengths also diagnosed in memory")
    parser.add_argument("--folder", type=Path)
    parser.add_argument("--files", type=int, default=0, help="also: this many training files through executors")
    parser.add_argument("--file-samples", type=int, default=100_000)
    parser.add_argument("--no-flag", type=int, nargs="*", default=[],
                        help="lengths diagnosed with no flag (the CLI decides the path and the derivatives) and "
                             "with --chunk-size (derivatives chosen too): the answers compared")
    args = parser.parse_args()
    folder = args.folder or Path(tempfile.gettempdir()) / "robot_oed_bench_streaming_diagnose"
    folder.mkdir(parents=True, exist_ok=True)
    print(f"records in {folder}; {os.cpu_count()} cores, load average {os.getloadavg()[0]:.1f}", flush=True)
    if args.no_flag:
        print("diagnose with no flag against --chunk-size (KUKA, 7 joints, declared viscous):")
        for length in args.no_flag:
            bench_no_flag(folder, length, args.chunk_size)
    if args.lengths is None:
        args.lengths = [] if args.no_flag else [100_000, 300_000, 1_000_000]
    validate = record(folder, VALIDATION_SAMPLES, seed=2)
    if args.lengths:
        print(f"diagnose, filter path, chunks of {args.chunk_size} (KUKA, 7 joints, declared viscous; truth adds "
              f"Coulomb on every joint, an offset on joint {[j + 1 for j in OFFSET]}); validation "
              f"{VALIDATION_SAMPLES} samples:")
    rows = []
    for length in args.lengths:
        train = record(folder, length, seed=1)
        seconds, cpu, peak, document = time_diagnose(train, validate, folder / f"diagnose_{length}.json",
                                                     args.chunk_size, args.subsample)
        rows.append((length, seconds, cpu, peak))
        subsample = document["streaming"]["subsample"]
        parts = document["streaming"]["seconds"]
        print(f"  {length:>9} samples: wall {seconds:7.1f} s, CPU {cpu:7.1f} s, peak {peak:7.0f} MB "
              f"(subsample {subsample['samples']}); {summary(document)}", flush=True)
        print("             wall by part: " + ", ".join(f"{name} {value:.1f} s" for name, value in parts.items()),
              flush=True)
    if len(rows) > 1:
        (n0, t0, c0, _), (n1, t1, c1, _) = rows[0], rows[-1]
        print(f"  wall ratio {t1 / t0:.2f}, CPU ratio {c1 / c0:.2f} for a length ratio {n1 / n0:.2f}; "
              f"marginal {1e6 * (t1 - t0) / (n1 - n0):.1f} µs a sample")
    for length in args.in_memory:
        train = record(folder, length, seed=1)
        seconds, cpu, peak, document = time_diagnose(train, validate, folder / f"diagnose_memory_{length}.json",
                                                     None, None, extra=("--memory-budget", "1TB"))  # in memory
        print(f"  in memory {length:>9} samples: wall {seconds:7.1f} s, CPU {cpu:7.1f} s, peak {peak:7.0f} MB; "
              f"{summary(document)}", flush=True)
    print(f"  load average {os.getloadavg()[0]:.1f}")
    if args.files:
        bench_files(folder, args.files, args.file_samples, args.chunk_size)


if __name__ == "__main__":
    main()
