"""Benchmark: identification of long records in bounded memory, and many files on a cluster.

KUKA LWR4+ (7 joints, URDF of ``../shared/data/kuka_lwr4``), internal model with viscous friction,
filter path (the files hold ``t, q1..q7, tau1..tau7`` only: Butterworth-filtered derivatives on
overlapping windows). The records are synthetic (the real runs have 5 027 samples): a random
5-harmonic Fourier motion at 1 kHz, torques from the model with the URDF's parameters and
viscous friction, white noise on positions (1e-5 rad) and torques (0.05 N m), written as Parquet in
row groups of 50 000 samples, chunk by chunk (the generator runs in bounded memory too).

Two parts:

* ``--lengths 100000 300000 1000000``: ``oed identify --chunk-size C --cutoff 5`` on one record
  of each length in a fresh process under ``/usr/bin/time -v`` (peak resident memory, wall time).
  Targets: peak < 1 GB, time linear in the length, 1 M samples in < 2 min. The run's ``cov_method``
  (``batch_means``: the standard deviations from a third pass over the file), the passes' seconds
  (``streaming.seconds``: sums pass, covariance pass) and the covariance pass's share are printed,
  with the median ratio of the batch-means to the classical standard deviations.
* ``--in-memory 100000 300000``: the same without ``--chunk-size`` (the in-memory path), and
  ``--chunk-sizes 1000 … 100000`` on the 300 000-sample record: the trade-off behind the default.
* ``--files 10 --file-samples 100000``: the ten records through :func:`estimation.streaming.cluster.sum_files`
  serially, in a 2-process pool and on a 2-worker dask ``LocalCluster`` (processes): wall times,
  cold (the workers import the toolkit and build the model on their first task) and warm (a second
  pass), and the estimates equal to 1e-10 (relative, norm-wise).

Run: ``python benchmarks/bench_streaming.py [--lengths N ...] [--files K --file-samples N]
[--chunk-size C] [--folder DIR]``. The records are kept in ``--folder`` (default a temporary
folder under /tmp) and reused when present.
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
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from dynamics.models import build_model  # noqa: E402
from dynamics.robots import load_robot  # noqa: E402
from oed.fourier import FourierTrajectory  # noqa: E402

URDF = ROOT / ".." / "shared" / "data" / "kuka_lwr4" / "kuka_lwr4.urdf"
RATE = 1000.0
CUTOFF = 5.0
ROW_GROUP = 50_000


def robot_and_model():
    robot = load_robot(urdf=URDF)
    return robot, build_model(robot, "internal", "viscous")


def trajectory(robot, seed: int) -> FourierTrajectory:
    generator = np.random.default_rng(seed)
    n, harmonics, frequency = robot.n_joints, 5, 0.1
    centre = np.zeros(n)
    a, b = generator.normal(size=(n, harmonics)), generator.normal(size=(n, harmonics))
    probe = FourierTrajectory(frequency, centre, a, b)
    _, q, dq, _ = probe.sample(100.0, 1)
    scale = 0.6 * np.minimum(1.2 / np.max(np.abs(q), axis=0), 1.0 / np.max(np.abs(dq), axis=0))
    return FourierTrajectory(frequency, centre, a * scale[:, None], b * scale[:, None])


def write_record(path: Path, n_samples: int, seed: int, truth=None) -> None:
    """A synthetic record (see the module docstring), written row group by row group; ``truth``:
    ``(robot, model, theta)`` of the torques (default the declared model with viscous friction 0.5)."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    if truth is None:
        robot, model = robot_and_model()
        theta = model.nominal_parameters(viscous=0.5)
    else:
        robot, model, theta = truth
    motion = trajectory(robot, seed)
    generator = np.random.default_rng(seed + 1000)
    n = robot.n_joints
    names = ["t"] + [f"q{i}" for i in range(1, n + 1)] + [f"tau{i}" for i in range(1, n + 1)]
    temporary = path.with_suffix(".partial")
    with pq.ParquetWriter(temporary, pa.schema([(name, pa.float64()) for name in names])) as writer:
        for start in range(0, n_samples, ROW_GROUP):
            t = np.arange(start, min(start + ROW_GROUP, n_samples)) / RATE
            q, dq, ddq = motion.evaluate(t)
            tau = model.predict(theta, q, dq, ddq) + 0.05 * generator.standard_normal((t.size, n))
            q = q + 1e-5 * generator.standard_normal(q.shape)
            table = np.column_stack([t, q, tau])
            writer.write_table(pa.table({name: table[:, i] for i, name in enumerate(names)}))
    temporary.replace(path)


def record(folder: Path, n_samples: int, seed: int, truth=None, prefix: str = "kuka") -> Path:
    path = folder / f"{prefix}_{n_samples}_{seed}.parquet"
    if not path.exists():
        started = time.perf_counter()
        write_record(path, n_samples, seed, truth)
        print(f"  wrote {path.name} in {time.perf_counter() - started:.1f} s", flush=True)
    return path


def time_identify(path: Path, chunk_size: int | None, out: Path,
                  validate: Path | None = None) -> tuple[float, float, float]:
    """Wall time (s), CPU time (user + system, s) and peak resident memory (MB) of ``oed identify`` on
    ``path`` in a fresh process (the CPU time is the steadier figure on a shared machine); without
    ``chunk_size`` the in-memory path; ``validate``: a validation record (the default answer is then chosen
    among the candidate models on it)."""
    command = ["/usr/bin/time", "-v", sys.executable, "-m", "oed", "identify", "--urdf", str(URDF), "--model",
               "internal", "--friction", "viscous", "--data", str(path), "--cutoff", str(CUTOFF), "--out", str(out)]
    if validate is not None:
        command += ["--validate", str(validate)]
    if chunk_size is not None:
        command += ["--chunk-size", str(chunk_size)]
    run = subprocess.run(command, capture_output=True, text=True, cwd=ROOT)
    if run.returncode != 0:
        raise RuntimeError(f"oed identify failed: {run.stderr[-2000:]}")
    peak = float(re.search(r"Maximum resident set size \(kbytes\): (\d+)", run.stderr).group(1)) / 1024
    wall = re.search(r"Elapsed \(wall clock\) time \(h:mm:ss or m:ss\): ([\d:.]+)", run.stderr).group(1)
    seconds = sum(float(part) * 60**index for index, part in enumerate(reversed(wall.split(":"))))
    cpu = sum(float(re.search(rf"{kind} time \(seconds\): ([\d.]+)", run.stderr).group(1)) for kind in ("User", "System"))
    return seconds, cpu, peak


def bench_lengths(folder: Path, lengths: list[int], chunk_size: int, validate_length: int | None = None) -> None:
    print(f"identify, filter path, chunks of {chunk_size} (KUKA, 7 joints, internal + viscous)"
          + (f", validated on another motion of {validate_length} samples" if validate_length else "") + ":")
    validate = None if not validate_length else record(folder, validate_length, seed=2)
    rows = []
    for length in lengths:
        path = record(folder, length, seed=1)
        seconds, cpu, peak = time_identify(path, chunk_size, folder / f"identify_{length}.json", validate)
        rows.append((length, seconds, cpu, peak))
        print(f"  {length:>9} samples: wall {seconds:7.1f} s, CPU {cpu:7.1f} s, peak {peak:7.0f} MB, "
              f"{1e6 * seconds / length:6.1f} µs a sample", flush=True)
        document = json.loads((folder / f"identify_{length}.json").read_text())
        print("            " + covariance_summary(document), flush=True)
        if document.get("model_selection"):
            selection = document["model_selection"]
            print(f"            chosen {selection['chosen']} ({selection['selection']}); scores "
                  + ", ".join(f"{c['name']} {c['score']:.4g}" for c in selection["candidates"] if c["score"] is not None),
                  flush=True)
    if len(rows) > 1:
        (n0, t0, c0, _), (n1, t1, c1, _) = rows[0], rows[-1]
        print(f"  wall ratio {t1 / t0:.2f}, CPU ratio {c1 / c0:.2f} for a length ratio {n1 / n0:.2f}")


def covariance_summary(document: dict) -> str:
    """``cov_method``, the passes' seconds and the covariance pass's share, and the std ratio."""
    seconds = document["streaming"].get("seconds", {})
    text = f"cov_method {document['cov_method']}"
    if "covariance_pass" in seconds:
        share = seconds["covariance_pass"] / sum(seconds.values())
        classical = document["streaming"]["covariance"]["classical_std"]
        ratio = np.median([entry["std"] / classical[entry["name"]] for entry in document["parameters"]])
        text += (f" (batch length {document['streaming']['covariance']['batch_length']}): sums pass "
                 f"{seconds['sums_pass']:.1f} s, covariance pass {seconds['covariance_pass']:.1f} s "
                 f"({100 * share:.0f} % of the passes and solve), median std / classical std {ratio:.2f}")
    return text


def bench_in_memory(folder: Path, lengths: list[int]) -> None:
    print("identify, in memory (no --chunk-size), for comparison:")
    for length in lengths:
        path = record(folder, length, seed=1)
        seconds, cpu, peak = time_identify(path, None, folder / f"identify_memory_{length}.json")
        print(f"  {length:>9} samples: wall {seconds:7.1f} s, CPU {cpu:7.1f} s, peak {peak:7.0f} MB", flush=True)


def bench_chunk_sizes(folder: Path, length: int, sizes: list[int]) -> None:
    print(f"identify on {length} samples by chunk size (the choice of the default):")
    path = record(folder, length, seed=1)
    for size in sizes:
        seconds, cpu, peak = time_identify(path, size, folder / f"identify_chunk_{size}.json")
        print(f"  chunks of {size:>6}: wall {seconds:7.1f} s, CPU {cpu:7.1f} s, peak {peak:7.0f} MB", flush=True)


def bench_files(folder: Path, count: int, samples: int, chunk_size: int) -> None:
    from estimation.streaming.cluster import sum_files
    from estimation.estimators.summed_least_squares import SummedLeastSquares

    paths = [record(folder, samples, seed=10 + index) for index in range(count)]
    _, model = robot_and_model()
    options = dict(chunk_size=chunk_size, cutoff_hz=CUTOFF)
    results = {}
    started = time.perf_counter()
    total, _ = sum_files(model, paths, **options)
    results["serial"] = (time.perf_counter() - started, total)
    with ProcessPoolExecutor(2) as executor:
        for label in ("process pool (2), cold", "process pool (2), warm"):  # cold: workers import and build
            started = time.perf_counter()
            total, _ = sum_files(model, paths, executor=executor, **options)
            results[label] = (time.perf_counter() - started, total)
    try:
        from dask.distributed import Client, LocalCluster
    except ImportError:
        print("  dask not installed (pip install 'robot-oed[cluster]'): no cluster run")
    else:
        with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as cluster, \
                Client(cluster) as client:
            for label in ("dask LocalCluster (2 workers), cold", "dask LocalCluster (2 workers), warm"):
                started = time.perf_counter()
                total, _ = sum_files(model, paths, executor=client.get_executor(pure=False), **options)
                results[label] = (time.perf_counter() - started, total)
    reference = SummedLeastSquares().fit(results["serial"][1]).theta_
    print(f"{count} files of {samples} samples, filter path, chunks of {chunk_size}:")
    for label, (seconds, total) in results.items():
        theta = SummedLeastSquares().fit(total).theta_
        difference = np.linalg.norm(theta - reference) / np.linalg.norm(reference)
        print(f"  {label:<36} {seconds:7.1f} s  ({total.n_samples} samples; estimate vs serial {difference:.1e})")
    print(f"  load average {os.getloadavg()[0]:.1f}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--lengths", type=int, nargs="*", default=[100_000, 300_000, 1_000_000])
    parser.add_argument("--files", type=int, default=10)
    parser.add_argument("--file-samples", type=int, default=100_000)
    parser.add_argument("--chunk-size", type=int, default=10_000)
    parser.add_argument("--folder", type=Path)
    parser.add_argument("--validate-length", type=int, default=0,
                        help="samples of a validation record of another motion given to the --lengths runs (0: none)")
    parser.add_argument("--in-memory", type=int, nargs="*", default=[100_000, 300_000],
                        help="lengths also identified in memory, for comparison")
    parser.add_argument("--chunk-sizes", type=int, nargs="*", default=[1000, 3000, 10_000, 30_000, 100_000],
                        help="chunk sizes tried on the 300 000-sample record")
    args = parser.parse_args()
    folder = args.folder or Path(tempfile.gettempdir()) / "robot_oed_bench_streaming"
    folder.mkdir(parents=True, exist_ok=True)
    print(f"records in {folder}; {os.cpu_count()} cores, load average {os.getloadavg()[0]:.1f} (other jobs make wall "
          "times longer: the CPU times of the identify runs are the steadier figure)")
    if args.lengths:
        bench_lengths(folder, args.lengths, args.chunk_size, args.validate_length or None)
    if args.in_memory:
        bench_in_memory(folder, args.in_memory)
    if args.chunk_sizes:
        bench_chunk_sizes(folder, 300_000, args.chunk_sizes)
    if args.files:
        bench_files(folder, args.files, args.file_samples, args.chunk_size)


if __name__ == "__main__":
    main()
