"""Benchmark: the diagnosis (``estimation.diagnosis.search.diagnose``) with every default candidate, plain
and shaped (``coulomb:tanh``, ``stribeck:velocity``, ``sigmoid``, ``ripple``).

1. PUMA 560, 3 joints, internal model, two simulated 10 000-sample records (1 kHz, 0.2 Hz Fourier
   motion) with undeclared tanh Coulomb friction (smoothing 0.03 rad/s) and offsets. Target < 10 s.
2. KUKA LWR4+, 7 joints: identify on run 1, validate on run 3 (``../shared/data/kuka_lwr4``;
   skipped when absent). Target < 30 s.
3. End to end, as a user runs it: ``oed diagnose`` in a new process (imports, reading, the derivatives chosen by
   held-out error, the search, the report) on a 7-joint log of 14 000 samples, the KUKA LWR4+ URDF simulated by
   ``oed simulate`` under PD control (1 kHz, two 7 s periods of a 5-harmonic Fourier excitation, Coulomb
   friction and offsets the declared viscous model lacks; positions and torques only). Target ≤ 10 s. The
   baseline, timed in the same run: one least-squares fit of the declared model's stacked regressor on the
   training record (``numpy.linalg.lstsq``, 98 000 rows): the ratio says how many such fits the whole
   diagnosis costs, whatever the machine's speed (``--skip-end-to-end`` leaves it out). With ``--excitation
   TRAJECTORY.json`` (a designed excitation, as ``benchmarks/README.md`` ran it: "Where the time of `oed diagnose`
   goes"), the records are simulated from it, three seeds (training, validation, test), in two cases: the URDF's
   own friction (the declared model is at its noise floor: one round of candidates, nothing added) and Coulomb
   friction and offsets of 0.1–3 N·m (14 effects to find); each is timed end to end against the same fit.
   With ``--baseline COMMIT`` (default ``6dc3793``, ``main`` when issue 34 was filed; ``none`` leaves it out), the
   same ``oed diagnose`` of that commit of this repository (``git archive`` into a temporary folder, checked to be
   the code the process imports), timed in the same run: ``--repeats`` pairs, the commit's run and this checkout's
   alternating, each in a new process (``OMP_NUM_THREADS=1``), the ratio this/baseline of wall and CPU time taken
   pair by pair and its median printed (issue 34: "within 1.5x of today's time"). With ``--panda``, part 3 alone on
   the real Franka Panda instead (``bench_real_robots.py``'s training and validation files: 7 joints, 13 840
   training samples), against the baseline.

Parts 1 and 2 time ``diagnose`` alone (the records are made or loaded before), one run, with the
compiled column functions already in the cache (``~/.cache/robot-oed``; a first run compiles them
once, a few seconds more). Run: ``python benchmarks/bench_diagnose.py [--skip-kuka] [--skip-end-to-end] [--excitation TRAJECTORY.json]
[--baseline COMMIT|none] [--repeats N] [--panda]``.
"""

from __future__ import annotations

import argparse
import dataclasses
import io
import os
import resource
import subprocess
import sys
import tarfile
import tempfile
import time
from pathlib import Path

import numpy as np

from dynamics.effects.linear import CoulombFriction, JointOffset
from dynamics.models import build_model
from dynamics.robots import load_robot
from dynamics.runtime.threads import single_threaded_blas
from estimation.diagnosis.search import diagnose
from dynamics.simulation.synthetic import simulate, true_parameters
from estimation.data.records import read_record
from estimation.estimators.identification_problem import stack
from estimation.preprocessing.plan import choose_preprocessing, prepare
from oed.fourier import random_fourier

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT.parent / "shared" / "data" / "kuka_lwr4"


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


def oed_command(*arguments: str, code: Path = ROOT, cwd: Path | None = None) -> tuple[float, float]:
    """``python -m oed ARGUMENTS`` in a new process, the package imported from ``code`` (this checkout, or a
    baseline commit's export) run in ``cwd`` (default ``code``): its wall time and its CPU time (user + system),
    s."""
    environment = dict(os.environ, PYTHONPATH=os.pathsep.join(filter(None, [str(code), os.environ.get("PYTHONPATH")])),
                       OMP_NUM_THREADS=os.environ.get("OMP_NUM_THREADS", "1"))
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    start = time.perf_counter()
    # the working folder comes first on sys.path (``-m``): never this checkout's when timing another code
    subprocess.run([sys.executable, "-m", "oed", *arguments], check=True, env=environment, cwd=code if cwd is None else cwd,
                   stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    wall = time.perf_counter() - start
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return wall, (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)


#: the Coulomb friction and offsets the declared viscous model lacks (part 3, "effects")
EFFECT_VALUES = '{"coulomb": [3.0, 3.0, 2.0, 2.0, 1.0, 0.5, 0.5], "offset": [0.5, -0.5, 0.3, -0.3, 0.2, 0.1, -0.1]}'


def seven_joint_log(folder: Path, trajectory: Path | None = None, values: str | None = EFFECT_VALUES,
                    records: tuple[str, ...] = ("train", "validate")) -> tuple[Path, ...]:
    """Records of the KUKA LWR4+ simulated by ``oed simulate`` (part 3), seeds 1, 2, …: from ``trajectory``
    (default a random 5-harmonic excitation at 1/7 Hz), with Coulomb friction and offsets of ``values`` (``None``:
    the URDF's own)."""
    if trajectory is None:
        robot = load_robot(urdf=DATA / "kuka_lwr4.urdf")
        trajectory = folder / "excitation.json"
        random_fourier(robot, seed=1, frequency_hz=1 / 7, harmonics=5).save(trajectory)
    paths = tuple(folder / f"{name}.csv" for name in records)
    for seed, path in enumerate(paths, start=1):
        oed_command("simulate", "--urdf", str(DATA / "kuka_lwr4.urdf"), "--trajectory", str(trajectory),
                    "--effects", "coulomb,offset", *(("--effect-values", values) if values else ()), "--bandwidth",
                    "10", "--periods", "2", "--warmup-periods", "1", "--seed", str(seed), "--out", str(path))
    return paths


def one_fit_seconds(train_path: Path, repeats: int = 5) -> float:
    """The baseline: the fastest of ``repeats`` least-squares fits of the declared model on the training record."""
    model = build_model(load_robot(urdf=DATA / "kuka_lwr4.urdf"), "internal", "viscous")
    train = read_record(train_path, model=model)
    prepared = prepare(train, choose_preprocessing(train, frequency_hz=1 / 7, harmonics=80))
    Y, y = stack(model, prepared.as_recorded).stacked()
    times = []
    with single_threaded_blas():  # as the CLI runs
        for _ in range(repeats):
            start = time.perf_counter()
            np.linalg.lstsq(Y, y, rcond=None)
            times.append(time.perf_counter() - start)
    print(f"   baseline: one least-squares fit of the declared model, {Y.shape[0]} x {Y.shape[1]}: "
          f"{min(times) * 1e3:.1f} ms")
    return min(times)


def baseline_code(commit: str, folder: Path) -> Path:
    """``commit`` of this repository exported into ``folder`` (``git archive``), checked to be the package a process
    run there imports."""
    archive = subprocess.run(["git", "-C", str(ROOT), "archive", commit], check=True, capture_output=True).stdout
    with tarfile.open(fileobj=io.BytesIO(archive)) as tar:
        tar.extractall(folder, filter="data")
    environment = dict(os.environ, PYTHONPATH=str(folder))
    imported = subprocess.run([sys.executable, "-c", "import oed; print(oed.__file__)"], check=True, env=environment,
                              cwd=folder, capture_output=True, text=True).stdout.strip()
    if Path(imported).resolve().parent != (folder / "oed").resolve():
        raise RuntimeError(f"the baseline {commit} imports {imported}, not its export in {folder}")
    return folder


def against_baseline(arguments: list[str], commit: str, repeats: int, folder: Path) -> None:
    """``oed diagnose ARGUMENTS`` of this checkout against ``commit``'s: ``repeats`` pairs, alternating, after one
    unreported run of each (compiled functions into the cache); the ratios' medians."""
    code = baseline_code(commit, folder / f"baseline-{commit}")
    runs = {"baseline": [], "this": []}
    for index in range(repeats + 1):
        for name, where in (("baseline", code), ("this", ROOT)):
            timing = oed_command(*arguments, code=where, cwd=folder)
            if index:
                runs[name].append(timing)
    ratios = [(this[0] / base[0], this[1] / base[1]) for this, base in zip(runs["this"], runs["baseline"])]
    median = lambda values: float(np.median(values))  # noqa: E731
    print(f"   against {commit} (the same command, {repeats} pairs alternating, medians): wall "
          f"{median([r[0] for r in runs['this']]):.1f} s / {median([r[0] for r in runs['baseline']]):.1f} s, CPU "
          f"{median([r[1] for r in runs['this']]):.1f} s / {median([r[1] for r in runs['baseline']]):.1f} s; ratio "
          f"this/baseline wall {median([r[0] for r in ratios]):.2f}x, CPU {median([r[1] for r in ratios]):.2f}x "
          "(issue 34: at most 1.5x)")


def end_to_end(target_s: float = 10.0, excitation: Path | None = None, baseline: str | None = None,
               repeats: int = 3) -> None:
    """Part 3: ``oed diagnose`` on a simulated 7-joint 14 000-sample log, against one least-squares fit (with a
    designed ``excitation``: the two cases of ``benchmarks/README.md``, training, validation and test records), and
    against a ``baseline`` commit's ``oed diagnose`` (:func:`against_baseline`)."""
    cases = {"random excitation, effects": EFFECT_VALUES} if excitation is None else \
        {"at its floor": None, "14 effects": EFFECT_VALUES}
    for label, values in cases.items():
        with tempfile.TemporaryDirectory() as folder:
            records = ("train", "validate") if excitation is None else ("train", "validate", "test")
            paths = seven_joint_log(Path(folder), excitation, values, records)
            fit = one_fit_seconds(paths[0])
            arguments = ["diagnose", "--urdf", str(DATA / "kuka_lwr4.urdf"), "--data", str(paths[0]), "--validate",
                         str(paths[1]), "--out", str(Path(folder) / "report.json")]
            if len(paths) > 2:
                arguments += ["--test", str(paths[2])]
            wall, cpu = oed_command(*arguments)
            print(f"KUKA LWR4+ simulated, 7 joints, 14 000-sample records, {label}: `oed diagnose` end to end "
                  f"{wall:.1f} s (target <= {target_s:g} s; CPU {cpu:.1f} s), {wall / fit:.0f} least-squares fits "
                  "of the record")
            if baseline is not None:
                against_baseline(arguments, baseline, repeats, Path(folder))


def panda_against_baseline(baseline: str | None, repeats: int) -> None:
    """Part 3 on the real Franka Panda (``--panda``): ``oed diagnose`` on ``bench_real_robots.py``'s training and
    validation files (7 joints, 13 616 training rows, read as 13 840 uniform samples) against ``baseline``'s
    (:func:`against_baseline`)."""
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    from bench_real_robots import DATA as SHARED, panda

    if not (SHARED / "panda").is_dir():
        print("Franka Panda: skipped (no ../shared/data/panda)")
        return
    with tempfile.TemporaryDirectory() as folder:
        case = panda(Path(folder))
        arguments = ["diagnose", *case.robot, "--data", str(case.files["train"]), "--validate",
                     str(case.files["validate"]), "--out", str(Path(folder) / "report.json")]
        wall, cpu = oed_command(*arguments)
        print(f"Franka Panda (real, 7 joints, {case.records['train'].t.shape[0]} training rows): `oed diagnose` end "
              f"to end {wall:.1f} s (CPU {cpu:.1f} s)")
        if baseline is not None:
            against_baseline(arguments, baseline, repeats, Path(folder))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--skip-kuka", action="store_true")
    parser.add_argument("--skip-end-to-end", action="store_true")
    parser.add_argument("--excitation", type=Path, default=None,
                        help="a designed trajectory JSON for part 3 (default: a random 5-harmonic excitation)")
    parser.add_argument("--baseline", default="6dc3793",
                        help="a commit whose `oed diagnose` part 3 also times, alternating ('none': not timed)")
    parser.add_argument("--repeats", type=int, default=3, help="pairs of runs against the baseline (default 3)")
    parser.add_argument("--panda", action="store_true",
                        help="part 3 on the real Franka Panda's training and validation files instead, against the "
                             "baseline, and nothing else")
    args = parser.parse_args()
    if args.panda:
        panda_against_baseline(None if args.baseline.lower() == "none" else args.baseline, args.repeats)
        return
    if not args.skip_end_to_end and DATA.is_dir():
        end_to_end(excitation=args.excitation, baseline=None if args.baseline.lower() == "none" else args.baseline,
                   repeats=args.repeats)
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
